"""Trajectory metrics: pure functions on associated (N, 4, 4) ``T_world_body`` pose arrays."""

from metrics.ape import ALIGNMENTS, ApeStats, ape, ape_errors, umeyama_se3
from metrics.divergence import is_diverged
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

__all__ = [
    "ALIGNMENTS",
    "DEFAULT_LENGTHS_M",
    "ApeStats",
    "MetricError",
    "RelativeErrorStats",
    "SegmentErrors",
    "ape",
    "ape_errors",
    "is_diverged",
    "path_distances",
    "relative_errors",
    "segment_errors",
    "timing_stats",
    "umeyama_se3",
]
