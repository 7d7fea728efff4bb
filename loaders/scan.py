"""The shared scan format: ``Scan``, ``SensorInfo`` and ``Sequence`` (poses: ``trajectory.py``).

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
from typing import Literal

import numpy as np

from loaders.errors import DataError
from loaders.trajectory import Trajectory

SensorKind = Literal["radar", "lidar"]
#: what a sequence's Doppler values are: ``radial`` = the raw range rate of each point relative
#: to the moving sensor (what Doppler methods need); ``ego-compensated`` = the sensor's own motion
#: already removed by the dataset (static points read about 0 m/s: unusable as radial velocity);
#: ``gt-reconstructed`` = radial velocity rebuilt from a compensated value and the GT's ego motion
#: (an explicit opt-in: every result made from it is GT-assisted).
DopplerKind = Literal["radial", "ego-compensated", "gt-reconstructed"]
DOPPLER_KINDS: tuple[str, ...] = ("radial", "ego-compensated", "gt-reconstructed")


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
class SensorInfo:
    """What kind of sensor produced a sequence.

    kind: "radar" or "lidar". period_s: nominal scan period [s] (methods use the actual stamps).
    T_body_sensor: extrinsic of the sensor in the vehicle/GT body frame (documentation of how
    ground truth was brought into the sensor frame). model: e.g. "radar-semidense".
    doppler_kind: what the Doppler values are (``DopplerKind``; "radial" unless a loader says
    otherwise; meaningless for a sequence without Doppler).
    """

    kind: SensorKind
    period_s: float
    T_body_sensor: np.ndarray = field(default_factory=lambda: np.eye(4))
    model: str = ""
    doppler_kind: DopplerKind = "radial"

    def __post_init__(self) -> None:
        if self.kind not in ("radar", "lidar"):
            raise DataError(f"sensor kind must be 'radar' or 'lidar', got {self.kind!r}")
        if self.doppler_kind not in DOPPLER_KINDS:
            raise DataError(f"doppler kind must be one of {', '.join(DOPPLER_KINDS)}, "
                            f"got {self.doppler_kind!r}")
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

    def close(self) -> None:  # noqa: B027 - a hook: most sequences hold no open file
        """Release open files (a store-backed sequence); nothing to do by default."""

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
        self.sensor = SensorInfo(s.kind, s.period_s * stride, s.T_body_sensor, s.model,
                                 s.doppler_kind)
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
        # frames of the source drive: composed with a cut the base already is (a cut of a cut,
        # a numbered frame folder's files)
        outer = base.provenance.get("frame_range") or {}
        first, step = int(outer.get("start") or 0), int(outer.get("stride") or 1)
        self.provenance = {**base.provenance,
                           "frame_range": {"start": first + start * step,
                                           "frames": len(indices), "stride": stride * step,
                                           **({"from": outer["from"]} if "from" in outer
                                              else {})}}

    def __len__(self) -> int:
        return len(self.indices)

    def scan(self, index: int) -> Scan:
        return self.base.scan(int(self.indices[index]))

    def close(self) -> None:
        self.base.close()

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
                  stride: int = 1, rename: bool = False) -> Sequence:
    """``seq`` itself for the full range, else a ``FrameRange`` view of it; with ``rename``
    the view is named by the frames it keeps (``range_name``), so a cut of a sequence never
    carries the name of the whole."""
    if start == 0 and frames is None and stride == 1:
        return seq
    cut = FrameRange(seq, start, frames, stride)
    if rename:
        cut.name = range_name(seq.name, cut.indices)
        if cut.provenance.get("display_name"):
            cut.provenance["display_name"] = range_name(cut.provenance["display_name"],
                                                        cut.indices)
    return cut


def range_name(name: str, indices: np.ndarray) -> str:
    """The name of frames ``indices`` of sequence ``name``: ``data1_frames60-249`` (with a
    stride: ``data1_frames60-438_every2``)."""
    step = int(indices[1] - indices[0]) if len(indices) > 1 else 1
    text = f"{name}_frames{int(indices[0])}-{int(indices[-1])}"
    return text + (f"_every{step}" if step > 1 else "")
