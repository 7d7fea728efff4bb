"""bench.studies.calibrate_checks_study, piece by piece (mutation testing): the rotated cues and
GT against scipy's Euler angles, the perturbations against their definitions, ``verdict``'s
wiring, the inputs, the study's rows with the cue collection and the fit replaced by an
independent one (scipy's Kabsch fit of the velocity directions, so a rotated GT frame moves the
estimate exactly), the held-out drives, the table and the command; and one real verdict on a
short synthetic drive (the estimate follows a rotated GT frame)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration.estimate import FrameCues
from bench.studies import calibrate_checks_study as ccs
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.trajectory import Trajectory


def euler(angles_deg) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll) of (roll, pitch, yaw) [deg], by scipy."""
    roll, pitch, yaw = angles_deg
    return Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).as_matrix()


def unit_rows(n: int, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def cues(n_frames: int = 8, vel=(0, 2, 3, 5, 7), road=(1, 3, 4, 6)) -> FrameCues:
    vel, road = np.array(vel), np.array(road)
    return FrameCues(n_frames, 0.1, vel, unit_rows(len(vel), 1), unit_rows(len(vel), 2), road,
                     unit_rows(len(road), 3), unit_rows(len(road), 4),
                     np.linspace(1.0, 2.0, len(road)))


def line(n: int = 40, rate_hz: float = 10.0, t0: float = 0.0) -> Trajectory:
    stamps = t0 + np.arange(n) / rate_hz
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = 5.0 * (stamps - t0)
    return Trajectory(stamps, poses)


# ---- rotating the GT frame ----------------------------------------------------------------

def test_rotated_cues_turn_the_gt_cues_from_a_frame_on():
    c = cues()
    angles = (10.0, -20.0, 30.0)
    E = euler(angles)
    got = ccs.rotated_cues(c, angles, from_frame=3)
    v = c.vel_frame >= 3  # rows of frames 3, 5, 7
    np.testing.assert_allclose(got.b[v], c.b[v] @ E.T, atol=1e-12)
    np.testing.assert_array_equal(got.b[~v], c.b[~v])
    r = c.road_frame >= 3  # frames 3, 4, 6
    np.testing.assert_allclose(got.ups[r], c.ups[r] @ E.T, atol=1e-12)
    np.testing.assert_array_equal(got.ups[~r], c.ups[~r])
    # the scans' cues are the same; the input is left alone
    for name in ("n_frames", "period_s", "vel_frame", "a", "road_frame", "normals", "heights"):
        np.testing.assert_array_equal(getattr(got, name), getattr(c, name))
    np.testing.assert_array_equal(c.b, cues().b)
    np.testing.assert_array_equal(c.ups, cues().ups)
    # from frame 0 on (the default): every GT cue turned
    whole = ccs.rotated_cues(c, (0.0, 0.0, 90.0))
    np.testing.assert_allclose(whole.b, c.b @ euler((0, 0, 90)).T, atol=1e-12)
    np.testing.assert_allclose(whole.ups, c.ups @ euler((0, 0, 90)).T, atol=1e-12)


def test_a_rotated_gt_is_its_poses_right_multiplied_by_the_inverse_turn():
    gt = line(5)
    gt.poses[:, :3, :3] = euler((3.0, 1.0, 40.0))
    angles = (5.0, 7.0, -11.0)
    got = ccs.rotated_gt(gt, angles)
    np.testing.assert_allclose(got.poses[:, :3, :3], gt.poses[:, :3, :3] @ euler(angles).T,
                               atol=1e-12)
    np.testing.assert_allclose(got.poses[:, :3, 3], gt.poses[:, :3, 3], atol=1e-12)
    np.testing.assert_array_equal(got.stamps, gt.stamps)


def test_jitter_and_resampling():
    gt = line(21)
    got = ccs.jittered(gt)
    np.testing.assert_allclose(got.poses[:, :3, 3] - gt.poses[:, :3, 3],
                               np.random.default_rng(0).normal(0.0, 0.005, (21, 3)), atol=1e-15)
    np.testing.assert_array_equal(got.poses[:, :3, :3], gt.poses[:, :3, :3])
    np.testing.assert_array_equal(got.stamps, gt.stamps)
    assert not np.shares_memory(got.stamps, gt.stamps)
    np.testing.assert_allclose(ccs.jittered(gt, 0.2, 3).poses[:, :3, 3] - gt.poses[:, :3, 3],
                               np.random.default_rng(3).normal(0.0, 0.2, (21, 3)), atol=1e-15)
    np.testing.assert_allclose(gt.poses[:, 1, 3], 0.0, atol=0)  # the input is left alone
    half = ccs.resampled(gt)  # 2 s at 5 Hz: 11 poses
    np.testing.assert_allclose(half.stamps, np.arange(11) * 0.2, atol=1e-9)
    np.testing.assert_allclose(half.poses[:, 0, 3], 5.0 * half.stamps, atol=1e-9)
    assert len(ccs.resampled(gt, rate_hz=2.0)) == 5


def test_another_gt_keeps_the_scans():
    scans = [Scan(0.1 * i, np.eye(3) + i, doppler=np.zeros(3)) for i in range(4)]
    base = MemorySequence("base", SensorInfo("radar", 0.1), scans, line(4))
    base.provenance = {"from": "here"}
    other = line(4, t0=0.05)
    seq = ccs.OtherGT(base, other)
    assert seq.ground_truth is other
    assert (seq.name, seq.sensor, seq.provenance) == ("base", base.sensor, {"from": "here"})
    assert len(seq) == 4
    np.testing.assert_array_equal(seq.stamps, [0.0, 0.1, 0.2, 0.30000000000000004])
    np.testing.assert_array_equal(seq.scan(2).points, scans[2].points)


# ---- verdict's wiring ---------------------------------------------------------------------

def test_a_verdict_is_the_fit_the_applied_angles_and_the_pieces_apart(monkeypatch):
    c = cues(n_frames=300)
    seen = {}
    cal = SimpleNamespace(angles_deg={"roll": 1.0, "pitch": 2.0, "yaw": 3.0},
                          interval_deg={"roll": (0, 2), "pitch": (1, 3), "yaw": (2, 4)},
                          not_observable=["yaw"])

    def calibrate_cues(cues_, bootstrap, name):
        seen["cal"] = (cues_, bootstrap, name)
        return cal

    def select_angles(angles, interval, fitted, width):
        seen["select"] = (angles, interval, fitted, width)
        return {"roll": 1.0}, {"pitch": "why"}

    def fit_pieces(cues_, bounds, bootstrap, name):
        seen["pieces"] = (cues_, bounds, bootstrap, name)
        return ["p1", "p2", "p3"]

    def disagreements(pieces):
        assert pieces == ["p1", "p2", "p3"]
        return [SimpleNamespace(angle=a) for a in ("yaw", "pitch", "yaw")]

    for name, fake in (("calibrate_cues", calibrate_cues), ("select_angles", select_angles),
                       ("fit_pieces", fit_pieces), ("disagreements", disagreements),
                       ("piece_bounds", lambda n: [(0, n // 2), (n // 2, n)])):
        monkeypatch.setattr(ccs, name, fake)
    got = ccs.verdict(c, "drive")
    assert got == {"cal": cal, "applied": {"roll": 1.0}, "pieces": 3, "apart": ["pitch", "yaw"]}
    assert seen["cal"] == (c, 200, "drive")
    assert seen["select"] == (cal.angles_deg, cal.interval_deg,
                              {"roll": True, "pitch": True, "yaw": False}, 2.0)
    assert seen["pieces"] == (c, [(0, 150), (150, 300)], 200, "drive")
    assert ccs.BOOTSTRAP == 200


def test_a_real_verdict_follows_a_rotated_gt_frame(monkeypatch):
    """A short straight drive: a GT frame rotated by 3 deg in pitch moves the estimate by 3
    deg, inside its interval; the drive as is has no pieces apart."""
    from loaders.synthetic.generate import SyntheticSequence

    monkeypatch.setattr(ccs, "BOOTSTRAP", 20)
    base = ccs.collect_cues(SyntheticSequence("straight-wall", "radar-sparse", 40, seed=10,
                                              attitude_deg=0.0))
    as_is = ccs.verdict(base, "as is")
    assert as_is["apart"] == []
    moved = ccs.verdict(ccs.rotated_cues(base, (0.0, 3.0, 0.0)), "moved")["cal"]
    shift = moved.angles_deg["pitch"] - as_is["cal"].angles_deg["pitch"]
    assert shift == pytest.approx(3.0, abs=0.02)
    assert ccs._covers(moved, "pitch", as_is["cal"].angles_deg["pitch"] + 3.0)


def test_an_interval_covers_a_value_when_finite_and_around_it():
    cal = SimpleNamespace(interval_deg={"roll": (1.0, 2.0), "pitch": (np.nan, np.nan),
                                        "yaw": (-np.inf, 5.0)})
    assert ccs._covers(cal, "roll", 1.0) and ccs._covers(cal, "roll", 2.0)
    assert ccs._covers(cal, "roll", 1.5) is True
    assert not ccs._covers(cal, "roll", 0.99) and not ccs._covers(cal, "roll", 2.01)
    assert ccs._covers(cal, "pitch", 0.0) is False
    assert ccs._covers(cal, "yaw", 0.0) is False


# ---- the inputs ---------------------------------------------------------------------------

def test_the_inputs_are_the_sample_its_parts_and_two_synthetic_drives():
    from loaders.store import StoreSequence

    got = ccs._bases(30)
    assert [name for name, _ in got] == [
        "sample frames 0-249", "sample first half", "sample second half",
        "sample frames 60-189", "synthetic loop (radar-eagle)",
        "synthetic straight drive (radar-sparse, flat)"]
    assert [len(s) for _, s in got] == [250, 125, 125, 130, 30, 30]
    sample = StoreSequence(ccs.SAMPLE)
    try:
        stamps = np.asarray(sample.stamps)
    finally:
        sample.close()
    for (_, seq), first in zip(got[:4], (0, 0, 125, 60), strict=True):
        np.testing.assert_allclose(seq.stamps, stamps[first:first + len(seq)], atol=1e-9)
    loop, straight = got[4][1], got[5][1]
    assert (loop.scene_name, loop.spec.name if hasattr(loop.spec, "name") else "radar-eagle") \
        == ("loop", "radar-eagle")
    assert straight.scene_name == "straight-wall" and straight.options == {"attitude_deg": 0.0}
    assert loop.options == {}


def test_the_held_out_drives_are_not_those_the_floor_was_chosen_on():
    assert ccs.HELD_OUT == [("straight-wall", "radar-sparse", {"attitude_deg": 0.0}, s)
                            for s in range(10, 20)] + [("curved-wall", "radar-eagle", {}, 0),
                                                       ("loop", "radar-frgen21", {}, 1)]


# ---- the study, with the cues and the fit replaced ----------------------------------------

class FakeSeq:
    """A sequence of ``n`` scans at 10 Hz with a GT along them."""

    def __init__(self, n: int = 40, t0: float = 0.0):
        self.stamps = t0 + np.arange(n) / 10.0
        self.ground_truth = line(n, t0=t0)
        self.name = "fake"
        self.sensor = SensorInfo("radar", 0.1)
        self.provenance = {}


def identity_cues(n: int = 40) -> FrameCues:
    """Cues of a sensor aligned with the GT frame (b = a, ups = normals)."""
    a, road = unit_rows(n, 5), np.arange(0, n, 2)
    normals = unit_rows(len(road), 6)
    return FrameCues(n, 0.1, np.arange(n), a, a.copy(), road, normals, normals.copy(),
                     np.ones(len(road)))


def fake_verdict(cues_: FrameCues, name: str) -> dict:
    """An independent fit: scipy's rotation taking the sensor's directions to the GT's, an
    interval of +-0.5 deg; pieces apart in pitch when the two halves disagree by 0.3 deg."""
    R = Rotation.align_vectors(cues_.b, cues_.a)[0].as_matrix()
    yaw, pitch, roll = Rotation.from_matrix(R).as_euler("ZYX", degrees=True)
    angles = {"roll": roll, "pitch": pitch, "yaw": yaw}
    half = cues_.vel_frame < cues_.n_frames // 2
    halves = [Rotation.align_vectors(cues_.b[m], cues_.a[m])[0].as_euler("ZYX", degrees=True)[1]
              for m in (half, ~half)]
    cal = SimpleNamespace(angles_deg=angles, R_gt_sensor=R,
                          interval_deg={k: (v - 0.5, v + 0.5) for k, v in angles.items()})
    return {"cal": cal, "applied": {"yaw": yaw, "roll": roll}, "pieces": 2,
            "apart": ["pitch"] if abs(halves[0] - halves[1]) > 0.3 else []}


def fake_collect(seq, name=None) -> FrameCues:
    """The cues of an aligned sensor; refused as collect_cues refuses a GT at fewer than 3
    scans."""
    if int(seq.ground_truth.coverage_mask(np.asarray(seq.stamps)).sum()) < 3:
        raise DataError(f"{name}: no scan has ground truth")
    return identity_cues(len(seq.stamps))


def run_study(monkeypatch, names, **kw) -> list[dict]:
    monkeypatch.setattr(ccs, "_bases", lambda frames: [(n, FakeSeq()) for n in names])
    monkeypatch.setattr(ccs, "collect_cues", fake_collect)
    monkeypatch.setattr(ccs, "verdict", fake_verdict)
    return ccs.study(**kw)


def test_the_study_rows_of_a_synthetic_straight_drive(monkeypatch):
    rows = run_study(monkeypatch, ["synthetic straight"], sizes=(1.0, 4.0), steps=(-1.0, 2.0))
    assert [(r["case"], r["size"]) for r in rows] == [
        ("as is", ""), ("GT jittered 5 mm", ""), ("GT resampled to 5 Hz", ""),
        ("GT not overlapping", ""),
        ("GT frame rotated in pitch", "1 deg"), ("GT frame rotated in pitch", "4 deg"),
        ("GT frame rotated in yaw", "1 deg"), ("GT frame rotated in yaw", "4 deg"),
        ("GT pitch changes half-way", "-1 deg"), ("GT pitch changes half-way", "2 deg")]
    assert all(r["input"] == "synthetic straight" for r in rows)
    first = rows[0]
    # the truth is the identity: the applied angles' intervals hold 0
    assert first == {"input": "synthetic straight", "case": "as is", "size": "", "apart": [],
                     "pieces": 2, "applied": ["roll", "yaw"], "missed_truth": []}
    for r in rows[1:3]:
        assert r == {"input": "synthetic straight", "case": r["case"], "size": "", "apart": [],
                     "pieces": 2, "applied": ["roll", "yaw"]}
    assert rows[3] == {"input": "synthetic straight", "case": "GT not overlapping", "size": "",
                       "refused": True}
    for r in rows[4:8]:
        assert abs(r["error_deg"]) < 1e-6 and r["covered"] is True and r["apart"] == []
        assert r["applied"] == ["roll", "yaw"] and "pieces" not in r
    for r in rows[8:]:
        assert r["apart"] == ["pitch"] and r["pieces"] == 2 and set(r) == {
            "input", "case", "size", "apart", "pieces"}


def test_the_rotations_are_about_their_own_axis_and_measured_from_the_estimate(monkeypatch):
    """With the sensor's own mounting (R0, 5 deg of roll) the expected angle is that of the
    turn applied to R0; the injected rotation is about the named axis only."""
    R0 = euler((5.0, 0.0, 0.0))

    def mounted(seq, name=None):
        c = fake_collect(seq, name)
        return FrameCues(c.n_frames, c.period_s, c.vel_frame, c.a, c.a @ R0.T, c.road_frame,
                         c.normals, c.normals @ R0.T, c.heights)

    monkeypatch.setattr(ccs, "_bases", lambda frames: [("sample frames 60-189", FakeSeq())])
    monkeypatch.setattr(ccs, "collect_cues", mounted)
    monkeypatch.setattr(ccs, "verdict", fake_verdict)
    rows = ccs.study(sizes=(10.0,), steps=())
    rotated = [r for r in rows if r["size"]]
    # the turn does not commute with R0: an expected angle of R0 turned the other way, or of
    # another axis, would be off by 0.03 deg or more
    for r, ax in zip(rotated, ("pitch", "yaw"), strict=True):
        assert r["case"] == f"GT frame rotated in {ax}"
        assert abs(r["error_deg"]) < 1e-6 and r["covered"] is True
    # not synthetic: no truth checked; not straight: no jitter or resampling
    assert "missed_truth" not in rows[0]
    assert [r["case"] for r in rows[:2]] == ["as is", "GT not overlapping"]


def test_a_missed_truth_and_a_missed_rotation_are_reported(monkeypatch):
    """A fit whose interval sits 1 deg off: 0 is outside every applied angle's interval and
    the injected angle outside the rotated one's."""
    def off(cues_, name):
        v = fake_verdict(cues_, name)
        v["cal"].interval_deg = {k: (x + 1.0, x + 2.0) for k, x in v["cal"].angles_deg.items()}
        return v

    monkeypatch.setattr(ccs, "_bases", lambda frames: [("synthetic loop", FakeSeq()),
                                                        ("sample first half", FakeSeq())])
    monkeypatch.setattr(ccs, "collect_cues", fake_collect)
    monkeypatch.setattr(ccs, "verdict", off)
    rows = ccs.study(sizes=(2.0,), steps=())
    assert sorted(rows[0]["missed_truth"]) == ["roll", "yaw"]
    assert [r["covered"] for r in rows if "covered" in r] == [False] * 4
    # the sample's first half is checked with a jittered and a resampled GT too
    assert [r["case"] for r in rows if r["input"] == "sample first half"][:3] == [
        "as is", "GT jittered 5 mm", "GT resampled to 5 Hz"]
    assert "missed_truth" not in [r for r in rows if r["input"] == "sample first half"][0]


def test_a_gt_overlapping_the_scans_is_not_a_refusal(monkeypatch):
    """The refusal row says whether collect_cues refused the GT moved past the scans: a
    collection that accepts it is reported as not refused."""
    monkeypatch.setattr(ccs, "_bases", lambda frames: [("x", FakeSeq())])
    monkeypatch.setattr(ccs, "collect_cues", lambda seq, name=None: identity_cues())
    monkeypatch.setattr(ccs, "verdict", fake_verdict)
    rows = ccs.study(sizes=(), steps=())
    assert rows[1] == {"input": "x", "case": "GT not overlapping", "size": "", "refused": False}


def test_the_gt_moved_past_the_scans_starts_after_their_end(monkeypatch):
    moved = []

    def collect(seq, name=None):
        if isinstance(seq, ccs.OtherGT):
            moved.append(seq.ground_truth.stamps.copy())
        return fake_collect(seq, name)

    monkeypatch.setattr(ccs, "_bases", lambda frames: [("x", FakeSeq(t0=100.0))])
    monkeypatch.setattr(ccs, "collect_cues", collect)
    monkeypatch.setattr(ccs, "verdict", fake_verdict)
    ccs.study(sizes=(), steps=())
    (stamps,) = moved
    span = 3.9  # moved by 1.01 spans and 1 s: 4.939 s
    np.testing.assert_allclose(stamps, 100.0 + np.arange(40) / 10.0 + 1.01 * span + 1.0,
                               atol=1e-9)


def test_the_study_passes_its_frame_count(monkeypatch):
    asked = []
    monkeypatch.setattr(ccs, "_bases", lambda frames: asked.append(frames) or [])
    assert ccs.study(frames=17) == [] and ccs.study() == []
    assert asked == [17, 250]
    import inspect

    params = inspect.signature(ccs.study).parameters
    assert params["sizes"].default == (1.0, 2.0, 5.0, 10.0)
    assert params["steps"].default == (-1.0, -0.5, 0.5, 1.0, 2.0, 3.0)


def test_the_held_out_rows(monkeypatch):
    made = []

    class Syn:
        def __init__(self, scene, sensor, frames, seed=0, **opts):
            made.append((scene, sensor, frames, seed, opts))
            self.n = frames

    collected = []

    def collect(seq, name=None):
        made.append(name)
        collected.append(identity_cues(seq.n))
        return collected[-1]

    pieces_seen = []

    def disagreements(pieces):
        assert pieces == ["p", "q"]
        return [SimpleNamespace(angle="yaw")] * 2

    monkeypatch.setattr(ccs, "HELD_OUT", [("loop", "radar-x", {"a": 1}, 4)])
    monkeypatch.setattr(ccs, "SyntheticSequence", Syn)
    monkeypatch.setattr(ccs, "collect_cues", collect)
    monkeypatch.setattr(ccs, "fit_pieces", lambda c, bounds, bootstrap, name: pieces_seen.append(
        (c, bounds, bootstrap, name)) or ["p", "q"])
    monkeypatch.setattr(ccs, "piece_bounds", lambda n: [(0, n)])
    monkeypatch.setattr(ccs, "disagreements", disagreements)
    rows = ccs.held_out(frames=40)
    name = "held out: loop radar-x seed 4"
    assert made == [("loop", "radar-x", 40, 4, {"a": 1}), name]
    assert pieces_seen == [(collected[0], [(0, 40)], 200, name)]
    assert rows == [{"input": name, "case": "as is", "size": "", "pieces": 2,
                     "apart": ["yaw"]}]
    made.clear()
    ccs.held_out()  # 250 frames by default
    assert made[0] == ("loop", "radar-x", 250, 4, {"a": 1})


# ---- the table and the command ------------------------------------------------------------

def test_the_table_prints_each_kind_of_row():
    rows = [{"input": "a", "case": "as is", "size": "", "apart": [], "pieces": 2,
             "applied": ["pitch", "roll"], "missed_truth": []},
            {"input": "a", "case": "as is", "size": "", "apart": ["yaw"], "pieces": 2,
             "applied": [], "missed_truth": ["pitch", "roll"]},
            {"input": "a", "case": "GT not overlapping", "size": "", "refused": True},
            {"input": "a", "case": "GT frame rotated in yaw", "size": "2 deg",
             "apart": ["pitch", "yaw"], "error_deg": -0.0349, "covered": True,
             "applied": ["yaw"]},
            {"input": "a", "case": "GT frame rotated in yaw", "size": "5 deg", "apart": [],
             "error_deg": 1.5, "covered": False, "applied": ["yaw"]},
            {"input": "b", "case": "GT pitch changes half-way", "size": "1 deg",
             "apart": ["pitch"], "pieces": 2}]
    assert ccs.table(rows).splitlines() == [
        "| input | case | size | pieces apart | applied | estimate - injected [deg] | "
        "interval covers it |",
        "|---|---|---|---|---|---:|---|",
        "| a | as is | - | none | pitch, roll |  | 0 inside |",
        "| a | as is | - | yaw | - |  | 0 outside: pitch, roll |",
        "| a | GT not overlapping | - | refused: True | | | |",
        "| a | GT frame rotated in yaw | 2 deg | pitch, yaw | yaw | -0.03 | yes |",
        "| a | GT frame rotated in yaw | 5 deg | none | yaw | +1.50 | NO |",
        "| b | GT pitch changes half-way | 1 deg | pitch | - |  |  |"]


def _main(monkeypatch, capsys, rows, held):
    monkeypatch.setattr(ccs, "study", lambda: rows)
    monkeypatch.setattr(ccs, "held_out", lambda: held)
    code = ccs.main([])
    return code, capsys.readouterr().out


def _r(case, apart):
    return {"input": "i", "case": case, "size": "", "apart": apart, "pieces": 2}


def test_the_command_fails_on_a_false_alarm_only(monkeypatch, capsys):
    quiet = [_r("as is", []), _r("GT pitch changes half-way", ["pitch"]),
             _r("GT frame rotated in yaw", ["yaw"])]
    code, out = _main(monkeypatch, capsys, quiet, [_r("as is", [])])
    assert code == 0
    assert out == ccs.table(quiet + [_r("as is", [])]) + "\n"
    for case in ("as is", "GT jittered 5 mm", "GT resampled to 5 Hz"):
        assert _main(monkeypatch, capsys, quiet, [_r(case, ["roll"])])[0] == 1
        assert _main(monkeypatch, capsys, [_r(case, ["yaw"])], [])[0] == 1


def test_the_command_takes_no_arguments(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "1000")  # argparse wraps (at hyphens too) to the terminal
    with pytest.raises(SystemExit) as exit_:
        ccs.main(["--frames", "3"])
    assert exit_.value.code == 2
    with pytest.raises(SystemExit) as help_:
        ccs.main(["--help"])
    assert help_.value.code == 0
    assert "false alarms and detections of bench calibrate's verdicts" in \
        " ".join(capsys.readouterr().out.split())


def test_each_check_names_its_input_and_turns_one_axis(monkeypatch):
    """Every cue collection and verdict gets the input's name (their messages name it); the
    injected rotation is about the named axis only (the fit finds size there, 0 elsewhere)."""
    names, found = [], []

    def collect(seq, name=None):
        names.append(("collect", name))
        return fake_collect(seq, name)

    def verdict(cues_, name):
        names.append(("verdict", name))
        v = fake_verdict(cues_, name)
        found.append([v["cal"].angles_deg[a] for a in ("roll", "pitch", "yaw")])
        return v

    monkeypatch.setattr(ccs, "_bases", lambda frames: [("synthetic straight", FakeSeq())])
    monkeypatch.setattr(ccs, "collect_cues", collect)
    monkeypatch.setattr(ccs, "verdict", verdict)
    ccs.study(sizes=(4.0,), steps=(1.0,))
    assert names == [("collect", "synthetic straight"), ("verdict", "synthetic straight")] + [
        ("collect", "synthetic straight"), ("verdict", "synthetic straight")] * 2 + [
        ("collect", "synthetic straight")] + [("verdict", "synthetic straight")] * 3
    # as is, jittered, resampled (identity), pitch 4, yaw 4; then the half-way change
    np.testing.assert_allclose(found[:5], [[0, 0, 0]] * 3 + [[0, 4, 0], [0, 0, 4]], atol=1e-9)


def test_the_pitch_changes_half_way_in_pitch_only(monkeypatch):
    """41 frames: GT cues of frames 20 on turned by (0, step, 0), those before left alone."""
    seen = []

    def verdict(cues_, name):
        seen.append(cues_)
        return fake_verdict(cues_, name)

    monkeypatch.setattr(ccs, "_bases", lambda frames: [("x", FakeSeq(41))])
    monkeypatch.setattr(ccs, "collect_cues", fake_collect)
    monkeypatch.setattr(ccs, "verdict", verdict)
    ccs.study(sizes=(), steps=(2.5,))
    half = seen[-1]
    assert half.n_frames == 41
    later = half.vel_frame >= 20
    assert later.sum() == 21
    np.testing.assert_allclose(half.b[later], half.a[later] @ euler((0, 2.5, 0)).T, atol=1e-12)
    np.testing.assert_allclose(half.b[~later], half.a[~later], atol=0)
    road = half.road_frame >= 20
    np.testing.assert_allclose(half.ups[road], half.normals[road] @ euler((0, 2.5, 0)).T,
                               atol=1e-12)
