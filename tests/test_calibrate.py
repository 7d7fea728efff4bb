"""bench calibrate: recovers a known sensor-to-GT rotation and says what it could not see."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration.calibrate import calibrate_store
from bench.data.calibration.estimate import CorrectedSequence, calibrate_sequence, rotation_check
from loaders.scan import MemorySequence
from loaders.store import StoreSequence, write_store
from loaders.synthetic import SyntheticSequence

ROLL, PITCH, YAW = 1.0, 2.0, -1.5


def rotated_gt(seq, roll=ROLL, pitch=PITCH, yaw=YAW):
    """``seq`` whose GT frame is rotated against the sensor: R_gt_sensor = Rz Ry Rx."""
    R = Rotation.from_euler("ZYX", [yaw, pitch, roll], degrees=True).as_matrix()
    return CorrectedSequence(seq, R.T)  # GT poses T_world_sensor @ R^T = T_world_gt


@pytest.fixture(scope="module")
def loop():
    # 150 frames (about 100 m of road): the road plane's roll averages the persistent
    # elevation biases of the ground scatterers it sees (0.3 deg each, sensors.py), and over 50
    # frames too few are seen for a tenth of a degree (synthetic 1.4, seeds 1-3: roll off by
    # 0.04 / 0.24 / 0.06 deg; over 150 frames 0.03 / 0.08 / 0.08, pitch 0.07 / 0.08 / 0.09)
    return SyntheticSequence("loop", "radar-semidense", frames=150, seed=2, noise=True)


def test_recovers_roll_pitch_yaw_within_a_tenth_of_a_degree(loop):
    cal = calibrate_sequence(rotated_gt(loop), bootstrap=50)
    assert cal.angles_deg["roll"] == pytest.approx(ROLL, abs=0.1)
    assert cal.angles_deg["pitch"] == pytest.approx(PITCH, abs=0.1)
    assert cal.angles_deg["yaw"] == pytest.approx(YAW, abs=0.1)
    # a car drives forward: roll is not seen by velocity, the road plane supplies it
    assert cal.source == {"roll": "road plane", "pitch": "velocity", "yaw": "velocity"}
    assert all(0 < s < 0.1 for s in cal.std_deg.values())
    assert cal.road["height_m"] == pytest.approx(0.7, abs=0.15)  # the mount height


def test_without_a_road_roll_is_reported_not_observable(loop):
    scans = [s.select(s.points[:, 2] > -0.2) for s in loop]  # nothing below the sensor
    bare = MemorySequence("no-road", loop.sensor, scans, loop.ground_truth)
    cal = calibrate_sequence(rotated_gt(bare, roll=0.0), bootstrap=20)
    assert cal.not_observable == ["roll"]
    # without the ground returns the elevation spread is small and the elevation-angle noise
    # biases the vertical velocity (errors in variables): measured 0.14 deg in pitch
    assert cal.angles_deg["pitch"] == pytest.approx(PITCH, abs=0.2)
    assert cal.angles_deg["yaw"] == pytest.approx(YAW, abs=0.1)


def test_inspect_check_and_corrected_store(loop, tmp_path):
    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(25)],
                           loop.ground_truth, {})
    _, warning = rotation_check(rotated_gt(short))
    assert warning is not None and "pitch" in warning
    assert rotation_check(short)[1] is None  # a correct GT frame raises no warning
    src = write_store(rotated_gt(short), tmp_path / "rot.h5")
    # every angle applied (25 frames can leave roll's interval wider than the default bound:
    # test_write_applies_only_the_angles_narrower_than_the_bound)
    cal = calibrate_store(src, tmp_path / "fixed.h5", bootstrap=10, frames=25, hand_eye=False,
                          max_width_deg=90.0)
    fixed = StoreSequence(tmp_path / "fixed.h5")
    # the corrected GT is the sensor's own: calibrating it again finds (almost) nothing
    again = calibrate_sequence(fixed, bootstrap=10)
    assert again.total_deg < 0.1 < cal.total_deg
    np.testing.assert_allclose(fixed[3].points, short[3].points)  # points untouched
    assert fixed.provenance["calibration"]["frames"] == [0, 25]


def test_bench_inspect_warns_and_plots_the_doppler_speed(loop, tmp_path):
    from typer.testing import CliRunner

    from bench.cli import app

    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(25)],
                           loop.ground_truth, {})
    src = write_store(rotated_gt(short), tmp_path / "rot.h5")
    png = tmp_path / "speed.png"
    res = CliRunner().invoke(app, ["inspect", str(src), "--plot", str(png)])
    assert res.exit_code == 0, res.output
    assert "looks rotated" in res.output and "pitch" in res.output
    assert png.stat().st_size > 10_000
    ok = write_store(short, tmp_path / "ok.h5")
    res = CliRunner().invoke(app, ["inspect", str(ok), "--plot", "-"])
    assert res.exit_code == 0 and "consistent within 0.5 deg" in res.output


def test_inspect_calls_consistent_only_the_angles_known_that_well():
    from bench.data.calibration.estimate import CalibrationResult, rotation_consistent_text

    def cal(sd, source):
        return CalibrationResult(np.eye(3), {"roll": 0.1, "pitch": -0.2, "yaw": 0.05},
                                 dict(zip(("roll", "pitch", "yaw"), sd, strict=True)),
                                 dict(zip(("roll", "pitch", "yaw"), source, strict=True)), 100)

    tight = rotation_consistent_text(cal((0.1, 0.1, 0.1), ["velocity"] * 3))
    assert "roll, pitch, yaw consistent within 0.5 deg" in tight and "loosely" not in tight
    # pitch at sd 0.2 (3 sd = 0.6 > 0.5): named as loosely known, not as consistent
    loose = rotation_consistent_text(cal((0.1, 0.2, 0.1), ["velocity"] * 3))
    assert "roll, yaw consistent within 0.5 deg" in loose
    assert "known only loosely, none found off: pitch +-0.20 deg" in loose
    unseen = rotation_consistent_text(cal((float("nan"), 2.0, 2.0),
                                          ["not observable", "velocity", "velocity"]))
    assert "no angle fixed to 0.5 deg" in unseen and "not observable: roll" in unseen


def test_hand_eye_alignment_recovers_the_rotation_without_doppler(loop):
    """KISS-ICP's trajectory (no Doppler) against the GT over the same frames: roll and pitch
    from the turn axes, yaw from the displacement directions, each within its stated (block
    bootstrap) uncertainty of the truth."""
    from bench.data.calibration.hand_eye import hand_eye_on

    seq = MemorySequence("loop", loop.sensor, list(loop), loop.ground_truth)
    he = hand_eye_on(rotated_gt(seq), bootstrap=30)
    assert he.source == {"roll": "turn axes", "pitch": "turn axes",
                         "yaw": "displacement directions"}
    for ax, truth in (("roll", ROLL), ("pitch", PITCH), ("yaw", YAW)):
        assert abs(he.angles_deg[ax] - truth) <= 3 * he.std_deg[ax] + 0.05, (ax, he)
        # a gross error (a sign, a swapped axis) is degrees; the turn-axes pitch of this
        # 150-frame loop scatters by about 0.4 deg from seed to seed (seeds 2-4: +0.03, +0.12,
        # -0.45 deg with the old field-of-view cut, -0.37, +0.49, -0.43 with the edge band)
        assert abs(he.angles_deg[ax] - truth) < 0.6, (ax, he.angles_deg)
    assert all(0 < s < 0.3 for s in he.std_deg.values())


def test_hand_eye_ignores_a_drifting_odometry_and_its_spread_covers_it():
    """An odometry that climbs slowly (a vertical translation drift, as on a near-planar
    drive) tilts every displacement direction; the turn axes are untouched, so pitch stays
    right, and the two estimates' disagreement is reported, not hidden."""
    from bench.data.calibration.hand_eye import hand_eye_rotation
    from loaders.se3 import exp_se3

    rng = np.random.default_rng(0)
    period, n = 0.1, 600
    twists = [np.array([10.0, 0, 0, 0, 0, 0.3 * np.sin(k / 40)]) for k in range(n)]
    gt = [np.eye(4)]
    for xi in twists[1:]:
        gt.append(gt[-1] @ exp_se3(xi * period))
    gt = np.array(gt)
    R = Rotation.from_euler("ZYX", [YAW, PITCH, ROLL], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3] = R
    est = np.linalg.inv(T) @ gt @ T  # the odometry in the sensor frame: exact, then ...
    drift = np.eye(4)
    for k in range(n):  # ... climbing 3 cm a metre and a little noise in rotation
        drift = drift @ exp_se3(np.r_[0, 0, 0.03, rng.normal(0, 2e-4, 3)])
        est[k] = est[k] @ drift if k else est[k]
    he = hand_eye_rotation(gt, est, period, bootstrap=50)
    assert he.source["pitch"] == "turn axes" and he.source["roll"] == "turn axes"
    assert he.angles_deg["pitch"] == pytest.approx(PITCH, abs=0.3)
    assert abs(he.angles_deg["pitch"] - PITCH) <= 3 * he.std_deg["pitch"] + 0.05


def test_calibrate_says_when_the_estimates_disagree():
    """Apart beyond the combined half-widths of the stated intervals, sqrt(0.2^2 + 0.1^2) =
    0.224 deg: 0.25 deg apart disagrees, 0.2 deg does not."""
    from types import SimpleNamespace

    from bench.data.calibration.calibrate import disagreements
    from bench.data.calibration.hand_eye import HandEyeResult

    angles = {"roll": 0.0, "pitch": -1.7, "yaw": 0.0}
    cal = SimpleNamespace(angles_deg=angles, not_observable=[],
                          interval_deg={a: (v - 0.2, v + 0.2) for a, v in angles.items()})
    he_angles = {**angles, "pitch": -1.95}
    he = HandEyeResult(np.eye(3), he_angles, dict.fromkeys(angles, 0.05),
                       dict.fromkeys(angles, True), 40, "kiss-icp",
                       interval_deg={a: (v - 0.1, v + 0.1) for a, v in he_angles.items()})
    assert [d.split()[0] for d in disagreements(he, cal)] == ["pitch"]
    he.angles_deg["pitch"] = -1.9  # 0.2 apart: within 0.224
    he.interval_deg["pitch"] = (-2.0, -1.8)
    assert disagreements(he, cal) == []
    he.observable["pitch"] = False  # an angle one estimate does not observe is not compared
    he.angles_deg["pitch"] = -5.0
    assert disagreements(he, cal) == []


def test_hand_eye_recovers_a_large_mount_rotation_exactly():
    """An exact odometry (the GT seen from a sensor mounted at roll 5, pitch -7, yaw 4 deg):
    the turn axes fix roll and pitch, then the displacements - moved by that first rotation -
    fix yaw; exact to 1e-6 deg. Moving the displacements by the transpose instead leaves yaw
    0.5 deg off, which the small rotations of the other tests hid."""
    from bench.data.calibration.hand_eye import hand_eye_rotation
    from loaders.se3 import exp_se3

    period, n = 0.1, 300
    gt = [np.eye(4)]
    for k in range(1, n):
        xi = np.array([8.0, 0, 0.4 * np.sin(k / 17), 0, 0, 0.35 * np.sin(k / 30)])
        gt.append(gt[-1] @ exp_se3(xi * period))
    gt = np.array(gt)
    truth = {"roll": 5.0, "pitch": -7.0, "yaw": 4.0}
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("ZYX", [truth["yaw"], truth["pitch"], truth["roll"]],
                                    degrees=True).as_matrix()
    est = np.linalg.inv(T) @ gt @ T  # the sensor's own trajectory, in its own frame
    he = hand_eye_rotation(gt, est, period, bootstrap=10, block_s=2.0)
    assert he.source == {"roll": "turn axes", "pitch": "turn axes",
                         "yaw": "displacement directions"}
    for ax, value in truth.items():
        assert he.angles_deg[ax] == pytest.approx(value, abs=1e-6), (ax, he.angles_deg)
    # the block asked for (2 s = 20 frames, or longer for correlated residuals) is used
    assert 20 <= he.block.frames <= n // 2 and he.frames_total == n


def test_calibrated_store_scores_only_the_frames_not_used(loop, tmp_path):
    """bench calibrate on a declared range writes it into the store; a run on the corrected
    store registers every frame, scores only the others and its table names the store so."""
    from typer.testing import CliRunner

    from bench.api import run_method
    from bench.cli import app

    src = write_store(rotated_gt(loop), tmp_path / "rot.h5")
    res = CliRunner().invoke(app, ["calibrate", str(src), "--start", "0", "--frames", "75",
                                   "--bootstrap", "20", "--write", str(tmp_path / "fixed.h5")])
    assert res.exit_code == 0, res.output
    assert "frames 0-74 of 150" in res.output
    # both estimates, and their difference, are printed
    assert "Doppler ego velocity" in res.output and "hand-eye alignment of kiss-icp" in res.output
    assert "difference to Doppler" in res.output
    fixed = StoreSequence(tmp_path / "fixed.h5")
    assert fixed.provenance["calibration"]["frames"] == [0, 75]
    assert len(fixed.provenance["calibration"]["hand_eye_rpy_deg"]) == 3
    metrics = run_method("doppler", tmp_path / "fixed.h5", out=tmp_path / "run")
    assert metrics.frames == 150 and metrics.frames_scored == 75
    import yaml

    config = yaml.safe_load((tmp_path / "run" / "config.yaml").read_text())
    assert "GT calibrated on frames 0-74, not scored" in config["sequence"]["display_name"]


def test_calibration_frames_are_excluded_by_index_whatever_the_gt_rate(loop, tmp_path):
    """GT at its own rate (not at the scan stamps) must not let the calibration frames back
    into the score: exclusion is by frame index."""
    from bench.api import run_method
    from loaders.trajectory import Trajectory

    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(60)], None, {})
    gt = loop.ground_truth
    # GT resampled half-way between the scans: no GT stamp equals a scan stamp
    mid = (gt.stamps[:-1] + gt.stamps[1:]) / 2
    poses = np.array([gt.poses[i] for i in range(len(mid))])
    short.ground_truth = Trajectory(mid, poses)
    fixed = CorrectedSequence(short, np.eye(3), (0, 20), {})
    store = write_store(fixed, tmp_path / "fixed.h5")
    metrics = run_method("icp-p2p", store, out=tmp_path / "run")
    assert metrics.frames == 60
    assert metrics.frames_scored <= 40  # frames 0-19 never scored


def test_a_method_consuming_the_gt_fitted_extrinsic_is_marked(loop, tmp_path):
    """dicp takes the store's extrinsic, which bench calibrate corrected with a rotation fitted
    to the GT: its row says so; a method that does not use the extrinsic is not marked, and a
    dicp run given its own extrinsic is not either."""
    from bench.api import run_method
    from bench.report.tables.paper import select
    from bench.runs.job import GT_EXTRINSIC_MARK

    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(40)], loop.ground_truth,
                           {})
    store = write_store(CorrectedSequence(short, np.eye(3), (0, 10), {}), tmp_path / "c.h5")
    out = tmp_path / "results"
    run_method("dicp", store, out=out / "s" / "dicp_seed")
    run_method("icp-p2p", store, out=out / "s" / "icp-p2p_seed")
    run_method("dicp", store, params={"T_vehicle_sensor": np.eye(4).tolist()},
               out=out / "s" / "own_seed")
    labels = sorted(r.label for r in select(out)[0])
    assert sum(GT_EXTRINSIC_MARK in label for label in labels) == 1, labels
    assert any("DICP " + GT_EXTRINSIC_MARK in label for label in labels), labels


def test_calibrate_apply_writes_the_chosen_estimate(loop, tmp_path):
    """`bench calibrate --write --apply doppler` corrects the GT by the Doppler rotation (the
    one calibrate_sequence finds on the same frames), `--apply hand-eye` by the hand-eye one;
    the two differ here, so a swapped choice shows."""
    from typer.testing import CliRunner

    from bench.cli import app
    from loaders.scan import FrameRange

    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(60)], loop.ground_truth,
                           {})
    src = write_store(rotated_gt(short), tmp_path / "rot.h5")
    written = {}
    for choice in ("doppler", "hand-eye"):
        out = tmp_path / f"{choice}.h5"
        # a bound no interval reaches: every observed angle of the chosen estimate is applied
        res = CliRunner().invoke(app, ["calibrate", str(src), "--frames", "60", "--bootstrap",
                                       "10", "--apply", choice, "--write", str(out),
                                       "--max-width", "1000"])
        assert res.exit_code == 0, res.output
        assert f"corrected by the {choice} estimate" in res.output
        fixed = StoreSequence(out)
        written[choice] = np.array(fixed.provenance["calibration"]["R_gt_sensor"])
        details = fixed.provenance["calibration"]
        assert details["applied_estimate"] == choice
        # the GT written is the source GT turned by that rotation
        original = StoreSequence(src)
        T_fix = np.eye(4)
        T_fix[:3, :3] = written[choice]
        np.testing.assert_allclose(fixed.ground_truth.poses[7],
                                   original.ground_truth.poses[7] @ T_fix, atol=1e-9)
        original.close()
        fixed.close()
    seq = StoreSequence(src)
    doppler = calibrate_sequence(FrameRange(seq, 0, 60), bootstrap=10).R_gt_sensor
    seq.close()
    np.testing.assert_allclose(written["doppler"], doppler, atol=1e-9)
    apart = np.degrees(Rotation.from_matrix(written["hand-eye"] @ doppler.T).magnitude())
    assert apart > 0.01  # the two estimates are distinguishable here
    rpy = Rotation.from_matrix(written["hand-eye"]).as_euler("ZYX", degrees=True)[::-1]
    np.testing.assert_allclose(rpy, details["hand_eye_rpy_deg"], atol=1e-9)


class _Lines:
    """A console that keeps what bench calibrate prints."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def print(self, line, highlight=False) -> None:
        self.lines.append(str(line))

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


def _tilt_step(seq, step_deg: float):
    """``seq`` with its GT frame rotated by R_gt_sensor of roll / pitch / yaw ROLL, PITCH, YAW
    up to the middle of the drive and pitch ``step_deg`` more after it."""
    from loaders.trajectory import Trajectory

    gt = seq.ground_truth
    middle = 0.5 * (seq.stamps[0] + seq.stamps[-1])
    poses = gt.poses.copy()
    for k, t in enumerate(gt.stamps):
        pitch = PITCH + (step_deg if t > middle else 0.0)
        T = np.eye(4)
        T[:3, :3] = Rotation.from_euler("ZYX", [YAW, pitch, ROLL], degrees=True).as_matrix().T
        poses[k] = poses[k] @ T
    return MemorySequence("tilted", seq.sensor, list(seq), Trajectory(gt.stamps, poses), {})


def test_bench_calibrate_reports_a_tilt_that_changes_half_way(loop, tmp_path):
    """Known answer through `bench calibrate`: the GT frame's pitch 1 deg higher from the
    middle of the 150 frames on: the two pieces (frames 0-74, 75-149) disagree in pitch and
    their estimates are near 2 and 3 deg; the same drive with a constant tilt: they agree."""
    import re

    step = write_store(_tilt_step(loop, 1.0), tmp_path / "step.h5")
    out = _Lines()
    calibrate_store(step, console=out, frames=150, bootstrap=30, hand_eye=False)
    assert "THE ROTATION CHANGES ALONG THE RANGE" in out.text, out.text
    found = re.search(r"pitch ([-+.\d]+) \(frames 0-74\) vs ([-+.\d]+) \(frames 75-149\)",
                      out.text)
    assert found, out.text
    assert float(found[1]) == pytest.approx(PITCH, abs=0.15)
    assert float(found[2]) == pytest.approx(PITCH + 1.0, abs=0.15)
    same = write_store(_tilt_step(loop, 0.0), tmp_path / "same.h5")
    out = _Lines()
    calibrate_store(same, console=out, frames=150, bootstrap=30, hand_eye=False)
    assert "CHANGES" not in out.text and "the pieces agree" in out.text, out.text


def test_write_applies_only_the_angles_narrower_than_the_bound(loop, tmp_path):
    """With a bound in the widest gap between the intervals' widths, --write applies the
    narrower angles, leaves the wider at 0 and says so; the written GT is turned by exactly
    the applied angles. The CLI's default bound is the module's."""
    import inspect

    from bench.cli import calibrate as calibrate_command
    from bench.data.calibration.estimate import ANGLES, euler_matrix
    from bench.data.calibration.write import WRITE_MAX_WIDTH_DEG

    assert inspect.signature(calibrate_command).parameters["max_width"].default == \
        WRITE_MAX_WIDTH_DEG
    src = write_store(rotated_gt(MemorySequence("s", loop.sensor, [loop[i] for i in range(75)],
                                                loop.ground_truth, {})), tmp_path / "rot.h5")
    cal = calibrate_store(src, frames=75, bootstrap=20, hand_eye=False)
    width = {ax: hi - lo for ax, (lo, hi) in cal.interval_deg.items()}
    # the bound in the widest gap between the sorted widths: the angles above it are left
    order = sorted(ANGLES, key=width.get)
    k = max(range(1, 3), key=lambda i: width[order[i]] / width[order[i - 1]])
    assert width[order[k]] > 1.2 * width[order[k - 1]] > 0, width
    bound = 0.5 * (width[order[k]] + width[order[k - 1]])
    wide = [ax for ax in ANGLES if width[ax] > bound]
    out = _Lines()
    calibrate_store(src, tmp_path / "fixed.h5", out, frames=75, bootstrap=20, hand_eye=False,
                    max_width_deg=bound)
    assert f"narrower than {bound:g} deg" in out.text
    assert f"left alone (0 in the written rotation): {wide[0]} (interval" in out.text, out.text
    fixed = StoreSequence(tmp_path / "fixed.h5")
    prov = fixed.provenance["calibration"]
    assert prov["applied_rpy_deg"] == [0.0 if ax in wide else cal.angles_deg[ax]
                                       for ax in ANGLES]
    assert sorted(prov["left_alone"]) == sorted(wide)
    R = euler_matrix(np.radians(prov["applied_rpy_deg"]))
    np.testing.assert_allclose(prov["R_gt_sensor"], R, atol=1e-12)
    original = StoreSequence(src)
    np.testing.assert_allclose(fixed.ground_truth.poses[5][:3, :3],
                               original.ground_truth.poses[5][:3, :3] @ R, atol=1e-9)
    original.close()
    fixed.close()


def test_select_angles_at_the_bound():
    from bench.data.calibration.write import select_angles

    angles = {"roll": 1.0, "pitch": 2.0, "yaw": -1.5}
    fitted = {"roll": True, "pitch": True, "yaw": True}
    applied, left = select_angles(angles, {"roll": (0.0, 1.0), "pitch": (1.5, 2.49),
                                           "yaw": (-2.0, -1.0 + 1e-9)}, fitted, 1.0)
    assert applied == {"pitch": 2.0} and set(left) == {"roll", "yaw"}  # width 1.0 is not < 1.0
    applied, left = select_angles(angles, {"roll": (0.5, 1.5), "pitch": (np.nan, np.nan),
                                           "yaw": (-1.6, -1.4)}, {**fitted, "roll": False}, 1.0)
    assert applied == {"yaw": -1.5}
    assert left == {"roll": "not observable", "pitch": "no interval"}


def _bench(monkeypatch, capsys, *args) -> tuple[int, str]:
    from bench.cli import main

    monkeypatch.setattr("sys.argv", ["bench", *map(str, args)])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    return exit_.value.code, " ".join((out.out + out.err).split())


def test_calibrate_never_writes_onto_its_input(loop, tmp_path, monkeypatch, capsys):
    """`--write` onto the input store (by any spelling) is refused with and without --force;
    an existing store bench calibrate wrote is replaced only with --force; another file never."""
    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(30)], loop.ground_truth,
                           {})
    src = write_store(rotated_gt(short), tmp_path / "S.h5")
    before = src.read_bytes()
    alias = tmp_path / "sub" / ".." / "S.h5"
    (tmp_path / "sub").mkdir()
    for target, force in ((src, []), (alias, ["--force"])):
        code, text = _bench(monkeypatch, capsys, "calibrate", src, "--frames", 30,
                            "--bootstrap", 10, "--write", target, *force)
        assert code == 2 and "never writes onto its own input" in text, text
        assert "Traceback" not in text
    assert src.read_bytes() == before
    made = tmp_path / "made.h5"
    calibrate_store(src, made, frames=30, bootstrap=10, hand_eye=False)
    code, text = _bench(monkeypatch, capsys, "calibrate", src, "--frames", 30, "--bootstrap",
                        10, "--write", made)
    assert code == 2 and "exists" in text and "--force" in text, text
    calibrate_store(src, made, frames=30, bootstrap=10, hand_eye=False, force=True)
    other = tmp_path / "notes.txt"
    other.write_text("mine")
    code, text = _bench(monkeypatch, capsys, "calibrate", src, "--frames", 30, "--bootstrap",
                        10, "--write", other, "--force")
    assert code == 2 and "not a store bench calibrate wrote" in text, text
    assert other.read_text() == "mine"


def test_calibrate_says_no_scan_has_ground_truth(loop, tmp_path, monkeypatch, capsys):
    """GT 1000 s off the scans: the store is named and the message says no scan has ground
    truth (not "only 0 frames faster than 2.0 m/s"), exit 2, no traceback."""
    from loaders.trajectory import Trajectory

    gt = loop.ground_truth
    short = MemorySequence("s", loop.sensor, [loop[i] for i in range(30)],
                           Trajectory(gt.stamps + 1000.0, gt.poses), {})
    src = write_store(short, tmp_path / "late.h5")
    code, text = _bench(monkeypatch, capsys, "calibrate", src, "--frames", 30)
    assert code == 2, text
    assert f"{src}: no scan of frames 0-29 has ground truth" in text
    assert "1000.000" in text and "faster than" not in text and "Traceback" not in text


@pytest.mark.parametrize("width", [0.0, -1.0, float("nan"), float("inf")])
def test_max_width_must_be_a_positive_number(width, tmp_path):
    from loaders.errors import DataError

    with pytest.raises(DataError, match="--max-width"):
        calibrate_store(tmp_path / "any.h5", max_width_deg=width)


def test_hand_eye_prints_no_number_for_an_angle_it_does_not_observe():
    """An angle neither the turn axes nor the displacements fix was printed as "+0.000 deg
    95 % [+0.000, +0.000] sd 0.000": now its reason and no number; the others as before."""
    from types import SimpleNamespace

    from bench.data.calibration.calibrate import format_hand_eye
    from bench.data.calibration.hand_eye import HandEyeResult

    angles = {"roll": 0.0, "pitch": -1.7, "yaw": 0.2}
    he = HandEyeResult(np.eye(3), angles, {"roll": 0.0, "pitch": 0.1, "yaw": 0.05},
                       {"roll": False, "pitch": True, "yaw": True}, 40, "kiss-icp",
                       {"pitch": "turn axes", "yaw": "displacement directions"},
                       {"roll": (0.0, 0.0), "pitch": (-1.9, -1.5), "yaw": (0.1, 0.3)})
    cal = SimpleNamespace(angles_deg={"roll": 0.5, "pitch": -1.6, "yaw": 0.1},
                          not_observable=[], R_gt_sensor=np.eye(3),
                          interval_deg={a: (-9.0, 9.0) for a in angles})
    lines = format_hand_eye(he, cal)
    (roll,) = [line for line in lines if line.strip().startswith("roll")]
    assert roll.split() == ["roll", "not", "observable:", "neither", "the", "turn", "axes",
                            "nor", "the", "displacement", "directions", "spread", "around",
                            "it"]
    (pitch,) = [line for line in lines if line.strip().startswith("pitch")]
    assert "[-1.900, -1.500]" in pitch and "difference to Doppler -0.100 deg" in pitch
