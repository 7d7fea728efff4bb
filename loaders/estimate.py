"""A trajectory estimated elsewhere (another odometry, a ROS node), read strictly for scoring.

Formats (``read_estimate``; ``fmt`` "auto" decides by the bag's suffix or folder, else by the
width of the first numeric row: 12 KITTI, 13 Boreas, else TUM):

- TUM: rows ``t x y z qx qy qz qw`` [s, m], optionally a 9th column: the method's own time for
  that frame [ms] ("reported by the method"); '#' comments and one leading header line skipped.
  Nine columns whose first is an integer index (``i t x y z qx qy qz qw``: the quaternion sits
  one column later) are refused, not read as stamps;
- KITTI: rows of 12 values (the 3x4 ``T_world_frame`` row-major) with their stamps from a
  separate file (``stamps``: one stamp [s] per row, as KITTI's ``times.txt``);
- Boreas (the odometry benchmark's submission format, pyboreas ``eval/odometry.md``;
  ``loaders.estimate_boreas``): rows of 13 values, an integer stamp [us] then the upper 3x4 of
  ``T_k_i`` row-major, which maps the stationary frame i into the robot's frame k: the inverse
  of the pose ``T_i_k`` (= ``T_world_frame``) that is read;
- a bag (ROS1 ``.bag``, ROS2 folder / ``.db3`` / ``.mcap``): a ``nav_msgs/Odometry``,
  ``geometry_msgs/PoseStamped`` or ``PoseWithCovarianceStamped`` topic, stamped by
  ``header.stamp``.

Stamps are seconds (Boreas: microseconds) unless ``stamp_unit`` (s, ms, us, ns) says otherwise;
they are returned in seconds. Per-frame times may also come from a file (``frame_times``: one
time [ms] per pose row).

Bad input is one ``DataError`` naming the file, the row and what was expected: a wrong column
count, a non-finite value, stamps that do not strictly increase, a quaternion whose norm is
not 1 within ``QUAT_NORM_TOLERANCE`` (files written with few digits are slightly off: those
are normalised, nothing further off is), a rotation block that is no rotation, a bag without
the topic, fewer than two poses.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.posefile import (
    QUAT_NORM_TOLERANCE,
    first_numeric_width,
    nearest_rotations,
    numeric_rows,
)
from loaders.se3 import T_from_tum, make_T
from loaders.trajectory import Trajectory

#: a quaternion shorter than this is no rotation
MIN_QUATERNION_NORM = 1e-6
FORMATS = ("auto", "tum", "kitti", "boreas", "bag")
#: a stamp unit -> seconds
STAMP_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
#: the unit of each format's stamps when none is given
DEFAULT_UNITS = {"tum": "s", "kitti": "s", "bag": "s", "boreas": "us"}


@dataclass(frozen=True)
class Estimate:
    """The estimated poses ``T_world_frame`` at their stamps [s], the method's own time of
    each row [ms] (None when it reported none) and the unit the stamps were read in."""

    trajectory: Trajectory
    frame_times_ms: np.ndarray | None = None
    #: the unit the stamps were read in (they are returned in seconds)
    stamp_unit: str = "s"
    #: the stamps as the file wrote them (before the unit; None: as ``trajectory.stamps``)
    raw_stamps: np.ndarray | None = None
    #: the format it was read as (tum, kitti, boreas, bag)
    fmt: str = ""


def check_stamps(stamps: np.ndarray, where: str, lines: list | None = None) -> None:
    """Stamps must be finite and strictly increase (a DataError names the first bad row)."""
    s = np.asarray(stamps, dtype=np.float64)
    if not np.all(np.isfinite(s)):
        r = int(np.flatnonzero(~np.isfinite(s))[0])
        raise DataError(f"{where}, {_row(r, lines)}: stamp is not finite")
    back = np.flatnonzero(np.diff(s) <= 0)
    if len(back):
        r = int(back[0]) + 1
        raise DataError(f"{where}, {_row(r, lines)}: stamp {s[r]:.9f} s does not increase from "
                        f"{s[r - 1]:.9f} s ({len(back)} such rows); expected strictly "
                        "increasing stamps, one pose per instant")


def _row(r: int, lines: list | None) -> str:
    return f"line {lines[r]}" if lines is not None else f"pose {r}"


def poses_from_tum(xyz: np.ndarray, quat_xyzw: np.ndarray, where: str,
                   lines: list | None = None) -> np.ndarray:
    """4x4 poses from positions and quaternions (x y z w); a quaternion whose norm is not 1
    within ``QUAT_NORM_TOLERANCE`` is a DataError naming its row (normalised otherwise)."""
    norms = np.linalg.norm(quat_xyzw, axis=1)
    zero = np.flatnonzero(norms < MIN_QUATERNION_NORM)
    if len(zero):
        raise DataError(f"{where}, {_row(int(zero[0]), lines)}: quaternion (qx qy qz qw) has "
                        f"zero norm ({len(zero)} such rows); expected a rotation")
    off = np.flatnonzero(np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE)
    if len(off):
        r = int(off[0])
        raise DataError(f"{where}, {_row(r, lines)}: quaternion (qx qy qz qw) = "
                        f"{' '.join(f'{v:.6g}' for v in quat_xyzw[r])} has norm {norms[r]:.6g} "
                        f"({len(off)} such rows); expected a unit quaternion (norm 1 within "
                        f"{QUAT_NORM_TOLERANCE:g}): a column missing or one too many?")
    return T_from_tum(xyz, quat_xyzw / norms[:, None])


def check_index_column(data: np.ndarray, where: str) -> None:
    """Nine TUM columns whose first is an integer index (``i t x y z qx qy qz qw``) are a
    ``DataError``: the first column increases by whole numbers and the quaternion is a unit one
    one column later than TUM puts it."""
    first = data[:, 0]
    integer = bool(np.all(first == np.round(first)) and np.all(np.diff(first) > 0))
    later = np.abs(np.linalg.norm(data[:, 5:9], axis=1) - 1.0) <= QUAT_NORM_TOLERANCE
    if integer and len(data) >= 2 and later.all():
        raise DataError(f"{where}: 9 columns whose first is an integer index "
                        f"({first[0]:.0f}, {first[1]:.0f}, ...) and whose unit quaternion is in "
                        "columns 6-9: an index column before t x y z qx qy qz qw? expected TUM "
                        "rows t x y z qx qy qz qw [time_ms]: drop the index column (e.g. "
                        "cut -d' ' -f2-)")


def read_tum_estimate(path: Path) -> Estimate:
    """TUM rows, with an optional 9th column: the method's time of the frame [ms]."""
    data, lines = numeric_rows(path, (8, 9), "t x y z qx qy qz qw [time_ms]")
    if data.shape[1] == 9:
        check_index_column(data, str(path))
    check_stamps(data[:, 0], str(path), lines)
    poses = poses_from_tum(data[:, 1:4], data[:, 4:8], str(path), lines)
    times = data[:, 8].copy() if data.shape[1] == 9 else None
    if times is not None and (times < 0).any():
        r = int(np.flatnonzero(times < 0)[0])
        raise DataError(f"{path}, line {lines[r]}: negative time in the 9th column; expected "
                        "the method's time of the frame [ms] >= 0")
    return Estimate(Trajectory(data[:, 0], poses), times)


def read_stamps(path: Path) -> np.ndarray:
    """One stamp [s] per line (KITTI's times.txt)."""
    data, lines = numeric_rows(path, (1,), "one stamp [s] a line")
    check_stamps(data[:, 0], str(path), lines)
    return data[:, 0]


def read_kitti_estimate(path: Path, stamps_file: Path | None) -> Estimate:
    """KITTI rows (12 values) and their stamps from ``stamps_file`` (one per row)."""
    if stamps_file is None:
        raise DataError(f"{path}: a KITTI pose file has no stamps; give its stamps file "
                        "(--stamps times.txt: one stamp [s] per pose row)")
    data, lines = numeric_rows(path, (12,), "12 values: the 3x4 pose row-major")
    stamps = read_stamps(Path(stamps_file))
    if len(stamps) != len(data):
        raise DataError(f"{path}: {len(data)} pose rows but {stamps_file} has {len(stamps)} "
                        "stamps; expected one stamp per pose row")
    M = data.reshape(-1, 3, 4)
    R = nearest_rotations(M[:, :, :3], str(path), lines)
    return Estimate(Trajectory(stamps, make_T(R, M[:, :, 3])), None)


def read_bag_estimate(path: Path, topic: str | None) -> Estimate:
    """Poses of an Odometry / PoseStamped topic of a bag (``loaders.rosbag.read_gt_topic``,
    sorted by ``header.stamp``)."""
    from loaders.rosbag import POSE_TYPES, bag_topics, read_gt_topic

    if topic is None:
        topics = bag_topics([path])
        poses = sorted(t for t, m in topics.items() if m in POSE_TYPES)
        if len(poses) != 1:
            raise DataError(f"{path}: {len(poses)} pose topics ({', '.join(POSE_TYPES)}); give "
                            "the estimate's topic (--topic); the bag has "
                            + (", ".join(f"{t} ({m})" for t, m in sorted(topics.items()))
                               or "no topics"))
        topic = poses[0]
    traj = read_gt_topic([path], topic, what="estimated pose")
    check_stamps(traj.stamps, f"{path}:{topic}")
    return Estimate(traj, None)


def detect_format(path: Path) -> str:
    """"bag" for a bag (suffix or ROS2 folder), else by the first numeric row's width: 12
    "kitti", 13 "boreas", anything else "tum" (whose reader names a wrong width)."""
    if is_bag(path):
        return "bag"
    from loaders.limits import check_file_size

    check_file_size(path, str(path))
    return {12: "kitti", 13: "boreas"}.get(first_numeric_width(path), "tum")


def is_bag(path: Path) -> bool:
    return path.suffix in (".bag", ".db3", ".mcap") or (path.is_dir()
                                                         and (path / "metadata.yaml").exists())


def read_estimate(path: str | Path, fmt: str = "auto", stamps: str | Path | None = None,
                  topic: str | None = None, frame_times: str | Path | None = None,
                  stamp_unit: str | None = None) -> Estimate:
    """An estimated trajectory from a TUM file, a KITTI file with its ``stamps`` file, a Boreas
    submission file or a bag's pose ``topic``; ``frame_times``: a file of per-row times [ms];
    ``stamp_unit`` (s, ms, us, ns; None: the format's own, ``DEFAULT_UNITS``): the unit of the
    stamps, returned in seconds (see the module docstring)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: trajectory file not found")
    if fmt not in FORMATS:
        raise DataError(f"{path}: unknown trajectory format {fmt!r}; expected one of "
                        f"{', '.join(FORMATS)}")
    if stamp_unit is not None and stamp_unit not in STAMP_UNITS:
        raise DataError(f"--stamp-unit {stamp_unit!r}: expected one of "
                        f"{', '.join(STAMP_UNITS)}")
    if fmt == "auto":
        fmt = detect_format(path)
    if fmt == "bag":
        est = read_bag_estimate(path, topic)
    elif fmt == "boreas":
        from loaders.estimate_boreas import read_boreas

        traj, lines = read_boreas(path)
        check_stamps(traj.stamps * 1e-6, str(path), lines)  # (its message in seconds)
        est = Estimate(traj, None)
    elif fmt == "kitti":
        est = read_kitti_estimate(path, None if stamps is None else Path(stamps))
    else:
        est = read_tum_estimate(path)
    if frame_times is not None:
        data, lines = numeric_rows(Path(frame_times), (1,), "one time [ms] a line")
        if len(data) != len(est.trajectory):
            raise DataError(f"{frame_times}: {len(data)} times but {path} has "
                            f"{len(est.trajectory)} poses; expected one time [ms] per pose")
        neg = np.flatnonzero(data[:, 0] < 0)
        if len(neg):
            raise DataError(f"{frame_times}, line {lines[int(neg[0])]}: negative time; "
                            "expected a time per frame [ms] >= 0")
        est = Estimate(est.trajectory, data[:, 0].copy())
    finite = np.isfinite(est.trajectory.poses).all(axis=(1, 2))
    if not finite.all():  # (text rows are checked by line; a bag's poses here)
        raise DataError(f"{path}: pose {int(np.flatnonzero(~finite)[0])} is not finite "
                        f"({int((~finite).sum())} such poses); expected finite poses")
    if len(est.trajectory) < 2:
        raise DataError(f"{path}: the estimate has {len(est.trajectory)} pose; expected a "
                        "trajectory of at least 2 poses")
    unit = stamp_unit or DEFAULT_UNITS[fmt]
    traj = est.trajectory
    return Estimate(Trajectory(traj.stamps * STAMP_UNITS[unit], traj.poses), est.frame_times_ms,
                    unit, traj.stamps.copy(), fmt)
