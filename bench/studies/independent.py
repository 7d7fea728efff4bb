"""``python -m bench.studies.independent``: each ICP-family baseline of ours beside an
independent implementation on the real radar frames (issue 25: "all six ICP-family baselines
within 1.15x of independent implementations at 8 m and 48 m"), each side tuned by the same
rule (configs/splits.yaml, bench/runs/tuning_rule.py).

Two experiments any ``bench run`` replays (the references loaded as a plugin,
``DOPPLER_BENCH_METHODS=bench.studies.independent_methods``):

1. ``configs/experiments/independent-real-tuning.yaml``: each reference's key settings swept
   on both halves of the real sample (A = store frames 0-124, B = 125-249) and on the
   synthetic radar domain, decided by the tuning rule against the reference's own default
   (criterion C: the mean over 8-48 m and both errors of the relative error divided by the
   default's; blocked cross-validation A -> B and B -> A; the synthetic radar as a veto; 1 %
   least gain; no edge of the grid) -- the rule our defaults were decided by. Besides the
   rule's decision over both folds, each half's own choice (:func:`half_choices`: the rule on
   that half alone, the synthetic veto kept, no validation half) is what the other half is
   scored against. The YAML's ``decided:`` records them; when a replay decides otherwise this
   says which and stops (no table from stale settings).
2. ``configs/experiments/independent-real-ours.yaml``: ours at their shipped defaults, with
   seed, on both halves.

Then the cross-fitted table: per baseline and half, ours on that half against the reference
on that half at the setting chosen on the OTHER half (its run is one of step 1's), at 8 m and
48 m (mean relative rotation [deg] / translation [m] error) and the ratio ours / reference of
each; a baseline passes on a half when all four ratios are at most ``LIMIT``. Written to
``results/independent/comparison.md`` and ``comparison.json``. Exit code 0 when every
baseline passes on both halves, 1 otherwise (or on a stale decision, a failed run).

The references (bench/studies/independent_methods.py): Open3D's point-to-plane ICP and
Generalized ICP pipelines for ``icp-p2plane`` and ``gicp``, small_gicp's own VGICP pipeline
for ``vgicp``, Open3D's Doppler ICP (the authors' implementation of DICP) for ``dicp``,
kiss-icp's own pipeline with its default config for ``kiss-icp``. ``doppler-icp`` (the
paper's Algorithm 1) has no library implementation: its reference is Open3D's Doppler ICP,
the closest independent Doppler + geometry ICP, a different algorithm.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console

from bench import guard
from bench.runs.tuning_rule import Decision, decide

ROOT = Path(__file__).resolve().parents[2]
TUNING = ROOT / "configs" / "experiments" / "independent-real-tuning.yaml"
OURS = ROOT / "configs" / "experiments" / "independent-real-ours.yaml"
OUT = ROOT / "results" / "independent"
PLUGIN = "bench.studies.independent_methods"
#: ours / reference at most this at every length, in rotation and in translation
LIMIT = 1.15
LENGTHS_M = (8.0, 48.0)
#: length [m] -> (mean rotation error [deg], mean translation error [m])
Errors = dict[float, tuple[float, float]]
#: ``decided:``'s key of the rule's decision over both folds (the others: the halves' names)
RULE = "rule"


@dataclass(frozen=True)
class Baseline:
    method: str      # ours
    reference: str   # the independent implementation (a plugin method)
    what: str        # what the reference is


BASELINES = (
    Baseline("icp-p2plane", "ref-open3d-p2plane", "Open3D point-to-plane ICP "
             "(voxel_down_sample, estimate_normals KNN, registration_icp PointToPlane)"),
    Baseline("gicp", "ref-open3d-gicp", "Open3D Generalized ICP (voxel_down_sample, "
             "estimate_normals KNN, registration_generalized_icp)"),
    Baseline("vgicp", "ref-small-gicp-vgicp", "small_gicp's own VGICP pipeline "
             "(preprocess_points, GaussianVoxelMap, align)"),
    Baseline("dicp", "ref-open3d-dicp", "Open3D's Doppler ICP (the DICP authors' "
             "implementation, open3d.t.pipelines.registration)"),
    Baseline("doppler-icp", "ref-open3d-dicp", "Open3D's Doppler ICP: NOT the same algorithm "
             "(no library implements the paper's Algorithm 1); the closest independent "
             "Doppler + geometry ICP"),
    Baseline("kiss-icp", "ref-kiss-icp", "kiss-icp's own pipeline (KissICP, the library's "
             "default config, range from the data)"),
)


@dataclass(frozen=True)
class Comparison:
    """One baseline on one half: ours and its reference's errors (None: no finished run or no
    segments of a length) and the ratios ours / reference; ``half`` the sequence scored and
    ``setting`` the reference's (chosen on ``tuned_on``), when known."""

    baseline: Baseline
    ours: Errors | None
    reference: Errors | None
    lengths_m: tuple[float, ...] = LENGTHS_M
    half: str | None = None
    tuned_on: str | None = None
    setting: dict | None = None

    def ratio(self, length_m: float, which: int) -> float | None:
        """ours / reference at ``length_m``, rotation (``which`` 0) or translation (1)."""
        if not self.ours or not self.reference or length_m not in self.ours \
                or length_m not in self.reference:
            return None
        ref = self.reference[length_m][which]
        return self.ours[length_m][which] / ref if ref > 0 else float("inf")

    def ratios(self) -> list[float | None]:
        return [self.ratio(x, i) for x in self.lengths_m for i in (0, 1)]

    @property
    def worst(self) -> float | None:
        r = self.ratios()
        return None if any(v is None for v in r) else max(r)

    @property
    def passed(self) -> bool:
        return self.worst is not None and self.worst <= LIMIT


def compare(errors: dict[str, Errors], baselines=BASELINES,
            lengths_m: tuple[float, ...] = LENGTHS_M, half: str | None = None,
            tuned_on: str | None = None, settings: dict[str, dict] | None = None
            ) -> list[Comparison]:
    """One ``Comparison`` per baseline from each method's errors (``errors``: method ->
    length -> (rotation, translation)) on ``half``; ``settings``: reference -> its setting
    (chosen on ``tuned_on``)."""
    return [Comparison(b, errors.get(b.method), errors.get(b.reference), tuple(lengths_m),
                       half, tuned_on, (settings or {}).get(b.reference))
            for b in baselines]


def _cell(errors: Errors | None, length_m: float) -> str:
    if not errors or length_m not in errors:
        return "-"
    rot, trans = errors[length_m]
    return f"{rot:.3f} / {trans:.3f}"


def _ratio_cell(c: Comparison, length_m: float) -> str:
    r = [c.ratio(length_m, i) for i in (0, 1)]
    return " / ".join("-" if v is None else (f"**{v:.2f}**" if v > LIMIT else f"{v:.2f}")
                      for v in r)


def _setting(point: dict | None) -> str:
    from bench.runs.sweep import format_value

    if point is None:
        return "-"
    return " ".join(f"{k}={format_value(v)}" for k, v in point.items())


def table_markdown(rows: list[Comparison]) -> str:
    """The comparison table (markdown) and what each reference is."""
    head = ["Baseline (ours)", "Reference"]
    halves = any(c.half for c in rows)
    if halves:
        head += ["Scored on", "Reference setting (tuned on)"]
    for x in rows[0].lengths_m if rows else LENGTHS_M:
        head += [f"ours {x:g} m", f"reference {x:g} m", f"ours / ref. {x:g} m"]
    head.append(f"within {LIMIT:g}x")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in rows:
        cells = [f"`{c.baseline.method}`", f"`{c.baseline.reference}`"]
        if halves:
            cells += [c.half or "-", f"{_setting(c.setting)} ({c.tuned_on or '-'})"]
        for x in c.lengths_m:
            cells += [_cell(c.ours, x), _cell(c.reference, x), _ratio_cell(c, x)]
        worst = c.worst
        cells.append("no run" if worst is None else
                     ("yes" if c.passed else "NO") + f" (worst {worst:.2f}x)")
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("Each cell: mean relative rotation [deg] / translation [m] error over the "
                 "segments of that length; ratios ours / reference (rotation / translation), "
                 f"above {LIMIT:g}x in bold." + (
                     " Ours at its shipped defaults; each reference at the setting the tuning "
                     "rule of configs/splits.yaml chose on the other half (cross-fitted)."
                     if halves else "") + " References:")
    for b in dict.fromkeys(c.baseline for c in rows):
        lines.append(f"- `{b.reference}` for `{b.method}`: {b.what}")
    return "\n".join(lines) + "\n"


def _errors_of(run, lengths_m) -> Errors:
    return {float(r.length_m): (r.rot_deg_mean, r.trans_m_mean)
            for r in run.result.relative_error if r.n and float(r.length_m) in lengths_m}


def errors_by_method(results_dir: Path, lengths_m=LENGTHS_M, sequence: str | None = None
                     ) -> dict[str, Errors]:
    """Each method's errors in a finished experiment (on ``sequence`` only, when given): its
    one unlabelled seeded (or guess-free) run; a method with several such runs is an error."""
    from bench.runs.folders import load_runs
    from methods.registry import Seed

    out: dict[str, Errors] = {}
    for run in load_runs(Path(results_dir)):
        if run.result.label is not None or run.result.seed is Seed.WITHOUT:
            continue
        if sequence is not None and run.sequence != sequence:
            continue
        if run.method in out:
            raise ValueError(f"{results_dir}: two runs of {run.method}")
        out[run.method] = _errors_of(run, lengths_m)
    return out


def half_choices(points: list[dict], errors: list, reference: int, criterion: dict
                 ) -> dict[str, Decision]:
    """The tuning rule on each half alone (its fold's tuning sequences; the criterion's
    domain as the veto, no validation half: the other half is what the choice is scored on):
    tuning half -> Decision. Plus ``RULE``: the rule's decision over every fold."""
    lengths = [float(x) for x in criterion["lengths_m"]]
    args = dict(level=criterion.get("level", 0.95), reps=criterion.get("reps", 1000),
                min_gain=criterion.get("min_gain", 0.0))
    domain = criterion.get("domain", [])
    folds = [(f["tuning"], f["validation"]) for f in criterion["folds"]]
    out = {RULE: decide(points, errors, reference, folds, domain, lengths, **args)}
    for tune, _ in folds:
        out["+".join(tune)] = decide(points, errors, reference, [(tune, [])], domain,
                                     lengths, **args)
    return out


def effective(decision: Decision, points: list[dict]) -> dict | None:
    """The setting a decision leaves in use: the chosen point; the reference when the rule
    asks for a wider grid first (nothing changes until it is widened); None when undecided
    (a run missing)."""
    if decision.chosen is not None:
        return dict(points[decision.chosen])
    return dict(points[decision.reference]) if decision.extend else None


@dataclass
class Tuned:
    """One reference's sweep in the tuning results: its points, each point's run folder per
    sequence, and the decisions of :func:`half_choices`."""

    method: str
    points: list[dict]
    runs: list[dict[str, Path]]
    decisions: dict[str, Decision]

    def setting(self, key: str) -> dict | None:
        return effective(self.decisions[key], self.points)

    def run_dir(self, point: dict, sequence: str) -> Path | None:
        from bench.report.tables.sweep import _same

        for p, runs in zip(self.points, self.runs, strict=True):
            if all(_same(p[k], point.get(k)) for k in p):
                return runs.get(sequence)
        return None


def tuned_references(tuning_dir: Path) -> dict[str, Tuned]:
    """Each reference sweep of the tuning results (``sweeps.json``) with its decisions."""
    from bench.report.tables.sweep import _reference_index
    from bench.runs.folders import read_run
    from bench.runs.sweep import read_sweep_index
    from bench.runs.tuning_rule import run_errors

    index = read_sweep_index(tuning_dir)
    criterion = index["criterion"]
    if not criterion or criterion.get("folds") is None:
        raise ValueError(f"{tuning_dir}: the sweep does not state the tuning rule")
    lengths = [float(x) for x in criterion["lengths_m"]]
    folds = {n for f in criterion["folds"] for n in f["tuning"] + f["validation"]}
    out = {}
    for sweep in index["sweeps"]:
        points = [p["point"] for p in sweep["points"]]
        runs = [{r["sequence"]: Path(tuning_dir) / r["dir"] for r in p["runs"] if r["seed"]}
                for p in sweep["points"]]
        # per point: its finished runs (None when a run on the folds' halves is missing; the
        # domain's runs are needed only where the folds admit a point, tuning_rule.decide)
        errors = []
        for point_runs in runs:
            done = {n: read_run(d) for n, d in point_runs.items()}
            done = {n: r for n, r in done.items() if r is not None}
            errors.append(None if not folds <= set(done) else
                          {n: run_errors(r.gt, r.est, lengths) for n, r in done.items()})
        out[sweep["method"]] = Tuned(sweep["method"], points, runs, half_choices(
            points, errors, _reference_index(sweep, criterion), criterion))
    return out


def stale_decisions(tuned: dict[str, Tuned], decided: dict | None) -> list[str]:
    """Where the tuning YAML's ``decided:`` is not what the runs decide (or a decision is
    missing): one line each; empty when every recorded setting is the replay's."""
    from bench.report.tables.sweep import _same

    problems = []
    for method, t in tuned.items():
        recorded = (decided or {}).get(method) or {}
        for key in t.decisions:
            have, want = recorded.get(key), t.setting(key)
            if want is None:
                problems.append(f"{method} ({key}): undecided ({t.decisions[key].text})")
            elif have is None or set(have) != set(want) or not all(
                    _same(have[k], want[k]) for k in want):
                problems.append(f"{method} ({key}): decided records {_setting(have)} but "
                                f"the runs decide {_setting(want)} ({t.decisions[key].text})")
    return problems


def cross_fitted(tuned: dict[str, Tuned], ours_dir: Path, halves: list[str],
                 baselines=BASELINES, lengths_m=LENGTHS_M) -> list[Comparison]:
    """Per half and baseline: ours on the half against the reference's run on the half at
    the setting chosen on the other half (two halves: each the other's)."""
    from bench.runs.folders import read_run

    rows = []
    for half in halves:
        (other,) = [h for h in halves if h != half]
        ours = errors_by_method(ours_dir, lengths_m, half)
        errors, settings = dict(ours), {}
        for b in baselines:
            t = tuned.get(b.reference)
            setting = t.setting(other) if t else None
            settings[b.reference] = setting
            run_dir = t.run_dir(setting, half) if t and setting else None
            run = read_run(run_dir) if run_dir else None
            if run is not None:
                errors[b.reference] = _errors_of(run, lengths_m)
        rows += compare(errors, baselines, lengths_m, half, other, settings)
    return rows


def decisions_markdown(tuned: dict[str, Tuned]) -> str:
    """Each reference's decisions (the rule over both folds, each half alone) and why."""
    lines = ["| Reference | Decision | Setting | Why |", "|---|---|---|---|"]
    for method, t in tuned.items():
        for key, d in t.decisions.items():
            what = "rule (both folds)" if key == RULE else f"tuned on {key} alone"
            lines.append(f"| `{method}` | {what} | {_setting(t.setting(key))} | {d.text} |")
    return "\n".join(lines) + "\n"


def run_experiment(console: Console, yaml_path: Path, jobs: int | None, force: bool,
                   executor: str) -> int:
    """One step: the experiment's runs, its table and, for a sweep, its index and sweep table
    (``sweeps.json``, ``sweep.md``: what ``stale_choices`` reads), as ``bench run
    EXPERIMENT.yaml`` writes them; built from the runs and report layers (this study sits
    below ``bench.commands``). Exit code 0 when every run finished or was reused, else 1."""
    from bench.report.tables.paper import write_tables
    from bench.report.tables.sweep import sweep_markdown
    from bench.runs.experiment import load_experiment
    from bench.runs.job import summarize
    from bench.runs.plan import jobs_for_experiment, plan
    from bench.runs.progress import run_jobs
    from bench.runs.sweep import sweep_index, write_sweep_index

    exp = load_experiment(yaml_path)
    job_list = plan(jobs_for_experiment(exp, console))
    sweeps = sweep_index(exp, job_list)
    outcomes = run_jobs(job_list, console, jobs or exp.jobs, force, executor, None, None)
    console.print(summarize(outcomes), markup=False)
    if any(o.status in ("done", "skipped") for o in outcomes):
        console.print(write_tables(exp.out_dir)["md"], markup=False, soft_wrap=True)
        if sweeps is not None:
            write_sweep_index(exp.out_dir, sweeps)
            text = sweep_markdown(exp.out_dir)
            guard.write_text(Path(exp.out_dir) / "sweep.md", text, guard.derived,
                             "a sweep table")
            console.print(text, markup=False, soft_wrap=True)
    return 1 if any(o.status not in ("done", "skipped") for o in outcomes) else 0


def index_experiment(console: Console, yaml_path: Path) -> None:
    """The experiment's sweep index (``sweeps.json``) written without running anything (what
    ``--no-run`` scores the finished runs by)."""
    from bench.runs.experiment import load_experiment
    from bench.runs.plan import jobs_for_experiment, plan
    from bench.runs.sweep import sweep_index, write_sweep_index

    exp = load_experiment(yaml_path)
    sweeps = sweep_index(exp, plan(jobs_for_experiment(exp, console)))
    if sweeps is not None:
        write_sweep_index(exp.out_dir, sweeps)


def _with_plugin() -> None:
    """The references registered here and in every worker (``DOPPLER_BENCH_METHODS``)."""
    from methods import registry

    loaded = [m.strip() for m in os.environ.get(registry.PLUGINS_ENV, "").split(",")
              if m.strip()]
    if PLUGIN not in loaded:
        os.environ[registry.PLUGINS_ENV] = ",".join([*loaded, PLUGIN])
    for cls in importlib.import_module(PLUGIN).METHODS:
        registry.METHODS.setdefault(cls.name, cls)


def write_outputs(rows: list[Comparison], out: Path, decisions: str = "") -> str:
    text = table_markdown(rows)
    if decisions:
        text += "\nThe references' settings (the tuning rule of configs/splits.yaml, " \
            "independent-real-tuning.yaml):\n\n" + decisions
    guard.output_folder(out)
    guard.write_text(out / "comparison.md", text, guard.derived, "a comparison")
    guard.write_text(out / "comparison.json", json.dumps([
        {"method": c.baseline.method, "reference": c.baseline.reference,
         "what": c.baseline.what, "half": c.half, "tuned_on": c.tuned_on,
         "setting": c.setting,
         "ours": {f"{x:g}": c.ours.get(x) for x in c.lengths_m} if c.ours else None,
         "reference_errors": ({f"{x:g}": c.reference.get(x) for x in c.lengths_m}
                              if c.reference else None),
         "ratios": {f"{x:g}": [c.ratio(x, 0), c.ratio(x, 1)] for x in c.lengths_m},
         "worst": c.worst, "limit": LIMIT, "passed": c.passed} for c in rows], indent=1) + "\n",
        guard.derived, "a comparison")
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="ICP-family baselines against independent "
                                 "implementations on the real radar frames, each tuned by the "
                                 "tuning rule (the references' sweep over both halves, ours "
                                 "at its defaults, then the cross-fitted table)")
    ap.add_argument("--jobs", type=int, default=None, help="parallel runs (default: the YAMLs')")
    ap.add_argument("--executor", default="process", help="local, process or dask")
    ap.add_argument("--force", action="store_true", help="run again even if finished")
    ap.add_argument("--out", type=Path, default=OUT, help="where the table is written")
    ap.add_argument("--no-run", action="store_true", help="start no run: decide and score "
                    "from the finished runs (a decision whose runs are missing is undecided)")
    args = ap.parse_args(argv)
    _with_plugin()
    from bench.runs.experiment import load_experiment

    console = Console()
    tuning = load_experiment(TUNING)
    ours_dir = load_experiment(OURS).out_dir
    tuned = None
    for step, yaml_path in (("tuning", TUNING), ("ours", OURS)):
        console.print(f"[bold]{step}[/bold]: {yaml_path.relative_to(ROOT)}")
        if args.no_run:
            index_experiment(console, yaml_path)
            code = 0
        else:
            code = run_experiment(console, yaml_path, args.jobs, args.force, args.executor)
        if code:
            console.print(f"{step}: a run failed (see above); no comparison table")
            return 1
        if step == "tuning":
            tuned = tuned_references(tuning.out_dir)
            stale = stale_decisions(tuned, tuning.decided)
            if stale:
                console.print("The recorded decisions are not the replay's; update `decided:` "
                              f"in {TUNING.relative_to(ROOT)}:\n" + "\n".join(stale),
                              markup=False)
                return 1
    halves = [f.tuning[0] for f in tuning.criterion.folds]
    rows = cross_fitted(tuned, ours_dir, halves)
    text = write_outputs(rows, args.out, decisions_markdown(tuned))
    console.print(text, markup=False, soft_wrap=True)
    console.print(f"written: {args.out / 'comparison.md'}", markup=False)
    return 0 if all(c.passed for c in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
