"""metrics/ape.py, what tests/test_metrics_ape.py leaves open (make mutate's survivors): the
per-pose NaN errors of a diverged estimate, the scale reported by the alignments that fit none,
Umeyama on three points and on an exactly planar path, Umeyama's default (no scale), the batched
Umeyama row by row against evo's ``umeyama_alignment``, when positions are degenerate (one side
on a line away from the origin, a kilometre line with sub-micrometre wiggles, a nanometre
jitter, an exact plane), the public functions' default alignment, "first-1", and the messages
a user reads.

Known answers: trajectories built by hand (lines, planes, rigid transforms), whose
cross-covariance rank is known from their construction; evo as the independent Umeyama."""

import re

import numpy as np
import pytest
from evo.core.geometry import umeyama_alignment
from scipy.spatial.transform import Rotation

from metrics.ape import (
    Alignment,
    ape,
    ape_errors,
    ape_with_errors,
    positions_degenerate,
    umeyama,
    umeyama_batch,
)
from metrics.relative import MetricError


def rigid(rotvec, trans):
    t = np.eye(4)
    t[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    t[:3, 3] = trans
    return t


def poses_at(positions, rotvecs=None):
    positions = np.asarray(positions, float)
    out = np.tile(np.eye(4), (len(positions), 1, 1))
    out[:, :3, 3] = positions
    if rotvecs is not None:
        out[:, :3, :3] = Rotation.from_rotvec(rotvecs).as_matrix()
    return out


def curve(n=50):
    """A 3-D curve (rank 3 about its mean) with turning orientations."""
    t = np.linspace(0.0, 4.0, n)
    return poses_at(np.column_stack([10 * np.sin(t), 6 * np.cos(0.7 * t), 2 * t]),
                    np.column_stack([0.1 * t, -0.05 * t, 0.4 * t]))


def line(n=50, offset=(100.0, 50.0, -20.0)):
    """A straight path away from the origin."""
    return poses_at(np.asarray(offset) + np.outer(np.linspace(0, 30, n), [1.0, 2.0, 0.5]),
                    np.outer(np.linspace(0, 1, n), [0.0, 0.0, 0.3]))


def test_a_diverged_estimate_gives_one_nan_per_pose():
    gt = curve(7)
    est = gt.copy()
    est[3, 0, 3] = np.inf
    trans, rot = ape_errors(gt, est)
    assert trans.shape == (7,) and rot.shape == (7,)
    assert np.isnan(trans).all() and np.isnan(rot).all()
    stats, t2, r2 = ape_with_errors(gt, est, "sim3")
    assert stats.n == 7 and t2.shape == (7,) and np.isnan(stats.scale)


@pytest.mark.parametrize("alignment, used", [("none", "none"), ("origin", "origin"),
                                             ("se3", "se3"), ("first-10", "se3-first-10")])
def test_alignments_without_a_fitted_scale_report_scale_one(alignment, used):
    gt = curve()
    est = rigid([0.1, 0.2, 0.3], [1.0, 2.0, 3.0]) @ gt
    est[:, :3, 3] *= 1.5
    stats = ape(gt, est, alignment)
    assert stats.alignment == used and stats.scale == 1.0


def test_the_orientation_fallback_reports_scale_one_even_for_sim3():
    gt = line()
    est = line(offset=(0.0, 0.0, 0.0))
    est[:, :3, 3] *= 2.0  # a scale error that sim3 could fit, were the positions not a line
    stats = ape(gt, est, "sim3")
    assert stats.alignment == "sim3-orientation" and stats.scale == 1.0


def test_three_non_collinear_poses_are_aligned_by_umeyama():
    gt = poses_at([[0.0, 0, 0], [4.0, 0, 0], [0.0, 3.0, 1.0]],
                  [[0, 0, 0], [0, 0, 0.5], [0.2, 0, 0]])
    truth = rigid([0.3, -0.2, 1.0], [5.0, 1.0, -2.0])
    est = np.linalg.inv(truth) @ gt
    est[:, :3, :3] = np.eye(3)  # orientations that disagree: the fallback would use them
    for alignment, used in (("se3", "se3"), ("first-3", "se3-first-3")):
        stats, trans, _ = ape_with_errors(gt, est, alignment)
        assert stats.alignment == used
        np.testing.assert_allclose(trans, 0.0, atol=1e-12)
    # on two poses the positions cannot fix a rotation: the orientations do
    assert ape(gt[:2], est[:2]).alignment == "se3-orientation"


def test_umeyama_on_three_points_and_on_an_exact_plane():
    truth = rigid([0.4, -0.1, 2.5], [1.0, 2.0, 3.0])
    for src in (np.array([[0.0, 0, 0], [4.0, 0, 0], [0.0, 3.0, 1.0]]),
                np.column_stack([np.cos(np.arange(20.0)) * 5, np.arange(20.0), np.zeros(20)])):
        dst = src @ truth[:3, :3].T + truth[:3, 3]
        transform, scale = umeyama(src, dst)
        np.testing.assert_allclose(transform, truth, atol=1e-12)
        assert scale == 1.0


def test_umeyama_fits_no_scale_unless_asked():
    rng = np.random.default_rng(3)
    src = rng.normal(size=(30, 3)) * [5, 3, 1]
    truth = rigid([0.2, 0.1, -0.7], [4.0, -1.0, 0.5])
    dst = 2.0 * src @ truth[:3, :3].T + truth[:3, 3]
    transform, scale = umeyama(src, dst)
    assert scale == 1.0
    np.testing.assert_allclose(transform[:3, :3], truth[:3, :3], atol=1e-12)
    transform, scale = umeyama(src, dst, with_scale=True)
    assert scale == pytest.approx(2.0, rel=1e-12)
    np.testing.assert_allclose(transform, truth, atol=1e-12)


def test_a_degenerate_umeyama_says_what_to_do():
    points = line()[:, :3, 3]
    with pytest.raises(MetricError, match="^" + re.escape(
            "se3 alignment is degenerate: estimated/GT positions are (nearly) collinear or "
            "identical; use alignment='origin'") + "$"):
        umeyama(points, points)


def test_batched_umeyama_matches_evo_row_by_row():
    rng = np.random.default_rng(7)
    batch, n = 3, 40
    src = rng.normal(size=(batch, n, 3)) * [[[8.0, 3.0, 1.0]], [[1.0, 1.0, 1.0]],
                                            [[20.0, 5.0, 0.5]]]
    scales = np.array([0.5, 1.0, 3.0])
    dst = np.empty_like(src)
    for c in range(batch):
        T = rigid(rng.normal(size=3), rng.normal(size=3) * 10)
        dst[c] = scales[c] * src[c] @ T[:3, :3].T + T[:3, 3] + rng.normal(0, 0.05, (n, 3))
    for with_scale in (False, True):
        rot, trans, scale, degenerate = umeyama_batch(src, dst, with_scale)
        assert not degenerate.any()
        for c in range(batch):
            r_evo, t_evo, s_evo = umeyama_alignment(src[c].T, dst[c].T, with_scale)
            np.testing.assert_allclose(rot[c], r_evo, atol=1e-10)
            np.testing.assert_allclose(trans[c], t_evo, atol=1e-9)
            assert scale[c] == pytest.approx(s_evo, rel=1e-10)


def test_one_side_on_a_line_away_from_the_origin_is_degenerate():
    # the cross-covariance of a line and anything has rank 1, wherever the line lies
    gt, est = curve(), line()
    assert positions_degenerate(est, gt) and positions_degenerate(gt, est)
    assert ape(gt, est).alignment == "se3-orientation"
    assert ape(est, gt).alignment == "se3-orientation"
    assert not positions_degenerate(gt, rigid([0.1, 0.2, 0.3], [100.0, 0, 0]) @ gt)


def test_an_exactly_planar_path_is_not_degenerate():
    t = np.linspace(0, 6, 60)
    flat = poses_at(np.column_stack([20 * np.cos(t), 10 * np.sin(t), np.zeros(60)]),
                    np.column_stack([np.zeros(60), np.zeros(60), t]))
    est = rigid([0.0, 0.0, 0.9], [3.0, -4.0, 0.0]) @ flat
    est[:, :3, :3] = np.eye(3)  # orientations that would mislead the fallback
    assert not positions_degenerate(est, flat)
    stats = ape(flat, est, "se3")
    assert stats.alignment == "se3" and stats.trans_max_m < 1e-9
    # its rank-2 cross-covariance also fixes the batched fit
    assert not umeyama_batch(est[None, :, :3, 3], flat[None, :, :3, 3], False)[3][0]


def test_a_kilometre_line_with_sub_micrometre_wiggles_is_degenerate():
    """The test is relative to the largest singular value: a 1 km line (variance about 8e4 m^2)
    whose sideways wiggles have a variance of about 1e-14 m^2 (1e-7 m) is a line to working
    precision (ratio 1e-19, far below machine epsilon)."""
    n = 200
    s = np.linspace(0.0, 1000.0, n)
    wiggle = 1e-7 * np.sin(np.arange(n) * 1.3)
    points = poses_at(np.column_stack([s, wiggle, np.zeros(n)]))
    assert positions_degenerate(points, points)
    assert ape(points, points).alignment == "se3-orientation"
    with pytest.raises(MetricError, match="degenerate"):
        umeyama(points[:, :3, 3], points[:, :3, 3])


def test_a_nanometre_jitter_is_degenerate():
    """Two estimates of a standing vehicle, each jittering by 1e-10 m: the cross-covariance is
    about 1e-20 m^2, below machine epsilon (the absolute floor for paths under 1 m)."""
    rng = np.random.default_rng(5)
    n = 1000
    gt = poses_at(rng.normal(0, 1e-10, (n, 3)) + [10.0, 20.0, 1.0])
    est = poses_at(rng.normal(0, 1e-10, (n, 3)))
    assert positions_degenerate(est, gt)
    assert ape(gt, est).alignment == "se3-orientation"


def test_the_default_alignment_is_se3_everywhere():
    gt = curve()
    est = rigid([0.05, -0.1, 0.2], [1.0, 2.0, 3.0]) @ gt
    est[:, :3, 3] *= 1.2
    est[:, 0, 3] += np.linspace(0, 1, len(gt))
    explicit = ape_errors(gt, est, "se3")
    for got in (ape_errors(gt, est), ape_with_errors(gt, est)[1:]):
        np.testing.assert_array_equal(got[0], explicit[0])
        np.testing.assert_array_equal(got[1], explicit[1])
    assert ape(gt, est).alignment == ape_with_errors(gt, est)[0].alignment == "se3"
    assert ape(gt, est).trans_rmse_m == ape(gt, est, "se3").trans_rmse_m > 0.01


def test_the_first_pose_alone_is_a_valid_fit_window():
    assert Alignment.parse("first-1") == Alignment("se3", 1)
    assert Alignment.parse("sim3-first-1") == Alignment("sim3", 1)
    gt = curve()
    est = rigid([0.0, 0.0, 0.4], [2.0, 0.0, 0.0]) @ gt
    # one pose cannot fix positions: its orientation aligns the estimate
    assert ape(gt, est, "first-1").alignment == "se3-orientation"


@pytest.mark.parametrize("text", ["sim4", "first-0", "sim3-first-0", "se3-first-x"])
def test_an_unknown_alignment_names_the_choices(text):
    expected = (f"unknown alignment {text!r}: expected one of se3, sim3, origin, none, first-N "
                "or sim3-first-N (N >= 1 poses)")
    with pytest.raises(MetricError, match="^" + re.escape(expected) + "$"):
        Alignment.parse(text)
