"""bench inspect's GT-clock study (bench.studies.inspect_clock_study), its parts checked one by
one: the verdict of each kind of line the check prints, the windows, the ground-truth variants
(jitter, 10 Hz nearest-sampling worked out from a drive whose position is its own stamp, the
lags), the study's loop (the check stood in for: what each piece is given), the table
(hand-made rows) and the exit code."""

import numpy as np
import pytest

import methods.ego_velocity
from bench.studies import inspect_clock_study as ic
from loaders.gt import nearest_indices
from loaders.store import StoreSequence
from loaders.trajectory import Trajectory

GREEN = ("green", "GT clock vs Doppler speed: the ground truth lags the sensor by +0.010 s (95 % "
                  "block-bootstrap interval [-0.020, +0.030] s); cross-correlation of the speeds "
                  "0.95 over 250 scans, one scan period 0.083 s: within one scan period")


def test_verdict_reads_the_first_line():
    assert ic.verdict([GREEN]) == "passed"
    assert ic.verdict([("yellow", "warning: GT clock vs Doppler speed: ... more than one scan "
                                  "period")]) == "warned"
    assert ic.verdict([("dim", "GT clock vs Doppler speed: not estimated (too few scans)")]) \
        == "cannot tell"
    assert ic.verdict([("yellow", "GT clock ...: more than a period, but the interval reaches "
                                  "within one period: inconclusive on this sequence")]) \
        == "cannot tell"
    assert ic.verdict([("dim", "GT clock ...: within one scan period, but the interval reaches "
                               "beyond: this sequence cannot time the ground truth")]) \
        == "cannot tell"
    # only the first line counts, and "warning:" only at its start
    assert ic.verdict([GREEN, ("yellow", "warning: x")]) == "passed"
    assert ic.verdict([("yellow", "warning: x"), GREEN]) == "warned"
    assert ic.verdict([("green", "no warning: x")]) == "passed"


def test_windows_are_the_whole_halves_and_100_frames_every_25():
    got = ic.windows(250)
    assert [label for label, _ in got] == [
        "whole", "first half", "second half", "frames 0-100", "frames 25-125", "frames 50-150",
        "frames 75-175", "frames 100-200", "frames 125-225", "frames 150-250"]
    assert [(s.start, s.stop) for _, s in got[:4]] == [(0, 250), (0, 125), (125, 250), (0, 100)]
    assert all(s.stop - s.start == 100 for _, s in got[3:])
    assert [label for label, _ in ic.windows(125)][3:] == ["frames 0-100", "frames 25-125"]
    assert [label for label, _ in ic.windows(100)][3:] == ["frames 0-100"]
    assert len(ic.windows(99)) == 3
    assert [(s.start, s.stop) for _, s in ic.windows(7)] == [(0, 7), (0, 3), (3, 7)]


def clock_drive(n: int = 120) -> Trajectory:
    """12 Hz ground truth whose x is its own stamp (so a pose tells the moment it was taken)."""
    t = np.arange(n) / 12
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = t
    return Trajectory(t, poses)


def test_variants_are_the_correct_ground_truths_and_every_lag_both_ways():
    gt = clock_drive()
    out = ic.variants(gt, np.random.default_rng(4))
    assert [(name, lag) for name, lag, _ in out] == [
        ("as is", None), ("GT jittered 2 cm", None), ("GT from 10 Hz, nearest", None),
        ("GT lagged", 0.2), ("GT lagged", -0.2), ("GT lagged", 0.5), ("GT lagged", -0.5),
        ("GT lagged", 1.0), ("GT lagged", -1.0), ("GT lagged", 2.0), ("GT lagged", -2.0)]
    assert out[0][2] is gt
    for _, lag, traj in out[3:]:
        np.testing.assert_allclose(traj.stamps, gt.stamps + lag)
        np.testing.assert_array_equal(traj.poses, gt.poses)
    jit = out[1][2]
    np.testing.assert_array_equal(jit.stamps, gt.stamps)
    d = jit.poses[:, :3, 3] - gt.poses[:, :3, 3]
    assert 0.017 < np.std(d) < 0.023 and abs(np.mean(d)) < 0.005
    np.testing.assert_array_equal(jit.poses[:, :3, :3], gt.poses[:, :3, :3])
    np.testing.assert_array_equal(gt.poses[:, 1, 3], 0.0)  # the ground truth itself untouched


def test_the_10_hz_variant_holds_at_each_scan_the_pose_nearest_its_10_hz_tick():
    """NTU's ground truth is 10 Hz, nearest-sampled onto the scans: each scan gets the pose of
    the nearest 0.1 s tick; here (12 Hz ground truth only) the pose taken nearest that tick."""
    gt = clock_drive()
    ntu = ic.variants(gt, np.random.default_rng(0))[2][2]
    np.testing.assert_array_equal(ntu.stamps, gt.stamps)
    tick = np.round(gt.stamps * 10) / 10
    nearest = np.round(tick * 12) / 12  # the 12 Hz stamp nearest each tick
    nearest = np.minimum(nearest, gt.stamps[-1])
    np.testing.assert_allclose(ntu.poses[:, 0, 3], nearest, atol=1e-12)
    assert np.abs(ntu.poses[:, 0, 3] - tick).max() <= 1 / 24 + 1e-9  # never a period off


def test_nearest_rows_picks_the_nearest_stamp_the_earlier_on_a_tie():
    """loaders.gt.nearest_indices, which the '10 Hz, nearest' variant uses."""
    def nearest_rows(stamps, query):
        return nearest_indices(stamps, query)[0]

    stamps = np.array([0.0, 1.0, 3.0, 4.0])
    query = np.array([-5.0, 0.4, 0.6, 2.0, 2.1, 3.9, 9.0, 1.0])
    np.testing.assert_array_equal(nearest_rows(stamps, query), [0, 0, 1, 1, 2, 3, 3, 1])
    np.testing.assert_array_equal(nearest_rows(np.array([0.0, 1.0]), query[:3]), [0, 0, 1])
    one = nearest_rows(np.array([2.0]), query[:3])
    np.testing.assert_array_equal(one, [0, 0, 0])
    assert one.dtype.kind == "i"  # indices, for poses[idx]


@pytest.fixture(scope="module")
def sample():
    seq = StoreSequence(ic.SAMPLE, fields=())
    try:
        yield seq.stamps, seq.ground_truth, seq.provenance, seq.sensor
    finally:
        seq.close()


def test_study_runs_the_check_on_every_variant_and_piece(monkeypatch, sample):
    stamps, gt, provenance, sensor = sample
    n = len(stamps)
    seen = []

    def speeds(seq):
        assert seq.stamps is not None and len(seq) == n
        return {"stamps": seq.stamps.copy(), "speed_doppler": np.arange(n) * 0.5}

    def check(cut, part):
        seen.append((cut, part))
        if len(seen) % 3 == 0:
            return [("yellow", f"warning: {len(seen)}"), GREEN]
        return [("green", f"line {len(seen)}")]

    monkeypatch.setattr(methods.ego_velocity, "speed_from_doppler", speeds)
    monkeypatch.setattr(ic, "clock_offset_lines", check)
    rows = ic.study(seed=3)
    names = ic.variants(gt, np.random.default_rng(3))
    pieces = ic.windows(n)
    assert len(rows) == len(seen) == len(names) * len(pieces) == 110
    k = 0
    for name, lag, traj in names:
        for label, sl in pieces:
            r = rows[k]
            cut, part = seen[k]
            k += 1
            assert (r["variant"], r["lag"], r["piece"]) == (name, lag, label)
            assert r["outcome"] == ("warned" if k % 3 == 0 else "passed")
            assert r["line"] == (f"warning: {k}" if k % 3 == 0 else f"line {k}")
            np.testing.assert_array_equal(cut.stamps, stamps[sl])
            assert len(cut) == sl.stop - sl.start
            np.testing.assert_allclose(cut.ground_truth.stamps, traj.stamps)
            np.testing.assert_allclose(cut.ground_truth.poses, traj.poses)
            assert cut.provenance == provenance and cut.sensor.kind == sensor.kind
            np.testing.assert_array_equal(part["stamps"], stamps[sl])
            np.testing.assert_array_equal(part["speed_doppler"], np.arange(n)[sl] * 0.5)


def test_study_seeds_the_jitter(monkeypatch, sample):
    _, gt, _, _ = sample
    got = []

    def check(cut, part):
        got.append(cut.ground_truth)
        return [GREEN]

    monkeypatch.setattr(methods.ego_velocity, "speed_from_doppler",
                        lambda seq: {"stamps": seq.stamps})
    monkeypatch.setattr(ic, "clock_offset_lines", check)
    ic.study()
    jittered = got[10]  # the second variant's first piece
    want = ic.variants(gt, np.random.default_rng(0))[1][2]
    np.testing.assert_allclose(jittered.poses, want.poses)


def row(variant, lag, outcome):
    return {"variant": variant, "lag": lag, "piece": "p", "outcome": outcome, "line": "x"}


def test_table_counts_outcomes_per_variant_and_size_of_lag():
    rows = [row("as is", None, "passed"), row("as is", None, "cannot tell"),
            row("GT jittered 2 cm", None, "warned"),
            row("GT lagged", 2.0, "warned"), row("GT lagged", -2.0, "cannot tell"),
            row("GT lagged", 0.2, "passed"), row("GT lagged", -0.2, "warned"),
            row("GT lagged", 0.2, "warned")]
    assert ic.table(rows).split("\n") == [
        "| GT | lag [s] | pieces | warned | cannot tell | passed |",
        "|---|---:|---:|---:|---:|---|",
        "| GT jittered 2 cm | - | 1 | 1 | 0 | 0 |",
        "| as is | - | 2 | 0 | 1 | 1 |",
        "| GT lagged | +-0.2 | 3 | 2 | 0 | 1 |",
        "| GT lagged | +-2 | 2 | 1 | 1 | 0 |"]


def test_main_prints_the_table_and_fails_only_on_a_false_alarm(monkeypatch, capsys):
    rows = [row("as is", None, "passed"), row("GT lagged", 1.0, "warned"),
            row("as is", None, "cannot tell")]
    monkeypatch.setattr(ic, "study", lambda: rows)
    assert ic.main([]) == 0
    assert capsys.readouterr().out == ic.table(rows) + "\n"
    rows.append(row("GT from 10 Hz, nearest", None, "warned"))
    assert ic.main([]) == 1
    with pytest.raises(SystemExit):
        ic.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert "false alarms and detections of bench inspect's GT-clock check on the sample" in out
    with pytest.raises(SystemExit):
        ic.main(["--unknown"])


def test_constants():
    assert ic.LAGS_S == (0.2, 0.5, 1.0, 2.0)
    assert ic.SAMPLE.is_file() and ic.SAMPLE.name == "ntu4dradlm-loop1.h5"
