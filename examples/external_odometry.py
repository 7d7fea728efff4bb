#!/usr/bin/env python3
"""A small odometry made outside the harness: it reads a bag written by `bench export` and
writes a TUM trajectory that `bench score` scores beside the harness's own runs.

It stands for any external method (a ROS node, another project's code): it imports nothing
from doppler-bench, only rosbags, NumPy and SciPy. The method is frame-to-frame point-to-point
ICP (nearest neighbours with a k-d tree, a closed-form rigid fit per iteration), started from
the previous step's motion (constant velocity)::

    python examples/external_odometry.py run_mcap/ odometry.tum [--topic /points] [--times]

Output rows: ``t x y z qx qy qz qw`` (the sensor pose in the first scan's frame, stamped with
the scan's header stamp); with ``--times`` a 9th column: this script's own time for the frame
[ms] (what `bench score` shows as "reported by the method").
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from rosbags.highlevel import AnyReader
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

FLOAT32 = 7


def read_clouds(bag: Path, topic: str):
    """Yield (stamp [s], points (N, 3) float64) of every PointCloud2 on ``topic``."""
    with AnyReader([bag]) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            raise SystemExit(f"{bag}: no topic {topic}")
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            offsets = {f.name: f.offset for f in msg.fields if f.datatype == FLOAT32}
            dtype = np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3,
                              "offsets": [offsets[a] for a in "xyz"],
                              "itemsize": msg.point_step})
            arr = np.frombuffer(np.asarray(msg.data, dtype=np.uint8).tobytes(), dtype=dtype)
            pts = np.column_stack([arr["x"], arr["y"], arr["z"]]).astype(np.float64)
            st = msg.header.stamp
            yield st.sec + st.nanosec * 1e-9, pts[np.isfinite(pts).all(axis=1)]


def rigid_fit(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """The 4x4 transform T minimising |T src - dst|^2 (Kabsch, reflection guarded)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    U, _, Vt = np.linalg.svd((src - cs).T @ (dst - cd))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, cd - R @ cs
    return T


def icp(tree: cKDTree, target: np.ndarray, source: np.ndarray, T0: np.ndarray,
        max_dist_m: float = 1.0, iterations: int = 30) -> np.ndarray:
    """T_target_source by point-to-point ICP from ``T0``."""
    T = T0.copy()
    for _ in range(iterations):
        moved = source @ T[:3, :3].T + T[:3, 3]
        dist, idx = tree.query(moved, distance_upper_bound=max_dist_m)
        ok = np.isfinite(dist)
        if ok.sum() < 3:
            break
        dT = rigid_fit(moved[ok], target[idx[ok]])
        T = dT @ T
        if np.linalg.norm(dT[:3, 3]) < 1e-6 and np.abs(dT[:3, :3] - np.eye(3)).max() < 1e-8:
            break
    return T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bag", type=Path, help="bag (ROS1 .bag, ROS2 folder, .mcap)")
    ap.add_argument("out", type=Path, help="TUM file to write")
    ap.add_argument("--topic", default="/points")
    ap.add_argument("--times", action="store_true", help="add each frame's time [ms]")
    args = ap.parse_args()
    rows, pose, motion = [], np.eye(4), np.eye(4)
    prev = None
    for stamp, pts in read_clouds(args.bag, args.topic):
        t0 = time.perf_counter()
        if prev is not None:
            step = icp(prev[0], prev[1], pts, motion)  # T_prev_curr
            pose, motion = pose @ step, step
        prev = (cKDTree(pts), pts)
        ms = (time.perf_counter() - t0) * 1e3
        q = Rotation.from_matrix(pose[:3, :3]).as_quat()
        rows.append([stamp, *pose[:3, 3], *q] + ([ms] if args.times else []))
    with open(args.out, "w") as f:
        f.write("# t x y z qx qy qz qw" + (" time_ms" if args.times else "") + "\n")
        for r in rows:
            f.write(" ".join(f"{v:.17g}" for v in r) + "\n")
    print(f"wrote {args.out}: {len(rows)} poses")


if __name__ == "__main__":
    main()
