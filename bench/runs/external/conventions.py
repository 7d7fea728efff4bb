"""Is the estimate read in the convention it was written in? (``bench score``)

A pose file read in the wrong convention still parses: quaternions written w x y z and read as
TUM's x y z w, a Boreas file holding the pose ``T_i_k`` where ``T_k_i`` belongs (or a KITTI
file holding the inverse poses). Which reading is right shows in what the ground truth gives:
over pairs of scans ``PAIR_S`` apart (1 s, and 4 s), the estimate's relative motion (its
rotation, and the direction of its translation: free of the world frame and of the scale)
agrees with the ground truth's under the right reading. Per pair the error is the angle of the
relative rotations' difference plus the angle between the two translations [deg]; the other
reading is named only when it is decisively better: the circular block bootstrap interval
(blocks of ``BLOCK_S``) of the mean error difference lies above 0 and its mean error is below
``RATIO`` of the reading's. Where it is not (a straight drive, too few pairs), nothing is said
but that the convention could not be checked.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from bench.runs.external.clock import block_weights
from loaders.se3 import inv_T, rotation_angle_deg

#: pairs of scans this far apart [s], each length on its own (an odometry that starts at the
#: identity and barely turns shows w x y z quaternions as a roll for a yaw: over 1 s pairs
#: kiss-icp's run on the sample could not tell, over 4 s it can; a synthetic straight drive
#: the other way round). The other reading is named when either length decides: on a correct
#: file the other reading is the wrong one, far worse, so two looks add no false alarm.
PAIR_S = (1.0, 4.0)
#: bootstrap blocks [s], replicates, level
BLOCK_S = 4.0
REPLICATES = 400
LEVEL = 0.95
#: the other reading must bring the mean error below this share of the reading's
RATIO = 0.5
#: at least this many pairs
MIN_PAIRS = 20
#: translations shorter than this [m] give no direction
MIN_STEP_M = 0.05


@dataclass(frozen=True)
class ConventionCheck:
    """The reading as read and the alternative (its name), their mean pair errors [deg], the
    interval of the difference (as read - other) and whether the other is decisively right."""

    other: str
    mean_read_deg: float
    mean_other_deg: float
    diff_interval_deg: tuple[float, float]
    decisive: bool
    pairs: int


def alternatives(fmt: str) -> dict[str, str]:
    """The misreadings worth checking for a format: name -> what the file then holds."""
    if fmt in ("tum", "bag"):
        return {"wxyz": "quaternions in w x y z order (TUM reads x y z w)"}
    if fmt == "boreas":
        return {"inverse": "the poses T_i_k where the format holds T_k_i (their inverses)"}
    if fmt == "kitti":
        return {"inverse": "the inverse poses (T_frame_world where T_world_frame belongs)"}
    return {}


def reread(poses: np.ndarray, other: str) -> np.ndarray:
    """The poses (``T_world_frame`` as read) under the other reading."""
    if other == "inverse":
        return inv_T(poses)
    out = poses.copy()
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x y z w as read: file columns 4-7
    out[:, :3, :3] = Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_matrix()  # columns were w x y z
    return out


def pair_errors(est: np.ndarray, gt: np.ndarray, step: int) -> np.ndarray:
    """Per pair (i, i + step) of scans with both: the relative rotations' difference [deg] plus
    the angle between the relative translations [deg] (0 where either is too short)."""
    ok = np.isfinite(est).all(axis=(1, 2)) & np.isfinite(gt).all(axis=(1, 2))
    i = np.flatnonzero(ok[:-step] & ok[step:]) if len(ok) > step else np.zeros(0, int)
    if len(i) == 0:
        return np.zeros(0)
    dE = inv_T(est[i]) @ est[i + step]
    dG = inv_T(gt[i]) @ gt[i + step]
    rot = rotation_angle_deg(np.swapaxes(dG[:, :3, :3], 1, 2) @ dE[:, :3, :3])
    a, b = dE[:, :3, 3], dG[:, :3, 3]
    na, nb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
    moved = (na > MIN_STEP_M) & (nb > MIN_STEP_M)
    cos = np.where(moved, (a * b).sum(axis=1) / np.where(moved, na * nb, 1.0), 1.0)
    return rot + np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def compare(read: np.ndarray, other: np.ndarray, gt: np.ndarray, period_s: float, name: str,
            seed: int = 0) -> ConventionCheck | None:
    """``compare_at`` every ``PAIR_S``: the first decisive one, else the last with pairs."""
    found = None
    for pair_s in PAIR_S:
        check = compare_at(read, other, gt, period_s, name, pair_s, seed)
        if check is not None and check.decisive:
            return check
        found = check or found
    return found


def compare_at(read: np.ndarray, other: np.ndarray, gt: np.ndarray, period_s: float, name: str,
               pair_s: float, seed: int = 0) -> ConventionCheck | None:
    """The two readings' pair errors (pairs ``pair_s`` apart) against ``gt`` (all (N, 4, 4)
    at the same scans, NaN where none); None when too few pairs."""
    step = max(1, int(round(pair_s / max(period_s, 1e-9))))
    e_read, e_other = pair_errors(read, gt, step), pair_errors(other, gt, step)
    if len(e_read) < MIN_PAIRS or len(e_read) != len(e_other):
        return None
    d = e_read - e_other
    rng = np.random.default_rng(seed)
    block = max(1, int(round(BLOCK_S / max(period_s, 1e-9))))
    means = np.array([np.average(d, weights=w) if (w := block_weights(len(d), block, rng)).any()
                      else d.mean() for _ in range(REPLICATES)])
    lo, hi = (float(v) for v in np.percentile(means, [50 * (1 - LEVEL), 50 * (1 + LEVEL)]))
    m_read, m_other = float(e_read.mean()), float(e_other.mean())
    decisive = lo > 0 and m_other < RATIO * m_read
    return ConventionCheck(name, m_read, m_other, (lo, hi), decisive, len(d))


def describe(check: ConventionCheck | None, what: str) -> str:
    """A line saying what the check found."""
    if check is None:
        return "convention not checked: too few pairs of scans with both poses"
    lo, hi = check.diff_interval_deg
    said = (f"relative motion error {check.mean_read_deg:.2f} deg as read, "
            f"{check.mean_other_deg:.2f} deg read as {what} (difference interval [{lo:.2f}, "
            f"{hi:.2f}] deg over {check.pairs} pairs)")
    if check.decisive:
        return said
    if lo > 0 or hi < 0:
        return f"as read ({said})"
    return f"the convention could not be told ({said}): scored as read"


ADVICE = {"wxyz": "reorder its quaternion columns to qx qy qz qw (e.g. awk '{print $1, $2, $3, "
                  "$4, $6, $7, $8, $5}')",
          "inverse": "invert its poses (each row the inverse transform) before scoring"}


def check_conventions(fmt: str, read: np.ndarray, match_other, gt_at_scans: np.ndarray,
                      period_s: float, where: str) -> str:
    """Refuse (``DataError``) an estimate whose other reading (``alternatives``) is decisively
    right; ``match_other(poses)``: those poses at the scans (as the estimate's were matched);
    ``read``: the estimate's at the scans. Returns the line saying what was found."""
    from loaders.errors import DataError

    lines = []
    for name, what in alternatives(fmt).items():
        check = compare(read, match_other(name), gt_at_scans, period_s, name)
        if check is not None and check.decisive:
            raise DataError(
                f"{where}: read as {fmt}, its relative motions disagree with the ground truth's; "
                f"read as {what}, they agree ({describe(check, name)}): the file holds {what}? "
                f"{ADVICE[name]}")
        lines.append(f"{name}: {describe(check, name)}")
    return "; ".join(lines) if lines else f"no other reading of {fmt} to check"
