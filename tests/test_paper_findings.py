"""The paper's own qualitative findings on small synthetic sequences (only claims the paper
makes: CI protects against regressions through `bench regress`'s baseline, not rankings).

- Repetitive geometry (empty tunnel, dense FMCW LiDAR): point-to-point ICP slides along the
  tunnel axis; Doppler Correspondence does not (paper Sec. V, Table VI).
- Doppler Correspondence assumes dT * |w| << 1: a U-turn (|w| ~ 0.55 rad/s) gives it at least
  twice the rotation error of a gentle-turn loop (|w| ~ 0.1 rad/s) (paper Sec. VI-A).
- Doppler 4D-ICP (Algorithm 1) beats both its ingredients through a U-turn (Table IV, Loop1_4)
  and does not slide along a tunnel as point-to-point ICP does (Table V).
"""

import numpy as np
import pytest

from loaders.scan import MemorySequence
from loaders.se3 import inv_T
from loaders.synthetic import SyntheticSequence
from methods.registry import make_method
from metrics import relative_errors


def _in_memory(seq):
    return MemorySequence(seq.name, seq.sensor, list(seq), seq.ground_truth)


def along_track_drift_m(gt_poses, est_poses) -> float:
    """|error of the end-to-end motion along the initial sensor x axis| [m]."""
    g = inv_T(gt_poses[0]) @ gt_poses[-1]
    p = inv_T(est_poses[0]) @ est_poses[-1]
    return abs(g[0, 3] - p[0, 3])


@pytest.fixture(scope="module")
def tunnels():
    # three empty-tunnel scenes, 40 LiDAR frames (~48 m) of ~8k points each
    return [_in_memory(SyntheticSequence("tunnel", "lidar-dense", frames=40, seed=s,
                                         points=8000)) for s in (1, 2, 3)]


@pytest.mark.parametrize("seed", [True, False], ids=["with-seed", "no-seed"])
def test_icp_drifts_along_the_tunnel_five_times_more_than_doppler(tunnels, seed):
    drift = {"doppler": 0.0, "icp-p2p": 0.0, "doppler-icp": 0.0}
    for seq in tunnels:
        gt = seq.ground_truth.poses
        drift["doppler"] += along_track_drift_m(gt, make_method("doppler").run(seq, True).poses)
        for name in ("icp-p2p", "doppler-icp"):  # Table V: ICP Div., Doppler 4D-ICP best
            est = make_method(name, {}, seq.sensor).run(seq, seed).poses
            drift[name] += along_track_drift_m(gt, est) if np.all(np.isfinite(est)) else np.inf
    assert drift["icp-p2p"] >= 5 * drift["doppler"], drift
    # the fixed Doppler pairs hold Doppler 4D-ICP along the axis where closest points slide
    assert drift["icp-p2p"] >= 5 * drift["doppler-icp"], drift
    travel = sum(abs((inv_T(s.ground_truth.poses[0]) @ s.ground_truth.poses[-1])[0, 3])
                 for s in tunnels)
    assert drift["doppler"] < 0.2 * travel  # doppler keeps tracking along the axis


def _doppler_rotation_error_8m(uturn: bool) -> tuple[float, float]:
    seq = SyntheticSequence("loop", "radar-semidense", frames=150, seed=5, uturn=uturn)
    result = make_method("doppler").run(seq, seed=True)
    rel = relative_errors(seq.ground_truth.poses, result.poses, (8,))
    max_rate = max(np.linalg.norm(seq.sensor_twist(i)[1]) for i in range(len(seq)))
    return rel[8].rot_deg_mean, max_rate


def test_uturn_doubles_the_rotation_error_of_doppler():
    gentle, gentle_rate = _doppler_rotation_error_8m(uturn=False)
    uturn, uturn_rate = _doppler_rotation_error_8m(uturn=True)
    assert gentle_rate < 0.15 and 0.45 < uturn_rate < 0.65  # the paper's two regimes
    assert uturn >= 2 * gentle, (uturn, gentle)


def test_doppler_icp_beats_doppler_and_icp_through_a_uturn():
    # Paper Table IV, Loop1_4 (U-turn): Doppler 4D-ICP 2.80 m APE, point-to-point ICP 3.15,
    # doppler 7.49. Physically: in the turn (|w| ~ 0.55 rad/s) Doppler Correspondence's
    # dT * |w| << 1 assumption fails (rotation error), closest points alone are ambiguous; the
    # fixed Doppler pairs plus closest points constrain both. On the gentle loops the paper's
    # own Table IV does not show it (Loop1_0: 63.25 vs doppler 54.87; Loop1_3: 114.76 vs
    # 101.74), and on the synthetic gentle loop with the 200 m semi-dense radar doppler's far,
    # noisy pairs pull the combination (alpha 0.7) off ICP, so that is not a test. Six scenes
    # (seeds 1-6), 40 frames each, the U-turn's first two seconds; the APE summed over them.
    from metrics import ape

    errors = {"doppler": 0.0, "icp-p2p": 0.0, "doppler-icp": 0.0}
    for s in range(1, 7):
        synth = SyntheticSequence("loop", "radar-semidense", frames=40, seed=s, uturn=True)
        rates = [np.linalg.norm(synth.sensor_twist(i)[1]) for i in range(len(synth))]
        assert max(rates) > 0.5, max(rates)  # the sequence reaches the U-turn's rate
        seq = _in_memory(synth)
        gt = seq.ground_truth.poses
        for name in errors:
            est = make_method(name, {}, seq.sensor).run(seq, seed=True).poses
            errors[name] += (ape(gt, est, alignment="se3").trans_rmse_m
                             if np.all(np.isfinite(est)) else np.inf)
    assert errors["doppler-icp"] <= min(errors["doppler"], errors["icp-p2p"]), errors
