"""Trajectory metrics: pure functions on associated (N, 4, 4) ``T_world_body`` pose arrays."""

from metrics.ape import ALIGNMENTS, Alignment, ApeStats, ape, ape_errors, umeyama, umeyama_se3
from metrics.divergence import is_diverged
from metrics.kitti import KITTI_LENGTHS_M, KittiDrift, kitti_drift
from metrics.relative import (
    DEFAULT_LENGTHS_M,
    MetricError,
    RelativeErrorStats,
    SegmentErrors,
    path_distances,
    relative_errors,
    segment_errors,
)
from metrics.timing import timing_stats
from metrics.velocity import DEFAULT_WINDOW_S, VelocityErrorStats, velocity_errors

__all__ = [
    "ALIGNMENTS",
    "DEFAULT_LENGTHS_M",
    "DEFAULT_WINDOW_S",
    "KITTI_LENGTHS_M",
    "Alignment",
    "ApeStats",
    "KittiDrift",
    "MetricError",
    "RelativeErrorStats",
    "SegmentErrors",
    "VelocityErrorStats",
    "ape",
    "ape_errors",
    "is_diverged",
    "kitti_drift",
    "path_distances",
    "relative_errors",
    "segment_errors",
    "timing_stats",
    "umeyama",
    "umeyama_se3",
    "velocity_errors",
]
