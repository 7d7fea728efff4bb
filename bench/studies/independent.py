"""``python -m bench.studies.independent``: each ICP-family baseline of ours beside an
independent implementation on the real radar frames (issue 25: "all six ICP-family baselines
within 1.15x of independent implementations at 8 m and 48 m").

Two steps, both experiments any ``bench run`` replays with the references loaded as a plugin
(``DOPPLER_BENCH_METHODS=bench.studies.independent_methods``):

1. ``configs/experiments/independent-real-tuning.yaml``: each reference's settings chosen on
   the declared tuning frames only (store frames 0-124 of samples/ntu4dradlm-loop1.h5) by a
   sweep of its key settings, criterion the mean translation error at 8 and 48 m (that of
   configs/tuning). The choices must be the settings the validation YAML runs: when they are
   not, this says which and stops (no table from stale settings).
2. ``configs/experiments/independent-real-validation.yaml``: ours at their defaults and each
   reference at its chosen settings, all with seed, on the validation frames 125-249 (never
   tuned on).

Then one table: per baseline, ours and its reference at 8 m and 48 m (mean relative rotation
[deg] / translation [m] error) and the ratio ours / reference of each; a baseline passes when
all four ratios are at most ``LIMIT``. Written to ``results/independent/comparison.md`` and
``comparison.json``. Exit code 0 when every baseline passes, 1 otherwise (or on a stale
choice, a failed run).

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

ROOT = Path(__file__).resolve().parents[2]
TUNING = ROOT / "configs" / "experiments" / "independent-real-tuning.yaml"
VALIDATION = ROOT / "configs" / "experiments" / "independent-real-validation.yaml"
OUT = ROOT / "results" / "independent"
PLUGIN = "bench.studies.independent_methods"
#: ours / reference at most this at every length, in rotation and in translation
LIMIT = 1.15
LENGTHS_M = (8.0, 48.0)
#: length [m] -> (mean rotation error [deg], mean translation error [m])
Errors = dict[float, tuple[float, float]]


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
    """One baseline: ours and its reference's errors (None: no finished run or no segments
    of a length) and the ratios ours / reference."""

    baseline: Baseline
    ours: Errors | None
    reference: Errors | None
    lengths_m: tuple[float, ...] = LENGTHS_M

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
            lengths_m: tuple[float, ...] = LENGTHS_M) -> list[Comparison]:
    """One ``Comparison`` per baseline from each method's errors (``errors``: method ->
    length -> (rotation, translation))."""
    return [Comparison(b, errors.get(b.method), errors.get(b.reference), tuple(lengths_m))
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


def table_markdown(rows: list[Comparison]) -> str:
    """The comparison table (markdown) and what each reference is."""
    head = ["Baseline (ours)", "Reference"]
    for x in rows[0].lengths_m if rows else LENGTHS_M:
        head += [f"ours {x:g} m", f"reference {x:g} m", f"ours / ref. {x:g} m"]
    head.append(f"within {LIMIT:g}x")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for c in rows:
        cells = [f"`{c.baseline.method}`", f"`{c.baseline.reference}`"]
        for x in c.lengths_m:
            cells += [_cell(c.ours, x), _cell(c.reference, x), _ratio_cell(c, x)]
        worst = c.worst
        cells.append("no run" if worst is None else
                     ("yes" if c.passed else "NO") + f" (worst {worst:.2f}x)")
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append("Each cell: mean relative rotation [deg] / translation [m] error over the "
                 "segments of that length; ratios ours / reference (rotation / translation), "
                 f"above {LIMIT:g}x in bold. References:")
    for b in dict.fromkeys(c.baseline for c in rows):
        lines.append(f"- `{b.reference}` for `{b.method}`: {b.what}")
    return "\n".join(lines) + "\n"


def errors_by_method(results_dir: Path, lengths_m=LENGTHS_M) -> dict[str, Errors]:
    """Each method's errors in a finished experiment: its one unlabelled seeded (or
    guess-free) run; a method with several such runs is an error."""
    from bench.runs.folders import load_runs
    from methods.registry import Seed

    out: dict[str, Errors] = {}
    for run in load_runs(Path(results_dir)):
        if run.result.label is not None or run.result.seed is Seed.WITHOUT:
            continue
        if run.method in out:
            raise ValueError(f"{results_dir}: two runs of {run.method}")
        out[run.method] = {float(r.length_m): (r.rot_deg_mean, r.trans_m_mean)
                           for r in run.result.relative_error
                           if r.n and float(r.length_m) in lengths_m}
    return out


def stale_choices(tuning_dir: Path, validation_yaml: Path) -> list[str]:
    """Where the validation YAML's reference settings are not the tuning sweep's choice (or
    a sweep chose nothing): one line each; empty when every choice is what it runs."""
    from bench.report.tables_sweep import _same, sweep_choices
    from bench.runs.experiment import load_experiment

    entries = {m.name: m for m in load_experiment(validation_yaml).methods}
    problems = []
    for choice in sweep_choices(tuning_dir):
        if choice.point is None:
            problems.append(f"{choice.group}: no point of the tuning sweep finished")
            continue
        entry = entries.get(choice.method)
        if entry is None:
            problems.append(f"{choice.method}: chosen on the tuning frames but not in "
                            f"{validation_yaml.name}")
            continue
        differs = {k: (entry.params.get(k), v) for k, v in choice.point.items()
                   if not _same(entry.params.get(k), v)}
        if differs:
            problems.append(f"{choice.method}: {validation_yaml.name} runs " + ", ".join(
                f"{k}={has} but the tuning sweep chose {k}={want}"
                for k, (has, want) in differs.items()))
    return problems


def run_experiment(console: Console, yaml_path: Path, jobs: int | None, force: bool,
                   executor: str) -> int:
    """One step: the experiment's runs, its table and, for a sweep, its index and sweep table
    (``sweeps.json``, ``sweep.md``: what ``stale_choices`` reads), as ``bench run
    EXPERIMENT.yaml`` writes them; built from the runs and report layers (this study sits
    below ``bench.commands``). Exit code 0 when every run finished or was reused, else 1."""
    from bench.report.tables import write_tables
    from bench.report.tables_sweep import sweep_markdown
    from bench.runs.experiment import load_experiment
    from bench.runs.job import summarize
    from bench.runs.plan import jobs_for_experiment, plan
    from bench.runs.progress import run_jobs
    from bench.runs.sweep import sweep_index, write_sweep_index
    from loaders.fileio import atomic_write_text

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
            atomic_write_text(Path(exp.out_dir) / "sweep.md", text)
            console.print(text, markup=False, soft_wrap=True)
    return 1 if any(o.status not in ("done", "skipped") for o in outcomes) else 0


def _with_plugin() -> None:
    """The references registered here and in every worker (``DOPPLER_BENCH_METHODS``)."""
    from methods import registry

    loaded = [m.strip() for m in os.environ.get(registry.PLUGINS_ENV, "").split(",")
              if m.strip()]
    if PLUGIN not in loaded:
        os.environ[registry.PLUGINS_ENV] = ",".join([*loaded, PLUGIN])
    for cls in importlib.import_module(PLUGIN).METHODS:
        registry.METHODS.setdefault(cls.name, cls)


def write_outputs(rows: list[Comparison], out: Path) -> str:
    from loaders.fileio import atomic_write_text

    text = table_markdown(rows)
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "comparison.md", text)
    atomic_write_text(out / "comparison.json", json.dumps([
        {"method": c.baseline.method, "reference": c.baseline.reference,
         "what": c.baseline.what,
         "ours": {f"{x:g}": c.ours.get(x) for x in c.lengths_m} if c.ours else None,
         "reference_errors": ({f"{x:g}": c.reference.get(x) for x in c.lengths_m}
                              if c.reference else None),
         "ratios": {f"{x:g}": [c.ratio(x, 0), c.ratio(x, 1)] for x in c.lengths_m},
         "worst": c.worst, "limit": LIMIT, "passed": c.passed} for c in rows], indent=1) + "\n")
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="ICP-family baselines against independent "
                                 "implementations on the real radar frames (tuning, then "
                                 "validation)")
    ap.add_argument("--jobs", type=int, default=None, help="parallel runs (default: the YAMLs')")
    ap.add_argument("--executor", default="process", help="local, process or dask")
    ap.add_argument("--force", action="store_true", help="run again even if finished")
    ap.add_argument("--out", type=Path, default=OUT, help="where the table is written")
    args = ap.parse_args(argv)
    _with_plugin()
    from bench.runs.experiment import load_experiment

    console = Console()
    tuning_dir = load_experiment(TUNING).out_dir
    validation_dir = load_experiment(VALIDATION).out_dir
    steps = (("tuning", TUNING), ("validation", VALIDATION))
    for step, yaml_path in steps:
        console.print(f"[bold]{step}[/bold]: {yaml_path.relative_to(ROOT)}")
        code = run_experiment(console, yaml_path, args.jobs, args.force, args.executor)
        if code:
            console.print(f"{step}: a run failed (see above); no comparison table")
            return 1
        if step == "tuning":
            stale = stale_choices(tuning_dir, VALIDATION)
            if stale:
                console.print("The validation settings are not the tuning choices; update "
                              f"{VALIDATION.relative_to(ROOT)}:\n" + "\n".join(stale),
                              markup=False)
                return 1
    rows = compare(errors_by_method(validation_dir))
    text = write_outputs(rows, args.out)
    console.print(text, markup=False, soft_wrap=True)
    console.print(f"written: {args.out / 'comparison.md'}", markup=False)
    return 0 if all(c.passed for c in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
