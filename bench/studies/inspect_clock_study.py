"""False alarms and detections of ``bench inspect``'s GT-clock check
(``bench.data.inspect_checks.clock_offset_lines``), measured on the vendored NTU4DRadLM sample
(``python -m bench.studies.inspect_clock_study``).

The Doppler speeds are computed once (``methods.ego_velocity.speed_from_doppler``); the
ground truth is then lagged by known amounts and the check run on the whole sample, its halves
and 100-frame windows every 25 frames. Correct inputs (lag 0, the ground truth jittered by
2 cm, or nearest-sampled from 10 Hz like NTU's): a warning is a false alarm. Faults (lags of
0.2 - 2 s, beyond one scan period): a warning is a detection, "inconclusive" or "not estimated"
says the data could not tell, a green line is a miss. Nothing here tuned the check (its
constants predate this study).
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from bench.data.inspect_checks import clock_offset_lines
from loaders.gt import nearest_indices
from loaders.store import StoreSequence
from loaders.trajectory import Trajectory

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "ntu4dradlm-loop1.h5"
LAGS_S = (0.2, 0.5, 1.0, 2.0)


class _Piece(SimpleNamespace):
    def __len__(self):
        return len(self.stamps)


def verdict(lines: list[tuple[str, str]]) -> str:
    style, text = lines[0]
    if text.startswith("warning:"):
        return "warned"
    if "not estimated" in text or "inconclusive" in text or "cannot time" in text:
        return "cannot tell"
    return "passed"


def windows(n: int) -> list[tuple[str, slice]]:
    out = [("whole", slice(0, n)), ("first half", slice(0, n // 2)),
           ("second half", slice(n // 2, n))]
    return out + [(f"frames {a}-{a + 100}", slice(a, a + 100)) for a in range(0, n - 99, 25)]


def variants(gt: Trajectory, rng: np.random.Generator) -> list[tuple[str, float | None,
                                                                     Trajectory]]:
    jit = gt.poses.copy()
    jit[:, :3, 3] += rng.normal(0, 0.02, (len(gt), 3))
    idx = nearest_indices(gt.stamps, np.round(gt.stamps / 0.1) * 0.1)[0]
    out = [("as is", None, gt), ("GT jittered 2 cm", None, Trajectory(gt.stamps, jit)),
           ("GT from 10 Hz, nearest", None, Trajectory(gt.stamps, gt.poses[idx]))]
    for lag in LAGS_S:
        for sign in (1, -1):
            out.append(("GT lagged", sign * lag, Trajectory(gt.stamps + sign * lag, gt.poses)))
    return out


def study(seed: int = 0) -> list[dict]:
    from methods.ego_velocity import speed_from_doppler

    seq = StoreSequence(SAMPLE)
    try:
        speeds, gt, stamps = speed_from_doppler(seq), seq.ground_truth, seq.stamps
        sensor, provenance = seq.sensor, seq.provenance
    finally:
        seq.close()
    rng = np.random.default_rng(seed)
    rows = []
    for name, gt_v in ((v[0], v) for v in variants(gt, rng)):
        _, lag, traj = gt_v
        for piece, sl in windows(len(stamps)):
            cut = _Piece(stamps=stamps[sl], ground_truth=traj, provenance=provenance,
                         sensor=sensor)
            part = {k: v[sl] for k, v in speeds.items()}
            lines = clock_offset_lines(cut, part)
            rows.append({"variant": name, "lag": lag, "piece": piece,
                         "outcome": verdict(lines), "line": lines[0][1]})
    return rows


def table(rows: list[dict]) -> str:
    groups = defaultdict(list)
    for r in rows:
        groups[(r["variant"], None if r["lag"] is None else abs(r["lag"]))].append(r)
    lines = ["| GT | lag [s] | pieces | warned | cannot tell | passed |",
             "|---|---:|---:|---:|---:|---|"]
    for (variant, lag), rs in sorted(groups.items(), key=lambda kv: (kv[0][1] or 0, kv[0][0])):
        c = {o: sum(r["outcome"] == o for r in rs) for o in ("warned", "cannot tell", "passed")}
        lines.append(f"| {variant} | {'-' if lag is None else f'+-{lag:g}'} | {len(rs)} | "
                     f"{c['warned']} | {c['cannot tell']} | {c['passed']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    argparse.ArgumentParser(description="false alarms and detections of bench inspect's "
                            "GT-clock check on the sample").parse_args(argv)
    rows = study()
    print(table(rows))
    return 1 if any(r["lag"] is None and r["outcome"] == "warned" for r in rows) else 0


if __name__ == "__main__":
    raise SystemExit(main())
