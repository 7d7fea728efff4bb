"""Divergence flag for an estimated trajectory."""

from __future__ import annotations

import numpy as np

from metrics.relative import RelativeErrorStats


def is_diverged(est_poses: np.ndarray, rel: dict[float, RelativeErrorStats]) -> bool:
    """True if the run diverged.

    Diverged means: any estimated pose (``T_world_body``, (N,4,4)) has a non-finite entry, or,
    at the longest segment length L [m] in ``rel`` with n > 0, the mean translation error
    exceeds L / 2 (or is NaN). With no populated length only the first test applies.
    """
    if not np.all(np.isfinite(np.asarray(est_poses, dtype=np.float64))):
        return True
    populated = [length for length, stats in rel.items() if stats.n > 0]
    if not populated:
        return False
    longest = max(populated)
    mean = rel[longest].trans_m_mean
    return bool(not np.isfinite(mean) or mean > 0.5 * longest)
