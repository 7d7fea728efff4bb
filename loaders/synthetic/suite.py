"""Named suites of synthetic sequences, written to stores and regenerated only when stale.

``synthetic-paper`` mirrors the paper's evaluation sequences (same names, classes and sensor
densities) with modest sizes so that every method runs on all of it quickly. Each store is
``data_dir/<suite>/<Name>.h5``; its provenance holds ``suite_entry_hash`` (the entry's
parameters + the generator version) and the file is rewritten only when that hash changes
(or the file is missing or unreadable).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from loaders.errors import DataError
from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR
from loaders.store import StoreSequence, write_store
from loaders.synthetic.generate import GENERATOR_VERSION, SyntheticSequence

SPARSE, SEMI_DENSE, DENSE = SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR


@dataclass(frozen=True)
class SuiteEntry:
    """One sequence of a suite. ``name`` is the file stem, ``display`` the paper's name,
    ``klass`` the sensor class label."""

    name: str
    display: str
    klass: str
    scene: str
    sensor: str
    frames: int
    seed: int
    options: dict = field(default_factory=dict)
    noise: bool = True

    def params(self) -> dict:
        return asdict(self)

    def entry_hash(self) -> str:
        text = json.dumps({**self.params(), "generator_version": GENERATOR_VERSION},
                          sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def sequence(self, suite: str = "") -> SyntheticSequence:
        """The generator for this entry (scans are produced on demand)."""
        meta = {"suite": suite, "display_name": self.display, "class": self.klass,
                "suite_entry_hash": self.entry_hash()}
        return SyntheticSequence(self.scene, self.sensor, self.frames, self.seed, self.noise,
                                 name=self.name, meta=meta, **self.options)


_LIDAR = {"points": 50000}

SUITES: dict[str, list[SuiteEntry]] = {
    "synthetic-paper": [
        SuiteEntry("Campus1", "Campus1", SPARSE, "campus", "radar-sparse", 220, 101),
        SuiteEntry("Campus2", "Campus2", SPARSE, "campus", "radar-sparse", 220, 102),
        SuiteEntry("Loop1_0", "Loop1_0", SEMI_DENSE, "loop", "radar-semidense", 180, 110),
        SuiteEntry("Loop1_1", "Loop1_1", SEMI_DENSE, "loop", "radar-semidense", 180, 111),
        SuiteEntry("Loop1_2", "Loop1_2", SEMI_DENSE, "loop", "radar-semidense", 180, 112),
        SuiteEntry("Loop1_3", "Loop1_3", SEMI_DENSE, "loop", "radar-semidense", 180, 113),
        SuiteEntry("Loop1_4", "Loop1_4", SEMI_DENSE, "loop", "radar-semidense", 200, 114,
                   {"uturn": True}),
        SuiteEntry("StraightWall", "Straight Wall", DENSE, "straight-wall", "lidar-dense", 80,
                   120, dict(_LIDAR)),
        SuiteEntry("CurvedWall", "Curved Wall", DENSE, "curved-wall", "lidar-dense", 80, 121,
                   dict(_LIDAR)),
        # the real Aeva tunnel data has per-point times (sweep); Baker-Barry has one lane with
        # alternating signals, so its traffic drives with the ego (one_lane); README.md
        SuiteEntry("Tunnel_Empty", "Baker-Barry Tunnel (Empty)", DENSE, "tunnel",
                   "lidar-dense", 80, 122, {**_LIDAR, "sweep": True}),
        SuiteEntry("Tunnel_Vehicles", "Baker-Barry Tunnel (Vehicles)", DENSE,
                   "tunnel-vehicles", "lidar-dense", 80, 123,
                   {**_LIDAR, "sweep": True, "one_lane": True}),
    ],
    # small sequences of every sensor class for CI regression (configs/experiments/ci.yaml)
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
                 progress: Callable[[str, int, int], None] | None = None) -> list[Path]:
    """Write the stores of suite ``name`` under ``data_dir/name/`` (only missing or stale ones)
    and return their paths in suite order. ``progress(entry_name, done, total)`` is called after
    each written frame, and once with done == total for a store that is already current."""
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
            write_store(seq, path, cb)
        paths.append(path)
    return paths
