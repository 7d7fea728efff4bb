"""Dense FMCW LiDAR (Aeva, CARLA) from per-frame folders, in three layouts detected from the
folder contents:

- ``dicp`` (Doppler-ICP CARLA sequences): ``point_clouds/*.bin`` float32 N x 4 (x, y, z,
  doppler), ``calibration.json`` ``{"T_V_to_S": {"translation": {x,y,z}, "quaternion":
  {w,x,y,z}}}`` - despite its name it is applied as sensor -> vehicle (``T_vehicle_sensor``),
  ``ref_poses.txt`` TUM vehicle poses (0.1 s apart).
- ``open3d`` (Open3D demo copy of the same data): ``xyzd_sequence/*.xyzd`` ASCII "x y z doppler",
  ``calibration.json`` with ``transform_vehicle_to_sensor`` (16 values, row-major; also applied
  as sensor -> vehicle) and ``period``, ``ground_truth_poses.txt`` TUM.
- ``steam`` (Aeva real data as used by steam_icp: Baker-Barry tunnel, ...): ``frames/*.bin``
  float32 x, y, z, v, t (20 bytes a point; t = per-point time relative to the frame stamp in
  ns -> field ``time_offset_s``), ``timestamps.txt`` (one per frame; unit detected), a
  ``*poses.txt`` KITTI 3x4 file (vehicle poses, one per frame), sensor -> vehicle translation
  (1.42, 0.24, 1.37) m, identity rotation.

Frames are sorted by the number in their file name and read lazily. Stamps: ``timestamps.txt``
when present; otherwise the GT stamps when the GT has one row per frame; otherwise
``index * period``. Ground truth becomes ``T_world_sensor = T_world_vehicle @ T_vehicle_sensor``.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan, median_period
from loaders.errors import DataError
from loaders.gt import associate
from loaders.limits import check_file_size
from loaders.options import GroundTruthTimeOptions, OpensFromOptions
from loaders.posefile import detect_pose_format, parse_extrinsic, read_gt_file
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

#: steam_icp's sensor -> vehicle translation for the Aeva real data (identity rotation).
STEAM_T_VEHICLE_SENSOR = "1.42 0.24 1.37 0 0 0 1"
DEFAULT_PERIOD_S = 0.1
DEFAULT_MAX_GAP_S = 0.25
#: a dense FMCW LiDAR frame holds tens of thousands of points (CARLA 40k-120k); radar frames
#: hold a few hundred to a few thousand: below this median the data look like radar
RADAR_LIKE_MEDIAN_POINTS = 10_000

LAYOUTS = {
    "dicp": ("point_clouds", ".bin"),
    "open3d": ("xyzd_sequence", ".xyzd"),
    "steam": ("frames", ".bin"),
}


def detect_layout(root: Path) -> str:
    """Which of the three layouts ``root`` holds (DataError listing what was found)."""
    found = [name for name, (sub, ext) in LAYOUTS.items()
             if (root / sub).is_dir() and any((root / sub).glob(f"*{ext}"))]
    if len(found) == 1:
        return found[0]
    if not root.is_dir():
        raise DataError(f"{root}: not a folder")
    if not found:
        have = sorted(p.name + ("/" if p.is_dir() else "") for p in root.iterdir())[:20]
        raise DataError(
            f"{root}: no Aeva/CARLA frame folder found; expected point_clouds/*.bin (Doppler-ICP), "
            f"xyzd_sequence/*.xyzd (Open3D demo) or frames/*.bin (steam_icp Aeva); the folder "
            f"has {have}"
        )
    raise DataError(f"{root}: several layouts found {found}; pass layout= explicitly")


def sorted_frames(folder: Path, ext: str) -> list[Path]:
    """Frame files sorted by the (last) number in their name, then by name."""
    def key(p: Path):
        nums = re.findall(r"\d+", p.stem)
        return (int(nums[-1]) if nums else -1, p.name)

    files = sorted((p for p in folder.glob(f"*{ext}") if p.is_file()), key=key)
    if not files:
        raise DataError(f"{folder}: no *{ext} frame files")
    return files


def read_timestamps(path: Path, unit: str = "auto") -> tuple[np.ndarray, str]:
    """One stamp per line (first column); ``unit`` auto picks s/ms/us/ns from the magnitude."""
    check_file_size(path, str(path))
    try:
        values = np.loadtxt(path, ndmin=2, usecols=0, comments="#")
    except ValueError as err:
        raise DataError(f"{path}: expected one number per line ({err})") from None
    v = np.asarray(values, dtype=np.float64).ravel()
    if not np.all(np.isfinite(v)):
        bad = int(np.flatnonzero(~np.isfinite(v))[0])
        raise DataError(f"{path}: stamp {bad + 1} is {v[bad]}; expected finite numbers")
    if unit == "auto":
        m = float(np.median(np.abs(v))) if len(v) else 0.0
        unit = "ns" if m > 1e17 else "us" if m > 1e14 else "ms" if m > 1e11 else "s"
    scale = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}.get(unit)
    if scale is None:
        raise DataError(f"{path}: unknown timestamp unit {unit!r} (s, ms, us, ns or auto)")
    return v * scale, unit


def _calibration_dicp(path: Path) -> np.ndarray:
    check_file_size(path, str(path))
    try:
        cal = json.loads(path.read_text(errors="replace"))["T_V_to_S"]
        t, q = cal["translation"], cal["quaternion"]
        xyz = [float(t["x"]), float(t["y"]), float(t["z"])]
        quat = [float(q["x"]), float(q["y"]), float(q["z"]), float(q["w"])]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise DataError(
            f"{path}: expected {{'T_V_to_S': {{'translation': {{x,y,z}}, 'quaternion': "
            f"{{w,x,y,z}}}}}} ({type(err).__name__}: {err})"
        ) from None
    return _extrinsic_of(path, xyz + quat)


def _calibration_open3d(path: Path) -> tuple[np.ndarray, float | None]:
    check_file_size(path, str(path))
    try:
        cal = json.loads(path.read_text(errors="replace"))
        T = np.asarray(cal["transform_vehicle_to_sensor"], dtype=np.float64)
        period = cal.get("period")
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise DataError(
            f"{path}: expected 'transform_vehicle_to_sensor' (16 values) and 'period' "
            f"({type(err).__name__}: {err})"
        ) from None
    if T.size != 16:
        raise DataError(f"{path}: transform_vehicle_to_sensor has {T.size} values, expected 16")
    return _extrinsic_of(path, T.ravel()), (float(period) if period is not None else None)


def _extrinsic_of(path: Path, values) -> np.ndarray:
    """``parse_extrinsic`` of a calibration file's values, its error naming the file."""
    try:
        return parse_extrinsic(values)
    except DataError as err:
        raise DataError(f"{path}: {err}") from None


class Options(GroundTruthTimeOptions):
    """``bench convert aeva`` / a dataset config's ``options``."""

    layout: Literal["auto", "dicp", "open3d", "steam"] = Field(
        "auto", description="folder layout: auto, dicp, open3d or steam")
    kind: Literal["lidar", "radar"] = Field(
        "lidar", description="sensor kind of the frames: lidar (Aeva, CARLA) or radar (radar "
        "bins written in this layout; give --period too)")
    period_s: float | None = Field(None, gt=0, description="frame period [s] when there are "
                                   "no stamps (default: calibration period, else 0.1)")
    T_vehicle_sensor: str | None = Field(
        None, json_schema_extra={"cli": "extrinsic"},
        description='sensor -> vehicle "x y z qx qy qz qw" or 16 numbers (default: the '
        "layout's)")
    invert_calibration: bool = Field(False, description="use the inverse of "
                                     "calibration.json's matrix")
    gt: Path | None = Field(None, description="GT file (default: the layout's)")
    no_gt: bool = Field(False, description="ignore ground truth")
    gt_association: Literal["auto", "index", "time"] = Field(
        "auto", description="auto (one GT row per frame: by index, else by time), index or "
        "time")
    point_time_scale: float = Field(1e-9, description="steam layout: per-point t -> seconds")
    timestamp_unit: Literal["auto", "s", "ms", "us", "ns"] = Field(
        "auto", description="steam layout: unit of timestamps.txt")
    doppler_sign: Literal[1.0, -1.0] = Field(1.0, description="+1 or -1")


class AevaSequence(OpensFromOptions, Sequence):
    """Dense FMCW LiDAR frames from a folder (layouts: see the module docstring).

    root: the sequence folder. layout: "auto" | "dicp" | "open3d" | "steam".
    period_s: frame period when the data has no stamps (default: calibration ``period``, else
    0.1 s). T_vehicle_sensor: override the extrinsic ("x y z qx qy qz qw", 16 numbers or 4x4).
    invert_calibration: use the inverse of the calibration file's matrix (if a copy of the data
    stores the opposite direction). gt: override the GT file (None: the layout's file if present;
    False: no GT). gt_association: "auto" (row per frame when the counts match, else time),
    "index" or "time". time_offset_s / max_gap_s: for time association.
    point_time_scale: steam layout per-point t -> seconds (1e-9: ns). timestamp_unit: steam
    ``timestamps.txt`` unit (auto). doppler_sign: +1 (positive = receding) or -1.
    kind: "lidar" (default) or "radar": radar bins written in one of these layouts are stored
    as radar; a LiDAR whose frames look like radar (median points per frame below
    ``RADAR_LIKE_MEDIAN_POINTS``) gets a warning.
    """

    Options = Options
    inputs = "sequence folder (point_clouds/, xyzd_sequence/ or frames/)"

    @classmethod
    def open(cls, paths: list[Path], options: Options) -> AevaSequence:
        o = options
        return cls(paths[0], layout=o.layout, period_s=o.period_s,
                   T_vehicle_sensor=o.T_vehicle_sensor,
                   invert_calibration=o.invert_calibration,
                   gt=False if o.no_gt else o.gt, gt_association=o.gt_association,
                   time_offset_s=o.time_offset_s,
                   max_gap_s=DEFAULT_MAX_GAP_S if o.max_gap_s is None else o.max_gap_s,
                   point_time_scale=o.point_time_scale, timestamp_unit=o.timestamp_unit,
                   doppler_sign=o.doppler_sign, uncovered=o.uncovered, name=o.name,
                   kind=o.kind)

    def __init__(
        self,
        root: Path | str,
        layout: str = "auto",
        period_s: float | None = None,
        T_vehicle_sensor: str | np.ndarray | None = None,
        invert_calibration: bool = False,
        gt: Path | str | bool | None = None,
        gt_association: str = "auto",
        time_offset_s: float = 0.0,
        max_gap_s: float = DEFAULT_MAX_GAP_S,
        point_time_scale: float = 1e-9,
        timestamp_unit: str = "auto",
        doppler_sign: float = 1.0,
        uncovered: str = "keep",
        name: str | None = None,
        kind: str = "lidar",
    ) -> None:
        self.root = Path(root)
        if not self.root.is_dir():
            raise DataError(f"{self.root}: sequence folder not found")
        self.layout = detect_layout(self.root) if layout == "auto" else layout
        if self.layout not in LAYOUTS:
            raise DataError(f"unknown Aeva layout {layout!r}; expected one of {list(LAYOUTS)}")
        if float(doppler_sign) not in (1.0, -1.0):
            raise DataError(f"doppler_sign must be +1 or -1, got {doppler_sign}")
        self.doppler_sign = float(doppler_sign)
        self.point_time_scale = float(point_time_scale)
        self.name = name or self.root.name
        sub, ext = LAYOUTS[self.layout]
        self._files = sorted_frames(self.root / sub, ext)
        n = len(self._files)

        # extrinsic and period
        cal_period = None
        cal_file = self.root / "calibration.json"
        if self.layout == "dicp":
            T = _calibration_dicp(cal_file) if cal_file.exists() else np.eye(4)
            default_gt = "ref_poses.txt"
        elif self.layout == "open3d":
            T, cal_period = (_calibration_open3d(cal_file) if cal_file.exists()
                             else (np.eye(4), None))
            default_gt = "ground_truth_poses.txt"
        else:
            T = parse_extrinsic(STEAM_T_VEHICLE_SENSOR)
            default_gt = None
        cal_source = str(cal_file) if cal_file.exists() and self.layout != "steam" else "default"
        if invert_calibration:
            T = np.linalg.inv(T)
        if T_vehicle_sensor is not None:
            T = parse_extrinsic(T_vehicle_sensor)
            cal_source = "option"
        period = float(period_s or cal_period or DEFAULT_PERIOD_S)

        # ground-truth file
        gt_path: Path | None = None
        if gt is None:
            if default_gt and (self.root / default_gt).exists():
                gt_path = self.root / default_gt
            elif self.layout == "steam":
                cands = sorted(self.root.glob("*poses.txt"))
                gt_path = cands[0] if cands else None
        elif gt is not False:
            gt_path = Path(gt)

        # stamps
        stamp_source = "index x period"
        stamps = np.arange(n, dtype=np.float64) * period
        ts_file = self.root / "timestamps.txt"
        unit = None
        if self.layout == "steam" and ts_file.exists():
            stamps, unit = read_timestamps(ts_file, timestamp_unit)
            if len(stamps) != n:
                raise DataError(f"{ts_file}: {len(stamps)} stamps for {n} frames in "
                                f"{self.root / sub}; expected one per frame")
            stamp_source = f"{ts_file} ({unit})"
        traj = None
        if gt_path is not None:
            if detect_pose_format(gt_path) == "kitti":
                traj = read_gt_file(gt_path, "kitti")
                if len(traj) != n:
                    raise DataError(
                        f"{gt_path}: {len(traj)} KITTI poses for {n} frames; KITTI poses "
                        "carry no stamps, so one per frame is required"
                    )
                traj = traj.with_stamps(stamps)
            else:
                traj = read_gt_file(gt_path, "tum")
        mode = gt_association
        if mode == "auto":
            mode = "index" if traj is not None and len(traj) == n else "time"
        if mode not in ("index", "time"):
            raise DataError(f"gt_association must be auto, index or time, got {gt_association!r}")
        if traj is not None and mode == "index":
            if len(traj) != n:
                raise DataError(f"{gt_path}: {len(traj)} poses for {n} frames; index association "
                                "needs one per frame (use gt_association='time')")
            if stamp_source == "index x period":
                stamps = traj.stamps.copy()
                stamp_source = f"{gt_path} (one row per frame)"
            traj = Trajectory(stamps, traj.poses)
        self._stamps_all = stamps
        keep = np.arange(n)
        self.provenance: dict = {
            "loader": "aeva",
            "root": str(self.root),
            "layout": self.layout,
            "frames_found": n,
            "stamp_source": stamp_source,
            "period_s": period,
            "T_vehicle_sensor": T.tolist(),
            "calibration_source": cal_source,
            "invert_calibration": bool(invert_calibration),
            "doppler_sign": self.doppler_sign,
            "nan_points_dropped": 0,
        }
        if self.layout == "steam":
            self.provenance["point_time_scale"] = self.point_time_scale
        if np.any(np.diff(stamps) <= 0):
            raise DataError(f"{self.root}: frame stamps ({stamp_source}) are not strictly "
                            "increasing")
        self.ground_truth = None
        if traj is not None:
            if mode == "index":
                self.ground_truth = traj.transformed(None, T)
                self.provenance["gt_association"] = {"gt_file": str(gt_path), "mode": "index"}
            else:
                assoc = associate(traj, stamps, offset_s=time_offset_s, max_gap_s=max_gap_s,
                                  T_body_sensor=T, uncovered=uncovered, gt_file=gt_path,
                                  scan_file=self.root)
                keep = assoc.keep
                self.ground_truth = assoc.ground_truth
                self.provenance["gt_association"] = assoc.report
        self._keep = keep
        self._stamps = stamps[keep]
        if kind not in ("lidar", "radar"):
            raise DataError(f"sensor kind must be lidar or radar, got {kind!r}")
        if kind == "radar":
            model = f"radar ({self.layout} layout)"
        else:
            model = ("lidar-fmcw (CARLA)" if self.layout != "steam"
                     else "lidar-fmcw (Aeva Aeries I)")
            self._warn_if_radar_like(stamp_source, period)
        self.provenance["sensor_kind"] = kind
        self.sensor = SensorInfo(kind, median_period(self._stamps, period), T, model)

    def _warn_if_radar_like(self, stamp_source: str, period: float) -> None:
        """Warn when LiDAR frames hold as few points as radar frames (radar bins written in an
        Aeva layout were silently stored as LiDAR with 0.1 s). Point counts come from the file
        sizes (binary layouts) or the line count of the middle frame (ASCII)."""
        if self.layout == "open3d":
            middle = self._files[len(self._files) // 2]
            with open(middle, "rb") as f:
                median = sum(1 for line in f if line.strip())
        else:
            width = 16 if self.layout == "dicp" else 20
            median = int(np.median([p.stat().st_size for p in self._files])) // width
        self.provenance["median_points_per_frame"] = median
        if median < RADAR_LIKE_MEDIAN_POINTS:
            timing = (f"; the frames are stamped index x {period:g} s" if
                      stamp_source == "index x period" else "")
            warnings.warn(
                f"{self.root}: frames hold a median of {median} points, as radar frames do (a "
                f"dense FMCW LiDAR frame has tens of thousands); they are stored as LiDAR"
                f"{timing}. If this is radar data, pass --kind radar (kind: radar) and the "
                "scan period (--period SECONDS)", stacklevel=3)

    def __len__(self) -> int:
        return len(self._keep)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        k = int(self._keep[index])
        path = self._files[k]
        where = f"{path}, frame {index}"
        fields: dict[str, np.ndarray] = {}
        check_file_size(path, where)
        if self.layout == "open3d":
            try:
                values = np.array(path.read_text(errors="replace").split(), dtype=np.float64)
            except ValueError as err:
                raise DataError(f"{where}: expected ASCII 'x y z doppler' lines ({err})") from None
            if values.size % 4:
                raise DataError(f"{where}: {values.size} numbers, not a multiple of 4 "
                                "(x y z doppler per line)")
            data = values.reshape(-1, 4)
        else:
            width = 4 if self.layout == "dicp" else 5
            raw = path.read_bytes()
            if len(raw) % (4 * width):
                raise DataError(
                    f"{where}: {len(raw)} bytes is not a multiple of {4 * width} "
                    f"(float32 x, y, z, doppler{', t' if width == 5 else ''} per point)"
                )
            data = np.frombuffer(raw, dtype="<f4").reshape(-1, width)
            if width == 5:
                fields["time_offset_s"] = (data[:, 4].astype(np.float64)
                                           * self.point_time_scale).astype(np.float32)
        doppler = self.doppler_sign * data[:, 3].astype(np.float64)
        return finish_scan(float(self._stamps_all[k]), data[:, :3], doppler, fields, where,
                           self.provenance)
