"""False alarms and detections of ``bench run``'s ground-truth checks
(``python -m bench.studies.run_checks_study``).

What ``bench run`` checks of a store's ground truth, and where:

- ``loaders.gt.clean_trajectory`` (through ``gt_for_frames``, when the run is planned and
  scored): a row repeating the previous stamp *and* pose is a duplicate, dropped with a
  ``GroundTruthWarning``; a repeated stamp with another pose, or a stamp going backwards, is
  refused (``DataError``).
- ``bench.runs.plan._lengths_problems``: a warning when a segment length (or a KITTI length)
  does not fit into the GT's path; a refusal when none does.
- ``bench.runs.evaluate.score``: a refusal when no frame has ground truth (a GT that does not
  overlap the scans; raised when the run is scored, after the method ran).

Frames without GT (a gap, a lag cutting the ends) are left unscored by ``gt_for_frames``
without a warning (the run's metrics give ``frames_scored``): the table counts them. A jump in
the GT's positions and a stalled GT (poses repeated) have no check in ``bench run``
(``bench inspect`` reports repeats, not jumps).

Correct inputs: the vendored NTU4DRadLM sample (whole, halves, frames 60-189) and synthetic
sequences (a loop with the NTU GT pipeline at 10 Hz, a straight drive, a flat speed profile,
campus with its GT pipeline); realistic perturbations of each: GT positions jittered by 5 mm,
the GT resampled to 5 Hz, the GT lagged by 20 ms. Segment lengths are set from each input's
own path (half of it and 1.2 x, KITTI 0.9 x): they fit the as-is GT. Nothing was tuned here.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

from bench.runs.evaluate import score
from bench.runs.plan import _lengths_problems
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.store import StoreSequence
from loaders.synthetic.generate import SyntheticSequence
from loaders.trajectory import Trajectory

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "ntu4dradlm-loop1.h5"
SYNTHETIC = {
    "loop, radar-eagle, NTU GT pipeline": ("loop", "radar-eagle", {"gt": "ntu4dradlm"}),
    "straight drive": ("straight-wall", "radar-sparse", {"attitude_deg": 0.0}),
    "flat speed 8 m/s": ("loop", "radar-eagle", {"speed": (8.0, 8.0)}),
    "campus, its GT pipeline": ("campus", "radar-frgen21", {"gt": "campus"}),
}


def inputs(frames: int = 250) -> list[tuple[str, np.ndarray, Trajectory]]:
    """(name, scan stamps, ground truth) of every correct input."""
    out = []
    seq = StoreSequence(SAMPLE)
    try:
        stamps, gt = np.asarray(seq.stamps, dtype=np.float64), seq.ground_truth
    finally:
        seq.close()
    n = len(stamps)
    for label, a, b in (("sample whole", 0, n), ("sample first half", 0, n // 2),
                        ("sample second half", n // 2, n), ("sample frames 60-189", 60, 190)):
        s = stamps[a:b]
        keep = (gt.stamps >= s[0] - 1e-6) & (gt.stamps <= s[-1] + 1e-6)
        out.append((label, s, Trajectory(gt.stamps[keep], gt.poses[keep])))
    for label, (scene, sensor, opts) in SYNTHETIC.items():
        syn = SyntheticSequence(scene, sensor, frames, **opts)
        out.append((label, np.asarray(syn.stamps, dtype=np.float64), syn.ground_truth))
    return out


def jittered(gt: Trajectory, sigma_m: float = 0.005, seed: int = 0) -> Trajectory:
    poses = gt.poses.copy()
    poses[:, :3, 3] += np.random.default_rng(seed).normal(0.0, sigma_m, (len(gt), 3))
    return Trajectory(gt.stamps.copy(), poses)


def resampled(gt: Trajectory, rate_hz: float = 5.0) -> Trajectory:
    t = np.arange(gt.stamps[0], gt.stamps[-1] + 1e-9, 1.0 / rate_hz)
    return gt.interpolate(t)


def lagged(gt: Trajectory, lag_s: float = 0.02) -> Trajectory:
    return Trajectory(gt.stamps + lag_s, gt.poses.copy())


PASS = {"as is": lambda g: g, "jittered 5 mm": jittered, "resampled to 5 Hz": resampled,
        "lagged 20 ms": lagged}


def run_checks(stamps: np.ndarray, gt: Trajectory, lengths: tuple[float, ...],
               kitti: tuple[float, ...]) -> dict:
    """What ``bench run``'s GT checks say of ``gt`` against scans at ``stamps``: warnings,
    the refusal (or ""), the frames scored."""
    from bench.runs.job import Job

    job = Job(store=Path("store.h5"), method="icp-p2p", seed=0, out_root=Path("."),
              lengths_m=lengths, kitti_lengths_m=kitti, name="store")
    found: list[str] = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            poses, scored = gt_for_frames(gt, stamps, name="store")
            if not scored.any():
                score(poses, poses, np.zeros(len(stamps)), scored=scored, name="store")
            problems = _lengths_problems(job, gt.path_length_m(), set())
            if problems:
                raise DataError(problems[0])
            refusal = ""
        except DataError as err:
            refusal, scored = str(err), np.zeros(len(stamps), dtype=bool)
        found = [str(w.message) for w in caught]
    return {"warnings": found, "refusal": refusal, "scored": int(scored.sum()),
            "frames": len(stamps)}


def _drop_window(gt: Trajectory, seconds: float) -> Trajectory:
    mid = 0.5 * (gt.stamps[0] + gt.stamps[-1])
    keep = np.abs(gt.stamps - mid) > 0.5 * seconds
    return Trajectory(gt.stamps[keep], gt.poses[keep])


def _jump(gt: Trajectory, metres: float) -> Trajectory:
    poses = gt.poses.copy()
    poses[len(gt) // 2:, 0, 3] += metres
    return Trajectory(gt.stamps.copy(), poses)


def _stall(gt: Trajectory, rows: int) -> Trajectory:
    poses = gt.poses.copy()
    m = len(gt) // 2
    poses[m:m + rows] = poses[m - 1]
    return Trajectory(gt.stamps.copy(), poses)


def _duplicates(gt: Trajectory, rows: int) -> Trajectory:
    idx = np.sort(np.r_[np.arange(len(gt)), np.linspace(1, len(gt) - 2, rows).astype(int)])
    return Trajectory(gt.stamps[idx], gt.poses[idx])


def _two_poses(gt: Trajectory, rows: int) -> Trajectory:
    dup = _duplicates(gt, rows)
    poses = dup.poses.copy()
    same = np.flatnonzero(np.diff(dup.stamps) == 0) + 1
    poses[same, 1, 3] += 0.01
    return Trajectory(dup.stamps, poses)


def _backwards(gt: Trajectory, seconds: float) -> Trajectory:
    s = gt.stamps.copy()
    s[len(s) // 2] -= seconds + (s[len(s) // 2] - s[len(s) // 2 - 1])
    return Trajectory(s, gt.poses.copy())


def _shifted(gt: Trajectory, fraction: float) -> Trajectory:
    span = gt.stamps[-1] - gt.stamps[0]
    return Trajectory(gt.stamps + fraction * span, gt.poses.copy())


def _truncated(gt: Trajectory, fraction: float) -> Trajectory:
    n = max(2, int(round(fraction * len(gt))))
    return Trajectory(gt.stamps[:n], gt.poses[:n])


#: fault -> (make(gt, size), sizes, unit)
FAULTS = {
    "duplicate rows (logged twice)": (_duplicates, (1, 5), "rows"),
    "repeated stamp, other pose": (_two_poses, (1, 5), "rows"),
    "stamp going backwards": (_backwards, (0.001, 0.1), "s"),
    "GT not overlapping (shifted)": (_shifted, (1.01, 2.0), "x span"),
    "GT partly overlapping (shifted)": (_shifted, (0.2, 0.5), "x span"),
    "GT stops early": (_truncated, (0.9, 0.4), "of rows kept"),
    "gap in the GT": (_drop_window, (0.5, 2.0), "s"),
    "position jump": (_jump, (0.5, 5.0), "m"),
    "stalled GT (pose repeated)": (_stall, (3, 20), "rows"),
}


def _said(r: dict) -> str:
    if r["refusal"]:
        return "refused"
    if r["warnings"]:
        return "warned"
    return "silent"


def study(frames: int = 250) -> list[dict]:
    rows = []
    for name, stamps, gt in inputs(frames):
        path = gt.path_length_m()
        lengths, kitti = (0.5 * path, 1.2 * path), (0.9 * path,)
        for what, change in PASS.items():
            r = run_checks(stamps, change(gt), lengths, kitti)
            rows.append({"input": name, "case": what, "kind": "pass", "size": "",
                         "said": _said(r), "unscored": r["frames"] - r["scored"],
                         "text": (r["refusal"] or "; ".join(r["warnings"]))[:100]})
        for what, (make, sizes, unit) in FAULTS.items():
            for size in sizes:
                r = run_checks(stamps, make(gt, size), lengths, kitti)
                rows.append({"input": name, "case": what, "kind": "fault",
                             "size": f"{size:g} {unit}", "said": _said(r),
                             "unscored": r["frames"] - r["scored"],
                             "text": (r["refusal"] or "; ".join(r["warnings"]))[:100]})
    return rows


def table(rows: list[dict]) -> str:
    lines = ["| GT | size | inputs | refused | warned | silent | frames unscored (median) |",
             "|---|---|---:|---:|---:|---:|---:|"]
    keys = list(dict.fromkeys((r["case"], r["size"]) for r in rows))
    for case, size in keys:
        rs = [r for r in rows if r["case"] == case and r["size"] == size]
        count = {k: sum(r["said"] == k for r in rs) for k in ("refused", "warned", "silent")}
        lines.append(f"| {case} | {size or '-'} | {len(rs)} | {count['refused']} | "
                     f"{count['warned']} | {count['silent']} | "
                     f"{int(np.median([r['unscored'] for r in rs]))} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="false alarms and detections of bench run's "
                                     "ground-truth checks")
    parser.add_argument("--frames", type=int, default=250, help="synthetic frames")
    parser.add_argument("--verbose", action="store_true", help="every row and its message")
    args = parser.parse_args(argv)
    rows = study(args.frames)
    print(table(rows))
    if args.verbose:
        for r in rows:
            print(r)
    alarms = [r for r in rows if r["kind"] == "pass" and r["said"] != "silent"]
    return 1 if alarms else 0


if __name__ == "__main__":
    raise SystemExit(main())
