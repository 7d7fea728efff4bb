"""Snail-Radar (Huai et al., Wuhan University; ODbL + DbCL): Oculii Eagle G7 or Continental
ARS548 4D radar scans from a sequence's ROS1 bag or its extracted folder.

Facts from the dataset's own tools (github.com/snail-radar/dataset_tools) and site
(snail-radar.github.io/docs/format.html):

- 44 sequences (``python/dataset_metadata.py``: 59 m to 8.5 km), grouped by day:
  ``20240123/data3`` (afternoon / evening groups end in ``_aft`` / ``_eve``). Each sequence is a
  monolithic ROS1 bag and an extracted folder.
- Topics (``matlab/frame_ids.md``, ``python/bag_to_folder.py``): Eagle ``/radar_enhanced_pcl2``
  and ``/radar_pcl2`` (``sensor_msgs/PointCloud2``: x y z Doppler Range Power Alpha Beta
  rangeAccu aziAccu eleAccu dopplerAccu recoveredSpeed dotFlags denoiseFlag historyFrameFlag
  dopplerCorrectionFlag, all float32, frame ``oculii``: xyz forward-left-up); ARS548
  ``/ars548`` (x y z doppler intensity range_std azimuth_std elevation_std doppler_std,
  float32, frame ``ars548``: forward-left-up; in the bags doppler sits at byte 16 after 4
  bytes of padding, ``python/folder_to_bag.py`` ``create_point_cloud2_msg``). Fields are read
  by NAME, never by offset.
- Extracted folders (``bag_to_folder.py``): ``ars548/points``, ``eagleg7/enhanced``,
  ``eagleg7/pcl`` (and ``eagleg7/trk``, ``xt32``), each ``<sec>.<nsec:09d>.pcd`` named by the
  message's ``header.stamp`` plus ``times.txt`` (one such stamp per line). PCD ``DATA binary``
  (or ``ascii``), every value float32 (``loaders.pcd``).
- Extrinsics (``matlab/``; the body frame is at the Hesai XT32 lidar, forward-left-up,
  ``matlab/readme.md``): ``Body_T_Oculii.m`` "refined" (the default of the published script:
  rotation estimated from Eagle ego velocity against the X36D INS, ``R_body_x36d @
  R_x36d_oculii``, ``p = (0.07, 0, -0.115)``; its "manual" variant is the older hand-measured
  identity rotation, available as ``extrinsic="manual"``), ``Body_T_Ars548.m`` (depends on the
  date: the radar was remounted several times; ``p = (0, 0, 0.07)``), ``Body_T_X36d.m``,
  ``Body_T_Xt32.m`` (``R_body_xt32 = [[0,-1,0],[1,0,0],[0,0,1]]``, lidar axes left-back-up).
  The date comes from the sequence's group folder like ``matlab/convert_seqname_to_dateval.m``
  (``20231105_aft`` -> 20231105.5) or the ``date`` option.
- Ground truth: the reference motion of the XT32 lidar from lidar-inertial localisation in a
  terrestrial-laser-scan map, only where the map covers (long sequences: their start and end),
  as TUM rows ``t x y z qx qy qz qw`` of ``T_world_xt32`` (the authors' files are named
  ``tls_T_xt32.txt`` / ``utm50r_T_xt32.txt``). It is interpolated at the scan stamps between
  GT rows at most ``max_gap_s`` apart (``loaders.gt.associate``); scans inside a longer gap
  keep no pose (never interpolated across: a scored segment never uses an invented pose) and
  are only excluded from scoring. ``gt_frame="body"`` takes rows of ``T_world_body`` instead.
  The same reference trajectory circulates as ``ref_trajs/<date>/<run>/ref_tls_T_xt32.csv``
  (comma-separated, one ``#`` header line, 11 columns ``time, M_p_L_x, M_p_L_y, M_p_L_z,
  M_q_L_x, M_q_L_y, M_q_L_z, M_q_L_w, W_v_L_x, W_v_L_y, W_v_L_z``: the header the authors' TLS
  localisation writes; ``M_p_L`` / ``M_q_L`` the XT32 lidar's pose in the map, the same frame
  as the TUM ``tls_T_xt32``; the world velocity is not used). Without ``gt`` these names are
  looked for in the sequence folder, then in ``ref_trajs/<date>/<run>/`` and
  ``full_trajs/<date>/<run>/`` (gaussian-rio's ``full_trajs/<day>/dataN/utm50r_T_xt32.txt``)
  in the folders above the sequence (``find_gt_file``), and the first GT position is
  subtracted (``remove_gt_origin``: UTM -> metres from the start).
  ``T_world_radar = T_world_xt32 @ inv(T_body_xt32) @ T_body_radar`` (``provenance
  ["T_gtbody_radar"]``); ``sensor.T_body_sensor`` is ``T_body_radar``, the radar in the
  dataset's forward-left-up body frame (the vehicle frame for methods that use one).
- Doppler: both radars publish the raw relative radial velocity of each detection (not
  ego-motion compensated; the dataset's extrinsic rotations were themselves estimated from
  these values against the INS velocity, ``Body_T_Oculii.m`` / ``Body_T_Ars548.m``). The tools
  state no sign; the Oculii driver's ``Doppler`` is positive when the target recedes (the
  convention this harness confirmed on NTU4DRadLM's Eagle frames, REFERENCE.md), and the ARS548
  range rate likewise (*unconfirmed* on this dataset: ``bench inspect`` checks the sign against
  the GT; ``doppler_sign=-1`` flips it).
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from loaders.assemble import finish_scan, median_period
from loaders.errors import DataError
from loaders.gt import associate
from loaders.limits import check_file_size
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.pcd import read_pcd
from loaders.posefile import parse_extrinsic, read_gt_file
from loaders.ros1 import BagTopic, sort_unique_stamps, topic_stamps
from loaders.ros1_msgs import parse_pointcloud2
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.se3 import inv_T, make_T

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"

#: sensor -> (bag topic, folder under the sequence, Doppler field, model, nominal period [s])
STREAMS = {
    ("eagle", "enhanced"): ("/radar_enhanced_pcl2", "eagleg7/enhanced", "Doppler"),
    ("eagle", "pcl"): ("/radar_pcl2", "eagleg7/pcl", "Doppler"),
    ("ars548", "points"): ("/ars548", "ars548/points", "doppler"),
}
#: sensor model = the harness's sensor class key (``loaders.sensor_classes.BY_MODEL``)
MODELS = {"eagle": "radar-semidense", "ars548": "radar-sparse"}
SENSOR_NAMES = {"eagle": "Oculii Eagle G7", "ars548": "Continental ARS548"}
DEFAULT_PERIOD_S = {"eagle": 0.1, "ars548": 0.05}


def _rotation(R: list[list[float]]) -> np.ndarray:
    """The rotation nearest to ``R`` (the published matrices are rounded to 15 digits)."""
    u, _, vt = np.linalg.svd(np.asarray(R, dtype=np.float64))
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


# -- the published extrinsics (matlab/Body_T_*.m) ------------------------------------------------

R_BODY_XT32 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
T_BODY_XT32 = make_T(R_BODY_XT32, np.zeros(3))
_R_X36D_XT32 = [[-0.001402106, -0.999967799, 0.007901562],
                [0.999997759, -0.001414596, -0.001575345],
                [0.001586472, 0.007899336, 0.999967541]]
R_BODY_X36D = _rotation(R_BODY_XT32 @ np.asarray(_R_X36D_XT32).T)
_R_X36D_OCULII = [[0.999829834123514, 0.0183936527785399, -0.001405821470991],
                  [-0.0183512882701082, 0.999498727400647, 0.0257977546176971],
                  [0.00187963171211191, -0.0257675660851007, 0.999666194048132]]
P_BODY_OCULII = np.array([0.07, 0.0, -0.115])
P_BODY_ARS548 = np.array([0.0, 0.0, 0.07])
#: (dates below which a mounting holds, R_x36d_ars548), in Body_T_Ars548.m's order
_ARS548_MOUNTS = [
    (20231105.5, [[0.969444991668881, 0.0114058478618076, -0.245043495654703],
                  [-0.0138540154094491, 0.999869833844876, -0.00826931823403215],
                  [0.244917280699337, 0.0114114855112841, 0.969476819533747]]),
    (20231109, [[0.99933556159366, 0.0350592694139522, 0.00996408362298175],
                [-0.0350697556851544, 0.999384479850069, 0.000879585692152998],
                [-0.00992711289698246, -0.00122843923992157, 0.999949970431803]]),
    (20231201, [[0.998776199461003, 0.0482799447996405, 0.0107308117297966],
                [-0.0484342320906938, 0.998719432121254, 0.0146157813744353],
                [-0.0100114210790212, -0.0151176331991534, 0.999835600793668]]),
    (20231208, [[0.99888971377047, 0.0432636174020788, -0.0186440106424698],
                [-0.0432064520575256, 0.999060179650875, 0.00345831412160802],
                [0.0187761078008922, -0.00264893285107753, 0.999820204302054]]),
    (20231213, [[0.998861908053375, 0.0445688670331839, -0.0169854270287433],
                [-0.0445188967507348, 0.999003062288094, 0.00330898339477966],
                [0.0171159712569224, -0.0025490449952668, 0.999850261737998]]),
    (20240113, [[0.99912647794293, 0.039117559886893, -0.0147002578838332],
                [-0.0390210149947843, 0.999215265264576, 0.00679809171902766],
                [0.0149546468407877, -0.00621853445265288, 0.999868835581512]]),
    (float("inf"), [[0.998536832685765, 0.0494527313667313, -0.0218774114156895],
                    [-0.0494029253854064, 0.998774972684787, 0.00281156573196022],
                    [0.0219896505939817, -0.0017266438170843, 0.999756707388295]]),
]
FIRST_ARS548_DATE = 20231104


def body_T_oculii(variant: str = "refined") -> np.ndarray:
    """``Body_T_Oculii.m``: the Eagle's point frame (forward-left-up) in the body frame."""
    if variant == "manual":
        return make_T(np.eye(3), P_BODY_OCULII)
    if variant != "refined":
        raise DataError(f"Eagle extrinsic must be 'refined' or 'manual', got {variant!r}")
    return make_T(_rotation(R_BODY_X36D @ np.asarray(_R_X36D_OCULII)), P_BODY_OCULII)


def body_T_ars548(date: float, where: str = "") -> np.ndarray:
    """``Body_T_Ars548.m``: the ARS548 frame in the body frame on ``date`` (20231105.5 for the
    afternoon of 2023-11-05)."""
    if date < FIRST_ARS548_DATE:
        raise DataError(f"{where}: no ARS548 before 2023-11-04 (date {date:g}); the sequences "
                        "of that time carry only the Eagle (sensor='eagle')")
    R = next(R for limit, R in _ARS548_MOUNTS if date < limit)
    return make_T(_rotation(R_BODY_X36D @ np.asarray(R)), P_BODY_ARS548)


#: the reference-trajectory file names of the authors' tools (TLS-map localisation of the
#: XT32 and the full trajectory in UTM zone 50R), TUM rows, looked for in the sequence folder
GT_NAMES = ("tls_T_xt32.txt", "utm50r_T_xt32.txt")
#: the same reference trajectory in its comma-separated form, as it circulates in
#: ``ref_trajs/<date>/<run>/`` (``loaders.posefile.read_ref_csv``)
GT_CSV_NAME = "ref_tls_T_xt32.csv"
#: folders of the per-sequence reference trajectories, ``<name>/<date>/<run>/`` (ref_trajs:
#: the CSV form; full_trajs: gaussian-rio's ``full_trajs/<day>/dataN/utm50r_T_xt32.txt``)
GT_TREES = ("ref_trajs", "full_trajs")
#: how many folders above the sequence a GT tree is looked for in
GT_SEARCH_LEVELS = 4


def _sequence_folder(path: Path) -> Path:
    """The sequence folder of an input: the folder itself, ``dataN`` for ``dataN.bag``, and
    ``dataN`` for one of its sensor folders (``dataN/eagleg7/enhanced``)."""
    if not path.is_dir():
        return path.with_suffix("")
    if any(path.parent.name == a and path.name == b for _, (_, sub, _) in STREAMS.items()
           for a, b in [sub.split("/")]):
        return path.parent.parent
    return path


def _in_folder(folder: Path) -> list[Path]:
    return [folder / n for n in (*GT_NAMES, GT_CSV_NAME) if (folder / n).is_file()]


def _pick(found: list[Path], where: str) -> Path | None:
    """One reference trajectory of a folder: the TLS one (TUM, else its CSV form) before the
    UTM one; ``tls_T_xt32.txt`` and ``utm50r_T_xt32.txt`` together are ambiguous."""
    names = {p.name for p in found}
    if {"tls_T_xt32.txt", "utm50r_T_xt32.txt"} <= names:
        raise DataError(f"{where}: both {' and '.join(GT_NAMES)} are present; choose one with "
                        "gt (--gt FILE)")
    for name in ("tls_T_xt32.txt", GT_CSV_NAME, "utm50r_T_xt32.txt"):
        if name in names:
            return next(p for p in found if p.name == name)
    return None


def gt_candidates(path: Path) -> list[Path]:
    """Folders that may hold the sequence's reference trajectory, in the order searched: the
    sequence folder (``path`` itself, or for a bag ``dataN.bag`` the folder ``dataN`` beside
    it), then ``<tree>/<date>/<run>/`` (tree ``ref_trajs`` or ``full_trajs``; date the group
    folder the sequence is in, e.g. ``20240123`` or ``20231105_aft``; run the sequence name,
    ``dataN``) in each folder above the sequence up to ``GT_SEARCH_LEVELS``, so a tree beside
    the day folders (``root/ref_trajs/20240123/data3`` for ``root/20240123/data3.bag``) or
    inside them is found."""
    seq = _sequence_folder(path.resolve())
    run = seq.name
    date = seq.parent.name
    out = [seq]
    for up in list(seq.parents)[:GT_SEARCH_LEVELS]:
        for tree in GT_TREES:
            out.append(up / tree / date / run)
    return out


def find_gt_file(path: Path) -> Path | None:
    """The reference trajectory of a sequence, without ``gt``: the first folder of
    ``gt_candidates`` holding one of ``tls_T_xt32.txt``, ``ref_tls_T_xt32.csv``,
    ``utm50r_T_xt32.txt`` (in that order of preference; the TLS and the UTM TUM files together
    in the sequence folder are a ``DataError``: say which with ``gt``); None when there is
    none."""
    for folder in gt_candidates(Path(path)):
        if folder.is_dir():
            found = _pick(_in_folder(folder), str(folder))
            if found is not None:
                return found
    seq = _sequence_folder(Path(path).resolve())
    if _GROUP.match(seq.parent.name):
        return None
    # no day folder above the sequence: <tree>/<any day>/<run>/, if only one day has that run
    hits = sorted({f for up in list(seq.parents)[:GT_SEARCH_LEVELS] for tree in GT_TREES
                   for folder in (up / tree).glob(f"*/{seq.name}") if folder.is_dir()
                   for f in [_pick(_in_folder(folder), str(folder))] if f is not None})
    if len(hits) > 1:
        raise DataError(f"{path}: the sequence is in no day folder (like 20240123/) and "
                        f"{len(hits)} reference trajectories are named {seq.name} "
                        f"({', '.join(map(str, hits[:4]))}); choose one with gt (--gt FILE)")
    return hits[0] if hits else None


_GROUP = re.compile(r"^(\d{8})(_aft|_eve)?$")


def sequence_name(path: Path) -> str:
    """A sequence's default name: its day folder and run, ``20231105_aft_data4`` for
    ``.../20231105_aft/data4.bag`` or the folder ``.../20231105_aft/data4`` (or one of its
    sensor folders), so the runs of different days (every day has a ``data1``) never share a
    name; the run alone when no day folder is above it."""
    seq = _sequence_folder(path.resolve())
    day = seq.parent.name
    return f"{day}_{seq.name}" if _GROUP.match(day) else seq.name


def date_from_path(path: Path) -> float | None:
    """The date value of ``convert_seqname_to_dateval.m`` from the group folder in ``path``
    (``.../20231105_aft/data4`` -> 20231105.5); None when no part of the path is a group."""
    for part in reversed(path.resolve().parts):
        m = _GROUP.match(part)
        if m:
            return float(m.group(1)) + (0.5 if m.group(2) else 0.0)
    return None


# -- options and sources ------------------------------------------------------------------------

class Options(LoaderOptions):
    sensor: Literal["eagle", "ars548"] = Field(
        "eagle", description="radar the methods see: eagle (Oculii Eagle G7, semi-dense) or "
        "ars548 (Continental ARS548, sparse)")
    cloud: Literal["enhanced", "pcl"] = Field(
        "enhanced", description="Eagle stream: enhanced (/radar_enhanced_pcl2, "
        "eagleg7/enhanced) or pcl (/radar_pcl2, eagleg7/pcl); ignored for ars548")
    gt: Path | None = Field(None, description="ground-truth file: TUM (t x y z qx qy qz qw, "
                            "e.g. tls_T_xt32.txt / utm50r_T_xt32.txt) or the reference CSV "
                            "ref_tls_T_xt32.csv (default: found in the sequence folder or in "
                            "ref_trajs/<date>/<run>/ beside it)")
    gt_frame: Literal["xt32", "body"] = Field(
        "xt32", description="frame whose poses the GT rows give: xt32 (the lidar, as the "
        "dataset's reference trajectories) or body")
    date: float | None = Field(
        None, description="sequence date for the ARS548 mounting, e.g. 20231105.5 for "
        "20231105_aft (default: from the group folder in the input path)")
    extrinsic: Literal["refined", "manual"] = Field(
        "refined", description="Eagle extrinsic of Body_T_Oculii.m: refined (published default) "
        "or manual (older hand-measured)")
    T_body_radar: str | None = Field(
        None, description="override the radar extrinsic in the body frame: 'x y z qx qy qz qw' "
        "or 16 numbers")
    remove_gt_origin: bool = Field(
        True, description="subtract the first GT position (UTM coordinates -> metres from the "
        "start; relative errors are unchanged)")
    time_offset_s: float = Field(0.0, description="gt_stamp + offset = scan stamp [s]")
    max_gap_s: float = Field(0.35, description="largest GT gap interpolated across [s]; scans "
                             "in a longer gap have no GT (not scored)")
    uncovered: Literal["keep", "trim", "error"] = Field(
        "keep", description="scans without GT: keep (unscored), trim (cut the leading / "
        "trailing ones) or error")
    doppler_sign: float = Field(
        1.0, description="multiply the Doppler field by this: +1 (positive = receding) or -1")
    stamp: Literal["header", "record"] = Field(
        "header", description="bags: scan stamp from header.stamp or the bag's record time")

    @field_validator("doppler_sign")
    @classmethod
    def _unit_sign(cls, v: float) -> float:
        if v not in (1.0, -1.0):
            raise ValueError(f"doppler_sign must be +1 or -1, got {v}")
        return v


class _BagFrames:
    """Frames of one topic of the sequence's ROS1 bag."""

    def __init__(self, bag: Path, topic: str, stamp: str) -> None:
        self.index = BagTopic([bag], topic, accept=(POINTCLOUD2,))
        if len(self.index) == 0:
            raise DataError(f"{bag}: topic {topic} has no messages")
        self.stamps = topic_stamps(self.index, stamp, str(bag))
        self.label = str(bag)

    def where(self, k: int) -> str:
        return self.index.where(k)

    def read(self, k: int) -> tuple[np.ndarray, list[str]]:
        _, arr, names = parse_pointcloud2(self.index.raw(k), self.where(k))
        return arr, names

    def close(self) -> None:
        self.index.close()


class _FolderFrames:
    """Frames of an extracted folder: ``times.txt`` + ``<sec>.<nsec>.pcd``."""

    def __init__(self, folder: Path) -> None:
        times = folder / "times.txt"
        if not times.is_file():
            raise DataError(f"{folder}: no times.txt; expected the extracted layout "
                            "<sec>.<nsec>.pcd + times.txt (snail-radar dataset_tools "
                            "bag_to_folder.py)")
        check_file_size(times, str(times))
        names = [line.strip() for line in times.read_text(errors="replace").splitlines()
                 if line.strip()]
        if not names:
            raise DataError(f"{times}: no stamps; expected one <sec>.<nsec> per line")
        try:
            self.stamps = np.array([float(n) for n in names])
            if not np.all(np.isfinite(self.stamps)):
                raise ValueError("a stamp is not finite")
        except ValueError as err:
            raise DataError(f"{times}: a line is not a stamp <sec>.<nsec> ({err})") from None
        have = {p.name for p in folder.iterdir()}
        missing = [f"{n}.pcd" for n in names if f"{n}.pcd" not in have]
        if missing:
            raise DataError(f"{folder}: {len(missing)} of the {len(names)} frames listed in "
                            f"times.txt have no .pcd file (first: {missing[0]}); the folder "
                            "is incompletely extracted")
        extra = len([n for n in have if n.endswith(".pcd")]) - len(set(names))
        if extra > 0:
            warnings.warn(f"{folder}: {extra} .pcd files not listed in times.txt are ignored",
                          stacklevel=3)
        self.files = [folder / f"{n}.pcd" for n in names]
        self.label = str(folder)

    def where(self, k: int) -> str:
        return str(self.files[k])

    def read(self, k: int) -> tuple[np.ndarray, list[str]]:
        return read_pcd(self.files[k])

    def close(self) -> None:
        pass


# -- the sequence --------------------------------------------------------------------------------

class SnailRadarSequence(Sequence, OpensFromOptions):
    """Snail-Radar radar scans (Eagle or ARS548) from a sequence's bag or extracted folder, read
    one frame at a time, with ground truth in the radar frame (see the module docstring)."""

    Options = Options
    inputs = ("a Snail-Radar sequence: its ROS1 bag (e.g. 20240123/data3.bag) or extracted "
              "folder (e.g. 20240123/data3 with eagleg7/ and ars548/)")
    many_inputs = False

    def __init__(self, path: str | Path, options: Options | None = None, **overrides) -> None:
        from pydantic import ValidationError

        try:
            o = options or Options()
            if overrides:
                o = Options.model_validate({**o.model_dump(), **overrides})
        except ValidationError as err:
            raise DataError(f"snail-radar options: {err}") from None
        self.options = o
        path = Path(path)
        cloud = "points" if o.sensor == "ars548" else o.cloud
        topic, sub, self.doppler_field = STREAMS[(o.sensor, cloud)]
        if not path.exists():
            raise DataError(f"{path}: not found; expected a Snail-Radar sequence bag or folder")
        if path.is_dir():
            folder = path if (path / "times.txt").is_file() else path / sub
            if not folder.is_dir():
                have = sorted(p.name for p in path.iterdir() if p.is_dir())
                raise DataError(f"{path}: no {sub}/ folder for sensor {o.sensor!r}; the folder "
                                f"has {', '.join(have) or 'no subfolders'} (an incompletely "
                                "extracted sequence, or another sensor?)")
            self._src = _FolderFrames(folder)
        else:
            self._src = _BagFrames(path, topic, o.stamp)
        self.name = o.name or sequence_name(path)
        self.date = o.date if o.date is not None else date_from_path(path)
        T_body_radar = self._extrinsic(path)
        T_gtbody_radar = (inv_T(T_BODY_XT32) @ T_body_radar if o.gt_frame == "xt32"
                          else T_body_radar)
        order, dropped = sort_unique_stamps(self._src.stamps, self._src.label)
        self.provenance: dict = {
            "loader": "snail-radar",
            "input": str(path),
            "sensor": SENSOR_NAMES[o.sensor],
            "stream": topic if path.is_file() else sub,
            "doppler_field": self.doppler_field,
            "doppler_sign": o.doppler_sign,
            "date": self.date,
            "extrinsic": o.T_body_radar or (o.extrinsic if o.sensor == "eagle"
                                            else "Body_T_Ars548.m"),
            "T_body_radar": T_body_radar.tolist(),
            "gt_frame": o.gt_frame,
            "T_gtbody_radar": T_gtbody_radar.tolist(),
            "messages": int(len(self._src.stamps)),
            "repeated_stamps_dropped": dropped,
            "nan_points_dropped": 0,
        }
        self.ground_truth = None
        gt_path = o.gt if o.gt is not None else find_gt_file(path)
        if gt_path is not None:
            found_in = ("the sequence folder" if Path(gt_path).parent == _sequence_folder(
                path.resolve()) else "the reference trajectories beside the sequence")
            self.provenance["gt_file"] = str(gt_path) + ("" if o.gt is not None else
                                                         f" (found in {found_in})")
            gt = read_gt_file(gt_path, "auto")
            if len(gt) and Path(gt_path).suffix == ".csv":
                self.provenance["gt_format"] = ("reference CSV (time, M_p_L, M_q_L: the XT32 "
                                                "pose in the map; W_v_L not used)")
            fix = None
            if o.remove_gt_origin:
                fix = make_T(np.eye(3), -gt.poses[0, :3, 3])
                self.provenance["gt_origin_removed"] = gt.poses[0, :3, 3].tolist()
            assoc = associate(gt, self._src.stamps[order],
                              offset_s=o.time_offset_s, max_gap_s=o.max_gap_s,
                              uncovered=o.uncovered, T_body_sensor=T_gtbody_radar,
                              T_world_fix=fix, gt_file=gt_path, scan_file=self._src.label)
            order = order[assoc.keep]
            self.ground_truth = assoc.ground_truth
            self.provenance["gt_association"] = assoc.report
        self._order = order
        self._stamps = self._src.stamps[order]
        # the vehicle frame the methods may use (DICP's T_vehicle_sensor) is the dataset's body
        # frame (forward-left-up at the XT32); the GT transform is in the provenance
        self.sensor = SensorInfo("radar", median_period(self._stamps, DEFAULT_PERIOD_S[o.sensor]),
                                 T_body_radar, MODELS[o.sensor], "radial")

    def _extrinsic(self, path: Path) -> np.ndarray:
        o = self.options
        if o.T_body_radar is not None:
            return parse_extrinsic(o.T_body_radar)
        if o.sensor == "eagle":
            return body_T_oculii(o.extrinsic)
        if self.date is None:
            raise DataError(f"{path}: the ARS548 extrinsic depends on the sequence date and no "
                            "group folder like 20231105 or 20231105_aft is in the path; give "
                            "--date (e.g. --date 20231105.5)")
        return body_T_ars548(self.date, str(path))

    def __len__(self) -> int:
        return len(self._order)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        k = int(self._order[index])
        where = f"{self._src.where(k)} (frame {index})"
        arr, names = self._src.read(k)
        missing = [f for f in ("x", "y", "z", self.doppler_field) if f not in names]
        if missing:
            raise DataError(f"{where}: no field(s) {', '.join(missing)}; the frame has fields "
                            f"{' '.join(names)} (expected the {self.options.sensor} layout: "
                            f"x y z {self.doppler_field} ...)")
        points = np.column_stack([arr["x"], arr["y"], arr["z"]]).astype(np.float64)
        doppler = arr[self.doppler_field].astype(np.float64) * self.options.doppler_sign
        fields = {}
        for name in names:
            if name in ("x", "y", "z", self.doppler_field):
                continue
            fields[name.lower()] = np.asarray(arr[name], dtype=np.float32)
        return finish_scan(float(self._stamps[index]), points, doppler, fields, where,
                           self.provenance)

    def close(self) -> None:
        self._src.close()
