"""View-of-Delft (VoD): the ZF FRGen21 3+1D radar - the paper's sparse radar class - from the
dataset's KITTI-style frame folders.

Format facts (tudelft-iv/view-of-delft-dataset; file paths in that repository):

- Radar scans ``radar/<split>/velodyne/NNNNN.bin``: float32 N x 7
  ``[x, y, z, RCS, v_r, v_r_compensated, time]`` in the radar frame (``vod/frame/
  data_loader.py`` ``get_radar_scan``: ``np.fromfile(..., float32).reshape(-1, 7)``;
  ``docs/SENSORS_AND_DATA.md`` "Radar"). ``v_r`` is the relative radial velocity (the raw range
  rate, what Doppler methods need); ``v_r_compensated`` the ego-motion compensated one (static
  points about 0); ``time`` the scan id of accumulated clouds (0 in the single-scan folder read
  here; ignored). Sign: receding positive, like the harness - measured on the devkit's three
  ``example_set/radar/training/velodyne`` frames: a least-squares ego velocity from
  ``v_r = -d . v`` points forward (+x, 1.9-3.0 m/s), and ``v_r - v_r_compensated`` fits
  ``-d . v_ego`` to 1e-5 m/s. So ``doppler = +v_r``.
- Poses ``radar/<split>/pose/NNNNN.json``: three JSON lines ``{"odomToCamera": 16 values}``,
  ``{"mapToCamera": ...}``, ``{"UTMToCamera": ...}`` (row-major 4x4). The devkit
  (``vod/frame/transformations.py`` ``get_world_transform``) reads them as ``T_odom_camera``
  etc.: the camera's pose in that world ("from the camera frame to the odom frame"). Odometry is
  RTK GPS + IMU + wheel odometry at about 30 Hz, matched to each frame within 0.04 s
  (``docs/SENSORS_AND_DATA.md`` "Odometry", "Syncronization").
- Calibration ``radar/<split>/calib/NNNNN.txt`` (KITTI): ``Tr_velo_to_cam`` (12 values, 3x4
  row-major) is ``T_camera_radar`` in the radar folder (``transformations.py``
  ``get_sensor_transforms('radar')`` reads line 6 as "the radar frame, to the camera frame").
- Frames are synchronised to the LiDAR at about 10 Hz (the radar runs at about 13 Hz; each
  frame holds the radar scan closest to the LiDAR stamp) and VoD publishes no frame stamps, so
  frame ``NNNNN`` is stamped ``CLOCK_ORIGIN_S + NNNNN x period`` (option ``period``, default
  0.1 s: frame 00544 at 1054.4 s; said in the provenance and a warning: Doppler methods
  integrate velocity over it). A frame counter, not a time of day: its origin keeps every stamp
  positive (ROS reads a 0 s stamp as "no time", and a clip may start at frame 00000) and far
  from any date a reader could take for the recording's (1970-01-01 00:16:40 on); the frame
  number keeps two clips, or two cuts of one clip, on one clock. ``bench export`` keeps it, so
  a trajectory made from the exported bag scores against the store unchanged.
- The frames come in clips with gaps between them (frame numbers jump; the test clips are not
  in the training folder). **A gap ends a segment**: a jump in the frame numbers, or a pose step
  faster than ``max_speed_mps``, splits the folder into segments, and a sequence is one segment
  (option ``segment``); a folder of several segments without ``segment`` is a ``DataError``
  listing them, never one long jump.

Ground truth: ``T_world_radar = T_world_camera @ T_camera_radar`` at each frame (world: option
``world``, default the local ``odom`` frame); ``SensorInfo.T_body_sensor`` is
``T_camera_radar`` (the pose files give the camera, the "body" here). The provenance names the
frames (``world_frame`` odom / map / utm, ``body_frame`` camera, ``sensor_frame`` radar), which
``bench export`` uses as the bag's frame ids. The calibration is read
from every frame of the segment and must agree. Licence: the dataset is under the VoD Research
Use Licence (no redistribution), so no real frames are vendored in the tests.
"""

from __future__ import annotations

import json
import re
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan
from loaders.errors import DataError
from loaders.limits import check_file_size, file_number
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.records import read_records, record_dtype
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

#: the frame rate of VoD's synchronised frames (LiDAR-led, ~10 Hz): the default period
DEFAULT_PERIOD_S = 0.1
#: frame NNNNN is stamped CLOCK_ORIGIN_S + NNNNN x period [s] (VoD publishes no stamps)
CLOCK_ORIGIN_S = 1000.0
RADAR_RECORD = record_dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("rcs", "<f4"),
                             ("v_r", "<f4"), ("v_r_compensated", "<f4"), ("time", "<f4")])
LAYOUT = "View-of-Delft radar N x 7"
#: other record sizes a VoD-like file may have, for the error message
ALTERNATIVES = {"the VoD LiDAR N x 4 (x y z intensity, no Doppler)": 16}
POSE_KEYS = {"odom": "odomToCamera", "map": "mapToCamera", "utm": "UTMToCamera"}
_FRAME = re.compile(r"^(\d+)\.bin$")


class Options(LoaderOptions):
    """Options of the View-of-Delft loader."""

    period: float = Field(DEFAULT_PERIOD_S, gt=0, description=(
        "seconds between frames: VoD publishes no stamps; its frames are synchronised to the "
        f"LiDAR at about 10 Hz (default 0.1); frame NNNNN is stamped {CLOCK_ORIGIN_S:g} s + "
        "NNNNN x period"))
    segment: int | None = Field(None, ge=0, description=(
        "which clip of the folder to load (0-based; a gap in the frame numbers or a pose jump "
        "ends a clip); needed when the folder holds several"))
    split: str = Field("training", description="subfolder of radar/ (training or testing)")
    world: Literal["odom", "map", "utm"] = Field("odom", description=(
        "ground-truth world frame: odom (local, default), map or utm (the pose files' three "
        "transforms)"))
    doppler: Literal["v_r", "v_r_compensated"] = Field("v_r", description=(
        "Doppler column: v_r (raw radial velocity, default) or v_r_compensated "
        "(ego-motion compensated: unusable as radial velocity, stored as ego-compensated)"))
    max_speed_mps: float = Field(40.0, gt=0, description=(
        "a pose step between consecutive frames faster than this ends a clip (m/s)"))


def find_radar_root(path: Path, split: str) -> Path:
    """The folder holding ``velodyne/``, ``pose/`` and ``calib/`` (``radar/<split>``)."""
    path = Path(path)
    for cand in (path / "radar" / split, path / split, path):
        if (cand / "velodyne").is_dir():
            return cand
    if path.name == "velodyne" and path.is_dir():
        return path.parent
    if not path.exists():
        raise DataError(f"{path}: not found; expected the View-of-Delft folder with "
                        f"radar/{split}/velodyne/NNNNN.bin")
    raise DataError(f"{path}: no View-of-Delft radar frames; expected radar/{split}/velodyne/"
                    "NNNNN.bin (with pose/ and calib/ beside velodyne/)")


def read_pose_file(path: Path, key: str) -> np.ndarray:
    """``T_world_camera`` (4x4) from a VoD pose file (one JSON object a line, or one object)."""
    try:
        if path.exists():  # (a missing file: the OSError below names it)
            check_file_size(path, str(path))
        text = path.read_text(errors="replace")
    except OSError as err:
        raise DataError(f"{path}: cannot read the pose file ({err.strerror or err}); expected "
                        "one per radar frame") from None
    found: dict = {}
    try:
        for line in text.splitlines():
            if line.strip():
                found.update(json.loads(line))
    except (ValueError, TypeError, AttributeError):
        try:
            found = dict(json.loads(text))
        except (ValueError, TypeError) as err:
            raise DataError(f"{path}: not JSON ({err}); expected lines like "
                            '{"odomToCamera": [16 numbers]}') from None
    if key not in found:
        raise DataError(f"{path}: no {key!r} (has {sorted(found)}); expected odomToCamera, "
                        "mapToCamera and UTMToCamera")
    try:
        values = np.asarray(found[key], dtype=np.float64).ravel()
    except (ValueError, TypeError):
        raise DataError(f"{path}: {key} holds {str(found[key])[:60]!r}; expected 16 numbers "
                        "(a row-major 4x4)") from None
    if values.size != 16 or not np.all(np.isfinite(values)):
        raise DataError(f"{path}: {key} has {values.size} values; expected 16 finite numbers "
                        "(a row-major 4x4)")
    return rigid(values.reshape(4, 4), f"{path}: {key}")


def read_calib(path: Path) -> np.ndarray:
    """``T_camera_radar`` from a KITTI calibration file's ``Tr_velo_to_cam`` row."""
    try:
        if path.exists():  # (a missing file: the OSError below names it)
            check_file_size(path, str(path))
        lines = path.read_text(errors="replace").splitlines()
    except OSError as err:
        raise DataError(f"{path}: cannot read the calibration ({err.strerror or err})") from None
    for line in lines:
        key, _, rest = line.partition(":")
        if key.strip() == "Tr_velo_to_cam":
            try:
                values = np.array(rest.split(), dtype=np.float64)
            except ValueError:
                values = np.array([])
            if values.size != 12:
                raise DataError(f"{path}: Tr_velo_to_cam has {values.size} values; expected "
                                "12 (a 3x4 row-major radar -> camera transform)")
            return rigid(np.vstack([values.reshape(3, 4), [0, 0, 0, 1]]),
                         f"{path}: Tr_velo_to_cam")
    raise DataError(f"{path}: no Tr_velo_to_cam row; expected a KITTI calibration file")


def rigid(T: np.ndarray, what: str) -> np.ndarray:
    """``T`` with its rotation projected onto SO(3) (the files print about 8 digits);
    ``DataError`` when it is not close to a rotation."""
    U, s, Vt = np.linalg.svd(T[:3, :3])
    if np.abs(s - 1).max() > 1e-3 or np.linalg.det(U @ Vt) < 0 or not np.allclose(
            T[3], [0, 0, 0, 1]):
        raise DataError(f"{what}: not a rigid transform (singular values {np.round(s, 4)})")
    out = T.copy()
    out[:3, :3] = U @ Vt
    return out


def split_segments(numbers: np.ndarray, positions: np.ndarray, period_s: float,
                   max_speed_mps: float) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the clips: a jump in the frame numbers or a position step
    faster than ``max_speed_mps`` over one period ends a clip."""
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    breaks = np.flatnonzero((np.diff(numbers) != 1) | (steps > max_speed_mps * period_s)) + 1
    edges = [0, *breaks.tolist(), len(numbers)]
    return list(zip(edges[:-1], edges[1:], strict=True))


def frame_stamps(numbers: np.ndarray, period_s: float) -> np.ndarray:
    """The stamps [s] of the frames numbered ``numbers``: ``CLOCK_ORIGIN_S + number x
    period_s`` (a frame counter: VoD publishes no stamps)."""
    return CLOCK_ORIGIN_S + np.asarray(numbers, dtype=np.float64) * period_s


class VodSequence(OpensFromOptions, Sequence):
    """One clip of View-of-Delft radar frames with ``T_world_radar`` ground truth."""

    Options = Options
    inputs = "View-of-Delft folder (with radar/<split>/velodyne, pose, calib)"
    many_inputs = False

    def __init__(self, path: str | Path, options: Options | None = None, **kwargs) -> None:
        opts = options if options is not None else Options(**kwargs)
        self.options = opts
        self.root = find_radar_root(Path(path), opts.split)
        frame_dir = self.root / "velodyne"
        numbered = sorted((file_number(p.stem, p), p) for p in frame_dir.iterdir()
                          if _FRAME.match(p.name))
        if not numbered:
            raise DataError(f"{frame_dir}: no NNNNN.bin radar frames")
        files = [p for _, p in numbered]
        numbers = np.array([n for n, _ in numbered], dtype=np.int64)
        key = POSE_KEYS[opts.world]
        pose_dir = self.root / "pose"
        if not pose_dir.is_dir():
            raise DataError(f"{pose_dir}: pose folder not found; expected pose/NNNNN.json "
                            "beside velodyne/")
        T_world_camera = np.stack([read_pose_file(pose_dir / f"{p.stem}.json", key)
                                   for p in files])
        segments = split_segments(numbers, T_world_camera[:, :3, 3], opts.period,
                                  opts.max_speed_mps)
        described = [f"{k}: frames {files[a].stem}-{files[b - 1].stem} ({b - a})"
                     for k, (a, b) in enumerate(segments)]
        if opts.segment is None and len(segments) > 1:
            shown = "; ".join(described[:8]) + ("; ..." if len(described) > 8 else "")
            a, b = segments[0][1] - 1, segments[1][0]
            raise DataError(
                f"{frame_dir}: the frames form {len(segments)} clips separated by gaps (first "
                f"gap: frame {files[a].stem} -> {files[b].stem}); a sequence must not jump "
                f"across a gap: choose one with segment=K (--segment K): {shown}")
        k = opts.segment or 0
        if k >= len(segments):
            raise DataError(f"{frame_dir}: segment {k} does not exist; the folder has "
                            f"{len(segments)} clip(s): {'; '.join(described[:8])}")
        start, stop = segments[k]
        self._files = files[start:stop]
        calib_dir = self.root / "calib"
        calibs = [read_calib(calib_dir / f"{p.stem}.txt") for p in self._files]
        T_camera_radar = calibs[0]
        for p, T in zip(self._files, calibs, strict=True):
            if not np.allclose(T, T_camera_radar, atol=1e-6):
                raise DataError(f"{calib_dir / (p.stem + '.txt')}: Tr_velo_to_cam differs "
                                f"from frame {self._files[0].stem}'s; expected one radar "
                                "calibration per clip")
        self._stamps = frame_stamps(numbers[start:stop], opts.period)
        poses = T_world_camera[start:stop] @ T_camera_radar
        self.ground_truth = Trajectory(self._stamps.copy(), poses)
        self.name = opts.name or f"vod_{self._files[0].stem}-{self._files[-1].stem}"
        self.doppler_column = opts.doppler
        kind = "radial" if opts.doppler == "v_r" else "ego-compensated"
        self.sensor = SensorInfo("radar", opts.period, T_camera_radar,
                                 "radar-sparse (ZF FRGen21, VoD)", doppler_kind=kind)
        self.provenance = {
            "loader": "vod",
            "root": str(self.root),
            "segment": k,
            "segments_in_folder": len(segments),
            "frames": [self._files[0].stem, self._files[-1].stem],
            "stamp_source": f"{CLOCK_ORIGIN_S:g} s + frame number x period {opts.period} s "
                            "(VoD publishes no frame stamps: a frame counter, not a time of day; "
                            "option period)",
            "clock_origin_s": CLOCK_ORIGIN_S,
            "period_s": opts.period,
            "world": f"{opts.world} ({key})",
            "world_frame": opts.world,
            "body_frame": "camera",
            "sensor_frame": "radar",
            "T_body_sensor": "T_camera_radar from calib/NNNNN.txt Tr_velo_to_cam; GT = "
                             f"T_{opts.world}_camera @ T_camera_radar",
            "doppler_column": opts.doppler,
            "doppler_sign": "+1 (v_r is receding-positive like the harness)",
            "nan_points_dropped": 0,
        }
        warnings.warn(f"{frame_dir}: View-of-Delft publishes no frame stamps: frames "
                      f"{self._files[0].stem}-{self._files[-1].stem} stamped "
                      f"{CLOCK_ORIGIN_S:g} s + frame number x {opts.period} s "
                      f"({self._stamps[0]:.6g}-{self._stamps[-1]:.6g} s; option period)",
                      stacklevel=2)

    def __len__(self) -> int:
        return len(self._files)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        path = self._files[index]
        where = f"{path}, frame {index}"
        rec = read_records(path, RADAR_RECORD, where, LAYOUT, ALTERNATIVES)
        points = np.column_stack([rec["x"], rec["y"], rec["z"]])
        doppler = rec[self.doppler_column].astype(np.float64)
        return finish_scan(float(self._stamps[index]), points, doppler,
                           {"rcs": rec["rcs"].copy()}, where, self.provenance)
