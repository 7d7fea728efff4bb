"""Tests for loaders.aeva (Doppler-ICP, Open3D demo and steam_icp Aeva folder layouts)."""

import numpy as np
import pytest

from helpers_bags import Motion, doppler_sign_cosine, make_truth, write_aeva_folder
from loaders.aeva import STEAM_T_VEHICLE_SENSOR, AevaSequence, detect_layout, sorted_frames
from loaders.errors import DataError
from loaders.posefile import parse_extrinsic
from loaders.se3 import make_T
from loaders.store import StoreSequence, write_store

CARLA_T = make_T(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]), [1.0, 0.2, 1.8])


def truth_for(layout, frames=6, points=50):
    T = parse_extrinsic(STEAM_T_VEHICLE_SENSOR) if layout == "steam" else CARLA_T
    return make_truth(Motion(T_body_sensor=T), frames=frames, points=points, period=0.1)


@pytest.mark.parametrize("layout", ["dicp", "open3d", "steam"])
def test_layouts_points_doppler_gt(tmp_path, layout):
    truth = truth_for(layout)
    root = write_aeva_folder(tmp_path / layout, truth, layout)
    assert detect_layout(root) == layout
    seq = AevaSequence(root)
    assert len(seq) == 6 and seq.sensor.kind == "lidar"
    for i in range(len(seq)):
        s = seq.scan(i)
        np.testing.assert_allclose(s.points, truth.points[i], rtol=0, atol=2e-6)
        np.testing.assert_allclose(s.doppler, truth.doppler[i], rtol=0, atol=2e-7)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, truth.motion.T_body_sensor, atol=1e-9)
    assert seq.sensor.period_s == pytest.approx(0.1, abs=1e-6)
    assert doppler_sign_cosine(seq) > 0.99
    assert doppler_sign_cosine(AevaSequence(root, doppler_sign=-1)) < -0.99
    if layout == "steam":
        t = seq.scan(0).fields["time_offset_s"]
        assert t[0] == 0.0 and t[-1] == pytest.approx(0.099, abs=1e-6)
        np.testing.assert_allclose(seq.stamps, truth.stamps, atol=1e-6)
        assert "(us)" in seq.provenance["stamp_source"]
    else:
        np.testing.assert_allclose(seq.stamps, 0.1 * np.arange(6))
        assert seq.scan(0).fields == {}


def test_frames_sorted_numerically_and_stamps_from_period(tmp_path):
    truth = truth_for("dicp", frames=12, points=10)
    root = write_aeva_folder(tmp_path / "d", truth, "dicp")
    for p in (root / "point_clouds").iterdir():
        p.rename(p.with_name(f"{int(p.stem)}.bin"))  # 1.bin .. 12.bin: lexicographic != numeric
    assert [p.stem for p in sorted_frames(root / "point_clouds", ".bin")][:3] == ["1", "2", "3"]
    (root / "ref_poses.txt").unlink()
    seq = AevaSequence(root, period_s=0.05)
    assert seq.ground_truth is None and seq.provenance["stamp_source"] == "index x period"
    np.testing.assert_allclose(seq.stamps, 0.05 * np.arange(12))
    np.testing.assert_array_equal(seq.scan(10).points.astype(np.float32), truth.points[10])


def test_time_association_when_gt_rows_differ(tmp_path):
    truth = truth_for("open3d", frames=6)
    root = write_aeva_folder(tmp_path / "o", truth, "open3d")
    from helpers_bags import write_tum

    t = np.arange(-0.2, 0.81, 0.05)
    write_tum(root / "ground_truth_poses.txt", t, truth.motion.body_pose(truth.stamps[0] + t))
    seq = AevaSequence(root)
    assert seq.provenance["gt_association"]["mode"] == "interpolate"
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)


def test_errors(tmp_path):
    with pytest.raises(DataError, match="not found"):
        AevaSequence(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match=r"point_clouds/\*\.bin"):
        AevaSequence(tmp_path / "empty")
    truth = truth_for("dicp", frames=3, points=5)
    root = write_aeva_folder(tmp_path / "d", truth, "dicp")
    (root / "point_clouds" / "00002.bin").write_bytes(b"\0" * 20)
    (root / "point_clouds" / "00003.bin").write_bytes(b"")
    seq = AevaSequence(root)
    with pytest.raises(DataError, match=r"00002\.bin, frame 1: 20 bytes.*multiple of 16"):
        seq.scan(1)
    with pytest.raises(DataError, match=r"00003\.bin, frame 2: empty scan"):
        seq.scan(2)
    steam = write_aeva_folder(tmp_path / "s", truth_for("steam", frames=3), "steam")
    (steam / "timestamps.txt").write_text("1\n2\n")
    with pytest.raises(DataError, match="2 stamps for 3 frames"):
        AevaSequence(steam)


def test_nan_points_dropped_with_warning(tmp_path):
    truth = truth_for("dicp", frames=3, points=5)
    root = write_aeva_folder(tmp_path / "d", truth, "dicp")
    f = root / "point_clouds" / "00001.bin"
    data = np.fromfile(f, dtype="<f4").reshape(-1, 4)
    data[2, 3] = np.nan
    data.tofile(f)
    seq = AevaSequence(root)
    with pytest.warns(UserWarning, match="dropped 1 of 5"):
        assert len(seq.scan(0)) == 4
    assert seq.provenance["nan_points_dropped"] == 1


def test_store_round_trip(tmp_path):
    truth = truth_for("steam", frames=3)
    seq = AevaSequence(write_aeva_folder(tmp_path / "s", truth, "steam"))
    st = StoreSequence(write_store(seq, tmp_path / "Tunnel_Empty.h5"))
    np.testing.assert_array_equal(st.scan(2).fields["time_offset_s"],
                                  seq.scan(2).fields["time_offset_s"])
    np.testing.assert_allclose(st.ground_truth.poses, seq.ground_truth.poses)
    st.close()


def test_convert_commands(tmp_path):
    """The generated `bench convert LOADER` commands (built from each loader's Options model)
    keep the options of the hand-written commands they replaced."""
    from typer.testing import CliRunner

    from bench.cli import app
    from helpers_bags import write_campus_bag, write_gt_tum, write_ntu_bag

    runner = CliRunner()
    truth = truth_for("dicp", frames=6, points=20)
    root = write_aeva_folder(tmp_path / "d", truth, "dicp")
    r = runner.invoke(app, ["convert", "aeva", str(root), "--out", str(tmp_path / "a.h5"),
                            "--start", "1", "--stride", "2"])
    assert r.exit_code == 0, r.output
    st = StoreSequence(tmp_path / "a.h5")
    assert len(st) == 3 and st.sensor.period_s == pytest.approx(0.2)
    np.testing.assert_array_equal(st.scan(1).points, truth.points[3])
    st.close()
    r = runner.invoke(app, ["convert", "aeva", str(root), "--no-gt", "--out",
                            str(tmp_path / "nogt.h5")])
    assert r.exit_code == 0, r.output
    st = StoreSequence(tmp_path / "nogt.h5")
    assert st.ground_truth is None and len(st) == 6
    st.close()
    bag = write_ntu_bag(tmp_path / "n.bag", truth)
    gt = tmp_path / "gt.txt"
    write_gt_tum(gt, truth.motion, truth.stamps[0] - 0.2, truth.stamps[-1] + 0.2)
    r = runner.invoke(app, ["convert", "ntu4dradlm", str(bag), "--gt", str(gt), "--extrinsic",
                            "1 0.2 1.8 0 0 0.7071067811865476 0.7071067811865476",
                            "--time-offset", "0", "--max-gap", "0.5",
                            "--frames", "4", "--out", str(tmp_path / "n.h5")])
    assert r.exit_code == 0, r.output
    st = StoreSequence(tmp_path / "n.h5")
    assert len(st) == 4
    np.testing.assert_allclose(st.ground_truth.poses, truth.sensor_poses()[:4], atol=1e-5)
    st.close()
    cbag, _ = write_campus_bag(tmp_path / "c.bag", truth)
    r = runner.invoke(app, ["convert", "campus", str(cbag), "--elevation-sign", "-1",
                            "--keep-utm", "--out", str(tmp_path / "c.h5")])
    assert r.exit_code == 0, r.output
    st = StoreSequence(tmp_path / "c.h5")
    assert st.provenance["elevation_sign"] == -1.0
    assert "gt_origin_removed" not in st.provenance  # --keep-utm
    st.close()
    r = runner.invoke(app, ["convert", "campus", str(cbag), "--gt-topic", "/nope", "--out",
                            str(tmp_path / "x.h5")])
    assert isinstance(r.exception, DataError) and "/ground_truth" in str(r.exception)
    # a value the Options model refuses: one message naming the flag
    r = runner.invoke(app, ["convert", "campus", str(cbag), "--doppler-sign", "2", "--out",
                            str(tmp_path / "y.h5")])
    assert isinstance(r.exception, DataError) and "--doppler-sign" in str(r.exception)
    assert not (tmp_path / "y.h5").exists()

@pytest.mark.parametrize("layout", ["dicp", "open3d", "steam"])
def test_radar_bins_in_an_aeva_layout(tmp_path, layout):
    """Radar frames written in an Aeva layout were silently stored as LiDAR with 0.1 s: a
    LiDAR with radar-sized frames is warned about (naming --kind and --period); kind='radar'
    stores radar with the period given."""
    truth = truth_for(layout, frames=4, points=300)
    root = write_aeva_folder(tmp_path / layout, truth, layout)
    with pytest.warns(UserWarning, match=r"median of 300 points.*--kind radar.*--period"):
        seq = AevaSequence(root)
    assert seq.sensor.kind == "lidar" and seq.provenance["median_points_per_frame"] == 300
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no radar-like warning when the kind is said
        radar = AevaSequence(root, kind="radar", period_s=0.0833)
    assert radar.sensor.kind == "radar" and radar.provenance["sensor_kind"] == "radar"
    np.testing.assert_allclose(radar.scan(1).points, truth.points[1], atol=2e-6)
    if layout != "steam":  # without stamps of their own, the frames take the period given
        no_gt = AevaSequence(root, kind="radar", period_s=0.0833, gt=False)
        assert no_gt.sensor.period_s == pytest.approx(0.0833)
        np.testing.assert_allclose(no_gt.stamps, np.arange(4) * 0.0833)


def test_dense_lidar_frames_are_not_warned_about(tmp_path):
    truth = truth_for("dicp", frames=2, points=12_000)
    root = write_aeva_folder(tmp_path / "d", truth, "dicp")
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        seq = AevaSequence(root)
    assert seq.sensor.kind == "lidar"
