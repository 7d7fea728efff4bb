"""bench calibrate: recovers a known sensor-to-GT rotation and says what it could not see."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibrate import calibrate_store
from bench.data.calibration import CorrectedSequence, calibrate_sequence, rotation_check
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
    cal = calibrate_store(src, tmp_path / "fixed.h5", bootstrap=10, frames=25, hand_eye=False)
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


def test_hand_eye_alignment_recovers_the_rotation_without_doppler(loop):
    """KISS-ICP's trajectory (no Doppler) against the GT over the same frames: roll and pitch
    from the turn axes, yaw from the displacement directions, each within its stated (block
    bootstrap) uncertainty of the truth."""
    from bench.data.hand_eye import hand_eye_on

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
    from bench.data.hand_eye import hand_eye_rotation
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

    from bench.data.calibrate import disagreements
    from bench.data.hand_eye import HandEyeResult

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
    from bench.data.hand_eye import hand_eye_rotation
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
    from bench.report.tables import select
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
        res = CliRunner().invoke(app, ["calibrate", str(src), "--frames", "60", "--bootstrap",
                                       "10", "--apply", choice, "--write", str(out)])
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
    np.testing.assert_allclose(written["doppler"], doppler, atol=1e-12)
    apart = np.degrees(Rotation.from_matrix(written["hand-eye"] @ doppler.T).magnitude())
    assert apart > 0.01  # the two estimates are distinguishable here
    rpy = Rotation.from_matrix(written["hand-eye"]).as_euler("ZYX", degrees=True)[::-1]
    np.testing.assert_allclose(rpy, details["hand_eye_rpy_deg"], atol=1e-9)
