"""Commands that span the purpose folders (cli.py's commands each call one function):
``bench run`` (runs, then the experiment's table or the single run's key metrics) and
``bench synth`` (data generation, or the suite's fidelity studies)."""

from __future__ import annotations

import warnings
from pathlib import Path

from rich.console import Console

from bench.runs.executors import EXECUTORS
from bench.runs.folders import read_run
from loaders.errors import DataError
from methods.registry import seed_option


def run_command(console: Console, experiment: Path | None, method: str | None,
                data: Path | None, out: Path | None, seed: bool | None, params: dict,
                jobs: int | None, force: bool, executor: str, scheduler: str | None,
                job_timeout: float | None) -> int:
    """Plan and run; returns the exit code (0 all done, 1 when any run failed). ``seed`` None:
    not given (a single run is seeded by default)."""
    from bench.runs.experiment import load_experiment
    from bench.runs.job import summarize
    from bench.runs.plan import jobs_for_experiment, plan, single_job
    from bench.runs.progress import run_jobs
    from bench.runs.sweep import sweep_index

    if executor not in EXECUTORS:
        raise DataError(f"unknown executor {executor!r}; choose from {', '.join(EXECUTORS)}")
    if experiment is not None:
        single = [name for name, value in (("--method", method), ("--data", data),
                                           ("-p/--param", params or None),
                                           ("--seed/--no-seed", seed)) if value is not None]
        if single:
            raise DataError(f"{', '.join(single)} set a single run and would be ignored beside "
                            f"{experiment}, which lists its own methods, stores, parameters and "
                            "seed options: edit the YAML, or run `bench run --method M --data "
                            "STORE.h5` without it")
        exp = load_experiment(experiment)
        if out is not None:
            exp.out = out
        job_list = plan(jobs_for_experiment(exp, console))
        workers, results_dir = jobs or exp.jobs, exp.out_dir
        sweeps = sweep_index(exp, job_list)
    else:
        if method is None or data is None:
            raise DataError("give an EXPERIMENT.yaml, or --method M --data PATH.h5 [--out DIR]")
        if seed is False and seed_option(method, False) is None:
            warnings.warn(f"{method} takes no initial guess: --no-seed changes nothing (it runs "
                          "once, as in the paper)", stacklevel=2)
        job_list = plan([single_job(method, data, seed is not False, out, params)])
        workers, results_dir, sweeps = 1, None, None
    outcomes = run_jobs(job_list, console, workers, force, executor, job_timeout, scheduler)
    console.print(summarize(outcomes), markup=False)
    if results_dir is not None and any(o.status in ("done", "skipped") for o in outcomes):
        from bench.report.tables import write_tables

        # tables are never wrapped mid-row (a terminal narrower than a row scrolls instead)
        console.print(write_tables(results_dir)["md"], markup=False, soft_wrap=True)
        if sweeps is not None:
            print_sweeps(results_dir, sweeps, console)
    elif results_dir is None and outcomes and outcomes[0].run_dir is not None:
        print_run_summary(outcomes[0].run_dir, console)
    return 1 if any(o.status not in ("done", "skipped") for o in outcomes) else 0


def print_sweeps(results_dir: Path, index: dict, console: Console) -> None:
    """Write the experiment's sweep index and its sweep table (sweep.md), and print the table
    with each sweep's chosen point (bench/report/tables_sweep.py)."""
    from bench.report.tables_sweep import sweep_markdown
    from bench.runs.sweep import write_sweep_index
    from loaders.fileio import atomic_write_text

    write_sweep_index(results_dir, index)
    text = sweep_markdown(results_dir)
    atomic_write_text(Path(results_dir) / "sweep.md", text)
    console.print(text, markup=False, soft_wrap=True)


def print_run_summary(run_dir: Path, console: Console) -> None:
    """Key metrics of a finished single run, and its folder."""
    run = read_run(run_dir)
    if run is not None:
        rel = run.relative_error
        scored = [k for k, r in rel.items() if r.get("n")]  # lengths with segments
        parts = []
        for length in dict.fromkeys(scored[:1] + scored[-1:]):  # the shortest and longest
            r = rel[length]
            parts.append(f"{length} m: {r['rot_deg_mean']:.3f} deg / "
                         f"{r['trans_m_mean']:.3f} m")
        if run.ape.get("trans_rmse_m") is not None:
            parts.append(f"APE {run.ape['trans_rmse_m']:.3f} m")
        if run.time_ms.get("mean") is not None:
            parts.append(f"time {run.time_ms['mean']:.2f} ms/frame")
        if run.diverged:
            parts.append("DIVERGED")
        console.print("; ".join(parts) or "no ground truth: no errors", markup=False)
    console.print(f"run folder: {run_dir}", markup=False)


def synth_dispatch(console: Console, fidelity: bool, fidelity_out: Path, realism: bool,
                   data_dir: Path, **synth_options) -> int:
    """``bench synth --fidelity`` (the paper's tables on the synthetic suite, run when missing,
    then the fidelity report) / ``--realism`` (studies), else ``synth_command``."""
    if fidelity:
        from bench.studies.reproduce import reproduce_table

        return 1 if reproduce_table(fidelity_out, data_dir, 2, False, True, console) else 0
    if realism:
        from bench.studies.realism import main as realism_main

        return realism_main([])
    from bench.data.synth import synth_command

    return synth_command(console, data_dir=data_dir, **synth_options)
