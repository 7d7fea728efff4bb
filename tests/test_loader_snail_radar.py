"""Tests for loaders.snail_radar and loaders.pcd on the dataset's exact layouts (ROS1 bag with
the Eagle and ARS548 PointCloud2 layouts, extracted folders of binary / ascii PCD + times.txt,
a TUM file of T_world_xt32), written from frames whose truth is known."""

import pickle
import warnings

import numpy as np
import pytest

from helpers_bags import Motion, doppler_sign_cosine, make_truth, write_gt_tum, write_tum
from helpers_snail import (
    ARS548_FIELDS,
    EAGLE_FIELDS,
    radar_array,
    stamp_name,
    write_snail_bag,
    write_snail_folder,
)
from loaders.errors import DataError, GroundTruthWarning
from loaders.pcd import read_pcd, write_pcd
from loaders.se3 import inv_T
from loaders.snail_radar import (
    T_BODY_XT32,
    Options,
    SnailRadarSequence,
    body_T_ars548,
    body_T_oculii,
)

DATE = 20240123.0
T_XT32_EAGLE = inv_T(T_BODY_XT32) @ body_T_oculii()
T_XT32_ARS = inv_T(T_BODY_XT32) @ body_T_ars548(DATE)


def arrays(sensor, truth, seed=0):
    rng = np.random.default_rng(seed)
    return [(t, radar_array(sensor, p, d, rng))
            for t, p, d in zip(truth.stamps, truth.points, truth.doppler, strict=True)]


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A sequence 20240123/data3 as a bag and as an extracted folder, plus its GT file."""
    root = tmp_path_factory.mktemp("snail") / "20240123"
    root.mkdir()
    eagle = make_truth(Motion(T_body_sensor=T_XT32_EAGLE), frames=8, points=50, period=0.1)
    ars = make_truth(Motion(T_body_sensor=T_XT32_ARS), frames=10, points=30, period=0.05,
                     seed=1)
    pcl = make_truth(Motion(T_body_sensor=T_XT32_EAGLE), frames=6, points=20, period=0.1,
                     seed=2)
    frames = {"/radar_enhanced_pcl2": arrays("eagle", eagle), "/ars548": arrays("ars548", ars),
              "/radar_pcl2": arrays("eagle", pcl, 3)}
    bag = write_snail_bag(root / "data3.bag", frames)
    seq = root / "data3"
    write_snail_folder(seq / "eagleg7" / "enhanced", frames["/radar_enhanced_pcl2"])
    write_snail_folder(seq / "eagleg7" / "pcl", frames["/radar_pcl2"], data="ascii")
    write_snail_folder(seq / "ars548" / "points", frames["/ars548"])
    gt = root / "utm50r_T_xt32.txt"  # T_world_xt32 at 20 Hz around the scans
    write_gt_tum(gt, eagle.motion, eagle.stamps[0] - 0.5, eagle.stamps[-1] + 0.5, step=0.05)
    return {"bag": bag, "folder": seq, "gt": gt, "eagle": eagle, "ars": ars, "pcl": pcl,
            "frames": frames}


def check_scans(seq, truth, frames):
    assert len(seq) == len(truth.stamps)
    for i in range(len(seq)):
        s = seq.scan(i)
        np.testing.assert_array_equal(s.points.astype(np.float32), truth.points[i])
        np.testing.assert_array_equal(s.doppler.astype(np.float32), truth.doppler[i])
        assert s.stamp == pytest.approx(truth.stamps[i], abs=1e-6)
        arr = frames[i][1]
        names = arr.dtype.names
        assert set(s.fields) == {n.lower() for n in names[4:]}
        np.testing.assert_array_equal(s.fields[names[4].lower()], arr[names[4]])


@pytest.mark.parametrize("source", ["bag", "folder"])
def test_eagle_enhanced_points_doppler_and_gt_in_radar_frame(data, source):
    seq = SnailRadarSequence(data[source], gt=data["gt"])
    truth = data["eagle"]
    check_scans(seq, truth, data["frames"]["/radar_enhanced_pcl2"])
    assert set(seq.scan(0).fields) >= {"power", "range", "alpha", "beta", "doppleraccu"}
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, body_T_oculii(), atol=1e-12)
    np.testing.assert_allclose(seq.provenance["T_gtbody_radar"], T_XT32_EAGLE, atol=1e-12)
    assert seq.sensor.doppler_kind == "radial" and seq.sensor.model == "radar-semidense"
    assert seq.sensor.period_s == pytest.approx(0.1, abs=1e-6)
    assert doppler_sign_cosine(seq) > 0.99
    seq.close()


@pytest.mark.parametrize("source", ["bag", "folder"])
def test_ars548_padded_layout_and_date_extrinsic(data, source):
    seq = SnailRadarSequence(data[source], sensor="ars548", gt=data["gt"])
    truth = data["ars"]
    check_scans(seq, truth, data["frames"]["/ars548"])
    assert seq.date == DATE  # from the group folder 20240123
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, body_T_ars548(DATE), atol=1e-12)
    np.testing.assert_allclose(seq.provenance["T_gtbody_radar"], T_XT32_ARS, atol=1e-12)
    assert doppler_sign_cosine(seq) > 0.99
    flipped = SnailRadarSequence(data[source], sensor="ars548", gt=data["gt"], doppler_sign=-1)
    assert doppler_sign_cosine(flipped) < -0.99


def test_gt_at_its_own_rate_is_interpolated(tmp_path, data):
    """GT at 10 Hz, ARS548 scans at 20 Hz: scans on a GT row get it exactly, the others an
    SE(3) interpolation (a chord of the 8 m/s arc: millimetres off)."""
    truth = data["ars"]
    gt = tmp_path / "gt10.txt"
    write_gt_tum(gt, truth.motion, truth.stamps[0] - 0.5, truth.stamps[-1] + 0.5, step=0.1)
    seq = SnailRadarSequence(data["bag"], sensor="ars548", gt=gt)
    err = np.linalg.norm(seq.ground_truth.poses[:, :3, 3] - truth.sensor_poses()[:, :3, 3],
                         axis=1)
    assert np.all(err[0::2] < 1e-6) and np.all(err[1::2] > 1e-4) and np.all(err < 5e-3)


@pytest.mark.parametrize("source", ["bag", "folder"])
def test_eagle_pcl_stream(data, source):
    """/radar_pcl2 and eagleg7/pcl (the folder written as ascii PCD)."""
    seq = SnailRadarSequence(data[source], cloud="pcl")
    check_scans(seq, data["pcl"], data["frames"]["/radar_pcl2"])
    assert seq.ground_truth is None
    clone = pickle.loads(pickle.dumps(seq))  # sequences go to worker processes
    np.testing.assert_array_equal(clone.scan(3).doppler.astype(np.float32),
                                  data["pcl"].doppler[3])


def test_utm_gt_found_in_the_folder_and_origin_removed(tmp_path, data):
    """A reference trajectory in UTM (``utm50r_T_xt32.txt`` in the sequence folder) is found by
    name, and its first position is subtracted (relative motion unchanged)."""
    import shutil

    truth = data["eagle"]
    seq_dir = tmp_path / "20240123" / "data3"
    shutil.copytree(data["folder"] / "eagleg7", seq_dir / "eagleg7")
    utm = np.array([245821.138870949, 3380553.013607463, 20.123183885])
    t = truth.stamps[0] - 0.2 + 0.05 * np.arange(20)
    poses = truth.motion.body_pose(t)
    poses[:, :3, 3] += utm
    write_tum(seq_dir / "utm50r_T_xt32.txt", t, poses)
    seq = SnailRadarSequence(seq_dir)
    assert "found in the sequence folder" in seq.provenance["gt_file"]
    origin = poses[0, :3, 3]
    np.testing.assert_allclose(seq.provenance["gt_origin_removed"], origin)
    expected = truth.sensor_poses()
    expected[:, :3, 3] += utm - origin
    np.testing.assert_allclose(seq.ground_truth.poses, expected, atol=1e-6)
    kept = SnailRadarSequence(seq_dir, remove_gt_origin=False)
    np.testing.assert_allclose(kept.ground_truth.poses[:, :3, 3] - seq.ground_truth.poses[:, :3, 3],
                               np.broadcast_to(origin, (len(truth.stamps), 3)), atol=1e-6)
    write_tum(seq_dir / "tls_T_xt32.txt", t, poses)
    with pytest.raises(DataError, match="both tls_T_xt32.txt and utm50r_T_xt32.txt"):
        SnailRadarSequence(seq_dir)


def test_published_extrinsics():
    """The refined Eagle extrinsic (Body_T_Oculii.m default), not the hand-measured one; the
    ARS548 mounting changes with the date (Body_T_Ars548.m)."""
    refined, manual = body_T_oculii(), body_T_oculii("manual")
    np.testing.assert_allclose(manual[:3, :3], np.eye(3))
    np.testing.assert_allclose(refined[:3, 3], manual[:3, 3])
    angle = np.degrees(np.arccos((np.trace(refined[:3, :3].T @ manual[:3, :3]) - 1) / 2))
    assert 1.0 < angle < 3.0  # the ego-velocity calibration moved it by ~2 deg
    for T in (refined, body_T_ars548(20231105.0), body_T_ars548(20240116.0)):
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)
    # the morning of 2023-11-05 the ARS548 was tilted back ~14 deg, corrected that afternoon
    pitch = [np.degrees(np.arcsin(-body_T_ars548(d)[2, 0])) for d in (20231105.0, 20231105.5)]
    assert abs(pitch[0]) > 12 and abs(pitch[1]) < 3
    with pytest.raises(DataError, match="no ARS548"):
        body_T_ars548(20230921.0)


def test_ars548_without_date_needs_the_option(tmp_path, data):
    import shutil

    bag = tmp_path / "mybag.bag"
    shutil.copy(data["bag"], bag)
    with pytest.raises(DataError, match="date") as err:
        SnailRadarSequence(bag, sensor="ars548")
    assert str(bag) in str(err.value)
    seq = SnailRadarSequence(bag, sensor="ars548", date=DATE)
    np.testing.assert_allclose(seq.sensor.T_body_sensor, body_T_ars548(DATE), atol=1e-12)


def test_options_model_and_open(data):
    from loaders.registry import get_loader

    cls = get_loader("snail-radar").load_class()
    assert cls is SnailRadarSequence and cls.Options is Options and not cls.many_inputs
    seq = cls.open([data["folder"]], Options(sensor="ars548", name="x"))
    assert seq.name == "x" and len(seq) == len(data["ars"].stamps)
    with pytest.raises(Exception, match="extra"):
        Options(sensr="eagle")


def test_gt_gap_is_never_interpolated(tmp_path, data):
    """GT only at the start and the end (the TLS map covers those): scans in between have no
    pose and are not scored; with uncovered='error' the gap is an error naming the file."""
    truth = data["eagle"]
    m = truth.motion
    t0 = truth.stamps[0]  # scans at t0 + 0.0 ... 0.7; GT rows 0.1 apart with a 0.49 s gap
    t = np.concatenate([t0 + 0.005 + 0.1 * np.arange(-3, 3), t0 + 0.695 + 0.1 * np.arange(4)])
    gt = tmp_path / "tls_T_xt32.txt"
    write_tum(gt, t, m.body_pose(t))
    with pytest.warns(GroundTruthWarning, match="excluded from scoring"):
        seq = SnailRadarSequence(data["bag"], gt=gt, remove_gt_origin=False)
    assert len(seq) == len(truth.stamps)
    np.testing.assert_allclose(seq.ground_truth.stamps, truth.stamps[[0, 1, 2, 7]], atol=1e-6)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses()[[0, 1, 2, 7]],
                               atol=5e-3)
    assert seq.provenance["gt_association"]["uncovered_inside"] == 4
    with pytest.raises(DataError, match="not covered") as err:
        SnailRadarSequence(data["bag"], gt=gt, uncovered="error")
    assert str(gt) in str(err.value)


# -- bad inputs ----------------------------------------------------------------------------------

def one_frame(tmp_path, arr, data="binary"):
    folder = tmp_path / "20240123" / "data9" / "eagleg7" / "enhanced"
    write_snail_folder(folder, [(1706001762.5, arr)], data)
    return folder.parents[1], folder / f"{stamp_name(1706001762.5)}.pcd"


def eagle_frame(n=5):
    rng = np.random.default_rng(0)
    pts = rng.uniform(1, 20, (n, 3)).astype(np.float32)
    return radar_array("eagle", pts, rng.uniform(-3, 3, n).astype(np.float32), rng)


def test_pcd_round_trip_binary_and_ascii(tmp_path):
    arr = eagle_frame()
    for kind in ("binary", "ascii"):
        path = write_pcd(tmp_path / f"f_{kind}.pcd", arr, kind)
        back, names = read_pcd(path)
        assert names == EAGLE_FIELDS
        for n in names:
            np.testing.assert_array_equal(back[n], arr[n])


def test_pcd_truncated_is_not_whole_records(tmp_path):
    seq_dir, pcd = one_frame(tmp_path, eagle_frame())
    pcd.write_bytes(pcd.read_bytes()[:-3])
    with pytest.raises(DataError, match="not a whole number of 68-byte records") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_pcd_point_count_disagrees_with_bytes(tmp_path):
    seq_dir, pcd = one_frame(tmp_path, eagle_frame())
    pcd.write_bytes(pcd.read_bytes().replace(b"WIDTH 5\n", b"WIDTH 5000000000\n")
                    .replace(b"POINTS 5\n", b"POINTS 5000000000\n"))
    with pytest.raises(DataError, match="POINTS 5000000000 but the data hold 5 records") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_pcd_field_list_disagrees_with_sizes(tmp_path):
    seq_dir, pcd = one_frame(tmp_path, eagle_frame())
    pcd.write_bytes(pcd.read_bytes().replace(b"SIZE 4 4 4 ", b"SIZE 4 4 "))
    with pytest.raises(DataError, match="17 FIELDS .* but 16 SIZE") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_pcd_ascii_line_count(tmp_path):
    seq_dir, pcd = one_frame(tmp_path, eagle_frame(), "ascii")
    lines = pcd.read_bytes().splitlines(keepends=True)
    pcd.write_bytes(b"".join(lines[:-1]))
    with pytest.raises(DataError, match="POINTS 5 but the file has 4 data lines") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_pcd_binary_compressed_refused(tmp_path):
    seq_dir, pcd = one_frame(tmp_path, eagle_frame())
    pcd.write_bytes(pcd.read_bytes().replace(b"DATA binary", b"DATA binary_compressed"))
    with pytest.raises(DataError, match="binary_compressed is not supported") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_missing_doppler_field(tmp_path):
    arr = eagle_frame()
    names = [n for n in arr.dtype.names if n != "Doppler"]
    seq_dir, pcd = one_frame(tmp_path, arr[names].copy())
    with pytest.raises(DataError, match="no field.* Doppler") as err:
        SnailRadarSequence(seq_dir).scan(0)
    assert str(pcd) in str(err.value)


def test_missing_doppler_field_in_bag(tmp_path):
    rng = np.random.default_rng(0)
    pts = rng.uniform(1, 20, (4, 3)).astype(np.float32)
    arr = radar_array("ars548", pts, np.zeros(4, np.float32), rng)
    renamed = arr.copy()
    renamed.dtype.names = ["velocity" if n == "doppler" else n for n in ARS548_FIELDS]
    bag = write_snail_bag(tmp_path / "d.bag", {"/ars548": [(1706001762.5, renamed)]})
    with pytest.raises(DataError, match="no field.* doppler") as err:
        SnailRadarSequence(bag, sensor="ars548", date=DATE).scan(0)
    assert str(bag) in str(err.value) and "velocity" in str(err.value)


def test_half_extracted_folder(tmp_path, data):
    import shutil

    seq_dir = tmp_path / "20240123" / "data3"
    shutil.copytree(data["folder"], seq_dir)
    with pytest.raises(DataError, match="no eagleg7/enhanced/ folder") as err:
        shutil.rmtree(seq_dir / "eagleg7")
        SnailRadarSequence(seq_dir)
    assert str(seq_dir) in str(err.value) and "ars548" in str(err.value)
    folder = seq_dir / "ars548" / "points"
    victim = sorted(folder.glob("*.pcd"))[3]
    victim.unlink()
    with pytest.raises(DataError, match="1 of the 10 frames .* no .pcd file") as err:
        SnailRadarSequence(seq_dir, sensor="ars548")
    assert victim.name in str(err.value)


def test_gt_file_with_no_rows_and_no_overlap(tmp_path, data):
    empty = tmp_path / "gt.txt"
    empty.write_text("# t x y z qx qy qz qw\n")
    with pytest.raises(DataError, match="no TUM pose rows") as err:
        SnailRadarSequence(data["bag"], gt=empty)
    assert str(empty) in str(err.value)
    late = tmp_path / "late.txt"
    m = data["eagle"].motion
    t = data["eagle"].stamps[-1] + 100 + np.arange(5) * 0.1
    write_tum(late, t, m.body_pose(t))
    with pytest.raises(DataError, match="does not overlap") as err:
        SnailRadarSequence(data["bag"], gt=late)
    assert str(late) in str(err.value)


# -- store round trip and a Doppler run -----------------------------------------------------------

def test_store_round_trip_and_doppler_run_match_memory(tmp_path):
    """Synthetic semi-dense radar frames written in the Snail-Radar folder layout: the loader's
    store gives the frames, GT and the same `doppler` odometry as the frames in memory."""
    from loaders.scan import MemorySequence
    from loaders.store import StoreSequence, write_store
    from loaders.synthetic import SyntheticSequence
    from methods.registry import make_method

    syn = SyntheticSequence("loop", "radar-semidense", frames=6, seed=3, t0=1706001762.4)
    mem = MemorySequence(syn.name, syn.sensor, list(syn), syn.ground_truth)
    names = [stamp_name(t) for t in mem.stamps]
    stamps = np.array([float(n) for n in names])
    rng = np.random.default_rng(5)
    items = [(t, radar_array("eagle", s.points.astype(np.float32),
                             s.doppler.astype(np.float32), rng))
             for t, s in zip(stamps, mem, strict=True)]
    seq_dir = tmp_path / "20240123" / "data7"
    write_snail_folder(seq_dir / "eagleg7" / "enhanced", items)
    gt = tmp_path / "utm50r_T_xt32.txt"
    T_world_xt32 = mem.ground_truth.poses @ inv_T(T_XT32_EAGLE)
    write_tum(gt, stamps, T_world_xt32)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        loaded = SnailRadarSequence(seq_dir, gt=gt, remove_gt_origin=False)
    store = write_store(loaded, tmp_path / "snail.h5")
    stored = StoreSequence(store)
    assert len(stored) == len(mem)
    for a, b in zip(stored, mem, strict=True):
        np.testing.assert_allclose(a.points, b.points, atol=1e-5)
        np.testing.assert_allclose(a.doppler, b.doppler, atol=1e-6)
    np.testing.assert_allclose(stored.ground_truth.poses, mem.ground_truth.poses, atol=1e-6)
    assert stored.sensor.doppler_kind == "radial"

    def steps(method, seq):
        res = make_method(method, {}, seq.sensor).run(seq, seed=True)
        rel = inv_T(res.poses[:-1]) @ res.poses[1:]
        return np.linalg.norm(rel[:, :3, 3], axis=1)

    gt_steps = np.linalg.norm((inv_T(mem.ground_truth.poses[:-1])
                               @ mem.ground_truth.poses[1:])[:, :3, 3], axis=1)
    for method in ("doppler", "icp-p2plane"):
        d_mem = steps(method, mem)
        np.testing.assert_allclose(steps(method, stored), d_mem, rtol=0.02, err_msg=method)
        np.testing.assert_allclose(d_mem, gt_steps, rtol=0.2, err_msg=method)  # sensible runs
    stored.close()


# -- the reference trajectory in its CSV form (ref_trajs/<date>/<run>/ref_tls_T_xt32.csv) ------

CSV_HEADER = ("#time, M_p_L_x, M_p_L_y, M_p_L_z, M_q_L_x, M_q_L_y, M_q_L_z, M_q_L_w, W_v_L_x, "
              "W_v_L_y, W_v_L_z")


def write_ref_csv(path, motion, t_start, t_end, step=0.05, header=CSV_HEADER):
    """The authors' CSV form: one '#' header line, 11 comma-separated columns (the XT32 pose in
    the map and its world velocity)."""
    from loaders.se3 import tum_from_T

    t = np.arange(t_start, t_end + step / 2, step)
    xyz, q = tum_from_T(motion.body_pose(t))
    v = np.gradient(xyz, t, axis=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [",".join(f"{x:.9f}" for x in (ti, *p, *qq, *vv))
            for ti, p, qq, vv in zip(t, xyz, q, v, strict=True)]
    path.write_text(header + "\n" + "\n".join(rows) + "\n")
    return path


@pytest.fixture()
def released(tmp_path, data):
    """The release layout: root/20240123/data3.bag, root/20240123/data3/ (extracted) and
    root/ref_trajs/20240123/data3/ref_tls_T_xt32.csv; no TUM file anywhere."""
    import shutil

    root = tmp_path / "snail"
    day = root / "20240123"
    day.mkdir(parents=True)
    shutil.copy(data["bag"], day / "data3.bag")
    shutil.copytree(data["folder"], day / "data3")
    eagle = data["eagle"]
    csv = write_ref_csv(root / "ref_trajs" / "20240123" / "data3" / "ref_tls_T_xt32.csv",
                        eagle.motion, eagle.stamps[0] - 0.5, eagle.stamps[-1] + 0.5)
    return {"bag": day / "data3.bag", "folder": day / "data3", "csv": csv, "root": root}


@pytest.mark.parametrize("source", ["bag", "folder"])
def test_reference_csv_is_found_without_gt_and_matches_the_tum_form(released, data, source):
    seq = SnailRadarSequence(released[source], remove_gt_origin=False)
    assert seq.provenance["gt_file"].startswith(str(released["csv"]))
    assert "found in the reference trajectories" in seq.provenance["gt_file"]
    assert "W_v_L not used" in seq.provenance["gt_format"]
    truth = data["eagle"]
    np.testing.assert_allclose(seq.ground_truth.stamps, seq.stamps)
    np.testing.assert_allclose(seq.ground_truth.poses, truth.sensor_poses(), atol=1e-6)
    tum = SnailRadarSequence(released[source], gt=data["gt"], remove_gt_origin=False)
    np.testing.assert_allclose(seq.ground_truth.poses, tum.ground_truth.poses, atol=1e-6)
    # the ARS548 of the same sequence takes the same file, moved to its own frame
    ars = SnailRadarSequence(released[source], sensor="ars548", remove_gt_origin=False)
    np.testing.assert_allclose(ars.ground_truth.poses, data["ars"].sensor_poses(), atol=1e-6)
    # given explicitly (--gt), the CSV reads the same
    given = SnailRadarSequence(released[source], gt=released["csv"], remove_gt_origin=False)
    np.testing.assert_allclose(given.ground_truth.poses, seq.ground_truth.poses)
    # a sensor folder of the extracted sequence finds it too
    sub = SnailRadarSequence(released["folder"] / "eagleg7" / "enhanced",
                             remove_gt_origin=False)
    np.testing.assert_allclose(sub.ground_truth.poses, seq.ground_truth.poses)


def test_reference_csv_in_the_sequence_folder_and_the_preference_order(released, data):
    import shutil

    folder = released["folder"]
    shutil.copy(released["csv"], folder / "ref_tls_T_xt32.csv")
    seq = SnailRadarSequence(folder)
    assert seq.provenance["gt_file"] == (f"{folder / 'ref_tls_T_xt32.csv'} (found in the "
                                         "sequence folder)")
    shutil.copy(data["gt"], folder / "tls_T_xt32.txt")  # the TUM TLS file is preferred
    assert SnailRadarSequence(folder).provenance["gt_file"].startswith(
        str(folder / "tls_T_xt32.txt"))


def test_no_day_folder_finds_the_run_when_it_is_unique(tmp_path, data):
    import shutil

    root = tmp_path / "mine"
    root.mkdir()
    shutil.copy(data["bag"], root / "data3.bag")
    eagle = data["eagle"]
    csv = write_ref_csv(root / "ref_trajs" / "20240123" / "data3" / "ref_tls_T_xt32.csv",
                        eagle.motion, eagle.stamps[0] - 0.5, eagle.stamps[-1] + 0.5)
    assert SnailRadarSequence(root / "data3.bag", date=DATE).provenance["gt_file"].startswith(
        str(csv))
    write_ref_csv(root / "ref_trajs" / "20240124" / "data3" / "ref_tls_T_xt32.csv",
                  eagle.motion, eagle.stamps[0] - 0.5, eagle.stamps[-1] + 0.5)
    with pytest.raises(DataError, match="2 reference trajectories are named data3"):
        SnailRadarSequence(root / "data3.bag", date=DATE)


def test_reference_csv_errors_name_the_file_and_line(tmp_path, data):
    eagle = data["eagle"]
    bad = write_ref_csv(tmp_path / "a.csv", eagle.motion, eagle.stamps[0], eagle.stamps[-1],
                        header="#time, x, y, z, qx, qy, qz, qw, vx, vy, vz")
    with pytest.raises(DataError, match="a.csv: header columns time, x, y.*expected time, "
                                        "M_p_L_x"):
        SnailRadarSequence(data["bag"], gt=bad)
    csv = write_ref_csv(tmp_path / "b.csv", eagle.motion, eagle.stamps[0], eagle.stamps[-1])
    lines = csv.read_text().splitlines()
    cols = lines[3].split(",")
    cols[4:8] = ["0", "0", "0", "0"]
    lines[3] = ",".join(cols)
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"b.csv, line 4: quaternion .* norm 0"):
        SnailRadarSequence(data["bag"], gt=csv)
    lines[3] = ",".join(cols[:9])
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=r"b.csv, line 4: 9 values; expected 11"):
        SnailRadarSequence(data["bag"], gt=csv)
    # a header separated by spaces (not commas) names the same columns
    spaced = write_ref_csv(tmp_path / "c.csv", eagle.motion, eagle.stamps[0] - 0.5,
                           eagle.stamps[-1] + 0.5, header=CSV_HEADER.replace(",", ""))
    assert len(SnailRadarSequence(data["bag"], gt=spaced).ground_truth) == len(eagle.stamps)


def test_convert_without_gt_says_where_the_gt_came_from_or_warns(released, data, tmp_path,
                                                                  capsys, monkeypatch):
    """`bench convert snail-radar BAG` without --gt finds the CSV and says so; the store's GT
    is the TUM form's (what `bench run` scores against). A sequence with no GT anywhere
    converts with a warning that nothing will be scored."""
    from bench.cli import main
    from loaders.store import StoreSequence

    def bench(*args):
        monkeypatch.setattr("sys.argv", ["bench", *map(str, args)])
        with pytest.raises(SystemExit) as exit_:
            main()
        out = capsys.readouterr()
        return exit_.value.code, " ".join((out.out + out.err).split())

    code, out = bench("convert", "snail-radar", released["bag"], "--out", tmp_path / "a.h5")
    assert code == 0 and "warning" not in out, out
    assert (f"ground truth: {released['csv']} (found in the reference trajectories beside the "
            "sequence) (8 of 8 scans have a pose)") in out, out
    store = StoreSequence(tmp_path / "a.h5")
    tum = SnailRadarSequence(released["bag"], gt=data["gt"])
    assert len(store.ground_truth) == len(store) == 8
    rel = store.ground_truth.poses[:, :3, 3] - store.ground_truth.poses[:1, :3, 3]
    np.testing.assert_allclose(rel, tum.ground_truth.poses[:, :3, 3]
                               - tum.ground_truth.poses[:1, :3, 3], atol=1e-6)
    np.testing.assert_allclose(store.ground_truth.poses[:, :3, :3],
                               tum.ground_truth.poses[:, :3, :3], atol=1e-6)
    store.close()
    # no GT anywhere (the fixture's bag has its TUM file in the day folder, not searched)
    code, out = bench("convert", "snail-radar", data["bag"], "--out", tmp_path / "b.h5")
    assert code == 0 and "warning: 20240123_data3: no ground truth found" in out, out
    assert "scores none (give it with --gt)" in out


def test_default_names_carry_the_day_so_two_days_data3_differ(data, tmp_path):
    """Every Snail-Radar day has a data1, data2 ...: the default name is day_run for the bag,
    the extracted folder and a sensor folder inside it; a bag outside any day folder keeps its
    run name; another day's data3 gets another name."""
    import shutil

    from loaders.snail_radar import sequence_name

    assert sequence_name(data["bag"]) == "20240123_data3"
    assert sequence_name(data["folder"]) == "20240123_data3"
    assert sequence_name(data["folder"] / "eagleg7" / "enhanced") == "20240123_data3"
    other = tmp_path / "20231105_aft"
    other.mkdir()
    shutil.copy(data["bag"], other / "data3.bag")
    loose = tmp_path / "data3.bag"
    shutil.copy(data["bag"], loose)
    assert sequence_name(other / "data3.bag") == "20231105_aft_data3"
    assert sequence_name(loose) == "data3"
    seq = SnailRadarSequence(data["bag"], gt=data["gt"])
    assert seq.name == "20240123_data3"
