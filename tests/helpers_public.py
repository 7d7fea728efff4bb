"""Writers of the public datasets' exact byte layouts, for the loader tests.

Each writes frames whose truth is known in the layout the dataset's own reader expects (the
facts cited in ``loaders/vod.py``, ``loaders/coloradar.py`` and ``loaders/helipr.py``):

- View-of-Delft: ``radar/training/velodyne/NNNNN.bin`` float32 N x 7 ``[x y z RCS v_r
  v_r_compensated time]``, ``pose/NNNNN.json`` three JSON lines (odom/map/UTM -> camera),
  ``calib/NNNNN.txt`` KITTI lines with ``Tr_velo_to_cam`` (radar -> camera).
- ColoRadar: ``single_chip/pointclouds/data/radar_pointcloud_<i>.bin`` float32 N x 5,
  ``single_chip/pointclouds/timestamps.txt``, ``groundtruth/groundtruth_poses.txt`` (x y z qx
  qy qz qw) + ``groundtruth/timestamps.txt``, and ``calib/transforms/base_to_single_chip.txt``
  beside the run folder.
- HeLiPR: ``LiDAR/Aeva/<t_ns>.bin`` packed x y z reflectivity velocity (f32) time_offset_ns
  (i32) line_index (u8) [+ intensity f32], ``LiDAR_GT/Aeva_gt.txt`` (t_ns x y z qx qy qz qw).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from loaders.helipr import RECORD_25, RECORD_29
from loaders.se3 import inv_T, make_T, tum_from_T

#: a radar -> camera extrinsic like VoD's (radar x forward -> camera z forward)
VOD_T_CAMERA_RADAR = make_T(np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]]),
                            [0.05, 0.98, 1.44])
#: a base -> single_chip extrinsic (yawed 90 deg, 10 cm ahead)
COLORADAR_T_BASE_RADAR = make_T(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]),
                                [0.1, 0.0, 0.05])
MAP_FROM_ODOM = make_T(np.eye(3), [-750.0, 1020.0, 0.0])
UTM_FROM_ODOM = make_T(np.eye(3), [593000.0, 5762000.0, 0.0])


def _json_row(key: str, T: np.ndarray) -> str:
    return json.dumps({key: [float(v) for v in T.ravel()]})


def write_vod(root: Path, points: list[np.ndarray], doppler: list[np.ndarray],
              T_world_radar: np.ndarray, first: int = 0, rcs: list[np.ndarray] | None = None,
              compensated: list[np.ndarray] | None = None,
              T_camera_radar: np.ndarray = VOD_T_CAMERA_RADAR, split: str = "training") -> Path:
    """Frames ``first, first+1, ...`` of a VoD radar folder; returns the dataset root."""
    base = root / "radar" / split
    for sub in ("velodyne", "pose", "calib"):
        (base / sub).mkdir(parents=True, exist_ok=True)
    row = " ".join(f"{v:.17g}" for v in T_camera_radar[:3].ravel())
    for i, (p, d) in enumerate(zip(points, doppler, strict=True)):
        name = f"{first + i:05d}"
        n = len(p)
        rec = np.zeros((n, 7), dtype="<f4")
        rec[:, :3] = p
        rec[:, 3] = rcs[i] if rcs is not None else np.linspace(-10, 20, n)
        rec[:, 4] = d
        rec[:, 5] = compensated[i] if compensated is not None else 0.0
        rec.tofile(base / "velodyne" / f"{name}.bin")
        T_odom_camera = T_world_radar[i] @ inv_T(T_camera_radar)
        (base / "pose" / f"{name}.json").write_text("\n".join([
            _json_row("odomToCamera", T_odom_camera),
            _json_row("mapToCamera", MAP_FROM_ODOM @ T_odom_camera),
            _json_row("UTMToCamera", UTM_FROM_ODOM @ T_odom_camera)]))
        P = "1495.47 0.0 961.27 0.0 0.0 1495.47 624.90 0.0 0.0 0.0 1.0 0.0"
        (base / "calib" / f"{name}.txt").write_text(
            "".join(f"P{k}: {P}\n" for k in range(4))
            + "R0_rect: 1.0 0.0 0.0 0.0 1.0 0.0 0.0 0.0 1.0\n"
            + f"Tr_velo_to_cam: {row}\nTr_imu_to_velo: \n")
    return root


def write_coloradar(run: Path, stamps: np.ndarray, points: list[np.ndarray],
                    doppler: list[np.ndarray], gt_stamps: np.ndarray, T_world_base: np.ndarray,
                    T_base_radar: np.ndarray = COLORADAR_T_BASE_RADAR,
                    intensity: list[np.ndarray] | None = None) -> Path:
    """A ColoRadar run folder (calib/ written beside it, as released); returns the run."""
    data = run / "single_chip" / "pointclouds" / "data"
    data.mkdir(parents=True, exist_ok=True)
    for i, (p, d) in enumerate(zip(points, doppler, strict=True)):
        rec = np.zeros((len(p), 5), dtype="<f4")
        rec[:, :3] = p
        rec[:, 3] = intensity[i] if intensity is not None else 1.0
        rec[:, 4] = d
        rec.tofile(data / f"radar_pointcloud_{i}.bin")
    (data.parent / "timestamps.txt").write_text("".join(f"{t:.6f}\n" for t in stamps))
    gt = run / "groundtruth"
    gt.mkdir(parents=True, exist_ok=True)
    xyz, q = tum_from_T(T_world_base)
    (gt / "groundtruth_poses.txt").write_text("".join(
        " ".join(f"{v:.12f}" for v in (*p, *qq)) + "\n" for p, qq in zip(xyz, q, strict=True)))
    (gt / "timestamps.txt").write_text("".join(f"{t:.6f}\n" for t in gt_stamps))
    tf = run.parent / "calib" / "transforms"
    tf.mkdir(parents=True, exist_ok=True)
    t, qb = tum_from_T(T_base_radar[None])
    (tf / "base_to_single_chip.txt").write_text(
        " ".join(f"{v:.12f}" for v in t[0]) + "\n" + " ".join(f"{v:.12f}" for v in qb[0]) + "\n")
    return run


def write_helipr(root: Path, stamps_ns: np.ndarray, points: list[np.ndarray],
                 velocity: list[np.ndarray], gt_stamps_ns: np.ndarray, T_world_aeva: np.ndarray,
                 gt_name: str = "Aeva_gt.txt", time_offset_ns: list[np.ndarray] | None = None
                 ) -> Path:
    """A HeLiPR sequence folder; the record layout of each file follows its stamp."""
    aeva = root / "LiDAR" / "Aeva"
    aeva.mkdir(parents=True, exist_ok=True)
    for i, (t, p, v) in enumerate(zip(stamps_ns, points, velocity, strict=True)):
        dtype = RECORD_29 if int(t) > 1691936557946849179 else RECORD_25
        rec = np.zeros(len(p), dtype=dtype)
        rec["x"], rec["y"], rec["z"] = p[:, 0], p[:, 1], p[:, 2]
        rec["reflectivity"] = 0.5
        rec["velocity"] = v
        rec["time_offset_ns"] = (time_offset_ns[i] if time_offset_ns is not None
                                 else np.linspace(0, 99_000_000, len(p)).astype(np.int32))
        rec["line_index"] = np.arange(len(p)) % 64
        if "intensity" in dtype.names:
            rec["intensity"] = 7.0
        rec.tofile(aeva / f"{int(t)}.bin")
    gt = root / "LiDAR_GT"
    gt.mkdir(parents=True, exist_ok=True)
    xyz, q = tum_from_T(T_world_aeva)
    (gt / gt_name).write_text("".join(
        f"{int(t)} " + " ".join(f"{v:.12f}" for v in (*p, *qq)) + "\n"
        for t, p, qq in zip(gt_stamps_ns, xyz, q, strict=True)))
    return root


def write_npy_frames(folder: Path, points: list[np.ndarray], doppler: list[np.ndarray],
                     stamps: np.ndarray, poses: np.ndarray) -> Path:
    """The NumPy-frame route: frame_XXX.npy + frame_XXX_dop.npy + a TUM file (one row a
    frame)."""
    from helpers_bags import write_tum

    folder.mkdir(parents=True, exist_ok=True)
    for i, (p, d) in enumerate(zip(points, doppler, strict=True)):
        np.save(folder / f"frame_{i:03d}.npy", np.asarray(p, dtype=np.float32))
        np.save(folder / f"frame_{i:03d}_dop.npy", np.asarray(d, dtype=np.float32))
    write_tum(folder / "gt.txt", stamps, poses)
    return folder


def synthetic_frames(scene: str = "campus", sensor: str = "radar-frgen21", frames: int = 30,
                     seed: int = 1):
    """(stamps, points float32, doppler float32, T_world_sensor) of a synthetic sequence: real
    radar-like frames with exact truth."""
    from loaders.synthetic import SyntheticSequence

    seq = SyntheticSequence(scene, sensor, frames=frames, seed=seed)
    scans = list(seq)
    gt = seq.ground_truth.interpolate(seq.stamps).poses
    return (seq.stamps, [s.points.astype(np.float32) for s in scans],
            [s.doppler.astype(np.float32) for s in scans], gt)


def runs_agree(store_a: Path, store_b: Path, out: Path, methods=("doppler", "icp-p2plane"),
               rel: float = 0.02) -> dict:
    """Run each method on both stores (as ``bench run`` does) and assert the APE and the mean
    relative errors agree within ``rel``; returns the metrics by method."""
    import warnings

    from bench.api import run_method

    found = {}
    for method in methods:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a = run_method(method, store_a, out=out / f"a_{method}")
            b = run_method(method, store_b, out=out / f"b_{method}")
        assert a.frames == b.frames and a.frames_scored == b.frames_scored > 0
        pairs = [(a.ape.trans_rmse_m, b.ape.trans_rmse_m),
                 (a.ape.rot_rmse_deg, b.ape.rot_rmse_deg)]
        other_of = {r.length_m: r for r in b.relative_error}
        for cell in a.relative_error:
            if cell.trans_m_mean is not None:
                other = other_of[cell.length_m]
                pairs += [(cell.trans_m_mean, other.trans_m_mean),
                          (cell.rot_deg_mean, other.rot_deg_mean)]
        for x, y in pairs:
            assert abs(x - y) <= rel * max(abs(x), abs(y)) + 1e-9, (method, x, y)
        found[method] = (a, b)
    return found
