"""False alarms and detections of ``bench score``'s checks, measured
(``python -m bench.studies.score_checks [--runs EST_TUM ...] [--kiss TUM] [--json]``); its
cases are written to a temporary folder, removed after.

Every case of ``bench.studies.score_cases`` is read as ``bench score`` reads it
(``loaders.estimate.read_estimate``) and put through the contract's checks
(``bench.runs.external.checks.check_estimate``; no scoring). A correct case is a false alarm
when it is refused or warned; a faulty one is detected when it is refused (or warned, for a
bridged gap) with its cause's words, detected with another cause when refused for something
else, and missed when it passes. Prints one row per check and variant: cases, refused /
warned / passed, and for shifts the smallest size detected.

Tuning and reporting data (declared): the clock check's constants (``BLOCK_S``, ``LEVEL``)
were chosen looking at the sample's own runs (doppler, icp-p2plane, kiss-icp, doppler-ego on
the whole sample, its halves and frames 60-190, shifted by 0, +-0.1, +-0.37, 5 s); the
conventions' pair lengths ``PAIR_S`` (4 s added to 1 s) on the same runs read in w x y z order
(whole, frames 100-200, second half); the conventions' ``RATIO``, the orthonormality
tolerance and the bridged-gap limit were set before any measurement. The
sample's pieces and perturbations below overlap that tuning data (the same drive): the
synthetic drives are the data no constant was tuned on.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

from bench.runs.external.checks import check_estimate
from bench.runs.external.score import ExternalSpec
from bench.studies.score_cases import Base, correct_cases, fault_cases, pieces, synthetic_bases
from loaders.errors import DataError
from loaders.estimate import read_estimate
from loaders.posefile import read_tum
from loaders.store import StoreSequence

SAMPLE = Path(__file__).resolve().parents[2] / "samples" / "ntu4dradlm-loop1.h5"


def run_case(case) -> tuple[str, str]:
    """("passed" / "warned" / "refused", the message)."""
    spec = ExternalSpec(case.path, "study", **case.options)
    try:
        est = read_estimate(case.path, spec.fmt, spec.stamps, spec.topic, None, spec.stamp_unit)
        found = check_estimate(case.base.seq(), est, spec, np.eye(4), str(case.path), "store")
    except DataError as err:
        return "refused", str(err)
    if found.warnings:
        return "warned", " | ".join(found.warnings)
    return "passed", found.clock


def sample_bases(runs: list[Path], kiss: Path | None) -> list[Base]:
    seq = StoreSequence(SAMPLE, fields=())
    try:
        gt, scans = seq.ground_truth, seq.stamps
    finally:
        seq.close()
    out = [Base("sample: GT copy", "real", gt.stamps, gt.poses, scans, gt)]
    for path in runs:
        est = read_tum(path)
        out.append(Base(f"sample: {path.parent.name}", "real", est.stamps, est.poses, scans, gt))
    if kiss is not None:
        est = read_tum(kiss)
        out.append(Base("sample: kiss-icp pipeline on the exported bag", "real", est.stamps,
                        est.poses, scans, gt))
    return out


def classify(case, outcome: str, message: str) -> str:
    if case.cause is None:
        return "false alarm" if outcome != "passed" else "passed"
    if outcome == "passed":
        return "missed"
    causes = {"clock": ("its clock does not fit", "does not overlap", "--time-offset")}
    words = causes.get(case.cause, (case.cause,))
    return "detected" if any(w in message for w in words) else "other cause"


def study(runs: list[Path], kiss: Path | None, folder: Path, seed: int = 0) -> list[dict]:
    rng = np.random.default_rng(seed)
    rows = []
    real = sample_bases(runs, kiss)
    bases = [(b, True) for b in real] + [(b, True) for b in synthetic_bases(rng)]
    for b in real:
        bases += [(p, p.piece in ("flat speed", "straight")) for p in pieces(b)]
    for base, with_faults in bases:
        cases = correct_cases(base, folder, rng) + (fault_cases(base, folder) if with_faults
                                                    else [])
        for case in cases:
            outcome, message = run_case(case)
            rows.append({"base": base.name, "kind": base.kind, "piece": base.piece,
                         "variant": case.variant, "cause": case.cause, "size": case.size,
                         "outcome": outcome, "verdict": classify(case, outcome, message),
                         "message": message[:400]})
    return rows


def table(rows: list[dict]) -> str:
    """One markdown row per (variant, store kind): counts and the smallest shift detected."""
    groups = defaultdict(list)
    for r in rows:
        groups[(r["cause"] is not None, r["variant"], r["kind"])].append(r)
    lines = ["| input | store | cases | refused | warned | passed | verdict |",
             "|---|---|---:|---:|---:|---:|---|"]
    for (faulty, variant, kind), rs in sorted(groups.items()):
        n = len(rs)
        count = {o: sum(r["outcome"] == o for r in rs) for o in ("refused", "warned", "passed")}
        if not faulty:
            verdict = f"{count['refused'] + count['warned']} false alarms"
        else:
            det = sum(r["verdict"] == "detected" for r in rs)
            other = sum(r["verdict"] == "other cause" for r in rs)
            verdict = f"{det} detected, {other} other cause, {count['passed']} missed"
            sizes = sorted({abs(r["size"]) for r in rs if r["size"] is not None})
            if sizes and variant.startswith("shifted"):
                full = [all(r["verdict"] == "detected" for r in rs if abs(r["size"]) == s)
                        for s in sizes]
                upward = [s for k, s in enumerate(sizes) if all(full[k:])]
                verdict += (f"; every base at every size from {upward[0]:g} s" if upward else
                            "; some base missed at the largest size")
                verdict += "; detected per size " + ", ".join(
                    f"{s:g} s: {sum(r['verdict'] == 'detected' for r in rs if abs(r['size']) == s)}"
                    f"/{sum(abs(r['size']) == s for r in rs)}" for s in sizes)
        lines.append(f"| {'fault: ' if faulty else ''}{variant} | {kind} | {n} | "
                     f"{count['refused']} | {count['warned']} | {count['passed']} | {verdict} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="false alarms and detections of bench score's "
                                 "checks")
    ap.add_argument("--runs", type=Path, nargs="*", default=[],
                    help="est_tum.txt files of the harness's own runs on the sample")
    ap.add_argument("--kiss", type=Path, default=None,
                    help="kiss-icp pipeline's TUM poses on the sample's exported bag")
    ap.add_argument("--json", action="store_true", help="print every case as JSON after "
                    "the table")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="score-checks-") as folder:
        rows = study(args.runs, args.kiss, Path(folder))
    text = table(rows)
    print(text)
    if args.json:
        print(json.dumps(rows, indent=1))
    false_alarms = sum(r["verdict"] == "false alarm" for r in rows)
    return 1 if false_alarms else 0


if __name__ == "__main__":
    raise SystemExit(main())
