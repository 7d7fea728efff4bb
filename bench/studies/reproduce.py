"""``make reproduce-table``: the paper's Tables III, IV and V.

The tables are the experiments ``configs/experiments/table3.yaml`` (relative error and time),
``table4.yaml`` (APE, semi-dense radar) and ``table5.yaml`` (APE, dense LiDAR tunnels). Real
stores listed in ``configs/datasets/*.yaml`` and present under ``DATA_DIR/real/`` are used when
there are any; otherwise the synthetic suite ``synthetic-paper`` is generated (or reused) and
used. The union of the three tables' runs is planned once (a run two tables share runs once),
executed, and each table is written from its own runs. On the synthetic suite the fidelity
report (bench/studies/fidelity.py: every Table III cell next to the paper's, the paper's
findings checked) is written beside the tables and its path printed.

It says what it did: which of the paper's sequences it found under ``DATA_DIR/real`` and which
are missing, each real store checked against its dataset config (sensor kind, scan period,
path length: a warning when far off), only the tables that have rows written (a table none of
whose sequences is present is not, and an earlier one of that name is removed), and
``reproduction.json`` (data used, found, missing, tables written and not) and the results page
``report.html`` (``bench.report.html.page``) beside the tables.
"""

from __future__ import annotations

import json
import time
import warnings
from pathlib import Path

import numpy as np
from rich.console import Console

from bench import guard
from bench.data.datasets import dataset_configs
from bench.paths import EXPERIMENTS
from bench.report.figures.draw import make_figures
from bench.report.html.page import write_page
from bench.report.tables.ape import write_ape_tables
from bench.report.tables.paper import write_tables
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
    """Paper sequences whose converted store exists under ``data_dir/real`` (configs with
    ``paper: false``, e.g. NTU4DRadLM's whole routes, belong to public.yaml instead)."""
    return [SequenceEntry(path=data_dir / "real" / cfg.store, name=cfg.name,
                          display_name=cfg.display_name, sensor_class=cfg.sensor_class)
            for cfg in dataset_configs()
            if cfg.paper and (data_dir / "real" / cfg.store).exists()]


def missing_sequences(data_dir: Path) -> list[str]:
    """Paper sequences (``configs/datasets``) with no store under ``data_dir/real``."""
    return [cfg.name for cfg in dataset_configs()
            if cfg.paper and not (data_dir / "real" / cfg.store).exists()]


#: a store's scan period may differ from its dataset's by this fraction; its ground-truth path
#: length by this factor (either way) before ``check_store`` warns
PERIOD_TOLERANCE, PATH_FACTOR = 0.25, 3.0
#: the sequence's path over the store's duration outside this speed range [m/s]: the duration
#: is far off (``check_store``)
MIN_SPEED_MPS, MAX_SPEED_MPS = 0.3, 40.0


def check_store(cfg, path: Path) -> tuple[str, list[str]]:
    """A real store against its dataset config (``expected``: sensor kind, scan period, path
    length): a one-line description and the warnings for what is far off."""
    from loaders.store import StoreSequence

    seq = StoreSequence(path)
    try:
        stamps, gt, sensor = seq.stamps, seq.ground_truth, seq.sensor
        duration = float(stamps[-1] - stamps[0]) if len(stamps) > 1 else 0.0
        period = float(np.median(np.diff(stamps))) if len(stamps) > 1 else sensor.period_s
        path_m = gt.path_length_m() if gt is not None and len(gt) > 1 else None
    finally:
        seq.close()
    described = (f"{cfg.name}: {len(stamps)} frames, {duration:.1f} s, {sensor.kind} "
                 f"({sensor.model or 'model not recorded'}), period {period:.4f} s, GT path "
                 + (f"{path_m:.0f} m" if path_m is not None else "none"))
    exp, warns = cfg.expected, []
    if exp.sensor_kind and sensor.kind != exp.sensor_kind:
        warns.append(f"{path}: a {sensor.kind} store, but {cfg.name} is a {exp.sensor_kind} "
                     f"sequence ({cfg.sensor_class}): is it the right store?")
    if exp.period_s and abs(period / exp.period_s - 1) > PERIOD_TOLERANCE:
        warns.append(f"{path}: scans {period:.4f} s apart, but {cfg.name}'s sensor scans every "
                     f"{exp.period_s:.4f} s ({exp.source})")
    if exp.path_m and path_m is not None and not (
            exp.path_m / PATH_FACTOR <= path_m <= exp.path_m * PATH_FACTOR):
        warns.append(f"{path}: its ground truth's path is {path_m:.0f} m ({duration:.0f} s), "
                     f"far from {cfg.name}'s about {exp.path_m:.0f} m ({exp.source}): a part "
                     "of the sequence, or another one? Its numbers are not the paper's")
    if exp.path_m and duration > 0 and not (
            MIN_SPEED_MPS <= exp.path_m / duration <= MAX_SPEED_MPS):
        # no public figure gives these recordings' durations: the sequence's path over the
        # store's duration must be a speed a car, a cart or a person on foot could drive
        warns.append(f"{path}: {duration:.0f} s of scans, but {cfg.name} covers about "
                     f"{exp.path_m:.0f} m: that would be {exp.path_m / duration:.1f} m/s "
                     f"(expected {MIN_SPEED_MPS:g}-{MAX_SPEED_MPS:g} m/s), so the store's "
                     "duration is far off: a part of the sequence, or another one?")
    if path_m is None:
        warns.append(f"{path}: no ground truth: {cfg.name} gives no table row")
    return described, warns


def table_experiments(out: Path, data_dir: Path, real: list[SequenceEntry]) -> dict:
    """The table experiments that have rows, pointed at ``out`` and at the real stores or the
    suite; a table none of whose sequences is present is left out."""
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


def table_sequences(name: str) -> list[str]:
    """The paper sequences a table experiment names (its methods' ``sequences``)."""
    exp = load_experiment(EXPERIMENTS / f"{name}.yaml")
    return list(dict.fromkeys(s for m in exp.methods for s in (m.sequences or [])))


def _columns(exp: Experiment) -> list[str]:
    """The APE table's columns: the sequences its methods name, in the YAML's order."""
    return list(dict.fromkeys(s for m in exp.methods for s in (m.sequences or [])))


def _choose_data(data_dir: Path, synthetic_only: bool, console: Console
                 ) -> tuple[list[SequenceEntry], list[str]]:
    """The real stores to use (none: the synthetic suite) and the notes that say so."""
    real_dir = data_dir / "real"
    found = real_sequences(data_dir)
    total = sum(cfg.paper for cfg in dataset_configs())
    if synthetic_only:
        extra = (f" (ignoring {len(found)} real store(s) under {real_dir}: "
                 f"{', '.join(s.name for s in found)})" if found else "")
        console.print(f"synthetic only (as asked): using the synthetic suite 'synthetic-paper'"
                      f"{extra}", markup=False)
        return [], []
    if not found:
        console.print(f"no real stores under {real_dir} (the paper's sequences, "
                      "configs/datasets/*.yaml): using the synthetic suite 'synthetic-paper'",
                      markup=False)
        return [], []
    missing = missing_sequences(data_dir)
    console.print(f"real stores under {real_dir}: {len(found)} of the paper's {total} "
                  f"sequences found ({', '.join(s.name for s in found)})", markup=False)
    notes = []
    if missing:
        note = (f"missing ({len(missing)} of {total}): {', '.join(missing)}; the tables hold "
                "only the sequences found (configs/datasets/NAME.yaml says how to convert each)")
        console.print(note, style="yellow", markup=False)
        notes.append(note)
    configs = {c.name: c for c in dataset_configs()}
    for s in found:
        described, warns = check_store(configs[s.name], Path(s.path))
        console.print(f"  {described}", markup=False, highlight=False)
        for w in warns:
            warnings.warn(w, stacklevel=2)
            notes.append(w)
    return found, notes


def plan_tables(experiments: dict[str, Experiment], console: Console
                ) -> tuple[dict[str, list[Job]], list[Job]]:
    """Each table's planned jobs and their union, planned once more as one set (a run two
    tables share runs once). The per-table plans are quiet: every warning a plan gives (a path
    too short for a length, ...) is said once, by the union's plan."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        per_table = {name: plan(jobs_for_experiment(exp, console))
                     for name, exp in experiments.items()}
    return per_table, plan([j for js in per_table.values() for j in js])


def _remove_stale(out: Path, stem: str, console: Console) -> None:
    """Remove ``stem``'s files left by an earlier reproduction: this one writes no such table,
    so they would show runs that are not part of it."""
    removed = [p for p in (out / f"{stem}.{fmt}" for fmt in ("md", "tex", "csv"))
               if guard.derived(p)]  # tables of ours only: a user's file is left alone
    for p in removed:
        guard.remove(p, guard.derived, "a table")
    if removed:
        console.print(f"removed {out}/{stem}.* of an earlier reproduction (not part of this "
                      "one)", markup=False)


def _check_outputs(out: Path) -> None:
    """``out`` can take the reproduction: a folder (or new), not a run's, and its tables and
    page, where they exist, the harness's own (``bench.guard``)."""
    guard.output_folder(out)
    for _, stem, _ in TABLES.values():
        for name in (stem, f"{stem}_kitti", f"{stem}_velocity"):
            for fmt in ("md", "tex", "csv"):
                guard.regenerated_file(out / f"{name}.{fmt}", guard.derived, "a table")
    guard.regenerated_file(out / "report.html", guard.derived, "a report page")
    for name in ("fidelity.md", "fidelity.csv", "reproduction.json"):
        guard.regenerated_file(out / name, guard.derived, "a reproduction record")


def reproduce_table(out: Path, data_dir: Path, jobs: int, force: bool, synthetic_only: bool,
                    console: Console, executor: str = "process", scheduler: str | None = None,
                    job_timeout_s: float | None = None, scoring: dict | None = None,
                    marks: str = "intervals", ci: bool = False) -> list[str]:
    """Run and write the tables that have rows (and the KITTI-drift and velocity tables of
    Table III's runs); returns the failed runs' messages (empty on success). Says which paper
    sequences it found and which are missing, writes ``reproduction.json`` (what was used,
    found, missing and written) and the HTML page. ``scoring``
    (``bench.commands.scoring_options``) overrides the lengths, KITTI lengths and alignment;
    ``marks`` is the tables' marking rule (``bench.report.tables.model.MARK_RULES``); ``ci``
    prints each figure's interval in the cells (as ``bench table --ci``)."""
    t0 = time.perf_counter()
    _check_outputs(out)  # at once, before the suite is generated and anything runs
    real, notes = _choose_data(data_dir, synthetic_only, console)
    if real and out == Path("results/paper-synthetic"):
        out = Path("results/paper-real")
        _check_outputs(out)
    experiments = table_experiments(out, data_dir, real)
    given = {k: list(v) if isinstance(v, tuple) else v for k, v in (scoring or {}).items()
             if v is not None}
    if given:
        experiments = {k: e.model_copy(update=given) for k, e in experiments.items()}
    suites = {e.suite for e in experiments.values() if e.suite is not None}
    resolved = {name: suite_sequences(name, data_dir, console) for name in suites}
    experiments = {k: e if e.suite is None else e.model_copy(update={
        "suite": None, "sequences": resolved[e.suite]}) for k, e in experiments.items()}
    per_table, all_jobs = plan_tables(experiments, console)
    outcomes = run_jobs(all_jobs, console, jobs, force, executor, job_timeout_s, scheduler)
    written, not_written = [], {}
    for name in TABLES:
        kind, stem, caption = TABLES[name]
        if name not in experiments:
            _remove_stale(out, stem, console)
            not_written[stem] = ("none of its sequences found "
                                 f"({', '.join(table_sequences(name))})")
            continue
        exp = experiments[name]
        only = {j.run_dir_override for j in per_table[name]}
        try:
            if kind == "relative":
                texts = write_tables(out, out, only=only, stem=stem, marks=marks, ci=ci)
                for metric in ("kitti", "velocity"):
                    write_tables(out, out, only=only, stem=f"{stem}_{metric}", metric=metric,
                                 marks=marks, ci=ci)
                    written.append(f"{stem}_{metric}")
            else:
                texts = write_ape_tables(out, out, _columns(exp), stem, caption, only=only,
                                         marks=marks, ci=ci)
        except FileNotFoundError:
            _remove_stale(out, stem, console)
            not_written[stem] = "no finished run"
            console.print(f"{stem}: no finished runs", style="red")
            continue
        written.append(stem)
        console.print(f"\n{stem}", style="bold")
        console.print(texts["md"], markup=False, highlight=False, soft_wrap=True)
    figures = make_figures(out)
    if figures:
        console.print(f"figures: {out / 'figures'}/ ({len(figures)} files)", markup=False)
    tables = ", ".join(f"{out}/{stem}.{{md,tex,csv}}" for stem in written) or "no table"
    console.print(f"{summarize(outcomes)} in {time.perf_counter() - t0:.0f} s; wrote {tables}",
                  markup=False)
    for stem, why in not_written.items():
        console.print(f"not written: {stem} ({why})", markup=False)
    if not real:
        report = write_report(out)
        console.print(f"fidelity report (synthetic suite vs the paper): {report}", markup=False)
    names = [s.name for s in real] if real else [s.name for seqs in resolved.values()
                                                  for s in seqs]
    record = {"data": (f"real stores under {data_dir / 'real'}" if real else
                       "the synthetic suite 'synthetic-paper' (synthetic data, not the paper's)"),
              "found": list(dict.fromkeys(names)),
              "missing": missing_sequences(data_dir) if real else [],
              "tables_written": written, "tables_not_written": not_written,
              "notes": notes + [f"{stem} not written: {why}" for stem, why in
                                not_written.items()]}
    guard.write_text(out / "reproduction.json", json.dumps(record, indent=2), guard.derived,
                     "a reproduction record")
    page, _ = write_page(out)
    console.print(f"results page: {page}", markup=False)
    return [o.message for o in outcomes if o.status not in ("done", "skipped")]
