"""CI regression: the experiment ``configs/experiments/ci.yaml`` against a committed baseline.

The baseline (``configs/ci/baseline.json``) holds, per sequence x method x seed option (seeded
and no-seed runs both), the mean relative rotation [deg] and translation [m] error at every
length, and whether the run diverged. The check is two-sided, with the same ``tolerance``
(10 %) plus a small absolute floor (1 mm, 0.01 deg: below those the synthetic numbers are at
rounding level) either way:
- a **regression** (fails): an error grows beyond it, a run newly diverges, a run or a length
  of the baseline is missing;
- **to review** (fails too, unless accepted): an error drops beyond it or a run no longer
  diverges (a bug that shrinks errors, e.g. scoring against the wrong frames, looks like an
  improvement: a person looks before the baseline moves), and a run not in the baseline yet
  (it is checked against nothing). ``--accept-improvements`` lets improvements pass (printed);
  ``--update`` rewrites the baseline from the current results and prints what changed.
Smaller differences are printed as "changed" and pass.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

from bench import guard
from bench.paths import CI_BASELINE as BASELINE
from bench.paths import CI_EXPERIMENT
from bench.runs.folders import load_runs
from bench.runs.result import RunResult
from methods.registry import Seed

FLOOR = {"rot_deg": 0.01, "trans_m": 0.001}


def _key(result: RunResult) -> str:
    seed = {Seed.WITH: "seed", Seed.WITHOUT: "noseed", Seed.NONE: "-"}[result.seed]
    return f"{result.sequence}/{result.method}/{seed}"


def snapshot(results_dir: Path, only: set[Path] | None = None) -> dict:
    """{run key: {"diverged", "rot_deg": {length: mean}, "trans_m": {length: mean}}} (lengths
    written as in the baseline file: "8", "16" ...)."""
    out = {}
    for run in load_runs(results_dir, only):
        res = run.result
        scored = [r for r in res.relative_error if r.n]
        out[_key(res)] = {
            "diverged": bool(res.diverged),
            "rot_deg": {f"{r.length_m:g}": r.rot_deg_mean for r in scored},
            "trans_m": {f"{r.length_m:g}": r.trans_m_mean for r in scored},
        }
    return dict(sorted(out.items()))


#: what a ``Finding`` is (``kind``): fails CI / fails until reviewed / passes
REGRESSION, IMPROVED, NEW_RUN, CHANGED = "regression", "improved", "new run", "changed"
#: what to do about each kind
ADVICE = {
    REGRESSION: "deliberate? accept it with `bench regress --update`",
    IMPROVED: "review it, then accept it with `bench regress --update` (or let it pass with "
              "--accept-improvements)",
    NEW_RUN: "not in the baseline, so checked against nothing: run `bench regress --update`",
}


@dataclass
class Finding:
    run: str
    what: str
    baseline: float | None
    current: float | None
    kind: str = CHANGED

    @property
    def regression(self) -> bool:
        return self.kind == REGRESSION

    @property
    def review(self) -> bool:
        """An improvement or a new run: fails until a person accepts it."""
        return self.kind in (IMPROVED, NEW_RUN)

    def __str__(self) -> str:
        mark = {REGRESSION: "REGRESSION", IMPROVED: "! improved: review",
                NEW_RUN: "! new run, not in baseline", CHANGED: "changed"}[self.kind]
        return f"{mark:>10}  {self.run}  {self.what}: {_fmt(self.baseline)} -> " \
               f"{_fmt(self.current)}"


def _fmt(x) -> str:
    return "-" if x is None else (f"{x:.4f}" if isinstance(x, float) else str(x))


def check(baseline: dict, current: dict, tolerance: float = 0.10) -> list[Finding]:
    """Every difference between two snapshots, each with its ``kind`` (module docstring)."""
    findings = []
    for run in sorted(set(baseline) | set(current)):
        b, c = baseline.get(run), current.get(run)
        if b is None:
            findings.append(Finding(run, "run", None, "present", NEW_RUN))
            continue
        if c is None:
            findings.append(Finding(run, "run", "present", None, REGRESSION))
            continue
        if c["diverged"] != b["diverged"]:
            findings.append(Finding(run, "diverged", b["diverged"], c["diverged"],
                                    REGRESSION if c["diverged"] else IMPROVED))
        for q in ("rot_deg", "trans_m"):
            for length in sorted(set(b[q]) | set(c[q]), key=float):
                old, new = b[q].get(length), c[q].get(length)
                if old is None or new is None:
                    findings.append(Finding(run, f"{q} at {length} m", old, new,
                                            REGRESSION if new is None else NEW_RUN))
                    continue
                if not (math.isfinite(old) and math.isfinite(new)):
                    continue
                if new > old * (1 + tolerance) + FLOOR[q]:
                    kind = REGRESSION
                elif new < old * (1 - tolerance) - FLOOR[q]:
                    kind = IMPROVED
                elif abs(new - old) > 1e-9:
                    kind = CHANGED
                else:
                    continue
                findings.append(Finding(run, f"{q} at {length} m", old, new, kind))
    return findings


def failing(findings: list[Finding], accept_improvements: bool = False) -> list[Finding]:
    """The findings that fail CI: regressions, new runs, and improvements unless accepted."""
    return [f for f in findings if f.regression or f.kind == NEW_RUN
            or (f.kind == IMPROVED and not accept_improvements)]


def read_baseline(path: Path | None = None) -> dict:
    path = path or BASELINE
    if not path.exists():
        raise FileNotFoundError(f"{path}: no CI baseline yet; run `bench regress --update`")
    return json.loads(path.read_text())["runs"]


def write_baseline(current: dict, path: Path | None = None) -> None:
    path = path or BASELINE
    guard.write_text(path, json.dumps({
        "about": "bench regress baseline: mean relative error per sequence/method/seed and "
                 "length of configs/experiments/ci.yaml; update with `bench regress --update`",
        "runs": current}, indent=1) + "\n", is_baseline, "a regress baseline")


def is_baseline(path: Path) -> bool:
    """A baseline ``write_baseline`` wrote (its ``about`` says so): what --update replaces."""
    try:
        about = json.loads(Path(path).read_text()).get("about", "")
    except (OSError, ValueError, AttributeError):
        return False
    return isinstance(about, str) and about.startswith("bench regress baseline")


def regress_command(console, update: bool, tolerance: float, jobs: int,
                    data_dir: Path | None = None, out: Path | None = None,
                    accept_improvements: bool = False) -> int:
    """Run the CI experiment (finished runs reused; its suite under ``data_dir``, its runs under
    ``out``, default the experiment's) and compare with the baseline (or, with ``update``,
    rewrite it and print what changed); returns the exit code: 1 when a finding fails
    (``failing``), else 0."""
    from bench.runs.experiment import load_experiment
    from bench.runs.job import summarize
    from bench.runs.plan import jobs_for_experiment, plan
    from bench.runs.progress import run_jobs

    exp = load_experiment(CI_EXPERIMENT)
    if data_dir is not None:
        exp.data_dir = Path(data_dir)
    if out is not None:
        exp.out = Path(out)
    outcomes = run_jobs(plan(jobs_for_experiment(exp, console)), console, jobs)
    if any(o.status not in ("done", "skipped") for o in outcomes):
        console.print(summarize(outcomes), markup=False)
        return 1
    current = snapshot(exp.out_dir, {o.run_dir for o in outcomes})
    baseline = {} if update and not BASELINE.exists() else read_baseline(BASELINE)
    findings = check(baseline, current, tolerance)
    for f in findings:
        console.print(str(f), markup=False)
    if update:
        write_baseline(current, BASELINE)
        console.print(f"baseline updated: {BASELINE} ({len(findings)} changes)", markup=False)
        return 0
    regressions = sum(f.regression for f in findings)
    improved = sum(f.kind == IMPROVED for f in findings)
    new_runs = sum(f.kind == NEW_RUN for f in findings)
    console.print(f"{len(current)} runs, {len(findings)} changes, {regressions} regressions, "
                  f"{improved} improvements to review"
                  f"{' (accepted)' if accept_improvements and improved else ''}, "
                  f"{new_runs} new runs or lengths not in the baseline", markup=False)
    bad = failing(findings, accept_improvements)
    for kind in (REGRESSION, IMPROVED, NEW_RUN):
        if any(f.kind == kind for f in bad):
            console.print(f"{kind}: {ADVICE[kind]}", markup=False)
    return 1 if bad else 0
