"""``bench view STORE [--run RUN_DIR]``: a rerun recording (.rrd) of a sequence.

Logged (rerun-sdk, the optional extra ``doppler-bench[viewer]``), on the timelines ``frame``
and ``time`` [s from the first scan]: each scan in the world frame (placed by the ground truth,
else by the run's estimate), coloured by Doppler (blue approaching, red receding); the
ground-truth and estimated trajectories (the estimate aligned at the first pose); and, for
``pair`` = FRAME, that pair's closest-point and Doppler correspondences. Open it with
``rerun recording.rrd``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench import guard
from loaders.errors import DataError
from loaders.posefile import read_tum
from loaders.se3 import inv_T, transform_points
from loaders.store import StoreSequence
from loaders.trajectory import Trajectory


def _rerun():
    try:
        import rerun as rr
    except ImportError:
        raise DataError("bench view needs rerun-sdk: pip install 'doppler-bench[viewer]'") \
            from None
    return rr


def doppler_colors(doppler: np.ndarray, limit_mps: float) -> np.ndarray:
    """RGB (N, 3) uint8: blue for approaching (negative), red for receding, grey near 0."""
    x = np.clip(doppler / max(limit_mps, 1e-6), -1, 1)
    rgb = np.empty((len(x), 3))
    rgb[:, 0] = np.where(x > 0, 0.55 + 0.45 * x, 0.55 * (1 + x))
    rgb[:, 2] = np.where(x < 0, 0.55 - 0.45 * x, 0.55 * (1 - x))
    rgb[:, 1] = 0.55 * (1 - np.abs(x))
    return (rgb * 255).astype(np.uint8)


def write_recording(store: Path, out: Path, run_dir: Path | None = None,
                    pair: int | None = None, stride: int = 1) -> Path:
    out = Path(out)
    inputs = [store] + ([run_dir / "est_tum.txt", run_dir / "est_all_tum.txt"]
                        if run_dir is not None else [])
    guard.regenerated_file(out, guard.is_recording, "a rerun recording", inputs=inputs)
    holder = guard.run_kind(out.parent)
    if holder is not None:
        raise DataError(f"--out {out}: inside a run folder ({out.parent}), which holds its "
                        "run's own files only; write the recording elsewhere")
    rr = _rerun()
    seq = StoreSequence(store)
    try:
        gt = seq.ground_truth
        est = None
        if run_dir is not None:
            if not (run_dir / "est_tum.txt").exists():
                raise DataError(f"{run_dir}: no est_tum.txt (not a finished run folder)")
            all_frames = run_dir / "est_all_tum.txt"  # every frame, when some have no GT
            est = read_tum(all_frames if all_frames.exists() else run_dir / "est_tum.txt")
        rec = rr.RecordingStream("doppler-bench", recording_id=f"view-{Path(store).stem}")
        with guard.saving(rec, out, guard.is_recording, "a rerun recording"):
            _log_sequence(rr, rec, seq, gt, est, stride)
            if pair is not None:
                _log_pair(rr, rec, store, pair, gt)
            rec.flush()
            rec.disconnect()
    finally:
        seq.close()
    return Path(out)


def _pose_at(traj: Trajectory | None, stamp: float) -> np.ndarray | None:
    if traj is None or len(traj) == 0:
        return None
    k = int(np.argmin(np.abs(traj.stamps - stamp)))
    return traj.poses[k] if abs(traj.stamps[k] - stamp) < 1e-6 else None


def _log_sequence(rr, rec, seq, gt, est, stride: int) -> None:
    if est is not None:  # the estimate in the GT's world: aligned at the first pose
        T0 = _pose_at(gt, est.stamps[0]) if gt is not None else None
        est = Trajectory(est.stamps, (T0 if T0 is not None else np.eye(4))
                         @ inv_T(est.poses[0]) @ est.poses)
        rec.log("world/estimate", rr.LineStrips3D([est.positions], colors=[[255, 140, 0]]),
                static=True)
    if gt is not None:
        rec.log("world/ground_truth", rr.LineStrips3D([gt.positions], colors=[[20, 20, 20]]),
                static=True)
    stamps = seq.stamps
    limit = None
    for i in range(0, len(seq), stride):
        scan = seq[i]
        T = _pose_at(gt, scan.stamp)
        if T is None:
            T = _pose_at(est, scan.stamp)
        rec.set_time("frame", sequence=i)
        rec.set_time("time", duration=float(scan.stamp - stamps[0]))
        points = transform_points(T, scan.points) if T is not None else scan.points
        if scan.doppler is not None:
            limit = limit or float(np.percentile(np.abs(scan.doppler), 95)) or 1.0
            colors = doppler_colors(scan.doppler, limit)
        else:
            colors = None
        rec.log("world/scan", rr.Points3D(points, colors=colors, radii=0.05))
        if T is not None:
            rec.log("world/sensor", rr.Points3D([T[:3, 3]], radii=0.4, colors=[[0, 160, 0]]))


def _log_pair(rr, rec, store: Path, frame: int, gt) -> None:
    from bench.report.figures.pair import pair_correspondences

    data = pair_correspondences(store, frame)
    T_src = _pose_at(gt, StoreSequence(store).stamps[frame]) if gt is not None else None
    T_src = np.eye(4) if T_src is None else T_src
    T_tgt = T_src @ inv_T(data["T_true"]) if data["T_true"] is not None else T_src
    src, tgt = transform_points(T_src, data["source"]), transform_points(T_tgt, data["target"])
    rec.set_time("frame", sequence=frame)
    for name, (s_idx, t_idx), rgb in (("closest", data["closest"], [220, 40, 40]),
                                      ("doppler", data["doppler"], [40, 160, 40])):
        strips = np.stack([src[s_idx], tgt[t_idx]], axis=1)
        rec.log(f"world/pair/{name}_correspondences", rr.LineStrips3D(strips, colors=[rgb]))
