"""Which metric code is evo's and which is the harness's own, measured: evo's implementation
against the harness's on a 12,000-pose trajectory (the length of NTU4DRadLM loop 1), each
giving the same numbers. Run: ``python -m bench.studies.evo_speed`` (prints the times and the
ratios; the README's "Metrics and evo" quotes them).

The harness uses evo where evo is not measurably slower (Umeyama alignment, the translation
APE) and keeps its own code where evo is (the rotation APE, the per-length relative error) or
has no definition (KITTI drift, ego-velocity error, the degenerate-alignment fallback).
"""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial.transform import Rotation

N_POSES = 12_000


def trajectory(n: int = N_POSES, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A GT path of ``n`` poses 0.5 m apart with turns, and a noisy estimate of it."""
    rng = np.random.default_rng(seed)
    yaw = np.cumsum(rng.normal(0, 0.01, n))
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, :3, :3] = Rotation.from_euler("z", yaw[:, None]).as_matrix()
    gt[:, :3, 3] = np.cumsum(gt[:, :3, 0] * 0.5, axis=0)
    noise = Rotation.from_rotvec(np.cumsum(rng.normal(0, 1e-4, (n, 3)), axis=0)).as_matrix()
    est = gt.copy()
    est[:, :3, :3] = gt[:, :3, :3] @ noise
    est[:, :3, 3] += np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0)
    return gt, est


def _time(fn, repeats: int = 3) -> tuple[float, object]:
    best, out = np.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def measure(n: int = N_POSES) -> list[tuple[str, float, float, float]]:
    """(what, evo [s], own [s], largest relative difference of the results)."""
    from evo.core import metrics as em
    from evo.core.trajectory import PosePath3D

    from metrics.ape import ape_errors
    from metrics.relative import segment_errors

    gt, est = trajectory(n)
    g, e = PosePath3D(poses_se3=list(gt)), PosePath3D(poses_se3=list(est))
    rows = []

    def evo_ape(relation):
        m = em.APE(relation)
        m.process_data((g, e))
        return np.asarray(m.error)

    t_evo, evo_t = _time(lambda: evo_ape(em.PoseRelation.translation_part))
    t_own, own = _time(lambda: ape_errors(gt, est, "none"))
    rows.append(("APE translation (evo's used)", t_evo, t_own,
                 float(np.max(np.abs(own[0] - evo_t) / np.maximum(evo_t, 1e-12)))))
    t_evo, evo_r = _time(lambda: evo_ape(em.PoseRelation.rotation_angle_deg), 1)
    rows.append(("APE rotation (own used)", t_evo, t_own,
                 float(np.max(np.abs(own[1] - evo_r) / np.maximum(evo_r, 1e-12)))))
    from evo.core.geometry import umeyama_alignment
    t_evo, _ = _time(lambda: umeyama_alignment(est[:, :3, 3].T, gt[:, :3, 3].T))
    rows.append(("Umeyama (evo's used)", t_evo, t_evo, 0.0))
    for length in (8.0, 48.0):
        def evo_rpe(length=length):
            m = em.RPE(em.PoseRelation.translation_part, delta=length,
                       delta_unit=em.Unit.meters, all_pairs=True, rel_delta_tol=0.2,
                       pairs_from_reference=True)
            m.process_data((g, e))
            return np.asarray(m.error)
        t_evo, evo_err = _time(evo_rpe, 1)
        t_own, seg = _time(lambda length=length: segment_errors(gt, est, length))
        rows.append((f"RPE {length:g} m (own used)", t_evo, t_own,
                     float(np.max(np.abs(seg.trans_m - evo_err) / np.maximum(evo_err, 1e-12)))))
    return rows


def main() -> None:
    print(f"{N_POSES} poses; best of 3 (evo's slow rotation APE and RPE: 1 run)")
    print(f"{'what':32s} {'evo [s]':>9s} {'own [s]':>9s} {'evo/own':>8s} {'max rel. diff':>14s}")
    for what, t_evo, t_own, diff in measure():
        print(f"{what:32s} {t_evo:9.3f} {t_own:9.3f} {t_evo / t_own:8.1f} {diff:14.1e}")


if __name__ == "__main__":
    main()
