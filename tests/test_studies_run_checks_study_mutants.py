"""bench.studies.run_checks_study, piece by piece (mutation testing): each perturbation and
fault against its definition on a straight 1 m/s ground truth whose poses are known in closed
form, what ``run_checks`` reports of each kind of GT, the study's rows on one small input, its
table and its command line."""

from __future__ import annotations

import numpy as np
import pytest

from bench.studies import run_checks_study as rcs
from loaders.trajectory import Trajectory


def line(n: int = 100, rate_hz: float = 10.0, speed: float = 1.0, t0: float = 3.0) -> Trajectory:
    """A straight drive along x at ``speed`` from x = 0, ``n`` poses at ``rate_hz`` from
    ``t0``."""
    stamps = t0 + np.arange(n) / rate_hz
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = speed * (stamps - t0)
    return Trajectory(stamps, poses)


# ---- the perturbations that must pass -----------------------------------------------------

def test_jitter_moves_positions_by_the_seeds_draws_only():
    gt = line()
    got = rcs.jittered(gt)
    draws = np.random.default_rng(0).normal(0.0, 0.005, (100, 3))
    np.testing.assert_array_equal(got.stamps, gt.stamps)
    np.testing.assert_allclose(got.poses[:, :3, 3], gt.poses[:, :3, 3] + draws, atol=1e-15)
    np.testing.assert_array_equal(got.poses[:, :3, :3], gt.poses[:, :3, :3])
    other = rcs.jittered(gt, sigma_m=0.1, seed=4)
    np.testing.assert_allclose(other.poses[:, :3, 3] - gt.poses[:, :3, 3],
                               np.random.default_rng(4).normal(0.0, 0.1, (100, 3)), atol=1e-15)
    assert got.poses is not gt.poses and not np.shares_memory(got.stamps, gt.stamps)
    np.testing.assert_array_equal(gt.poses[:, 1, 3], 0.0)  # the input is left alone


def test_resampling_keeps_the_span_at_the_new_rate():
    gt = line(101)  # 10 s at 10 Hz
    got = rcs.resampled(gt)
    np.testing.assert_allclose(got.stamps, 3.0 + np.arange(51) * 0.2, atol=1e-9)
    np.testing.assert_allclose(got.poses[:, 0, 3], got.stamps - 3.0, atol=1e-9)
    assert len(rcs.resampled(gt, rate_hz=2.0)) == 21


def test_lag_shifts_the_stamps_only():
    gt = line()
    got = rcs.lagged(gt)
    np.testing.assert_allclose(got.stamps, gt.stamps + 0.02, atol=1e-12)
    np.testing.assert_array_equal(got.poses, gt.poses)
    np.testing.assert_allclose(rcs.lagged(gt, 0.5).stamps, gt.stamps + 0.5, atol=1e-12)


def test_the_passing_cases():
    gt = line()
    assert list(rcs.PASS) == ["as is", "jittered 5 mm", "resampled to 5 Hz", "lagged 20 ms"]
    assert rcs.PASS["as is"](gt) is gt
    assert rcs.PASS["jittered 5 mm"] is rcs.jittered
    assert rcs.PASS["resampled to 5 Hz"] is rcs.resampled
    assert rcs.PASS["lagged 20 ms"] is rcs.lagged


# ---- the faults ---------------------------------------------------------------------------

def test_a_dropped_window_leaves_out_the_middle_seconds():
    gt = line(101)  # stamps 3.0 ... 13.0, middle 8.0
    got = rcs._drop_window(gt, 2.05)  # 7.0 ... 9.0 dropped: 21 rows
    np.testing.assert_allclose(got.stamps, np.r_[gt.stamps[:40], gt.stamps[61:]], atol=0)
    np.testing.assert_allclose(got.poses[:, 0, 3], got.stamps - 3.0, atol=1e-9)


def test_a_jump_moves_the_second_half_along_x():
    gt = line(10)
    got = rcs._jump(gt, 2.5)
    np.testing.assert_allclose(got.poses[:, 0, 3], gt.poses[:, 0, 3] + np.r_[[0] * 5, [2.5] * 5])
    np.testing.assert_array_equal(got.poses[:, 1:3], gt.poses[:, 1:3])
    np.testing.assert_array_equal(got.stamps, gt.stamps)
    np.testing.assert_allclose(gt.poses[:, 0, 3], np.arange(10) / 10.0, atol=1e-12)


def test_a_stall_repeats_the_pose_before_the_middle():
    gt = line(10)
    got = rcs._stall(gt, 3)
    x = np.arange(10) / 10.0
    np.testing.assert_allclose(got.poses[:, 0, 3], np.r_[x[:5], [x[4]] * 3, x[8:]], atol=1e-12)
    np.testing.assert_array_equal(got.stamps, gt.stamps)
    np.testing.assert_allclose(gt.poses[:, 0, 3], x, atol=1e-12)


def test_duplicate_rows_repeat_rows_spread_along_the_gt():
    gt = line(11)
    got = rcs._duplicates(gt, 3)  # rows 1, 5, 9 logged twice
    idx = [0, 1, 1, 2, 3, 4, 5, 5, 6, 7, 8, 9, 9, 10]
    np.testing.assert_array_equal(got.stamps, gt.stamps[idx])
    np.testing.assert_array_equal(got.poses, gt.poses[idx])
    assert len(rcs._duplicates(gt, 1)) == 12  # the one repeat: row 1


def test_a_repeated_stamp_gets_another_pose():
    gt = line(11)
    got = rcs._two_poses(gt, 3)
    idx = [0, 1, 1, 2, 3, 4, 5, 5, 6, 7, 8, 9, 9, 10]
    np.testing.assert_array_equal(got.stamps, gt.stamps[idx])
    moved = np.zeros(14)
    moved[[2, 7, 12]] = 0.01  # the second row of each repeated stamp: 1 cm along y
    np.testing.assert_allclose(got.poses[:, 1, 3], moved, atol=0)
    np.testing.assert_array_equal(got.poses[:, 0, 3], gt.poses[idx, 0, 3])


def test_a_stamp_going_backwards_lands_before_the_previous_one():
    gt = line(10)
    got = rcs._backwards(gt, 0.05)
    want = gt.stamps.copy()
    want[5] = gt.stamps[4] - 0.05
    np.testing.assert_allclose(got.stamps, want, atol=1e-12)
    np.testing.assert_array_equal(got.poses, gt.poses)
    np.testing.assert_allclose(gt.stamps, line(10).stamps)  # the input is left alone


def test_a_shift_moves_the_stamps_by_a_share_of_the_span():
    gt = line(11)  # span 1 s
    np.testing.assert_allclose(rcs._shifted(gt, 0.5).stamps, gt.stamps + 0.5, atol=1e-12)
    np.testing.assert_allclose(rcs._shifted(line(21), 2.0).stamps, line(21).stamps + 4.0,
                               atol=1e-12)
    np.testing.assert_array_equal(rcs._shifted(gt, 0.5).poses, gt.poses)


def test_a_truncated_gt_keeps_its_first_rows_and_at_least_two():
    gt = line(10)
    np.testing.assert_array_equal(rcs._truncated(gt, 0.4).stamps, gt.stamps[:4])
    np.testing.assert_array_equal(rcs._truncated(gt, 0.46).poses, gt.poses[:5])
    assert len(rcs._truncated(gt, 0.01)) == 2
    assert len(rcs._truncated(gt, 0.25)) == 2  # round half to even: 2.5 -> 2
    assert len(rcs._truncated(gt, 0.35)) == 4  # 3.5 -> 4


def test_the_faults_and_their_sizes():
    assert {k: (make, sizes, unit) for k, (make, sizes, unit) in rcs.FAULTS.items()} == {
        "duplicate rows (logged twice)": (rcs._duplicates, (1, 5), "rows"),
        "repeated stamp, other pose": (rcs._two_poses, (1, 5), "rows"),
        "stamp going backwards": (rcs._backwards, (0.001, 0.1), "s"),
        "GT not overlapping (shifted)": (rcs._shifted, (1.01, 2.0), "x span"),
        "GT partly overlapping (shifted)": (rcs._shifted, (0.2, 0.5), "x span"),
        "GT stops early": (rcs._truncated, (0.9, 0.4), "of rows kept"),
        "gap in the GT": (rcs._drop_window, (0.5, 2.0), "s"),
        "position jump": (rcs._jump, (0.5, 5.0), "m"),
        "stalled GT (pose repeated)": (rcs._stall, (3, 20), "rows")}


# ---- what bench run's checks say ----------------------------------------------------------

def check(gt: Trajectory, lengths=(4.0,), kitti=(8.0,), stamps=None) -> dict:
    return rcs.run_checks(line().stamps if stamps is None else stamps, gt, lengths, kitti)


def test_a_correct_gt_is_silent_and_scores_every_frame():
    got = check(line())  # a 9.9 m path: 4 m segments and 8 m KITTI segments fit
    assert got == {"warnings": [], "refusal": "", "scored": 100, "frames": 100}
    assert rcs._said(got) == "silent"


def test_duplicate_rows_are_warned_about_and_dropped():
    got = check(rcs._duplicates(line(), 2))
    assert got["refusal"] == "" and got["scored"] == 100
    assert len(got["warnings"]) == 1 and "duplicate" in got["warnings"][0]
    assert rcs._said(got) == "warned"


@pytest.mark.parametrize("fault", [lambda g: rcs._two_poses(g, 1),
                                   lambda g: rcs._backwards(g, 0.1)])
def test_a_gt_out_of_time_order_is_refused_and_scores_nothing(fault):
    got = check(fault(line()))
    assert got["refusal"] and got["scored"] == 0 and got["frames"] == 100
    assert rcs._said(got) == "refused"


def test_a_gt_not_overlapping_the_scans_is_refused():
    got = check(rcs._shifted(line(), 1.5))
    assert got["scored"] == 0 and "ground truth" in got["refusal"]
    assert got["refusal"].startswith("store") or "store" in got["refusal"]


def test_lengths_longer_than_the_path_warn_and_none_fitting_refuses():
    gt = line()  # 9.9 m
    some = check(gt, lengths=(4.0, 50.0), kitti=(8.0,))
    assert some["refusal"] == "" and some["scored"] == 100
    assert len(some["warnings"]) == 1 and "no segments of 50 m" in some["warnings"][0]
    kitti = check(gt, lengths=(4.0,), kitti=(20.0,))
    assert len(kitti["warnings"]) == 1 and "KITTI" in kitti["warnings"][0]
    none = check(gt, lengths=(50.0, 60.0), kitti=(8.0,))
    assert "too short for the shortest segment length 50 m" in none["refusal"]
    assert none["scored"] == 0 and none["warnings"] == []


def test_what_a_check_said():
    assert rcs._said({"refusal": "no", "warnings": ["w"]}) == "refused"
    assert rcs._said({"refusal": "", "warnings": ["w"]}) == "warned"
    assert rcs._said({"refusal": "", "warnings": []}) == "silent"


# ---- the study ----------------------------------------------------------------------------

def test_the_inputs_are_the_sample_its_parts_and_four_synthetic_drives():
    got = rcs.inputs(frames=30)
    assert [name for name, _, _ in got] == [
        "sample whole", "sample first half", "sample second half", "sample frames 60-189",
        *rcs.SYNTHETIC]
    lengths = [len(s) for _, s, _ in got]
    assert lengths == [250, 125, 125, 130, 30, 30, 30, 30]
    whole = got[0][1]
    np.testing.assert_array_equal(got[1][1], whole[:125])
    np.testing.assert_array_equal(got[2][1], whole[125:])
    np.testing.assert_array_equal(got[3][1], whole[60:190])
    for _, stamps, gt in got:
        assert stamps.dtype == np.float64
        # each part's GT is the rows within its scans' span
        assert stamps[0] - 1e-6 <= gt.stamps[0] and gt.stamps[-1] <= stamps[-1] + 1e-6
    # the sample's GT is kept whole within each span: a row just inside the span stays
    full = got[0][2]
    for _, stamps, gt in got[1:4]:
        inside = (full.stamps >= stamps[0] - 1e-6) & (full.stamps <= stamps[-1] + 1e-6)
        np.testing.assert_array_equal(gt.stamps, full.stamps[inside])


def test_the_study_checks_every_case_of_every_input(monkeypatch):
    gt = line(150)  # 14.9 m: lengths 7.45 and 17.88 m (within the 20 % tolerance), KITTI 13.41
    monkeypatch.setattr(rcs, "inputs", lambda frames: [("line", gt.stamps.copy(), gt)])
    rows = rcs.study(frames=7)
    cases = [(r["case"], r["kind"], r["size"]) for r in rows]
    assert cases == [(c, "pass", "") for c in rcs.PASS] + [
        (c, "fault", f"{s:g} {u}") for c, (_, sizes, u) in rcs.FAULTS.items() for s in sizes]
    assert all(r["input"] == "line" for r in rows)
    by = {(r["case"], r["size"]): r for r in rows}
    # the lengths fit the as-is GT and its perturbations
    for case in rcs.PASS:
        assert by[(case, "")]["said"] == "silent", by[(case, "")]
    assert by[("as is", "")]["unscored"] == 0 and by[("as is", "")]["text"] == ""
    assert by[("repeated stamp, other pose", "1 rows")]["said"] == "refused"
    assert by[("repeated stamp, other pose", "1 rows")]["unscored"] == 150
    assert by[("GT not overlapping (shifted)", "2 x span")]["unscored"] == 150
    assert by[("GT stops early", "0.4 of rows kept")]["unscored"] > 0
    for r in rows:
        assert len(r["text"]) <= 100
    refusal = by[("stamp going backwards", "0.1 s")]
    assert refusal["said"] == "refused" and refusal["text"]
    dup = by[("duplicate rows (logged twice)", "5 rows")]
    assert dup["said"] == "warned" and "5 rows" in dup["text"] and dup["unscored"] == 0


def test_a_long_message_is_cut_to_100_characters(monkeypatch):
    monkeypatch.setattr(rcs, "inputs", lambda frames: [("line", line().stamps, line())])
    monkeypatch.setattr(rcs, "run_checks", lambda *a: {"warnings": ["w" * 80, "v" * 80],
                                                       "refusal": "", "scored": 90,
                                                       "frames": 100})
    rows = rcs.study()
    assert {r["text"] for r in rows} == {("w" * 80 + "; " + "v" * 80)[:100]}
    assert {r["unscored"] for r in rows} == {10}
    monkeypatch.setattr(rcs, "run_checks", lambda *a: {"warnings": ["w"], "refusal": "r" * 120,
                                                       "scored": 0, "frames": 100})
    assert {r["text"] for r in rcs.study()} == {"r" * 100}


def test_the_study_sets_the_lengths_from_the_inputs_own_path(monkeypatch):
    seen = []
    monkeypatch.setattr(rcs, "inputs", lambda frames: [("line", line().stamps, line())])
    monkeypatch.setattr(rcs, "run_checks", lambda stamps, gt, lengths, kitti: seen.append(
        (lengths, kitti)) or {"warnings": [], "refusal": "", "scored": 0, "frames": 0})
    rcs.study()
    path = 9.9
    assert len(seen) == 4 + 18
    for lengths, kitti in seen:
        np.testing.assert_allclose(lengths, (0.5 * path, 1.2 * path), rtol=1e-12)
        np.testing.assert_allclose(kitti, (0.9 * path,), rtol=1e-12)


def test_the_study_passes_its_frame_count_to_the_inputs(monkeypatch):
    asked = []
    monkeypatch.setattr(rcs, "inputs", lambda frames: asked.append(frames) or [])
    assert rcs.study(frames=33) == [] and rcs.study() == []
    assert asked == [33, 250]


# ---- the table and the command ------------------------------------------------------------

def _row(case, size, said, unscored, kind="fault"):
    return {"input": "x", "case": case, "kind": kind, "size": size, "said": said,
            "unscored": unscored, "text": ""}


def test_the_table_counts_what_each_case_said():
    rows = [_row("as is", "", "silent", 0, "pass"), _row("as is", "", "silent", 4, "pass"),
            _row("as is", "", "warned", 9, "pass"),
            _row("gap", "1 s", "refused", 5), _row("gap", "2 s", "warned", 7),
            _row("gap", "1 s", "refused", 6)]
    assert rcs.table(rows).splitlines() == [
        "| GT | size | inputs | refused | warned | silent | frames unscored (median) |",
        "|---|---|---:|---:|---:|---:|---:|",
        "| as is | - | 3 | 0 | 1 | 2 | 4 |",
        "| gap | 1 s | 2 | 2 | 0 | 0 | 5 |",
        "| gap | 2 s | 1 | 0 | 1 | 0 | 7 |"]


def _main(monkeypatch, capsys, rows, *argv):
    asked = []
    monkeypatch.setattr(rcs, "study", lambda frames: asked.append(frames) or rows)
    code = rcs.main(list(argv))
    return code, asked, capsys.readouterr().out


def test_the_command_fails_on_a_false_alarm_only(monkeypatch, capsys):
    quiet = [_row("as is", "", "silent", 0, "pass"), _row("gap", "1 s", "refused", 5)]
    code, asked, out = _main(monkeypatch, capsys, quiet)
    assert (code, asked) == (0, [250])
    assert out == rcs.table(quiet) + "\n"
    alarm = [_row("as is", "", "warned", 0, "pass"), _row("gap", "1 s", "silent", 5)]
    code, asked, out = _main(monkeypatch, capsys, alarm, "--frames", "40", "--verbose")
    assert (code, asked) == (1, [40])
    assert out.splitlines()[-2:] == [str(r) for r in alarm]


def test_the_commands_help(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # argparse wraps (at hyphens too) to the terminal
    with pytest.raises(SystemExit) as exit_:
        rcs.main(["--help"])
    assert exit_.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "false alarms and detections of bench run's ground-truth checks" in text
    assert "--frames FRAMES synthetic frames" in text
    assert "--verbose every row and its message" in text


# ---- killing the first run's survivors ----------------------------------------------------

def test_the_checks_name_the_store_as_bench_run_does():
    """Messages name the sequence ``store`` (the scratch job's store ``store.h5``)."""
    dup = check(rcs._duplicates(line(), 2))
    assert dup["warnings"][0].startswith("store: ")
    back = check(rcs._backwards(line(), 0.1))
    assert back["refusal"].startswith("store, pose row 50: stamp 7.800000 s goes backwards")
    apart = check(rcs._shifted(line(), 1.5))
    assert apart["refusal"] == "store: no frame has ground truth; nothing to score"
    some = check(line(), lengths=(4.0, 50.0))
    assert some["warnings"][0].startswith("store: the ground truth's path is 9.9 m long: no "
                                          "segments of 50 m")
    none = check(line(), lengths=(50.0,))
    assert none["refusal"].startswith("store.h5: the ground truth's path is 9.9 m long, too "
                                      "short")


def test_a_dropped_window_is_closed():
    """A 2 s window around the middle (8.0 s) takes 7.0 and 9.0 s with it."""
    gt = line(101)
    got = rcs._drop_window(gt, 2.0)
    np.testing.assert_allclose(got.stamps, np.r_[gt.stamps[:40], gt.stamps[61:]], atol=0)


def test_a_repeated_stamps_other_pose_is_moved_from_its_own():
    gt = line(11)
    gt.poses[:, 1, 3] = 2.0
    got = rcs._two_poses(gt, 1)  # row 1 twice: the second 1 cm further along y
    np.testing.assert_allclose(got.poses[:, 1, 3], [2.0, 2.0, 2.01] + [2.0] * 9, atol=1e-12)


def test_the_inputs_keep_the_gt_rows_within_a_microsecond_of_each_span(monkeypatch):
    """A recorded sample of 250 whole-second scans and GT rows just inside (1 us before the
    first scan, 1 us after the last) and just outside its span; synthetic drives of the
    frames asked for (250 by default) with their options; stamps as float64."""
    stamps = list(range(250))  # whole seconds, as integers
    gt_stamps = np.sort(np.r_[np.arange(250.0), -1e-6, 249.0 + 1e-6, -3e-6, 249.0 + 3e-6])
    poses = np.repeat(np.eye(4)[None], len(gt_stamps), axis=0)

    class Store:
        def __init__(self, path):
            assert path == rcs.SAMPLE
            self.stamps, self.ground_truth = stamps, Trajectory(gt_stamps, poses)

        def close(self):
            pass

    made = []

    class Syn:
        def __init__(self, scene, sensor, frames, **opts):
            made.append((scene, sensor, frames, opts))
            self.stamps = list(range(3))
            self.ground_truth = Trajectory(np.arange(3.0), np.repeat(np.eye(4)[None], 3, 0))

    monkeypatch.setattr(rcs, "StoreSequence", Store)
    monkeypatch.setattr(rcs, "SyntheticSequence", Syn)
    got = rcs.inputs()
    whole = got[0]
    assert whole[1].dtype == np.float64
    np.testing.assert_allclose(whole[2].stamps, np.r_[-1e-6, np.arange(250.0), 249.0 + 1e-6],
                               atol=0)
    assert made == [(scene, sensor, 250, opts) for scene, sensor, opts in
                    rcs.SYNTHETIC.values()]
    for _, s, _ in got[4:]:
        assert s.dtype == np.float64
