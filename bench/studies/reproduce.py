"""``make reproduce-table``: the paper's Tables III, IV and V.

The tables are the experiments ``configs/experiments/table3.yaml`` (relative error and time),
``table4.yaml`` (APE, semi-dense radar) and ``table5.yaml`` (APE, dense LiDAR tunnels). Real
stores listed in ``configs/datasets/*.yaml`` and present under ``DATA_DIR/real/`` are used when
there are any; otherwise the synthetic suite ``synthetic-paper`` is generated (or reused) and
used. The union of the three tables' runs is planned once (a run two tables share runs once),
executed, and each table is written from its own runs. On the synthetic suite the fidelity
report (bench/studies/fidelity.py: every Table III cell next to the paper's, the paper's
findings checked) is written beside the tables and its path printed.
"""

from __future__ import annotations

import time
from pathlib import Path

from rich.console import Console

from bench.data.datasets import dataset_configs
from bench.paths import EXPERIMENTS
from bench.report.figures import make_figures
from bench.report.tables import write_tables
from bench.report.tables_ape import write_ape_tables
from bench.runs.experiment import Experiment, SequenceEntry, load_experiment
from bench.runs.job import Job, summarize
from bench.runs.plan import jobs_for_experiment, plan, suite_sequences
from bench.runs.progress import run_jobs
from bench.studies.fidelity import write_report

TABLES = {  # experiment -> (kind, output stem, caption)
    "table3": ("relative", "table3", ""),
    "table4": ("ape", "table4", "Table IV: absolute pose error [m] on the semi-dense 4D radar "
                                "sequences: translation RMSE"),
    "table5": ("ape", "table5", "Table V: absolute pose error [m] on the dense 4D LiDAR "
                                "tunnels: translation RMSE"),
}


def real_sequences(data_dir: Path) -> list[SequenceEntry]:
    """Paper sequences whose converted store exists under ``data_dir/real``."""
    return [SequenceEntry(path=data_dir / "real" / cfg.store, name=cfg.name,
                          display_name=cfg.display_name, sensor_class=cfg.sensor_class)
            for cfg in dataset_configs() if (data_dir / "real" / cfg.store).exists()]


def table_experiments(out: Path, data_dir: Path, real: list[SequenceEntry]) -> dict:
    """The three table experiments, pointed at ``out`` and at the real stores or the suite."""
    experiments = {}
    names = {s.name for s in real}
    for name in TABLES:
        exp = load_experiment(EXPERIMENTS / f"{name}.yaml")
        update = {"out": out, "data_dir": data_dir}
        if real:
            methods = []
            for m in exp.methods:
                wanted = [s for s in (m.sequences or names) if s in names]
                if wanted:
                    methods.append(m.model_copy(update={"sequences": wanted}))
            if not methods:
                continue
            update.update(suite=None, sequences=real, methods=methods)
        experiments[name] = Experiment.model_validate({**exp.model_dump(), **update})
    return experiments


def _columns(exp: Experiment) -> list[str]:
    """The APE table's columns: the sequences its methods name, in the YAML's order."""
    return list(dict.fromkeys(s for m in exp.methods for s in (m.sequences or [])))


def reproduce_table(out: Path, data_dir: Path, jobs: int, force: bool, synthetic_only: bool,
                    console: Console, executor: str = "process", scheduler: str | None = None,
                    job_timeout_s: float | None = None, scoring: dict | None = None
                    ) -> list[str]:
    """Run and write the three tables (and the KITTI-drift and velocity tables of Table III's
    runs); returns the failed runs' messages (empty on success). ``scoring``
    (``bench.commands.scoring_options``) overrides the lengths, KITTI lengths and alignment."""
    t0 = time.perf_counter()
    real = [] if synthetic_only else real_sequences(data_dir)
    if real:
        console.print(f"real stores: {', '.join(s.name for s in real)}")
        out = out if out != Path("results/paper-synthetic") else Path("results/paper-real")
    else:
        console.print(f"no real stores under {data_dir / 'real'}: using the synthetic suite "
                      "'synthetic-paper'")
    experiments = table_experiments(out, data_dir, real)
    given = {k: list(v) if isinstance(v, tuple) else v for k, v in (scoring or {}).items()
             if v is not None}
    if given:
        experiments = {k: e.model_copy(update=given) for k, e in experiments.items()}
    suites = {e.suite for e in experiments.values() if e.suite is not None}
    resolved = {name: suite_sequences(name, data_dir, console) for name in suites}
    experiments = {k: e if e.suite is None else e.model_copy(update={
        "suite": None, "sequences": resolved[e.suite]}) for k, e in experiments.items()}
    per_table: dict[str, list[Job]] = {
        name: plan(jobs_for_experiment(exp, console)) for name, exp in experiments.items()}
    all_jobs = plan([j for js in per_table.values() for j in js])
    outcomes = run_jobs(all_jobs, console, jobs, force, executor, job_timeout_s, scheduler)
    written = []
    for name, exp in experiments.items():
        kind, stem, caption = TABLES[name]
        only = {j.run_dir_override for j in per_table[name]}
        try:
            if kind == "relative":
                texts = write_tables(out, out, only=only, stem=stem)
                for metric in ("kitti", "velocity"):
                    write_tables(out, out, only=only, stem=f"{stem}_{metric}", metric=metric)
                    written.append(f"{stem}_{metric}")
            else:
                texts = write_ape_tables(out, out, _columns(exp), stem, caption, only=only)
        except FileNotFoundError:
            console.print(f"{stem}: no finished runs", style="red")
            continue
        written.append(stem)
        console.print(f"\n{stem}", style="bold")
        console.print(texts["md"], markup=False, highlight=False, soft_wrap=True)
    figures = make_figures(out)
    if figures:
        console.print(f"figures: {out / 'figures'}/ ({len(figures)} files)", markup=False)
    tables = ", ".join(sorted(written)) or "no table"
    console.print(f"{summarize(outcomes)} in {time.perf_counter() - t0:.0f} s; wrote {out}/"
                  f"{{{tables}}}.{{md,tex,csv}}", markup=False)
    if not real:
        report = write_report(out)
        console.print(f"fidelity report (synthetic suite vs the paper): {report}", markup=False)
    return [o.message for o in outcomes if o.status not in ("done", "skipped")]
