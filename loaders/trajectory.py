"""``Trajectory``: timed poses ``T_world_frame`` (stamps [s], 4x4 poses), with time coverage and
interpolation. Reading and writing pose files (TUM, KITTI) is ``loaders.posefile``."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loaders.errors import DataError
from loaders.se3 import interpolate_poses


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
