"""bench.runs.external.conventions on synthetic trajectories and hand-made errors (no store):
which misreadings are checked per format, the re-reading of a pose under the other convention,
the per-pair error (a rotation angle plus a translation direction angle) on motions whose
answer is known, the bootstrap interval's percentiles and the decisive rule at its bounds (with
the pair errors and the bootstrap's weights replaced by hand-made ones), and the refusal's
message on a turning drive written with w x y z quaternions or as Boreas' inverse poses."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.runs.external import conventions as conv
from loaders.errors import DataError
from loaders.se3 import inv_T, make_T


def drive(n=300, period=0.1):
    """A drive of ``n`` poses ``period`` s apart that turns about every axis: 5 m/s along the
    body's x, yaw rate, pitch and roll varying smoothly (rich enough that a misread rotation
    shows in the relative motions)."""
    t = np.arange(n) * period
    euler = np.column_stack([0.4 * np.sin(0.3 * t) + 0.05 * t,  # yaw
                             0.15 * np.sin(0.5 * t + 1.0),  # pitch
                             0.1 * np.sin(0.7 * t)])  # roll
    R = Rotation.from_euler("zyx", euler)
    p = np.cumsum(R.apply([5.0 * period, 0.0, 0.0]), axis=0)
    return make_T(R.as_matrix(), p)


def misread_wxyz(poses):
    """What TUM's reader makes of rows whose quaternion columns were written w x y z: it takes
    the columns as x y z w."""
    q = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x y z w
    out = poses.copy()
    out[:, :3, :3] = Rotation.from_quat(q[:, [3, 0, 1, 2]]).as_matrix()  # w x y z read as xyzw
    return out


# --- which misreadings, and re-reading ---------------------------------------------------------

def test_each_format_checks_its_own_misreading():
    for fmt in ("tum", "bag"):
        assert list(conv.alternatives(fmt)) == ["wxyz"]
        assert conv.alternatives(fmt)["wxyz"].startswith("quaternions in w x y z order")
        assert conv.alternatives(fmt)["wxyz"].endswith("(TUM reads x y z w)")
    boreas = conv.alternatives("boreas")
    assert list(boreas) == ["inverse"]
    assert boreas["inverse"].startswith("the poses T_i_k") and boreas["inverse"].endswith(
        "(their inverses)")
    kitti = conv.alternatives("kitti")
    assert list(kitti) == ["inverse"]
    assert kitti["inverse"].startswith("the inverse poses") and kitti["inverse"].endswith(
        "(T_frame_world where T_world_frame belongs)")
    assert conv.alternatives("csv") == {} and conv.alternatives("") == {}


def test_reread_undoes_a_wxyz_file_and_inverts_for_inverse():
    truth = drive(20)
    read = misread_wxyz(truth)
    assert not np.allclose(read[:, :3, :3], truth[:, :3, :3], atol=1e-3)  # a real misreading
    back = conv.reread(read, "wxyz")
    np.testing.assert_allclose(back, truth, atol=1e-12)  # rotations back, translations kept
    np.testing.assert_allclose(read[:, :3, :3], misread_wxyz(truth)[:, :3, :3])  # input kept
    inv = conv.reread(truth, "inverse")
    np.testing.assert_allclose(inv @ truth, np.broadcast_to(np.eye(4), truth.shape), atol=1e-12)


# --- the per-pair error ------------------------------------------------------------------------

def _yaw(deg):
    return Rotation.from_euler("z", deg, degrees=True).as_matrix()


def _poses(rot_deg_per_step, translations):
    """Poses turning ``rot_deg_per_step`` about z each step, at the given positions."""
    translations = np.asarray(translations, float)
    n = len(translations)
    return make_T(np.stack([_yaw(k * rot_deg_per_step) for k in range(n)]), translations)


def test_pair_error_is_the_rotation_difference_plus_the_translation_angle():
    n = 30
    still = np.zeros((n, 3))
    # rotation only (no translation long enough to give a direction): gt turns 2 deg a step,
    # the estimate 5 deg: over pairs 3 steps apart the relative rotations differ by 9 deg
    err = conv.pair_errors(_poses(5.0, still), _poses(2.0, still), 3)
    assert len(err) == n - 3
    np.testing.assert_allclose(err, 9.0, atol=1e-9)
    # translation direction only: both straight, the estimate 30 deg off the gt's heading
    # (steps of 2 m and 3 m: the angle is the directions', whatever the lengths)
    gt = _poses(0.0, np.outer(np.arange(n), [2.0, 0.0, 0.0]))
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    est = _poses(0.0, np.outer(np.arange(n), [3 * c, 3 * s, 0.0]))
    np.testing.assert_allclose(conv.pair_errors(est, gt, 1), 30.0, atol=1e-9)
    # both: the two angles add up (a turning estimate; its translation in its own frame is
    # rotated by its heading, so the pairs' direction errors are the heading plus 30 deg)
    est = _poses(1.0, np.outer(np.arange(n), [3 * c, 3 * s, 0.0]))
    err = conv.pair_errors(est, gt, 1)
    heading = np.arange(n - 1) * 1.0  # the estimate's heading at the pair's first scan
    np.testing.assert_allclose(err, 1.0 + np.abs(30.0 - heading), atol=1e-9)
    assert conv.pair_errors(gt, gt, 5) == pytest.approx(np.zeros(n - 5), abs=1e-9)


def test_pairs_without_both_poses_are_left_out():
    gt = drive(12)
    est = gt.copy()
    est[4] = np.nan  # pairs (3, 4) and (4, 5) go
    gt_hole = gt.copy()
    gt_hole[9] = np.nan  # pairs (8, 9), (9, 10)
    assert len(conv.pair_errors(est, gt, 1)) == 11 - 2
    assert len(conv.pair_errors(gt, gt_hole, 1)) == 11 - 2
    assert len(conv.pair_errors(est, gt_hole, 1)) == 11 - 4
    assert len(conv.pair_errors(est, gt_hole, 2)) == 10 - 4  # (2,4) (4,6) (7,9) (9,11)
    assert len(conv.pair_errors(gt[:3], gt[:3], 3)) == 0  # no pair that far apart
    assert len(conv.pair_errors(gt[:3], gt[:3], 5)) == 0
    none = np.full_like(gt, np.nan)
    assert len(conv.pair_errors(none, gt, 1)) == 0


def _two(translation_a, translation_b):
    """One pair: identity, then a pure translation (exact in floating point)."""
    a, b = np.tile(np.eye(4), (2, 1, 1)), np.tile(np.eye(4), (2, 1, 1))
    a[1, :3, 3], b[1, :3, 3] = translation_a, translation_b
    return a, b


def test_a_translation_gives_a_direction_only_beyond_min_step():
    x, y = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    m = conv.MIN_STEP_M
    assert m == 0.05  # the documented threshold the cases below are built around
    for scale_a, scale_b, expected in ((0.06, 0.06, 90.0), (0.06, 1.0, 90.0),
                                       (0.05, 1.0, 0.0), (1.0, 0.05, 0.0),  # at it: too short
                                       (0.01, 1.0, 0.0), (1.0, 0.01, 0.0)):
        est, gt = _two(scale_a * x, scale_b * y)
        assert conv.pair_errors(est, gt, 1) == pytest.approx([expected], abs=1e-9), \
            (scale_a, scale_b)


def _cos(a, b):
    """The cosine as pair_errors computes it (rows)."""
    a, b = np.atleast_2d(a), np.atleast_2d(b)
    return ((a * b).sum(axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)))[0]


def test_parallel_and_opposite_translations_are_0_and_180_deg_despite_rounding():
    v = np.array([2.041, -2.556, 0.418])
    assert _cos(v, v) > 1.0 and _cos(v, -v) < -1.0  # the cosine rounds beyond +-1
    est, gt = _two(v, v)
    assert conv.pair_errors(est, gt, 1) == pytest.approx([0.0], abs=1e-6)
    est, gt = _two(v, -v)
    assert conv.pair_errors(est, gt, 1) == pytest.approx([180.0], abs=1e-6)


# --- the interval and the decisive rule (hand-made errors and bootstrap weights) --------------

@pytest.fixture
def scripted(monkeypatch):
    """``pair_errors`` returns the "poses" passed (1-D arrays of errors), and each bootstrap
    replicate r puts all its weight on pair r mod n: the 400 replicate means are the errors'
    differences, each n-th one in turn. Records the steps and the blocks asked for."""
    seen = {"steps": [], "blocks": [], "n": []}

    def pair_errors(errors, gt, step):
        seen["steps"].append(step)
        return np.asarray(errors, float)

    def block_weights(n, block, rng):
        seen["blocks"].append(block)
        seen["n"].append(n)
        w = np.zeros(n)
        w[(len(seen["blocks"]) - 1) % n] = 1.0
        return w

    monkeypatch.setattr(conv, "pair_errors", pair_errors)
    monkeypatch.setattr(conv, "block_weights", block_weights)
    return seen


def test_the_interval_is_the_2_5_and_97_5_percentiles_of_the_replicates(scripted):
    # differences 0, 1, ..., 39 (n = 40), each the mean of 10 of the 400 replicates: sorted,
    # replicate k is floor(k / 10); numpy's linear percentile at 2.5 % sits at 0.025 * 399 =
    # 9.975 (between 0 and 1: 0.975), at 97.5 % at 389.025 (between 38 and 39: 38.025)
    d = np.arange(40.0)
    check = conv.compare_at(d + 100.0, np.full(40, 100.0), None, 0.1, "wxyz", 1.0)
    assert check.diff_interval_deg == pytest.approx((0.975, 38.025), abs=1e-12)
    assert len(scripted["blocks"]) == conv.REPLICATES == 400
    assert set(scripted["n"]) == {40}
    assert set(scripted["blocks"]) == {40}  # 4 s blocks of a 0.1 s period
    assert scripted["steps"] == [10, 10]  # 1 s pairs, the reading's and the other's
    assert check.other == "wxyz" and check.pairs == 40
    assert check.mean_read_deg == pytest.approx(119.5) and check.mean_other_deg == 100.0
    assert not check.decisive  # 100 is not below half of 119.5


def test_steps_and_blocks_follow_the_period(scripted):
    e = np.full(30, 2.0)
    conv.compare_at(e, e, None, 0.25, "x", 4.0)  # 16 scans, blocks of 16
    conv.compare_at(e, e, None, 10.0, "x", 1.0)  # a period longer than the pair and block:
    assert scripted["steps"] == [16, 16, 1, 1]  # one scan apart, blocks of one
    assert set(scripted["blocks"][:400]) == {16} and set(scripted["blocks"][400:]) == {1}
    conv.compare_at(e, e, None, 1.0, "x", 1.0)
    assert scripted["steps"][-1] == 1 and scripted["blocks"][-1] == 4


def test_twenty_pairs_are_enough_and_nineteen_or_unequal_counts_are_not(scripted):
    assert conv.compare_at(np.full(20, 4.0), np.full(20, 1.0), None, 0.1, "x", 1.0).pairs == 20
    assert conv.compare_at(np.full(19, 4.0), np.full(19, 1.0), None, 0.1, "x", 1.0) is None
    assert conv.compare_at(np.full(30, 4.0), np.full(29, 1.0), None, 0.1, "x", 1.0) is None


def test_decisive_needs_the_interval_above_0_and_half_the_mean_error(scripted):
    def decisive(read, other):
        return conv.compare_at(np.asarray(read, float), np.asarray(other, float), None, 0.1,
                               "x", 1.0).decisive

    n = 40
    assert decisive(np.full(n, 2.0), np.full(n, 0.9))  # interval [1.1, 1.1], 0.9 < 1
    assert not decisive(np.full(n, 2.0), np.full(n, 1.0))  # exactly half: not below it
    assert not decisive(np.full(n, 2.0), np.full(n, 1.5))
    # the other reading's errors 0, the reading's two of them 0: the interval's low end is
    # exactly 0 (replicates 0-19 sorted are 0), which is not above 0
    read = np.r_[0.0, 0.0, np.arange(1.0, n - 1)]
    check = conv.compare_at(read, np.zeros(n), None, 0.1, "x", 1.0)
    assert check.diff_interval_deg[0] == 0.0 and not check.decisive
    read[1] = 0.5  # one zero: low end 0.975 * 0.5 > 0
    assert decisive(read, np.zeros(n))
    assert not decisive(np.zeros(n), np.full(n, 1.0))  # the other reading worse: never


def test_a_replicate_without_weight_takes_the_plain_mean(monkeypatch, scripted):
    monkeypatch.setattr(conv, "block_weights", lambda n, block, rng: np.zeros(n))
    check = conv.compare_at(np.arange(30.0) + 3.0, np.ones(30), None, 0.1, "x", 1.0)
    assert check.diff_interval_deg == pytest.approx((16.5, 16.5))  # mean of 2 .. 31


# --- the first decisive pair length, else the last with pairs ----------------------------------

def _scripted_compare(monkeypatch, results):
    asked = []

    def compare_at(read, other, gt, period_s, name, pair_s, seed=0):
        assert name == "x"  # the reading's name goes with its check
        asked.append((pair_s, seed))
        return results[pair_s]

    monkeypatch.setattr(conv, "compare_at", compare_at)
    return asked


def _check(decisive, pairs=30):
    return conv.ConventionCheck("x", 1.0, 0.1, (0.5, 1.0), decisive, pairs)


def test_compare_takes_the_first_decisive_pair_length_else_the_last_with_pairs(monkeypatch):
    one, four = _check(True, 31), _check(True, 34)
    asked = _scripted_compare(monkeypatch, {1.0: one, 4.0: four})
    assert conv.compare(None, None, None, 0.1, "x", seed=7) is one
    assert asked == [(1.0, 7)]  # 1 s pairs first; decided there, 4 s not looked at
    quiet_one, quiet_four = _check(False, 31), _check(False, 34)
    asked = _scripted_compare(monkeypatch, {1.0: quiet_one, 4.0: four})
    assert conv.compare(None, None, None, 0.1, "x") is four and asked == [(1.0, 0), (4.0, 0)]
    _scripted_compare(monkeypatch, {1.0: quiet_one, 4.0: quiet_four})
    assert conv.compare(None, None, None, 0.1, "x") is quiet_four
    _scripted_compare(monkeypatch, {1.0: quiet_one, 4.0: None})  # 4 s: too few pairs
    assert conv.compare(None, None, None, 0.1, "x") is quiet_one
    _scripted_compare(monkeypatch, {1.0: None, 4.0: None})
    assert conv.compare(None, None, None, 0.1, "x") is None


# --- what is said ------------------------------------------------------------------------------

def test_describe_says_which_reading_fits_or_that_it_could_not_be_told():
    assert conv.describe(None, "w").startswith("convention not checked: too few pairs")

    def said(lo, hi, decisive=False):
        return conv.describe(conv.ConventionCheck("wxyz", 1.234, 5.678, (lo, hi), decisive, 37),
                             "quaternions in w x y z order")

    line = said(0.5, 2.0, decisive=True)
    assert line.startswith("relative motion error 1.23 deg as read, 5.68 deg read as "
                           "quaternions in w x y z order (difference interval [0.50, 2.00] deg "
                           "over 37 pairs")
    assert said(-2.0, -0.5).startswith("as read (relative motion error 1.23 deg as read")
    assert said(0.5, 2.0).startswith("as read (")  # above 0 but not decisive: as read
    for lo, hi in ((-0.5, 2.0), (0.0, 2.0), (-2.0, 0.0)):  # 0 inside or on the interval's end
        line = said(lo, hi)
        assert line.startswith("the convention could not be told (relative motion error")
        assert line.endswith("): scored as read"), (lo, hi)


def _awk_print(fields: str, row: list[str]) -> list[str]:
    """What ``awk '{print $a, $b, ...}'`` prints for a row."""
    return [row[int(k) - 1] for k in re.findall(r"\$(\d+)", fields)]


def test_a_tum_file_with_wxyz_quaternions_is_refused_with_the_fix_and_a_right_one_passes():
    truth = drive()
    read = misread_wxyz(truth)

    def match_other(name):
        assert name == "wxyz"
        return conv.reread(read, name)

    with pytest.raises(DataError) as err:
        conv.check_conventions("tum", read, match_other, truth, 0.1, "est.tum")
    msg = str(err.value)
    assert msg.startswith("est.tum: read as tum, its relative motions disagree with the ground "
                          "truth's; read as quaternions in w x y z order")
    assert "the file holds quaternions in w x y z order (TUM reads x y z w)? reorder its " \
           "quaternion columns to qx qy qz qw" in msg
    # the awk line given does the reordering: a row "t x y z qw qx qy qz" becomes TUM's
    awk = re.search(r"awk '(\{print [^}]*\})'", msg).group(1)
    assert _awk_print(awk, ["t", "x", "y", "z", "qw", "qx", "qy", "qz"]) == \
        ["t", "x", "y", "z", "qx", "qy", "qz", "qw"]
    # the numbers said are the two readings' mean errors: the other (right) one near 0
    m = re.search(r"relative motion error ([\d.]+) deg as read, ([\d.]+) deg read as wxyz "
                  r"\(difference interval", msg)
    assert float(m.group(1)) > 1.0 and float(m.group(2)) < 0.01
    # the same drive written right: as read, no refusal
    line = conv.check_conventions("tum", truth, lambda name: conv.reread(truth, name), truth,
                                  0.1, "est.tum")
    assert line.startswith("wxyz: as read (relative motion error 0.00 deg as read")
    assert " deg read as wxyz (difference interval [" in line


def test_a_boreas_file_of_the_inverse_poses_is_refused_and_other_formats_are_not_checked():
    truth = drive()
    read = inv_T(truth)  # the file held T_i_k, read as T_k_i and inverted: the inverse poses
    with pytest.raises(DataError) as err:
        conv.check_conventions("boreas", read, lambda name: conv.reread(read, name), truth,
                               0.1, "poses.txt")
    msg = str(err.value)
    assert msg.startswith("poses.txt: read as boreas, its relative motions disagree")
    assert " deg read as inverse (difference interval [" in msg
    assert "the file holds the poses T_i_k where the format holds T_k_i (their inverses)? " \
           "invert its poses (each row the inverse transform) before scoring" in msg
    line = conv.check_conventions("kitti", truth, lambda name: conv.reread(truth, name), truth,
                                  0.1, "poses.txt")
    assert line.startswith("inverse: as read (") and " deg read as inverse (" in line
    assert conv.check_conventions("csv", truth, None, truth, 0.1, "x") == \
        "no other reading of csv to check"
    short = conv.check_conventions("tum", truth[:15], lambda name: conv.reread(truth[:15], name),
                                   truth[:15], 0.1, "x")
    assert short == "wxyz: convention not checked: too few pairs of scans with both poses"


def test_the_bootstrap_is_seeded_so_a_check_repeats():
    truth = drive()
    read = misread_wxyz(truth)
    first = conv.compare_at(read, conv.reread(read, "wxyz"), truth, 0.1, "wxyz", 1.0)
    again = conv.compare_at(read, conv.reread(read, "wxyz"), truth, 0.1, "wxyz", 1.0)
    assert first == again
    other = conv.compare_at(read, conv.reread(read, "wxyz"), truth, 0.1, "wxyz", 1.0, seed=1)
    assert other.diff_interval_deg != first.diff_interval_deg  # the seed is the only chance
    assert other.mean_read_deg == first.mean_read_deg
