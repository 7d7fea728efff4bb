"""The shared scan format: ``Scan``, ``Trajectory``, ``SensorInfo`` and ``Sequence``.

This module is the single definition every loader produces and every method consumes.

Conventions (see shared/REFERENCE.md):
- ``Scan.points`` are in the sensor frame [m]; ``Scan.doppler`` is the radial velocity of each
  point [m/s], **positive when the point recedes** (a static point ahead of a forward-moving
  sensor reads negative).
- ``Trajectory.poses`` are ``T_world_frame`` (4x4); a sequence's ground truth is always given
  for the sensor frame the methods see (``T_world_sensor``), extrinsic already applied.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from loaders.errors import DataError
from loaders.se3 import T_from_tum, interpolate_poses, make_T, tum_from_T

SensorKind = Literal["radar", "lidar"]


def _check_finite(name: str, values: np.ndarray, prefix: str) -> None:
    bad = ~np.isfinite(values)
    if bad.any():
        rows = np.flatnonzero(bad.reshape(len(values), -1).any(axis=1))
        raise DataError(
            f"{prefix}{name} has {len(rows)} non-finite rows (first at row {rows[0]}); "
            "expected finite values (drop NaN points in the loader and report the count)"
        )


@dataclass(frozen=True, eq=False)
class Scan:
    """One sensor scan.

    stamp: scan time [s, sensor clock]. points: (N, 3) in the sensor frame [m].
    doppler: (N,) radial velocity [m/s, positive = receding], or None when the sensor has none.
    fields: optional per-point arrays (N,) such as ``intensity``, ``power``, ``rcs``, ``snr`` or
    ``time_offset_s`` (per-point time relative to ``stamp`` [s]).
    source: where the scan came from ("file, frame i"), used in error messages only.
    """

    stamp: float
    points: np.ndarray
    doppler: np.ndarray | None = None
    fields: Mapping[str, np.ndarray] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        prefix = f"{self.source}: " if self.source else ""
        points = np.asarray(self.points, dtype=np.float64)
        if points.ndim != 2 or points.shape[1] != 3:
            raise DataError(f"{prefix}points must have shape (N, 3), got {points.shape}")
        if not np.isfinite(self.stamp):
            raise DataError(f"{prefix}stamp must be finite, got {self.stamp}")
        _check_finite("points", points, prefix)
        n = len(points)
        doppler = None
        if self.doppler is not None:
            doppler = np.asarray(self.doppler, dtype=np.float64)
            if doppler.shape != (n,):
                raise DataError(
                    f"{prefix}doppler must have shape ({n},) like the points, got {doppler.shape}"
                )
            _check_finite("doppler", doppler, prefix)
        fields = {}
        for name, values in self.fields.items():
            values = np.asarray(values)
            if values.shape != (n,):
                raise DataError(
                    f"{prefix}per-point field '{name}' must have shape ({n},), got {values.shape}"
                )
            fields[name] = values
        object.__setattr__(self, "stamp", float(self.stamp))
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "doppler", doppler)
        object.__setattr__(self, "fields", fields)

    def __len__(self) -> int:
        return len(self.points)

    @property
    def has_doppler(self) -> bool:
        return self.doppler is not None

    def select(self, mask: np.ndarray) -> Scan:
        """A scan with the points chosen by ``mask`` (boolean or index array), every per-point
        array selected together."""
        return Scan(
            stamp=self.stamp,
            points=self.points[mask],
            doppler=None if self.doppler is None else self.doppler[mask],
            fields={k: v[mask] for k, v in self.fields.items()},
            source=self.source,
        )


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Timed poses ``T_world_frame``: stamps (N,) [s] and poses (N, 4, 4)."""

    stamps: np.ndarray
    poses: np.ndarray

    def __post_init__(self) -> None:
        stamps = np.asarray(self.stamps, dtype=np.float64)
        poses = np.asarray(self.poses, dtype=np.float64)
        if stamps.ndim != 1 or poses.shape != (len(stamps), 4, 4):
            raise DataError(
                f"trajectory needs stamps (N,) and poses (N, 4, 4), got {stamps.shape} "
                f"and {poses.shape}"
            )
        object.__setattr__(self, "stamps", stamps)
        object.__setattr__(self, "poses", poses)

    def __len__(self) -> int:
        return len(self.stamps)

    @property
    def positions(self) -> np.ndarray:
        return self.poses[:, :3, 3]

    def path_length_m(self) -> float:
        """Length of the path through the positions [m]."""
        return float(np.linalg.norm(np.diff(self.positions, axis=0), axis=1).sum())

    def with_stamps(self, stamps: np.ndarray) -> Trajectory:
        return Trajectory(np.asarray(stamps, dtype=np.float64), self.poses)

    def transformed(self, T_left: np.ndarray | None = None, T_right: np.ndarray | None = None):
        """``T_left @ pose @ T_right`` for every pose (change of world and of body frame)."""
        poses = self.poses
        if T_left is not None:
            poses = T_left @ poses
        if T_right is not None:
            poses = poses @ T_right
        return Trajectory(self.stamps, poses)

    # -- time association --------------------------------------------------------------
    def coverage_mask(self, query_stamps: np.ndarray, max_gap_s: float | None = None,
                      tolerance_s: float = 1e-9) -> np.ndarray:
        """True where a query stamp lies inside the trajectory's time span and, if ``max_gap_s``
        is given, between two poses at most ``max_gap_s`` apart. A query within ``tolerance_s``
        of a pose is covered whatever the gaps around it (it takes that pose).

        Interpolation never bridges a longer gap: a scan just after the last pose before an
        outage is *not* covered (interpolating across the whole outage puts it on the chord,
        metres off the path on a curve)."""
        q = np.asarray(query_stamps, dtype=np.float64)
        s = self.stamps
        if len(s) == 0:
            return np.zeros(len(q), dtype=bool)
        inside = (q >= s[0] - tolerance_s) & (q <= s[-1] + tolerance_s)
        if len(s) < 2:
            return inside
        hi = np.clip(np.searchsorted(s, q), 1, len(s) - 1)
        on_pose = np.minimum(np.abs(q - s[hi - 1]), np.abs(s[hi] - q)) <= tolerance_s
        if max_gap_s is None:
            return inside
        gap = s[hi] - s[hi - 1]
        return inside & ((gap <= max_gap_s) | on_pose)

    def interpolate(
        self, query_stamps: np.ndarray, max_gap_s: float | None = None, name: str = "trajectory"
    ) -> Trajectory:
        """Poses at ``query_stamps`` (slerp + linear). Raises ``DataError`` when a query stamp is
        not covered (outside the span, or inside a gap longer than ``max_gap_s``)."""
        q = np.asarray(query_stamps, dtype=np.float64)
        if len(self) < 2 or np.any(np.diff(self.stamps) <= 0):
            raise DataError(
                f"{name}: interpolation needs at least 2 poses with strictly increasing stamps"
            )
        covered = self.coverage_mask(q, max_gap_s)
        if not covered.all():
            if not covered.any():
                raise DataError(
                    f"{name}: stamps [{self.stamps[0]:.3f}, {self.stamps[-1]:.3f}] s do not "
                    f"overlap the {len(q)} query stamps [{q.min():.3f}, {q.max():.3f}] s "
                    "(different clocks? set a time offset)"
                )
            first = int(np.flatnonzero(~covered)[0])
            raise DataError(
                f"{name}: {int((~covered).sum())} of {len(q)} query stamps are not covered "
                f"(first: index {first}, t={q[first]:.3f} s; span [{self.stamps[0]:.3f}, "
                f"{self.stamps[-1]:.3f}] s, max gap {max_gap_s} s)"
            )
        return Trajectory(q, interpolate_poses(self.stamps, self.poses,
                                               np.clip(q, self.stamps[0], self.stamps[-1])))

    # -- files ---------------------------------------------------------------------------
    @classmethod
    def read_tum(cls, path: str | Path) -> Trajectory:
        """Read TUM rows ``t x y z qx qy qz qw``; '#' comments and one leading header line that
        is not numeric are skipped."""
        path = Path(path)
        rows = []
        with open(path) as f:
            for lineno, line in enumerate(f, start=1):
                text = line.strip()
                if not text or text.startswith("#"):
                    continue
                parts = text.replace(",", " ").split()
                try:
                    values = [float(v) for v in parts]
                except ValueError:
                    if not rows:  # a header line such as "timestamp x y z ..."
                        continue
                    raise DataError(
                        f"{path}, line {lineno}: expected 8 numbers, got {text!r}"
                    ) from None
                if len(values) != 8:
                    raise DataError(
                        f"{path}, line {lineno}: expected 8 values (t x y z qx qy qz qw), "
                        f"got {len(values)}"
                    )
                rows.append(values)
        if not rows:
            raise DataError(f"{path}: no TUM pose rows found")
        data = np.array(rows)
        if not np.isfinite(data).all():
            raise DataError(f"{path}: non-finite values in the TUM rows")
        return cls(data[:, 0], T_from_tum(data[:, 1:4], data[:, 4:8]))

    def write_tum(self, path: str | Path) -> None:
        xyz, quat = tum_from_T(self.poses)
        np.savetxt(path, np.column_stack([self.stamps, xyz, quat]), fmt="%.9f")

    @classmethod
    def read_kitti(cls, path: str | Path, stamps: np.ndarray | None = None) -> Trajectory:
        """Read KITTI rows (12 values, 3x4 row-major); stamps default to the row index."""
        path = Path(path)
        try:
            data = np.loadtxt(path, ndmin=2)
        except ValueError as err:
            raise DataError(f"{path}: not a KITTI pose file ({err})") from err
        if data.shape[1] != 12:
            raise DataError(f"{path}: expected 12 values per KITTI row, got {data.shape[1]}")
        poses = make_T(data[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]].reshape(-1, 3, 3), data[:, [3, 7, 11]])
        if stamps is None:
            stamps = np.arange(len(poses), dtype=np.float64)
        elif len(stamps) != len(poses):
            raise DataError(f"{path}: {len(poses)} poses but {len(stamps)} stamps")
        return cls(np.asarray(stamps, dtype=np.float64), poses)

    def write_kitti(self, path: str | Path) -> None:
        np.savetxt(path, self.poses[:, :3, :].reshape(-1, 12), fmt="%.9e")


@dataclass(frozen=True, eq=False)
class SensorInfo:
    """What kind of sensor produced a sequence.

    kind: "radar" or "lidar". period_s: nominal scan period [s] (methods use the actual stamps).
    T_body_sensor: extrinsic of the sensor in the vehicle/GT body frame (documentation of how
    ground truth was brought into the sensor frame). model: e.g. "radar-semidense".
    """

    kind: SensorKind
    period_s: float
    T_body_sensor: np.ndarray = field(default_factory=lambda: np.eye(4))
    model: str = ""

    def __post_init__(self) -> None:
        if self.kind not in ("radar", "lidar"):
            raise DataError(f"sensor kind must be 'radar' or 'lidar', got {self.kind!r}")
        if not (self.period_s > 0):
            raise DataError(f"sensor period must be > 0 s, got {self.period_s}")
        T = np.asarray(self.T_body_sensor, dtype=np.float64)
        if T.shape != (4, 4):
            raise DataError(f"T_body_sensor must be 4x4, got {T.shape}")
        object.__setattr__(self, "T_body_sensor", T)


class Sequence(ABC):
    """A sequence of scans with optional ground truth.

    Subclasses provide ``__len__``, ``scan(i)`` and ``stamps``; iteration streams scans one at a
    time (a store-backed sequence never loads the whole sequence to iterate).
    ``ground_truth``, when present, holds ``T_world_sensor`` poses (usually at the scan stamps).
    """

    name: str
    sensor: SensorInfo
    ground_truth: Trajectory | None
    provenance: dict

    @abstractmethod
    def __len__(self) -> int: ...

    @abstractmethod
    def scan(self, index: int) -> Scan: ...

    @property
    @abstractmethod
    def stamps(self) -> np.ndarray: ...

    def __getitem__(self, index: int) -> Scan:
        n = len(self)
        if index < 0:
            index += n
        if not 0 <= index < n:
            raise IndexError(f"{self.name}: frame {index} out of range (0..{n - 1})")
        return self.scan(index)

    def __iter__(self) -> Iterator[Scan]:
        for i in range(len(self)):
            yield self.scan(i)

    def __repr__(self) -> str:
        gt = "with GT" if self.ground_truth is not None else "no GT"
        return (
            f"{type(self).__name__}({self.name!r}, {len(self)} frames, "
            f"{self.sensor.kind}, {gt})"
        )


class MemorySequence(Sequence):
    """A sequence held in memory (synthetic data, tests, small folders)."""

    def __init__(
        self,
        name: str,
        sensor: SensorInfo,
        scans: list[Scan],
        ground_truth: Trajectory | None = None,
        provenance: dict | None = None,
    ) -> None:
        self.name = name
        self.sensor = sensor
        self._scans = list(scans)
        self.ground_truth = ground_truth
        self.provenance = dict(provenance or {})

    def __len__(self) -> int:
        return len(self._scans)

    def scan(self, index: int) -> Scan:
        return self._scans[index]

    @property
    def stamps(self) -> np.ndarray:
        return np.array([s.stamp for s in self._scans], dtype=np.float64)


class FrameRange(Sequence):
    """Frames ``start, start+stride, ...`` of another sequence (at most ``frames`` of them).

    The nominal period is scaled by the stride; ground truth is cut to the selected time span
    (and, when it is sampled at the base's scans, to the selected scans).
    """

    def __init__(self, base: Sequence, start: int = 0, frames: int | None = None,
                 stride: int = 1) -> None:
        if start < 0 or stride < 1 or (frames is not None and frames < 1):
            raise DataError(
                f"{base.name}: bad frame range start={start}, frames={frames}, stride={stride} "
                "(expected start >= 0, frames >= 1, stride >= 1)"
            )
        indices = np.arange(start, len(base), stride)
        if frames is not None:
            indices = indices[:frames]
        if len(indices) == 0:
            raise DataError(f"{base.name}: start={start} is past the last frame ({len(base) - 1})")
        self.base = base
        self.indices = indices
        self.name = base.name
        s = base.sensor
        self.sensor = SensorInfo(s.kind, s.period_s * stride, s.T_body_sensor, s.model)
        self._stamps = base.stamps[indices]
        gt = base.ground_truth
        if gt is not None:
            keep = (gt.stamps >= self._stamps[0] - 1e-9) & (gt.stamps <= self._stamps[-1] + 1e-9)
            if _all_on(gt.stamps, base.stamps):
                # GT sampled at the base's scans: keep it at the selected scans only, so the
                # evaluation never interpolates across skipped scans (or a GT gap between them)
                keep &= _on(gt.stamps, self._stamps)
            gt = Trajectory(gt.stamps[keep], gt.poses[keep])
        self.ground_truth = gt
        self.provenance = {**base.provenance,
                           "frame_range": {"start": start, "frames": len(indices),
                                           "stride": stride}}

    def __len__(self) -> int:
        return len(self.indices)

    def scan(self, index: int) -> Scan:
        return self.base.scan(int(self.indices[index]))

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()


def _on(values: np.ndarray, stamps: np.ndarray, tolerance_s: float = 1e-6) -> np.ndarray:
    """True for each of ``values`` within ``tolerance_s`` of one of ``stamps``."""
    s = np.sort(np.asarray(stamps, dtype=np.float64))
    if len(s) == 0:
        return np.zeros(len(values), dtype=bool)
    hi = np.clip(np.searchsorted(s, values), 0, len(s) - 1)
    lo = np.clip(hi - 1, 0, len(s) - 1)
    return np.minimum(np.abs(s[hi] - values), np.abs(values - s[lo])) <= tolerance_s


def _all_on(values: np.ndarray, stamps: np.ndarray) -> bool:
    return bool(np.all(_on(values, stamps)))


def select_frames(seq: Sequence, start: int = 0, frames: int | None = None,
                  stride: int = 1) -> Sequence:
    """``seq`` itself for the full range, else a ``FrameRange`` view of it."""
    if start == 0 and frames is None and stride == 1:
        return seq
    return FrameRange(seq, start, frames, stride)
