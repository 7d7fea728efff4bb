"""Named suites of synthetic sequences, written to stores and regenerated only when stale.

- ``synthetic-paper``: the paper's eleven sequences imitated (same names, classes and sensor
  densities, modest sizes): each through the sensor model and the ground-truth pipeline of the
  dataset it imitates (``imitates``; groundtruth.py). What `make reproduce-table` runs without
  the real data.
- ``synthetic-clean``: the same scenes, sensors and seeds with exact ground truth, for method
  development (errors of the method alone).
- ``synthetic-ci``: small sequences of the generic sensors with exact ground truth for CI
  regression (configs/experiments/ci.yaml).

Each store is ``data_dir/<suite>/<Name>.h5``. Its provenance holds ``suite_entry_hash``: a hash
of the entry's parameters and of the generator's code (the content of every
``loaders/synthetic/*.py``), so any change of the generator regenerates the stores; a file is
rewritten only when that hash changes (or it is missing or unreadable).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from loaders.errors import DataError
from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR
from loaders.store import StoreSequence, write_store
from loaders.synthetic.codehash import current_code_hash
from loaders.synthetic.generate import SyntheticSequence

SPARSE, SEMI_DENSE, DENSE = SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR
#: what every store of a synthetic suite says about itself (provenance "notice")
NOTICE = ("synthetic data imitating {imitates}; made by this repository's generator, not the "
          "paper's data")


@dataclass(frozen=True)
class SuiteEntry:
    """One sequence of a suite. ``name`` is the file stem, ``display`` the paper's name,
    ``klass`` the sensor class label, ``imitates`` the real sequence it imitates (provenance;
    empty for sequences that imitate none)."""

    name: str
    display: str
    klass: str
    scene: str
    sensor: str
    frames: int
    seed: int
    options: dict = field(default_factory=dict)
    noise: bool = True
    imitates: str = ""

    def params(self) -> dict:
        return asdict(self)

    def entry_hash(self, code_hash: str | None = None) -> str:
        """Hash of the parameters and of the generator's code (``code_hash``, default the
        installed generator's: codehash.py)."""
        text = json.dumps({**self.params(), "generator_code": code_hash or current_code_hash()},
                          sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def sequence(self, suite: str = "") -> SyntheticSequence:
        """The generator for this entry (scans are produced on demand)."""
        meta = {"suite": suite, "display_name": self.display, "class": self.klass,
                "suite_entry_hash": self.entry_hash(), "generator_code_hash": current_code_hash()}
        if self.imitates:
            meta.update(imitates=self.imitates, notice=NOTICE.format(imitates=self.imitates))
        return SyntheticSequence(self.scene, self.sensor, self.frames, self.seed, self.noise,
                                 name=self.name, meta=meta, **self.options)


#: the speed of the DICP CARLA sample (aevainc/Doppler-ICP dataset/sample: 1.69 m per 0.1 s
#: frame, shared/REFERENCE.md), +-2.4 %
CARLA_SPEED = (16.5, 17.3)
_CAMPUS = {"gt": "campus"}
_NTU = {"gt": "ntu4dradlm"}
_CARLA = {"speed": CARLA_SPEED}
# the real Aeva tunnel data has per-point times (sweep); the Baker-Barry tunnel is a concrete-
# lined bore with LED ceiling lights and no documented ribs (CBS SF and Marin IJ, 2016), where
# every geometric ICP of the paper diverges (Table V): a smooth lining (rib_spacing 0); one
# lane with alternating signals, so its traffic drives with the ego (one_lane); README.md
_TUNNEL = {"sweep": True, "rib_spacing": 0}
_CAMPUS_SRC = "the Campus dataset's {} (ZF FRGen21 sparse 4D radar, NovAtel GNSS/INS GT)"
_NTU_SRC = "NTU4DRadLM loop 1, bag {} (Oculii Eagle semi-dense 4D radar, R2LIVE GT)"
_CARLA_SRC = "the DICP CARLA sequence {} (simulated Aeva FMCW LiDAR, exact GT)"
_AEVA_SRC = "the Aeva Baker-Barry tunnel sequence {} (Aeva Aeries I FMCW LiDAR)"

SYNTHETIC_PAPER = [
    SuiteEntry("Campus1", "Campus1", SPARSE, "campus", "radar-frgen21", 220, 101, _CAMPUS,
               imitates=_CAMPUS_SRC.format("Campus1")),
    SuiteEntry("Campus2", "Campus2", SPARSE, "campus", "radar-frgen21", 220, 102, _CAMPUS,
               imitates=_CAMPUS_SRC.format("Campus2")),
    SuiteEntry("Loop1_0", "Loop1_0", SEMI_DENSE, "loop", "radar-eagle", 180, 110, _NTU,
               imitates=_NTU_SRC.format("0 (Loop1_0)")),
    SuiteEntry("Loop1_1", "Loop1_1", SEMI_DENSE, "loop", "radar-eagle", 180, 111, _NTU,
               imitates=_NTU_SRC.format("1 (Loop1_1)")),
    SuiteEntry("Loop1_2", "Loop1_2", SEMI_DENSE, "loop", "radar-eagle", 180, 112, _NTU,
               imitates=_NTU_SRC.format("2 (Loop1_2)")),
    SuiteEntry("Loop1_3", "Loop1_3", SEMI_DENSE, "loop", "radar-eagle", 180, 113, _NTU,
               imitates=_NTU_SRC.format("3 (Loop1_3)")),
    SuiteEntry("Loop1_4", "Loop1_4", SEMI_DENSE, "loop", "radar-eagle", 200, 114,
               {**_NTU, "uturn": True}, imitates=_NTU_SRC.format("4 (Loop1_4, with a U-turn)")),
    SuiteEntry("StraightWall", "Straight Wall", DENSE, "straight-wall", "lidar-aeva", 80, 120,
               _CARLA, imitates=_CARLA_SRC.format("Straight Wall (Town04)")),
    SuiteEntry("CurvedWall", "Curved Wall", DENSE, "curved-wall", "lidar-aeva", 80, 121,
               _CARLA, imitates=_CARLA_SRC.format("Curved Wall (Town05)")),
    SuiteEntry("Tunnel_Empty", "Baker-Barry Tunnel (Empty)", DENSE, "tunnel", "lidar-aeva", 80,
               122, _TUNNEL, imitates=_AEVA_SRC.format("00 (Empty)")),
    SuiteEntry("Tunnel_Vehicles", "Baker-Barry Tunnel (Vehicles)", DENSE, "tunnel-vehicles",
               "lidar-aeva", 80, 123, {**_TUNNEL, "one_lane": True},
               imitates=_AEVA_SRC.format("01 (Vehicles)")),
]


def _clean(entry: SuiteEntry) -> SuiteEntry:
    """The entry with exact ground truth."""
    return replace(entry, options={k: v for k, v in entry.options.items() if k != "gt"})


SUITES: dict[str, list[SuiteEntry]] = {
    "synthetic-paper": SYNTHETIC_PAPER,
    "synthetic-clean": [_clean(e) for e in SYNTHETIC_PAPER],
    # small sequences of the generic sensors (exact GT) for CI regression
    # (configs/experiments/ci.yaml): their data does not depend on the paper calibration
    "synthetic-ci": [
        SuiteEntry("ci-sparse", "CI sparse radar", SPARSE, "campus", "radar-sparse", 60, 201),
        SuiteEntry("ci-semidense", "CI semi-dense radar", SEMI_DENSE, "loop", "radar-semidense",
                   50, 202),
        SuiteEntry("ci-uturn", "CI semi-dense radar U-turn", SEMI_DENSE, "loop",
                   "radar-semidense", 50, 203, {"uturn": True}),
        SuiteEntry("ci-tunnel", "CI dense LiDAR tunnel", DENSE, "tunnel", "lidar-dense", 25, 204,
                   {"points": 8000}),
        SuiteEntry("ci-wall", "CI dense LiDAR straight wall", DENSE, "straight-wall",
                   "lidar-dense", 25, 205, {"points": 8000}),
    ],
}


def suite_entries(name: str) -> list[SuiteEntry]:
    """The entries of suite ``name``."""
    if name not in SUITES:
        raise DataError(f"unknown synthetic suite {name!r}; known: {', '.join(SUITES)}")
    return list(SUITES[name])


def store_is_current(path: Path, entry: SuiteEntry) -> bool:
    """True when ``path`` is a readable store written for exactly this entry."""
    if not path.exists():
        return False
    try:
        store = StoreSequence(path)
    except DataError:
        return False
    try:
        return store.provenance.get("suite_entry_hash") == entry.entry_hash()
    finally:
        store.close()


def ensure_suite(name: str, data_dir: str | Path,
                 progress: Callable[[str, int, int], None] | None = None,
                 writer: Callable = write_store) -> list[Path]:
    """Write the stores of suite ``name`` under ``data_dir/name/`` (only missing or stale ones)
    and return their paths in suite order. ``progress(entry_name, done, total)`` is called after
    each written frame, and once with done == total for a store that is already current.
    ``writer(sequence, path, progress)``: the store writer (bench passes its output guard's, so
    a file of the suite's name that is not a synthetic store is never replaced)."""
    entries = suite_entries(name)
    out_dir = Path(data_dir) / name
    paths = []
    for entry in entries:
        path = out_dir / f"{entry.name}.h5"
        if store_is_current(path, entry):
            if progress:
                progress(entry.name, entry.frames, entry.frames)
        else:
            seq = entry.sequence(name)
            cb = None
            if progress:
                def cb(i, _n=entry.name, _t=entry.frames):
                    progress(_n, i + 1, _t)
            writer(seq, path, cb)
        paths.append(path)
    return paths
