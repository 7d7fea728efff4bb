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
    """KISS-ICP's trajectory (no Doppler) against the GT over the same frames: the same
    rotation as the Doppler estimate, within a tenth of a degree on this drive."""
    from bench.data.hand_eye import hand_eye_on

    seq = MemorySequence("loop", loop.sensor, list(loop), loop.ground_truth)
    he = hand_eye_on(rotated_gt(seq), bootstrap=30)
    assert all(he.observable.values())  # displacements fix pitch and yaw, the turns roll
    for ax, truth in (("roll", ROLL), ("pitch", PITCH), ("yaw", YAW)):
        assert he.angles_deg[ax] == pytest.approx(truth, abs=0.15), (ax, he.angles_deg)
    assert all(0 < s < 0.15 for s in he.std_deg.values())


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
