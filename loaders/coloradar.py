"""ColoRadar: the single-chip TI mmWave radar's point clouds of one run folder.

Format facts (the ColoRadar dataset tools, ``python/dataset_loaders.py``, as mirrored in
JzHuai0108/coloradar_tools; arpg/coloradar-library ``src/run/coloradar_plus_run.cpp`` and
``src/dataset/coloradar_plus_dataset.cpp`` read the same files):

- Scans ``single_chip/pointclouds/data/radar_pointcloud_<i>.bin`` (``i`` = 0, 1, ... without
  padding): float32 N x 5 ``[x, y, z, intensity, doppler]`` in the radar frame, no header
  (``get_pointcloud``: ``reshape((-1, 5))``; ``readRadarPointcloud`` reads five floats a point).
- Scan stamps ``single_chip/pointclouds/timestamps.txt``: one float [s] a line, line ``i`` for
  ``radar_pointcloud_<i>.bin`` (``get_timestamps``).
- Ground truth ``groundtruth/groundtruth_poses.txt``: ``x y z qx qy qz qw`` a line (no stamp;
  ``get_groundtruth``, ``readPoses``) and ``groundtruth/timestamps.txt``, one stamp per pose
  row: the pose of the ``base`` frame in the world.
- Extrinsics ``calib/transforms/base_to_single_chip.txt``: line 1 the translation ``x y z``,
  line 2 the rotation ``qx qy qz qw`` (``read_tf_file``; ``loadTransform`` builds
  ``Translation * Rotation``), applied as ``sensor pose = base pose * transform``
  (``coloradar_plus_dataset.cpp``: ``sensorPoses[i] = basePoses[i] * imuTransform_``): it is
  ``T_base_single_chip``. ColoRadar ships ``calib/`` once beside the run folders, so it is
  looked up in the run folder, then its parent (option ``calib``).
- Doppler sign: the devkit does not state it; TI mmWave's convention (and the radar
  convention generally) is negative for an approaching target, i.e. receding positive like the
  harness, so ``doppler = +doppler`` by default (option ``doppler_sign``). ``bench inspect``
  checks the sign against the GT motion on real data.

Ground truth (its own rate) is interpolated at the scan stamps (``loaders.gt.associate``; a
gap longer than ``max_gap_s``, default 3 median GT steps, is never bridged) and becomes
``T_world_radar = T_world_base @ T_base_single_chip``.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan, median_period
from loaders.errors import DataError
from loaders.gt import associate
from loaders.limits import check_file_size, file_number
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.posefile import parse_extrinsic
from loaders.records import read_records, record_dtype
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.se3 import T_from_tum
from loaders.trajectory import Trajectory

RADAR_RECORD = record_dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"),
                             ("doppler", "<f4")])
LAYOUT = "ColoRadar single-chip radar N x 5"
ALTERNATIVES = {"ColoRadar lidar N x 4 (x y z intensity, no Doppler)": 16}
CLOUD_DIR = Path("single_chip/pointclouds")
_FRAME = re.compile(r"^radar_pointcloud_(\d+)\.bin$")
#: the single-chip radar's nominal rate (used only when there is a single scan)
NOMINAL_PERIOD_S = 0.1


class Options(LoaderOptions):
    """Options of the ColoRadar loader."""

    calib: Path | None = Field(None, description=(
        "ColoRadar calib folder (with transforms/base_to_single_chip.txt; default: RUN/calib, "
        "then RUN/../calib)"))
    extrinsic: str | None = Field(None, description=(
        'radar -> base "x y z qx qy qz qw" instead of calib/transforms/'
        "base_to_single_chip.txt"))
    doppler_sign: float = Field(1.0, description="+1 (the file's doppler is receding "
                                "positive, TI convention) or -1")
    time_offset: float = Field(0.0, description="GT clock offset (s): gt_stamp + offset = "
                               "sensor clock")
    max_gap: float | None = Field(None, gt=0, description=(
        "largest GT gap interpolated across (s) (default: 3 median GT steps)"))
    uncovered: Literal["keep", "trim", "error"] = Field("keep", description=(
        "scans without GT: keep (run, unscored), trim (cut the ends) or error"))


def read_stamps(path: Path) -> np.ndarray:
    """One float stamp [s] a line (``DataError`` naming the line otherwise)."""
    if not path.exists():
        raise DataError(f"{path}: timestamps file not found; expected one stamp [s] a line")
    check_file_size(path, str(path))
    values = []
    with open(path, errors="replace") as f:
        for lineno, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                values.append(float(line.split()[0]))
                if not np.isfinite(values[-1]):
                    raise ValueError
            except ValueError:
                raise DataError(f"{path}, line {lineno}: expected a stamp in seconds, got "
                                f"{line.strip()[:40]!r}") from None
    return np.asarray(values, dtype=np.float64)


def read_poses(path: Path) -> np.ndarray:
    """``x y z qx qy qz qw`` rows as 4x4 poses."""
    if not path.exists():
        raise DataError(f"{path}: ground-truth poses not found; expected 'x y z qx qy qz qw' "
                        "a line")
    check_file_size(path, str(path))
    rows = []
    with open(path, errors="replace") as f:
        for lineno, line in enumerate(f, start=1):
            parts = line.split()
            if not parts:
                continue
            try:
                values = [float(v) for v in parts]
            except ValueError:
                values = []
            if len(values) != 7:
                raise DataError(f"{path}, line {lineno}: expected 7 numbers 'x y z qx qy qz qw',"
                                f" got {line.strip()[:60]!r}")
            rows.append(values)
    if not rows:
        raise DataError(f"{path}: no pose rows")
    data = np.asarray(rows)
    norms = np.linalg.norm(data[:, 3:], axis=1)
    if not np.all(np.isfinite(data)) or np.any(np.abs(norms - 1) > 1e-3):
        bad = int(np.flatnonzero(~np.isfinite(data).all(axis=1) | (np.abs(norms - 1) > 1e-3))[0])
        raise DataError(f"{path}, line {bad + 1}: not a finite pose with a unit quaternion")
    return T_from_tum(data[:, :3], data[:, 3:] / norms[:, None])


def read_transform(path: Path) -> np.ndarray:
    """``T_base_sensor`` from a ColoRadar transform file (translation line, quaternion line)."""
    if not path.exists():
        raise DataError(f"{path}: extrinsic not found; expected 'x y z' and 'qx qy qz qw' lines "
                        "(ColoRadar ships calib/ beside the run folders: give --calib DIR, or "
                        "--extrinsic 'x y z qx qy qz qw' (radar -> base; '0 0 0 0 0 0 1' when "
                        "the GT is the radar's own pose))")
    check_file_size(path, str(path))
    lines = [ln.split() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    if len(lines) < 2 or len(lines[0]) != 3 or len(lines[1]) != 4:
        raise DataError(f"{path}: expected a line 'x y z' and a line 'qx qy qz qw'")
    try:
        values = [float(v) for v in lines[0] + lines[1]]
    except ValueError:
        raise DataError(f"{path}: expected numbers 'x y z' / 'qx qy qz qw'") from None
    try:
        return parse_extrinsic(values)
    except DataError as err:
        raise DataError(f"{path}: {err}") from None


def find_calib(run: Path, calib: Path | None) -> Path:
    if calib is not None:
        return Path(calib)
    for cand in (run / "calib", run.parent / "calib"):
        if (cand / "transforms").is_dir():
            return cand
    return run / "calib"


class ColoradarSequence(OpensFromOptions, Sequence):
    """The single-chip radar scans of one ColoRadar run with ``T_world_radar`` ground truth."""

    Options = Options
    inputs = "ColoRadar run folder (single_chip/pointclouds, groundtruth; calib beside it)"
    many_inputs = False

    def __init__(self, run: str | Path, options: Options | None = None, **kwargs) -> None:
        opts = options if options is not None else Options(**kwargs)
        if float(opts.doppler_sign) not in (1.0, -1.0):
            raise DataError(f"doppler_sign must be +1 or -1, got {opts.doppler_sign}")
        self.options = opts
        self.root = Path(run)
        clouds = self.root / CLOUD_DIR
        if not (clouds / "data").is_dir():
            raise DataError(f"{self.root}: no {CLOUD_DIR}/data folder; expected a ColoRadar run "
                            f"with {CLOUD_DIR}/data/radar_pointcloud_<i>.bin and "
                            f"{CLOUD_DIR}/timestamps.txt")
        found = {file_number(m.group(1), p): p for p in (clouds / "data").iterdir()
                 if (m := _FRAME.match(p.name))}
        if not found:
            raise DataError(f"{clouds / 'data'}: no radar_pointcloud_<i>.bin files")
        n = max(found) + 1
        if len(found) != n:  # a gap or a stray index: found from the indices present only
            # (never a set of range(max + 1): a stray radar_pointcloud_20000000.bin would
            # allocate 20 million entries)
            idx = sorted(found)
            first = next((i for i, k in enumerate(idx) if i != k), len(idx))
            raise DataError(f"{clouds / 'data'}: radar_pointcloud_{first}.bin is missing "
                            f"({n - len(found)} of indices 0..{n - 1}; the highest is "
                            f"{found[idx[-1]].name}); expected one file per line of "
                            "timestamps.txt, indices 0..N-1")
        self._files = [found[i] for i in range(n)]
        stamp_file = clouds / "timestamps.txt"
        stamps = read_stamps(stamp_file)
        if len(stamps) != n:
            raise DataError(f"{stamp_file}: {len(stamps)} stamps for {n} scans in "
                            f"{clouds / 'data'}; expected one stamp per radar_pointcloud file")
        back = np.flatnonzero(np.diff(stamps) <= 0)
        if len(back):
            raise DataError(f"{stamp_file}, line {int(back[0]) + 2}: stamps must increase "
                            f"({stamps[back[0]]:.6f} -> {stamps[back[0] + 1]:.6f} s)")
        self._stamps_all = stamps
        calib = find_calib(self.root, opts.calib)
        if opts.extrinsic is not None:
            T = parse_extrinsic(opts.extrinsic)
            cal_source = "option extrinsic"
        else:
            tf = calib / "transforms" / "base_to_single_chip.txt"
            T = read_transform(tf)
            cal_source = str(tf)
        gt_dir = self.root / "groundtruth"
        poses = read_poses(gt_dir / "groundtruth_poses.txt")
        gt_stamps = read_stamps(gt_dir / "timestamps.txt")
        if len(poses) != len(gt_stamps):
            raise DataError(
                f"{gt_dir / 'groundtruth_poses.txt'}: {len(poses)} pose rows but "
                f"{len(gt_stamps)} stamps in {gt_dir / 'timestamps.txt'}; expected one pose "
                "per stamp")
        gt = Trajectory(gt_stamps, poses)
        max_gap = opts.max_gap
        if max_gap is None:
            steps = np.diff(gt_stamps)
            steps = steps[steps > 0]
            max_gap = 3.0 * float(np.median(steps)) if len(steps) else None
        assoc = associate(gt, stamps, offset_s=opts.time_offset, max_gap_s=max_gap,
                          T_body_sensor=T, uncovered=opts.uncovered,
                          gt_file=gt_dir / "groundtruth_poses.txt", scan_file=clouds)
        self._keep = assoc.keep
        self._stamps = stamps[assoc.keep]
        self.ground_truth = assoc.ground_truth
        self.doppler_sign = float(opts.doppler_sign)
        self.name = opts.name or self.root.name
        self.sensor = SensorInfo("radar", median_period(self._stamps, NOMINAL_PERIOD_S), T,
                                 "radar-sparse (TI AWR1843 single-chip, ColoRadar)")
        self.provenance = {
            "loader": "coloradar",
            "root": str(self.root),
            "frames_found": n,
            "stamp_source": str(stamp_file),
            "T_base_sensor": T.tolist(),
            "calibration_source": cal_source,
            "gt": "T_world_base (groundtruth_poses.txt + timestamps.txt) @ T_base_single_chip",
            "doppler_sign": self.doppler_sign,
            "gt_association": assoc.report,
            "nan_points_dropped": 0,
        }

    def __len__(self) -> int:
        return len(self._keep)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        k = int(self._keep[index])
        path = self._files[k]
        where = f"{path}, frame {index}"
        rec = read_records(path, RADAR_RECORD, where, LAYOUT, ALTERNATIVES)
        points = np.column_stack([rec["x"], rec["y"], rec["z"]])
        doppler = self.doppler_sign * rec["doppler"].astype(np.float64)
        return finish_scan(float(self._stamps_all[k]), points, doppler,
                           {"intensity": rec["intensity"].copy()}, where, self.provenance)
