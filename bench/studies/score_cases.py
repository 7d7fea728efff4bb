"""The inputs of the false-alarm / detection study of ``bench score``'s checks
(``bench.studies.score_checks``): correct trajectories (that must pass) and faulty ones (that
must be refused or warned with the right cause), written as the files a user would give.

Bases (an estimate with its scans and ground truth):

- the vendored NTU4DRadLM sample (250 real frames): a copy of its ground truth, the harness's
  own runs on it (``est_tum.txt`` of each method given) and kiss-icp's own pipeline on its
  exported bag (when given); and pieces of each: the halves, frames 60-190, the window of 100
  frames whose ground-truth speed varies least ("flat") and the one that turns least
  ("straight");
- synthetic drives (``loaders.synthetic.motion``, 12 Hz, 30 s): straight at a near-constant
  speed (the profile of the hidden drive: about 4.4 m/s), a constant curve, gentle turns, a
  U-turn; their estimate a simulated odometry (relative motions with 1 % scale and 0.2 deg
  noise, integrated: it drifts), their ground truth exact or NTU-like (10 Hz, nearest-sampled
  onto the scans: one row in six repeats).

Correct variants: as is; positions jittered (2 cm) and stamps jittered (2 ms, within the
tolerance); every other pose (6 Hz, ``--max-gap 0.25``); resampled at 5 Hz off the scan stamps
(``--max-gap 0.3``); lagged 5 ms; the 5 Hz estimate against the store's ground truth lagged
0.03 s or jittered by 2 cm. Faults: shifted by +-0.05 .. 5 s (as given, and with
``--max-gap 0.3``: then only the clock check stands between it and a score); positions in mm;
stamps in ms; frame indices as stamps; quaternions in w x y z order; a Boreas file holding
T_i_k; a KITTI file of inverse poses; a sheared rotation block; a 3.3 s hole bridged by
``--max-gap 1e9``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from scipy.spatial.transform import Rotation

from bench import guard
from loaders.se3 import exp_se3, interpolate_poses, inv_T, tum_from_T
from loaders.trajectory import Trajectory

PERIOD_S = 1 / 12
SHIFTS_S = (0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


@dataclass
class Base:
    """An estimate (stamps, poses) with the scans' stamps and ground truth it is scored
    against; ``kind``: real / synthetic; ``piece``: whole or which piece."""

    name: str
    kind: str
    stamps: np.ndarray
    poses: np.ndarray
    scans: np.ndarray
    gt: Trajectory
    piece: str = "whole"

    def seq(self):
        return SimpleNamespace(stamps=self.scans, ground_truth=self.gt, provenance={})


@dataclass
class Case:
    """One input: its base, variant, the file and the options it is scored with, and the
    cause it must be refused or warned for (None: it must pass)."""

    base: Base
    variant: str
    path: Path
    options: dict = field(default_factory=dict)
    cause: str | None = None
    size: float | None = None


def _text(rows: np.ndarray, fmt: str) -> str:
    """``rows`` as space-separated lines in the ``%`` format ``fmt`` (as ``np.savetxt``)."""
    return "".join(" ".join(fmt % v for v in row) + "\n" for row in np.asarray(rows).tolist())


def write_tum(path: Path, stamps, poses, order: str = "xyzw", fmt: str = "%.9f") -> Path:
    xyz, q = tum_from_T(np.asarray(poses))
    if order == "wxyz":
        q = q[:, [3, 0, 1, 2]]
    rows = np.column_stack([stamps, xyz, q])
    return guard.write_text(path, _text(rows, fmt), what="a case file")


def write_rows(path: Path, poses: np.ndarray, stamps_us: np.ndarray | None = None) -> Path:
    rows = np.asarray(poses)[:, :3, :].reshape(-1, 12)
    lines = [("" if stamps_us is None else f"{int(stamps_us[k])} ")
             + " ".join(f"{v:.9e}" for v in r) + "\n" for k, r in enumerate(rows)]
    return guard.write_text(path, "".join(lines), what="a case file")


def resample(stamps, poses, query) -> np.ndarray:
    return interpolate_poses(np.asarray(stamps), np.asarray(poses), np.asarray(query))


def _tag(base: Base) -> str:
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", f"{base.name}-{base.piece}")


def pieces(base: Base) -> list[Base]:
    """The halves, frames 60-190, the flattest and the straightest 100-frame windows."""
    n = len(base.scans)
    out = [("first half", slice(0, n // 2)), ("second half", slice(n // 2, n)),
           ("frames 60-190", slice(60, min(190, n)))]
    gt_at = resample(base.gt.stamps, base.gt.poses, base.scans)
    xyz = gt_at[:, :3, 3]
    speed = np.linalg.norm(np.diff(xyz, axis=0), axis=1) / np.diff(base.scans)
    yaw = Rotation.from_matrix(gt_at[:, :3, :3]).as_euler("ZYX")[:, 0]
    turn = np.abs(np.diff(np.unwrap(yaw)))
    starts = range(0, n - 99, 10)  # every 10 frames, the last window ending on the last scan
    flat = min(starts, key=lambda a: float(np.std(speed[a:a + 99])))
    straight = min(starts, key=lambda a: float(turn[a:a + 99].sum()))
    out += [("flat speed", slice(flat, flat + 100)), ("straight", slice(straight, straight + 100))]
    cut = []
    for label, sl in out:
        q = base.scans[sl]
        keep_e = (base.stamps >= q[0] - 1e-9) & (base.stamps <= q[-1] + 1e-9)
        keep_g = (base.gt.stamps >= q[0] - 1e-9) & (base.gt.stamps <= q[-1] + 1e-9)
        cut.append(Base(base.name, base.kind, base.stamps[keep_e], base.poses[keep_e], q,
                        Trajectory(base.gt.stamps[keep_g], base.gt.poses[keep_g]), label))
    return cut


def correct_cases(base: Base, folder: Path, rng: np.random.Generator) -> list[Case]:
    tag = _tag(base)
    t, P = base.stamps, base.poses
    cases = [Case(base, "as is", write_tum(folder / f"{tag}-asis.tum", t, P))]
    J = P.copy()
    J[:, :3, 3] += rng.normal(0, 0.02, (len(P), 3))
    tj = t + rng.uniform(-0.002, 0.002, len(t))
    cases.append(Case(base, "jittered (2 cm, 2 ms)", write_tum(folder / f"{tag}-jit.tum", tj, J)))
    cases.append(Case(base, "every other pose (6 Hz)",
                      write_tum(folder / f"{tag}-6hz.tum", t[::2], P[::2]), {"max_gap_s": 0.25}))
    q = np.arange(t[0] + 0.013, t[-1], 0.2)
    cases.append(Case(base, "resampled at 5 Hz off the scans",
                      write_tum(folder / f"{tag}-5hz.tum", q, resample(t, P, q)),
                      {"max_gap_s": 0.3}))
    cases.append(Case(base, "lagged 5 ms", write_tum(folder / f"{tag}-lag.tum", t + 0.005, P)))
    # the store's ground truth imperfect, the estimate right: lagged 0.03 s (within half a
    # scan period: more is a clock difference the check exists for), jittered 2 cm
    five = folder / f"{tag}-5hz.tum"
    g = base.gt
    lagged = Base(base.name, base.kind, t, P, base.scans, Trajectory(g.stamps + 0.03, g.poses),
                  base.piece)
    cases.append(Case(lagged, "store's GT lagged 0.03 s (5 Hz estimate)", five,
                      {"max_gap_s": 0.3}))
    jg = g.poses.copy()
    jg[:, :3, 3] += rng.normal(0, 0.02, (len(g), 3))
    jittered = Base(base.name, base.kind, t, P, base.scans, Trajectory(g.stamps, jg), base.piece)
    cases.append(Case(jittered, "store's GT jittered 2 cm (5 Hz estimate)", five,
                      {"max_gap_s": 0.3}))
    return cases


def fault_cases(base: Base, folder: Path) -> list[Case]:
    tag = _tag(base)
    t, P = base.stamps, base.poses
    out = []
    for s in SHIFTS_S:
        for sign in (1, -1):
            sh = sign * s
            path = write_tum(folder / f"{tag}-shift{sh:+g}.tum", t + sh, P)
            out.append(Case(base, "shifted, as given", path, {"min_coverage": 0.5}, "clock", sh))
            out.append(Case(base, "shifted, --max-gap 0.3", path,
                            {"max_gap_s": 0.3, "min_coverage": 0.5}, "clock", sh))
    mm = P.copy()
    mm[:, :3, 3] *= 1000.0
    out.append(Case(base, "positions in mm", write_tum(folder / f"{tag}-mm.tum", t, mm), {},
                    "positions in"))
    out.append(Case(base, "stamps in ms", write_tum(folder / f"{tag}-ms.tum", t * 1000, P), {},
                    "stamps in milliseconds"))
    out.append(Case(base, "frame indices as stamps",
                    write_tum(folder / f"{tag}-idx.tum", np.arange(len(t)), P), {},
                    "frame indices"))
    out.append(Case(base, "quaternions w x y z",
                    write_tum(folder / f"{tag}-wxyz.tum", t, P, "wxyz"), {}, "w x y z"))
    us = np.round(t * 1e6)
    out.append(Case(base, "Boreas holding T_i_k", write_rows(folder / f"{tag}-bor.txt", P, us),
                    {}, "T_i_k"))
    times = folder / f"{tag}-times.txt"
    guard.write_text(times, _text(t[:, None], "%.9f"), what="a case file")
    out.append(Case(base, "KITTI of inverse poses",
                    write_rows(folder / f"{tag}-inv.kitti", inv_T(P)), {"stamps": times},
                    "inverse poses"))
    for shear in (0.01, 0.2):
        S = P.copy()
        k = len(S) // 2
        S[k, :3, :3] = S[k, :3, :3] @ np.array([[1, shear, 0], [0, 1, 0], [0, 0, 1.0]])
        out.append(Case(base, "sheared rotation block", write_rows(
            folder / f"{tag}-shear{shear:g}.kitti", S), {"stamps": times}, "no rotation",
            shear))
    mid = t[0] + 0.4 * (t[-1] - t[0])
    keep = (t < mid) | (t > mid + 3.3)
    out.append(Case(base, "3.3 s hole, --max-gap 1e9",
                    write_tum(folder / f"{tag}-hole.tum", t[keep], P[keep]), {"max_gap_s": 1e9},
                    "bridged a gap"))
    return out


def simulated_odometry(gt_poses: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Relative motions with 1 % scale error and noise (2 cm, 0.2 deg), integrated."""
    rel = inv_T(gt_poses[:-1]) @ gt_poses[1:]
    out = [np.eye(4)]
    for T in rel:
        noisy = T.copy()
        noisy[:3, 3] *= 1.01
        noisy = noisy @ exp_se3(np.r_[rng.normal(0, 0.02, 3), rng.normal(0, np.radians(0.2), 3)])
        out.append(out[-1] @ noisy)
    return np.array(out)


def synthetic_bases(rng: np.random.Generator) -> list[Base]:
    from loaders.synthetic.motion import Motion, make_profile

    out = []
    drives = [("straight, flat 4.4 m/s", "straight", (4.3, 4.5), 0.0),
              ("curve", "curve", (4.0, 6.0), 0.02), ("gentle turns", "gentle", (3.0, 8.0), 0.0),
              ("U-turn", "uturn", (6.0, 9.0), 0.0)]
    scans = np.arange(0, 30.0, PERIOD_S)
    for label, kind, speed, curvature in drives:
        motion = Motion(make_profile(kind, rng, 31.0, speed, curvature=curvature), np.eye(4),
                        -1.0, 31.0)
        exact = motion.sensor_pose(scans)
        est = simulated_odometry(exact, rng)
        ticks = np.round(scans / 0.1) * 0.1  # NTU-like: 10 Hz GT nearest-sampled onto the scans
        ntu = motion.sensor_pose(ticks)
        out.append(Base(f"synthetic {label}", "synthetic", scans, est, scans,
                        Trajectory(scans, exact), "exact GT"))
        out.append(Base(f"synthetic {label}", "synthetic", scans, est, scans,
                        Trajectory(scans, ntu), "NTU-like GT"))
    return out
