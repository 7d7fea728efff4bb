"""Properties of every reader behind the commands (Hypothesis; strategies in
tests/strategies.py): pose files (TUM, KITTI with its stamps file, Boreas, pose bags) scored by
``bench score`` and stores with missing or odd attributes read by ``bench inspect`` /
``bench score`` end with exit 0 and their documented result, or exit 2 with one ``error:``
line naming the file; never a traceback, memory bounded, nothing but the output changed."""

from __future__ import annotations

import itertools
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from strategies import (
    assert_clean,
    bench,
    boreas_files,
    damage_store,
    examples,
    junk_bytes,
    kitti_files,
    npy_frame_folders,
    stamp_files,
    store_damage,
    tree_digest,
    tum_files,
)

from conftest import constant_twist_sequence
from loaders.store import write_store

_count = itertools.count()


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    root = tmp_path_factory.mktemp("readers")
    seq = constant_twist_sequence(n_frames=12, n_points=300, max_range_m=60)
    return root, write_store(seq, root / "twist.h5")


def _score(root: Path, store: Path, trajectory: Path, *extra: str):
    out = root / "out" / f"o{next(_count)}"
    before = tree_digest(root, Path.cwd(), skip=(out.parent,))
    res = bench(["score", trajectory, "--store", store, "--name", "est", "--out", out, *extra])
    assert tree_digest(root, Path.cwd(), skip=(out.parent,)) == before
    names = (str(trajectory), trajectory.name, "--", str(store), *map(str, extra))
    assert_clean(res, names=names)
    if res.code == 0:  # the documented result: an ordinary run folder (RESULTS_DIR/SEQUENCE/
        # NAME, the sequence named by the store) with its metrics
        assert [p.parent.parent.parent for p in out.glob("*/est/metrics.json")] == [out], \
            res.text
    return res


@examples(6)
@given(text=st.one_of(tum_files(), boreas_files()),
       fmt=st.sampled_from(["auto", "tum", "boreas"]))
def test_tum_and_boreas_files_score_or_name_the_file(inputs, text, fmt):
    root, store = inputs
    path = root / f"traj{next(_count)}.txt"
    path.write_text(text)
    _score(root, store, path, "--format", fmt)


@examples(6)
@given(poses=kitti_files(), stamps=st.one_of(stamp_files(), st.none()))
def test_kitti_files_with_stamps_score_or_name_the_file(inputs, poses, stamps):
    root, store = inputs
    path = root / f"kitti{next(_count)}.txt"
    path.write_text(poses)
    extra = ["--format", "kitti"]
    if stamps is not None:
        (root / f"{path.stem}.stamps").write_text(stamps)
        extra += ["--stamps", str(root / f"{path.stem}.stamps")]
    _score(root, store, path, *extra)


@examples(4)
@given(data=junk_bytes, suffix=st.sampled_from([".txt", ".bag", ".db3", ".mcap", ".h5", ""]))
def test_junk_bytes_as_any_trajectory_name_the_file(inputs, data, suffix):
    root, store = inputs
    path = root / f"junk{next(_count)}{suffix}"
    path.write_bytes(data)
    _score(root, store, path)


@st.composite
def pose_bag_plans(draw):
    n = draw(st.integers(0, 15))
    dt = draw(st.sampled_from([0.1, 0.0, -0.1, 0.05]))
    odd = draw(st.sampled_from(["none", "nan-position", "zero-quaternion", "huge"]))
    kind = draw(st.sampled_from(["odometry", "pose", "both", "other"]))
    return n, dt, odd, kind


def _write_pose_bag(path: Path, n: int, dt: float, odd: str, kind: str) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from helpers_bags import _header, _ns, odometry_msg

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types
    with Writer(path) as w:
        odo = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts) \
            if kind in ("odometry", "both") else None
        pst = w.add_connection("/pose", "geometry_msgs/msg/PoseStamped", typestore=ts) \
            if kind in ("pose", "both") else None
        other = w.add_connection("/imu_text", "std_msgs/msg/String", typestore=ts) \
            if kind == "other" else None
        for i in range(n):
            t = 1.0 + i * dt if dt >= 0 else 100.0 + i * dt
            pose = np.eye(4)
            pose[0, 3] = 0.8 * i
            msg = odometry_msg(ts, t, i, pose)
            q = msg.pose.pose.orientation
            if odd == "nan-position" and i == n // 2:
                msg.pose.pose.position.x = float("nan")
            elif odd == "zero-quaternion" and i == 0:
                q.x = q.y = q.z = q.w = 0.0
            elif odd == "huge":
                msg.pose.pose.position.y = 1e300
            stamp = max(t, 0.0)
            if odo is not None:
                w.write(odo, _ns(stamp), ts.serialize_ros1(msg, "nav_msgs/msg/Odometry"))
            if pst is not None:
                ps = T["geometry_msgs/msg/PoseStamped"](header=_header(ts, stamp, i),
                                                         pose=msg.pose.pose)
                w.write(pst, _ns(stamp), ts.serialize_ros1(ps,
                                                           "geometry_msgs/msg/PoseStamped"))
            if other is not None:
                w.write(other, _ns(stamp), ts.serialize_ros1(T["std_msgs/msg/String"](
                    data="x"), "std_msgs/msg/String"))


@examples(3)
@given(plan=pose_bag_plans(), topic=st.sampled_from([None, "/odom", "/pose", "/missing"]))
def test_pose_bags_score_or_name_the_bag(inputs, plan, topic):
    root, store = inputs
    path = root / f"poses{next(_count)}.bag"
    _write_pose_bag(path, *plan)
    extra = ["--topic", topic] if topic else []
    _score(root, store, path, *extra)


@examples(8)
@given(damage=store_damage)
def test_a_damaged_store_is_inspected_or_named(inputs, damage):
    root, store = inputs
    copy = root / f"damaged{next(_count)}.h5"
    shutil.copyfile(store, copy)
    damage_store(copy, damage)
    before = tree_digest(root, Path.cwd())
    res = bench(["inspect", copy, "--plot", "-"])
    assert tree_digest(root, Path.cwd()) == before
    assert_clean(res, names=(str(copy),))
    if res.code == 0:
        assert f"{copy}" in res.text and "frames" in res.text, res.text


@examples(4)
@given(damage=store_damage)
def test_a_damaged_store_scored_against_is_named(inputs, damage):
    from loaders.posefile import write_tum

    root, store = inputs
    copy = root / f"damaged{next(_count)}.h5"
    shutil.copyfile(store, copy)
    damage_store(copy, damage)
    gt = root / "gt.txt"
    if not gt.exists():
        write_tum(constant_twist_sequence(n_frames=12, n_points=300,
                                          max_range_m=60).ground_truth, gt)
    _score(root, copy, gt)


@examples(4)
@given(files=npy_frame_folders(), gt=st.one_of(st.none(), tum_files()),
       period=st.sampled_from(["0.1", "0.0833"]), associate=st.sampled_from(["order", "time"]))
def test_numpy_frame_folders_convert_or_name_the_file(inputs, files, gt, period, associate):
    root, _ = inputs
    folder = root / f"npy{next(_count)}"
    folder.mkdir()
    for name, array in files.items():
        np.save(folder / name, array, allow_pickle=array.dtype == object)
    out = root / "out" / f"{folder.name}.h5"
    args = ["convert", "npy-frames", folder, "--period", period, "--out", out]
    if gt is not None:
        (folder / "gt.txt").write_text(gt)
        args += ["--gt", folder / "gt.txt", "--associate", associate]
    before = tree_digest(root, Path.cwd(), skip=(root / "out",))
    res = bench(args)
    assert tree_digest(root, Path.cwd(), skip=(root / "out",)) == before
    assert_clean(res, names=(str(folder), "--"))
    if res.code == 0:  # the documented result: a store with every frame
        from loaders.store import StoreSequence

        seq = StoreSequence(out)
        assert len(seq) >= 1 and seq.sensor.period_s == pytest.approx(float(period))
        seq.close()
