"""loaders.estimate: an external trajectory read strictly (TUM [+ time_ms], KITTI + stamps, a
bag's Odometry / PoseStamped topic); every bad input is one DataError naming file and row."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.estimate import read_estimate
from loaders.se3 import make_T

STAMPS = 100.0 + 0.1 * np.arange(5)
R = Rotation.from_euler("z", 0.05 * np.arange(5)[:, None])
XYZ = np.column_stack([np.arange(5) * 0.8, np.arange(5) * 0.1, np.zeros(5)])


def tum_text(times=None, header=True) -> str:
    q = R.as_quat()
    rows = ["# t x y z qx qy qz qw"] if header else []
    for k in range(5):
        extra = [] if times is None else [times[k]]
        rows.append(" ".join(f"{v:.17g}" for v in [STAMPS[k], *XYZ[k], *q[k], *extra]))
    return "\n".join(rows) + "\n"


def write(tmp_path, text, name="est.txt"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_tum_rows_and_the_reported_times_column(tmp_path):
    est = read_estimate(write(tmp_path, tum_text()))
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS)
    np.testing.assert_allclose(est.trajectory.poses, make_T(R.as_matrix(), XYZ), atol=1e-15)
    assert est.frame_times_ms is None
    timed = read_estimate(write(tmp_path, tum_text(times=[1.5, 2, 3, 4, 5.5])))
    np.testing.assert_allclose(timed.frame_times_ms, [1.5, 2, 3, 4, 5.5])


def test_a_quaternion_off_unit_length_is_refused(tmp_path):
    """Slightly off unit length (printed with few digits): normalised; beyond the tolerance
    (0.01): refused naming the line, never normalised silently."""
    text = tum_text(header=False).splitlines()
    parts = text[2].split()
    parts[4:8] = [str(1.009 * float(v)) for v in parts[4:8]]
    text[2] = " ".join(parts)
    est = read_estimate(write(tmp_path, "\n".join(text) + "\n"))
    np.testing.assert_allclose(est.trajectory.poses[2, :3, :3], R[2].as_matrix(), atol=1e-12)
    parts[4:8] = [str(1.011 / 1.009 * float(v)) for v in parts[4:8]]
    text[2] = " ".join(parts)
    with pytest.raises(DataError, match=r"est.txt, line 3: quaternion \(qx qy qz qw\) = .* has "
                                        r"norm 1.011 .*expected a unit quaternion"):
        read_estimate(write(tmp_path, "\n".join(text) + "\n"))


def test_an_index_column_is_refused_not_taken_for_stamps(tmp_path):
    rows = [f"{k} {row}" for k, row in enumerate(tum_text(header=False).splitlines())]
    path = write(tmp_path, "\n".join(rows) + "\n", "indexed.txt")
    with pytest.raises(DataError, match=r"indexed.txt: 9 columns whose first is an integer index "
                                        r"\(0, 1, \.\.\.\) .*drop the index column"):
        read_estimate(path)
    # integer stamps with a 9th column of times are no index column: read as they are
    whole = "".join(f"{k + 100} {k} 0 0 0 0 0 1 {2.5 + k}\n" for k in range(5))
    est = read_estimate(write(tmp_path, whole, "whole.txt"))
    np.testing.assert_allclose(est.trajectory.stamps, 100 + np.arange(5))
    np.testing.assert_allclose(est.frame_times_ms, 2.5 + np.arange(5))


def test_one_pose_is_no_trajectory(tmp_path):
    path = write(tmp_path, tum_text().splitlines()[1] + "\n", "one.txt")
    with pytest.raises(DataError, match="one.txt: the estimate has 1 pose; expected a trajectory "
                                        "of at least 2 poses"):
        read_estimate(path)


def test_stamp_units_are_converted_to_seconds(tmp_path):
    rows = tum_text(header=False).splitlines()
    ms = [" ".join([f"{1000 * float(r.split()[0]):.17g}", *r.split()[1:]]) for r in rows]
    est = read_estimate(write(tmp_path, "\n".join(ms) + "\n"), stamp_unit="ms")
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS, rtol=1e-15)
    with pytest.raises(DataError, match="--stamp-unit 'min': expected one of s, ms, us, ns"):
        read_estimate(write(tmp_path, tum_text()), stamp_unit="min")


@pytest.mark.parametrize("edit, message", [
    (lambda rows: rows[:3] + [rows[3] + " 7 8"] + rows[4:], "line 4: expected 8 values"),
    (lambda rows: rows[:2] + [rows[2].replace(rows[2].split()[2], "nan", 1)] + rows[3:],
     "line 3: non-finite value"),
    (lambda rows: rows[:2] + [rows[3], rows[2]] + rows[4:], "line 4: stamp 100.100000000 s does "
     "not increase from 100.200000000 s"),
    (lambda rows: rows[:2] + [rows[1]] + rows[3:], "line 3: stamp 100.000000000 s does not "
     "increase"),
    (lambda rows: rows[:5] + [" ".join(rows[5].split()[:4] + ["0", "0", "0", "0"])],
     "line 6: quaternion (qx qy qz qw) has zero norm"),
    (lambda rows: rows[:1] + [" ".join(r.split()[:7]) for r in rows[1:]],
     "line 2: expected 8 or 9 values (t x y z qx qy qz qw [time_ms]), got 7"),
    (lambda rows: rows[:1], "no pose rows found"),
])
def test_bad_tum_rows_are_one_clear_error(tmp_path, edit, message):
    rows = tum_text().splitlines()
    path = write(tmp_path, "\n".join(edit(rows)) + "\n")
    with pytest.raises(DataError) as err:
        read_estimate(path, "tum")
    assert str(err.value).startswith(str(path)) and message in str(err.value), str(err.value)


def kitti_text() -> str:
    M = make_T(R.as_matrix(), XYZ)[:, :3, :].reshape(5, 12)
    return "".join(" ".join(f"{v:.17g}" for v in row) + "\n" for row in M)


def test_kitti_needs_its_stamps_one_per_row(tmp_path):
    path = write(tmp_path, kitti_text(), "poses.txt")
    with pytest.raises(DataError, match="a KITTI pose file has no stamps; give its stamps file"):
        read_estimate(path)
    times = write(tmp_path, "".join(f"{t:.17g}\n" for t in STAMPS), "times.txt")
    est = read_estimate(path, stamps=times)
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS)
    np.testing.assert_allclose(est.trajectory.poses, make_T(R.as_matrix(), XYZ), atol=1e-14)
    short = write(tmp_path, "".join(f"{t:.17g}\n" for t in STAMPS[:4]), "short.txt")
    with pytest.raises(DataError, match="5 pose rows but .*short.txt has 4 stamps"):
        read_estimate(path, stamps=short)
    bad = write(tmp_path, kitti_text().replace("\n", " 0\n", 1), "bad.txt")
    with pytest.raises(DataError, match="bad.txt, line 1: expected 12 values"):
        read_estimate(bad, "kitti", stamps=times)


def test_frame_times_file_one_per_pose(tmp_path):
    path = write(tmp_path, tum_text())
    ok = write(tmp_path, "1\n2\n3\n4\n5\n", "t.txt")
    np.testing.assert_allclose(read_estimate(path, frame_times=ok).frame_times_ms, [1, 2, 3, 4, 5])
    few = write(tmp_path, "1\n2\n", "few.txt")
    with pytest.raises(DataError, match="few.txt: 2 times but .* has 5 poses"):
        read_estimate(path, frame_times=few)
    neg = write(tmp_path, "1\n2\n-3\n4\n5\n", "neg.txt")
    with pytest.raises(DataError, match="neg.txt, line 3: negative time"):
        read_estimate(path, frame_times=neg)


def test_missing_file_and_unknown_format(tmp_path):
    with pytest.raises(DataError, match="trajectory file not found"):
        read_estimate(tmp_path / "none.txt")
    with pytest.raises(DataError, match="unknown trajectory format 'g2o'"):
        read_estimate(write(tmp_path, tum_text()), "g2o")


def _pose_bag(tmp_path, storage, msgtype):
    """A ROS2 bag with the poses on /odom as ``msgtype`` and an unrelated topic."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    T = store.types
    path = tmp_path / f"bag_{storage}"
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    q = R.as_quat()
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conn = w.add_connection("/odom", msgtype, typestore=store)
        other = w.add_connection("/chatter", "std_msgs/msg/String", typestore=store)
        for k in (2, 0, 1, 4, 3):  # record order is not stamp order
            sec, nsec = int(STAMPS[k]), int(round((STAMPS[k] % 1) * 1e9))
            header = T["std_msgs/msg/Header"](
                stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec), frame_id="odom")
            pose = T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=XYZ[k, 0], y=XYZ[k, 1], z=XYZ[k, 2]),
                orientation=T["geometry_msgs/msg/Quaternion"](x=q[k, 0], y=q[k, 1], z=q[k, 2],
                                                              w=q[k, 3]))
            if msgtype == "geometry_msgs/msg/PoseStamped":
                msg = T[msgtype](header=header, pose=pose)
            else:
                cov = np.zeros(36)
                zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
                msg = T[msgtype](
                    header=header, child_frame_id="base_link",
                    pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
                    twist=T["geometry_msgs/msg/TwistWithCovariance"](
                        twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero),
                        covariance=cov))
            w.write(conn, 1000 + k, store.serialize_cdr(msg, msgtype))
            w.write(other, 1000 + k, store.serialize_cdr(T["std_msgs/msg/String"](data="x"),
                                                         "std_msgs/msg/String"))
    return path


@pytest.mark.parametrize("storage, msgtype", [("mcap", "nav_msgs/msg/Odometry"),
                                              ("sqlite3", "geometry_msgs/msg/PoseStamped")])
def test_a_bag_pose_topic_sorted_by_header_stamp(tmp_path, storage, msgtype):
    path = _pose_bag(tmp_path, storage, msgtype)
    est = read_estimate(path)  # auto: a bag; its only pose topic
    np.testing.assert_allclose(est.trajectory.stamps, STAMPS, atol=1e-9)
    np.testing.assert_allclose(est.trajectory.poses, make_T(R.as_matrix(), XYZ), atol=1e-12)
    with pytest.raises(DataError, match=r"no estimated pose topic /est; the bag has /chatter "
                                        r"\(std_msgs/msg/String\), /odom"):
        read_estimate(path, topic="/est")
    with pytest.raises(DataError, match="estimated pose topic /chatter has type "
                                        "std_msgs/msg/String; expected one of"):
        read_estimate(path, topic="/chatter")


def boreas_text(stamps_us, poses) -> str:
    """Boreas submission rows: int stamp [us], the upper 3x4 of T_k_i = inverse of the pose
    (np.linalg.inv: not the harness's inverse)."""
    rows = []
    for t, T in zip(stamps_us, poses, strict=True):
        T_k_i = np.linalg.inv(T)
        rows.append(f"{int(t)} " + " ".join(f"{v:.17g}" for v in T_k_i[:3, :].ravel()))
    return "\n".join(rows) + "\n"


def test_a_boreas_submission_is_the_inverse_of_the_poses_in_microseconds(tmp_path):
    poses = make_T(R.as_matrix(), XYZ)
    stamps_us = np.round(STAMPS * 1e6).astype(np.int64) + 1_616_000_000_000_000
    path = write(tmp_path, boreas_text(stamps_us, poses), "boreas-2021-08-05-13-34.txt")
    for fmt in ("auto", "boreas"):  # 13 columns: detected by its content
        est = read_estimate(path, fmt)
        np.testing.assert_allclose(est.trajectory.stamps, stamps_us * 1e-6, rtol=0, atol=1e-6)
        np.testing.assert_allclose(est.trajectory.poses, poses, atol=1e-12)
    # the poses as written (T_k_i, not inverted) differ: the translation is not the position
    assert not np.allclose(np.linalg.inv(poses)[:, :3, 3], XYZ, atol=0.1)
    frac = write(tmp_path, boreas_text(stamps_us, poses).replace(str(stamps_us[2]),
                                                                 f"{stamps_us[2]}.5"), "f.txt")
    with pytest.raises(DataError, match=r"f.txt, line 3: stamp .* is not a whole number"):
        read_estimate(frac)
    skew = poses.copy()
    skew[1, :3, :3] *= 1.01
    with pytest.raises(DataError, match=r"line 2: the 3x3 block of T_k_i is no rotation"):
        read_estimate(write(tmp_path, boreas_text(stamps_us, skew), "s.txt"))
