"""loaders.estimate and loaders.estimate_boreas at unit level: TUM [+ time_ms], KITTI + stamps
file and Boreas rows read into the poses their formats define (cross-checked against scipy /
numpy), stamp units, and every bad input one DataError naming the file, the row and what was
expected. (Bags: tests/test_estimate.py.)"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.estimate import (
    DEFAULT_UNITS,
    STAMP_UNITS,
    check_index_column,
    check_stamps,
    detect_format,
    is_bag,
    poses_from_tum,
    read_estimate,
    read_kitti_estimate,
    read_stamps,
    read_tum_estimate,
)
from loaders.estimate_boreas import read_boreas

ROT = Rotation.from_euler("zyx", [[0.1, 0.2, -0.3], [0.5, -0.1, 0.2], [-1.0, 0.3, 0.05]])
XYZ = np.array([[1.0, 2.0, 3.0], [-4.0, 0.5, 0.25], [7.0, -8.0, 9.5]])
STAMPS = np.array([10.0, 10.5, 11.25])


def poses(rot=ROT, xyz=XYZ) -> np.ndarray:
    T = np.tile(np.eye(4), (len(xyz), 1, 1))
    T[:, :3, :3] = rot.as_matrix()
    T[:, :3, 3] = xyz
    return T


def fmt(values) -> str:
    return " ".join(f"{v:.17g}" for v in values)


def tum_rows(stamps=STAMPS, quat=None, times=None) -> list[str]:
    quat = ROT.as_quat() if quat is None else quat
    return [fmt([t, *p, *q] + ([] if times is None else [times[k]]))
            for k, (t, p, q) in enumerate(zip(stamps, XYZ, quat, strict=True))]


def write(tmp_path, lines, name="est.txt"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def error(call, path, *words) -> str:
    with pytest.raises(DataError) as err:
        call()
    msg = str(err.value)
    assert msg.startswith(str(path)), msg
    for w in words:
        assert w in msg, (w, msg)
    return msg


# -- stamps ---------------------------------------------------------------------------------


def test_check_stamps_names_the_first_bad_row():
    check_stamps(np.array([1.0, 2.0, 2.5]), "f")
    error(lambda: check_stamps(np.array([1.0, np.nan, 3.0]), "f"), "f", "f, pose 1:",
          "stamp is not finite")
    error(lambda: check_stamps(np.array([1.0, 2.0, np.inf]), "f", [4, 5, 7]), "f",
          "f, line 7: stamp is not finite")
    msg = error(lambda: check_stamps(np.array([1.0, 2.0, 2.0, 1.5]), "f", [3, 4, 6, 9]), "f",
                "f, line 6: stamp 2.000000000 s does not increase from 2.000000000 s",
                "(2 such rows)", "expected strictly increasing stamps")
    assert "line 9" not in msg
    error(lambda: check_stamps(np.array([5.0, 4.0]), "f"), "f",
          "f, pose 1: stamp 4.000000000 s does not increase from 5.000000000 s (1 such rows)")
    # integer stamps (a bag's nanoseconds) compared as numbers, not wrapped around
    error(lambda: check_stamps(np.array([5, 4], dtype=np.uint64), "f"), "f",
          "f, pose 1: stamp 4.000000000 s does not increase")


def test_read_stamps_one_per_line(tmp_path):
    path = write(tmp_path, ["# times", "0.5", "", "0.75", "1e3"], "times.txt")
    np.testing.assert_array_equal(read_stamps(path), [0.5, 0.75, 1000.0])
    back = write(tmp_path, ["1", "# c", "3", "2"], "back.txt")
    error(lambda: read_stamps(back), back, "line 4: stamp 2.000000000 s does not increase")
    wide = write(tmp_path, ["1", "2 3"], "wide.txt")
    error(lambda: read_stamps(wide), wide, "line 2", "expected 1 values (one stamp [s] a line)")


# -- TUM ------------------------------------------------------------------------------------


def test_tum_estimate_is_scipy_poses_with_optional_times(tmp_path):
    est = read_tum_estimate(write(tmp_path, tum_rows()))
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS, atol=1e-12)
    np.testing.assert_allclose(est.trajectory.poses, poses(), atol=1e-12)
    assert est.frame_times_ms is None
    timed = read_tum_estimate(write(tmp_path, tum_rows(times=[0.0, 2.5, 1.0]), "timed.txt"))
    np.testing.assert_array_equal(timed.frame_times_ms, [0.0, 2.5, 1.0])
    np.testing.assert_allclose(timed.trajectory.poses, poses(), atol=1e-12)
    neg = write(tmp_path, ["# h", *tum_rows(times=[0.0, 2.0, -0.5])], "neg.txt")
    error(lambda: read_tum_estimate(neg), neg, "line 4: negative time in the 9th column; expected "
          "the method's time of the frame [ms] >= 0")


def test_poses_from_tum_normalises_near_unit_and_refuses_others():
    q = ROT.as_quat() * np.array([[1.009], [0.991], [1.0]])
    np.testing.assert_allclose(poses_from_tum(XYZ, q, "f"), poses(), atol=1e-12)
    for scale, words in [(1.011, ["has norm 1.011", "(1 such rows)", "norm 1 within 0.01",
                                  "a column missing or one too many?"]),
                         (0.989, ["has norm 0.989"]),
                         (1e-3, ["has norm 0.001"]),
                         (2e-6, ["has norm 2e-06"]),
                         (1e-6, ["has norm 1e-06"]),  # not shorter than 1e-6
                         (5e-7, ["quaternion (qx qy qz qw) has zero norm (1 such rows)",
                                 "expected a rotation"]),
                         (0.0, ["zero norm"])]:
        bad = ROT.as_quat()
        bad[1] = [0, 0, 0, scale]
        error(lambda b=bad: poses_from_tum(XYZ, b, "f", [2, 4, 6]), "f", "f, line 4:", *words)
    two = ROT.as_quat() * 0.0
    error(lambda: poses_from_tum(XYZ, two * 0 + [[0, 0, 0, 1], [0, 0, 0, 2], [0, 0, 0, 3]], "f"),
          "f", "f, pose 1: quaternion (qx qy qz qw) = 0 0 0 2 has norm 2 (2 such rows)")
    error(lambda: poses_from_tum(XYZ, two, "f"), "f", "f, pose 0:", "(3 such rows)")


def index_rows(first) -> list[str]:
    """Rows ``i t x y z qx qy qz qw`` with z = 1 and q = identity, so that columns 4-8 read as
    a TUM quaternion are (1, 0, 0, 0): unit too."""
    return [fmt([i, 100.0 + k, k, 0, 1, 0, 0, 0, 1]) for k, i in enumerate(first)]


def test_an_integer_index_column_is_refused_only_when_all_signs_say_so(tmp_path):
    path = write(tmp_path, index_rows([0, 1, 2]), "idx.txt")
    error(lambda: read_estimate(path), path, "9 columns whose first is an integer index (0, 1, "
          "...)", "columns 6-9", "expected TUM rows t x y z qx qy qz qw [time_ms]")
    error(lambda: read_estimate(write(tmp_path, index_rows([3, 7, 8]), "i2.txt")), tmp_path,
          "integer index (3, 7, ...)", "drop the index column (e.g. cut -d' ' -f2-)")
    # a quaternion in columns 6-9 of which qx is not zero
    turned = [fmt([i, 100.0 + i, 0, 0, 0, 0.6, 0, 0, 0.8]) for i in range(3)]
    error(lambda: read_estimate(write(tmp_path, turned, "i3.txt")), tmp_path,
          "9 columns whose first is an integer index (0, 1, ...)")
    # not whole numbers: stamps, read as TUM (quaternion (1, 0, 0, 0), time 1 ms)
    est = read_estimate(write(tmp_path, index_rows([0.5, 1.5, 2.5]), "half.txt"))
    np.testing.assert_array_equal(est.trajectory.stamps, [0.5, 1.5, 2.5])
    np.testing.assert_allclose(est.trajectory.poses[:, :3, :3],
                               Rotation.from_quat([1, 0, 0, 0]).as_matrix()[None].repeat(3, 0),
                               atol=1e-15)
    np.testing.assert_array_equal(est.frame_times_ms, [1, 1, 1])
    # whole numbers that do not increase: no index; the stamps are refused instead
    flat = write(tmp_path, index_rows([2, 2, 3]), "flat.txt")
    error(lambda: read_estimate(flat), flat, "line 2: stamp 2.000000000 s does not increase")
    # an index but the later quaternion not unit in one row: read as TUM
    rows = index_rows([0, 1, 2])
    rows[1] = fmt([1, 101.0, 1, 0, 1, 0, 0, 0, 3])
    est = read_estimate(write(tmp_path, rows, "mixed.txt"))
    np.testing.assert_array_equal(est.frame_times_ms, [1, 3, 1])
    # a single row: no index (nothing to compare); refused as too short a trajectory
    one = write(tmp_path, index_rows([0]), "one.txt")
    error(lambda: read_estimate(one), one, "the estimate has 1 pose; expected a trajectory of "
          "at least 2 poses")


def test_check_index_column_direct():
    data = np.array([[0, 100, 0, 0, 1, 0, 0, 0, 1], [1, 101, 0, 0, 1, 0, 0, 0, 1.0]])
    with pytest.raises(DataError, match="^w: 9 columns"):
        check_index_column(data, "w")
    check_index_column(data[:1], "w")
    off = data.copy()
    off[:, 8] = 1.02  # columns 6-9 of norm 1.02: beyond the tolerance
    check_index_column(off, "w")
    near = data.copy()
    near[:, 8] = 1.009
    with pytest.raises(DataError):
        check_index_column(near, "w")
    low = data.copy()
    low[:, 8] = 0.98
    check_index_column(low, "w")


# -- KITTI ----------------------------------------------------------------------------------


def kitti_rows(T) -> list[str]:
    return [fmt(M[:3, :].ravel()) for M in T]


def test_kitti_estimate_with_its_stamps_file(tmp_path):
    path = write(tmp_path, ["# poses", *kitti_rows(poses())], "k.txt")
    times = write(tmp_path, [f"{t:.17g}" for t in STAMPS], "times.txt")
    est = read_kitti_estimate(path, times)
    np.testing.assert_allclose(est.trajectory.poses, poses(), atol=1e-12)
    np.testing.assert_array_equal(est.trajectory.stamps, STAMPS)
    assert est.frame_times_ms is None
    noisy = poses()
    noisy[1, :3, :3] += 3e-4 * np.eye(3)
    est = read_kitti_estimate(write(tmp_path, kitti_rows(noisy), "n.txt"), times)
    U, _, Vt = np.linalg.svd(noisy[1, :3, :3])
    np.testing.assert_allclose(est.trajectory.poses[1, :3, :3], U @ Vt, atol=1e-12)
    error(lambda: read_kitti_estimate(path, None), path, "a KITTI pose file has no stamps; give "
          "its stamps file (--stamps times.txt: one stamp [s] per pose row)")
    wide = write(tmp_path, [r + " 1" for r in kitti_rows(poses())], "wide.txt")
    error(lambda: read_kitti_estimate(wide, times), wide, "line 1: expected 12 values (12 values: "
          "the 3x4 pose row-major), got 13")
    skew = poses()
    skew[2, :3, :3] *= 1.01
    bad = write(tmp_path, ["# poses", *kitti_rows(skew)], "skew.txt")
    error(lambda: read_kitti_estimate(bad, times), bad, "line 4: the 3x3 block is no rotation")
    long = write(tmp_path, [f"{t:.17g}" for t in [*STAMPS, 12.0]], "long.txt")
    error(lambda: read_kitti_estimate(path, long), path, "3 pose rows but", "long.txt has 4 "
          "stamps; expected one stamp per pose row")


# -- Boreas ---------------------------------------------------------------------------------


def boreas_rows(stamps_us, T) -> list[str]:
    return [f"{int(t)} " + fmt(np.linalg.inv(M)[:3, :].ravel())
            for t, M in zip(stamps_us, T, strict=True)]


US = np.array([1_616_000_000_000_000, 1_616_000_000_100_000, 1_616_000_000_250_000])


def test_read_boreas_inverts_t_k_i_and_keeps_microseconds(tmp_path):
    path = write(tmp_path, ["# boreas", *boreas_rows(US, poses())], "b.txt")
    traj, lines = read_boreas(path)
    assert lines == [2, 3, 4]
    np.testing.assert_array_equal(traj.stamps, US.astype(float))
    np.testing.assert_allclose(traj.poses, poses(), atol=1e-9)
    # the file's T_k_i maps a world point into the frame: p_k = T_k_i p_i
    p_i = np.array([0.3, -2.0, 5.0, 1.0])
    T_k_i = np.array([float(v) for v in boreas_rows(US, poses())[0].split()[1:]]).reshape(3, 4)
    np.testing.assert_allclose(T_k_i @ p_i, (np.linalg.inv(traj.poses[0]) @ p_i)[:3], atol=1e-9)
    rows = boreas_rows(US, poses())
    rows[1] = rows[1].replace(str(US[1]), f"{US[1]}.25", 1)
    frac = write(tmp_path, rows, "frac.txt")
    error(lambda: read_boreas(frac), frac, "line 2: stamp", "is not a whole number; expected a "
          "Boreas row: an integer stamp [us] then 12 values")
    mirror = poses()
    mirror[2, :3, 0] *= -1
    bad = write(tmp_path, boreas_rows(US, mirror), "m.txt")
    error(lambda: read_boreas(bad), bad, "line 3: the 3x3 block of T_k_i is no rotation")
    short = write(tmp_path, [r.rsplit(" ", 1)[0] for r in boreas_rows(US, poses())], "s.txt")
    error(lambda: read_boreas(short), short, "line 1", "expected 13 values (13 values: stamp [us] "
          "and the 3x4 T_k_i row-major)")


def test_boreas_estimate_in_seconds_and_its_stamps_checked(tmp_path):
    path = write(tmp_path, boreas_rows(US, poses()), "b.txt")
    est = read_estimate(path)
    assert est.fmt == "boreas" and est.stamp_unit == "us"
    np.testing.assert_allclose(est.trajectory.stamps, US * 1e-6, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(est.raw_stamps, US.astype(float))
    back = write(tmp_path, boreas_rows(US[[0, 2, 1]], poses()), "back.txt")
    error(lambda: read_estimate(back), back, "line 3: stamp 1616000000.", "s does not increase "
          "from 1616000000.25")


# -- read_estimate --------------------------------------------------------------------------


def test_formats_detected_by_suffix_folder_or_width(tmp_path):
    assert DEFAULT_UNITS == {"tum": "s", "kitti": "s", "bag": "s", "boreas": "us"}
    for suffix in (".bag", ".db3", ".mcap"):
        assert is_bag(tmp_path / f"x{suffix}") and detect_format(tmp_path / f"x{suffix}") == "bag"
    folder = tmp_path / "ros2"
    folder.mkdir()
    assert not is_bag(folder)
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert is_bag(folder) and detect_format(folder) == "bag"
    assert not is_bag(tmp_path / "metadata.yaml")
    assert detect_format(write(tmp_path, tum_rows(), "t.txt")) == "tum"
    assert detect_format(write(tmp_path, kitti_rows(poses()), "k.txt")) == "kitti"
    assert detect_format(write(tmp_path, boreas_rows(US, poses()), "b.txt")) == "boreas"
    assert detect_format(write(tmp_path, ["1 2 3"], "three.txt")) == "tum"
    error(lambda: detect_format(tmp_path / "gone.txt"), tmp_path / "gone.txt",
          "cannot read the file")


@pytest.mark.parametrize("unit", ["s", "ms", "us", "ns"])
def test_stamp_units_to_seconds(tmp_path, unit):
    factor = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[unit]
    assert STAMP_UNITS[unit] == factor
    est = read_estimate(write(tmp_path, tum_rows()), "tum", stamp_unit=unit)
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS * factor, rtol=1e-15)
    np.testing.assert_array_equal(est.raw_stamps, STAMPS)
    assert est.stamp_unit == unit and est.fmt == "tum"
    np.testing.assert_allclose(est.trajectory.poses, poses(), atol=1e-12)


def test_read_estimate_defaults_and_refusals(tmp_path):
    path = write(tmp_path, tum_rows())
    est = read_estimate(path)
    assert est.stamp_unit == "s" and est.fmt == "tum"
    np.testing.assert_array_equal(est.trajectory.stamps, STAMPS)
    times = write(tmp_path, [f"{t:.17g}" for t in STAMPS], "times.txt")
    k = read_estimate(write(tmp_path, kitti_rows(poses()), "k.txt"), stamps=str(times))
    assert k.fmt == "kitti" and k.stamp_unit == "s"
    np.testing.assert_allclose(k.trajectory.poses, poses(), atol=1e-12)
    error(lambda: read_estimate(path, stamp_unit="sec"), "--stamp-unit 'sec'",
          "expected one of s, ms, us, ns")
    error(lambda: read_estimate(path, "csv"), path, "unknown trajectory format 'csv'",
          "expected one of auto, tum, kitti, boreas, bag")
    error(lambda: read_estimate(tmp_path / "none.txt"), tmp_path / "none.txt",
          "trajectory file not found")
    error(lambda: read_estimate(write(tmp_path, tum_rows()[:1], "one.txt")), tmp_path,
          "the estimate has 1 pose; expected a trajectory of at least 2 poses")
    two = read_estimate(write(tmp_path, tum_rows()[:2], "two.txt"))
    np.testing.assert_allclose(two.trajectory.poses, poses()[:2], atol=1e-12)


def test_frame_times_file(tmp_path):
    path = write(tmp_path, tum_rows(times=[5.0, 6.0, 7.0]))
    ft = write(tmp_path, ["# ms", "0", "1.5", "2"], "ft.txt")
    est = read_estimate(path, frame_times=ft, stamp_unit="ms")
    np.testing.assert_array_equal(est.frame_times_ms, [0.0, 1.5, 2.0])
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS * 1e-3)
    assert est.stamp_unit == "ms"
    neg = write(tmp_path, ["# ms", "0", "1.5", "-2"], "neg.txt")
    error(lambda: read_estimate(path, frame_times=neg), neg, "line 4: negative time; "
          "expected a time per frame [ms] >= 0")
    few = write(tmp_path, ["1", "2"], "few.txt")
    error(lambda: read_estimate(path, frame_times=few), few,
          f"2 times but {path} has 3 poses; expected one time [ms] per pose")
    wide = write(tmp_path, ["1 2", "3 4", "5 6"], "wide.txt")
    error(lambda: read_estimate(path, frame_times=wide), wide, "line 1",
          "expected 1 values (one time [ms] a line)")


# -- bags -----------------------------------------------------------------------------------


def ros1_bag(path, topics: dict, stamps=STAMPS, xyz=XYZ):
    """A ROS1 bag: ``topics`` {name: "odom" | "imu"}, one message per stamp each (odometry:
    the poses ROT, ``xyz``)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from helpers_bags import imu_msg, odometry_msg

    store = get_typestore(Stores.ROS1_NOETIC)
    T = np.tile(np.eye(4), (len(stamps), 1, 1))
    T[:, :3, :3] = Rotation.from_euler("z", 0.3 * np.arange(len(stamps))[:, None]).as_matrix()
    T[:, :3, 3] = xyz[:len(stamps)]
    with Writer(path) as w:
        for name, kind in topics.items():
            msgtype = "nav_msgs/msg/Odometry" if kind == "odom" else "sensor_msgs/msg/Imu"
            conn = w.add_connection(name, msgtype, typestore=store)
            for k, t in enumerate(stamps):
                msg = odometry_msg(store, t, k, T[k]) if kind == "odom" else imu_msg(store, t, k)
                w.write(conn, int(1e9 * (1 + k)), store.serialize_ros1(msg, msgtype))
    return path


def test_a_bag_needs_exactly_one_pose_topic_or_a_named_one(tmp_path):
    from loaders.rosbag import POSE_TYPES

    two = ros1_bag(tmp_path / "two.bag", {"/odom": "odom", "/imu": "imu", "/odom2": "odom"})
    error(lambda: read_estimate(two), two,
          f"2 pose topics ({', '.join(POSE_TYPES)}); give the estimate's topic (--topic); the "
          "bag has /imu (sensor_msgs/msg/Imu), /odom (nav_msgs/msg/Odometry), /odom2 "
          "(nav_msgs/msg/Odometry)")
    est = read_estimate(two, topic="/odom2")
    assert est.fmt == "bag" and est.frame_times_ms is None
    want = poses(Rotation.from_euler("z", 0.3 * np.arange(3)[:, None]))
    np.testing.assert_allclose(est.trajectory.poses, want, atol=1e-9)
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS, atol=1e-9)
    imu = ros1_bag(tmp_path / "imu.bag", {"/imu": "imu"})
    error(lambda: read_estimate(imu), imu, "0 pose topics (", "(--topic); the bag has /imu "
          "(sensor_msgs/msg/Imu)")
    empty = ros1_bag(tmp_path / "empty.bag", {})
    error(lambda: read_estimate(empty), empty, "0 pose topics", "the bag has no topics")


def test_a_bag_with_repeated_stamps_or_non_finite_poses_is_refused(tmp_path):
    rep = ros1_bag(tmp_path / "rep.bag", {"/odom": "odom"}, stamps=[1.0, 2.0, 2.0])
    error(lambda: read_estimate(rep), rep, f"{rep}:/odom, pose 2: stamp 2.000000000 s does not "
          "increase")
    xyz = np.array([[0, 0, 0], [np.nan, 0, 0], [1, 1, 1], [0, np.inf, 0], [2, 2, 2]], dtype=float)
    bad = ros1_bag(tmp_path / "nan.bag", {"/odom": "odom"}, stamps=[1.0, 2.0, 3.0, 4.0, 5.0],
                   xyz=xyz)
    error(lambda: read_estimate(bad), bad, f"{bad}: pose 1 is not finite (2 such poses); "
          "expected finite poses")
