"""Commands that span the purpose folders (cli.py's commands each call one function):
``bench run`` (runs, then the experiment's table or the single run's key metrics) and
``bench synth`` (data generation, or the suite's fidelity studies)."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from rich.console import Console

from bench.runs.executors import EXECUTORS
from bench.runs.folders import read_run
from loaders.errors import DataError
from methods.registry import seed_option


def parse_lengths(text: str | None, option: str = "--lengths") -> tuple[float, ...] | None:
    """"8,16,48" -> (8.0, 16.0, 48.0) (None for None); a DataError names the option."""
    if text is None:
        return None
    try:
        values = tuple(float(x) for x in text.split(","))
    except ValueError:
        raise DataError(f"{option} {text!r}: expected numbers in metres, e.g. 8,48") from None
    if not values or min(values) <= 0:
        raise DataError(f"{option} {text!r}: expected positive lengths in metres")
    return values


def scoring_options(lengths: str | None, kitti_lengths: str | None,
                    alignment: str | None) -> dict:
    """The scoring options given on the command line (None: not given), checked."""
    from metrics.ape import Alignment
    from metrics.relative import MetricError

    if alignment is not None:
        try:
            alignment = Alignment.parse(alignment).name
        except MetricError as err:
            raise DataError(f"--alignment: {err}") from None
    return {"lengths_m": parse_lengths(lengths),
            "kitti_lengths_m": parse_lengths(kitti_lengths, "--kitti-lengths"),
            "alignment": alignment}


def run_command(console: Console, experiment: Path | None, method: str | None,
                data: Path | None, out: Path | None, seed: bool | None, params: dict,
                jobs: int | None, force: bool, executor: str, scheduler: str | None,
                job_timeout: float | None, scoring: dict | None = None) -> int:
    """Plan and run; returns the exit code (0 all done, 1 when any run failed). ``seed`` None:
    not given (a single run is seeded by default). ``scoring`` (``scoring_options``) overrides
    the experiment's lengths, KITTI lengths and alignment."""
    given = {k: list(v) if isinstance(v, tuple) else v for k, v in (scoring or {}).items()
             if v is not None}
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
        if given:
            exp = exp.model_copy(update=given)
        if out is not None:
            exp.out = out
        check_external(exp, experiment)
        check_tables(exp.out_dir)
        refused: list[str] = []
        job_list = plan(jobs_for_experiment(exp, console), refused)
        if refused and not job_list:
            raise DataError("every run of the experiment was refused:\n" + "\n".join(refused))
        workers, results_dir = jobs or exp.jobs, exp.out_dir
        sweeps = sweep_index(exp, job_list)
    else:
        refused = []
        if method is None or data is None:
            raise DataError("give an EXPERIMENT.yaml, or --method M --data PATH.h5 [--out DIR]")
        if seed is False and seed_option(method, False) is None:
            warnings.warn(f"{method} takes no initial guess: --no-seed changes nothing (it runs "
                          "once, as in the paper)", stacklevel=2)
        job_list = plan([single_job(method, data, seed is not False, out, params,
                                    {k: tuple(v) if isinstance(v, list) else v
                                     for k, v in given.items()})], own_only=True)
        workers, results_dir, sweeps = 1, None, None
    outcomes = run_jobs(job_list, console, workers, force, executor, job_timeout, scheduler)
    console.print(summarize(outcomes), markup=False)
    external = external_runs(exp, force, console) if experiment is not None else []
    if results_dir is not None and (any(o.status in ("done", "skipped") for o in outcomes)
                                    or any(status != "failed" for _, status, _ in external)):
        from bench.report.tables.paper import write_tables

        # tables are never wrapped mid-row (a terminal narrower than a row scrolls instead)
        console.print(write_tables(results_dir)["md"], markup=False, soft_wrap=True)
        if sweeps is not None:
            print_sweeps(results_dir, sweeps, console)
    elif results_dir is None and outcomes and outcomes[0].run_dir is not None:
        print_run_summary(outcomes[0].run_dir, console)
    for line in refused:  # pairs the experiment did not run, and what would make them run
        console.print(f"refused {line}", markup=False, soft_wrap=True)
    if refused:
        console.print(f"{len(refused)} run(s) refused (recorded as failed rows, status "
                      "refused); the others ran", markup=False)
    return 1 if refused or any(o.status not in ("done", "skipped") for o in outcomes) or \
        any(status == "failed" for _, status, _ in external) else 0


def check_tables(results_dir: Path) -> None:
    """Before anything runs: the experiment's results folder is a folder (not a run's) and its
    tables and sweep table, where they exist, the harness wrote (``bench.guard``)."""
    from bench import guard

    guard.output_folder(Path(results_dir))
    for name in ("table.md", "table.tex", "table.csv", "sweep.md"):
        guard.regenerated_file(Path(results_dir) / name, guard.derived, "a table")


def check_external(exp, experiment: Path) -> None:
    """Every file an ``external`` entry names exists (one clear error before anything runs)."""
    for i, e in enumerate(exp.external):
        for key in ("trajectory", "store", "stamps", "frame_times"):
            path = getattr(e, key)
            if path is not None and not Path(path).exists():
                raise DataError(f"{experiment}: external[{i}] ({e.name}): {key} {path} not found")


def external_runs(exp, force: bool, console: Console) -> list[tuple[str, str, str]]:
    """Score the experiment's ``external`` trajectories (``bench score`` for each) and say how
    each went."""
    if not exp.external:
        return []
    from bench.runs.external.score import score_experiment_external

    done = score_experiment_external(exp, force)
    for name, status, message in done:
        console.print(f"external {name}: {status}: {message}", markup=False)
    return done


def print_sweeps(results_dir: Path, index: dict, console: Console) -> None:
    """Write the experiment's sweep index and its sweep table (sweep.md), and print the table
    with each sweep's chosen point (bench/report/tables/sweep.py)."""
    from bench import guard
    from bench.report.tables.sweep import sweep_markdown
    from bench.runs.sweep import write_sweep_index

    write_sweep_index(results_dir, index)
    text = sweep_markdown(results_dir)
    guard.write_text(Path(results_dir) / "sweep.md", text, guard.derived, "a sweep table")
    console.print(text, markup=False, soft_wrap=True)


def _with_ci(value: float | None, ci: list | None) -> str:
    text = "-" if value is None else f"{value:.3f}"
    if value is not None and ci and None not in ci:
        text += f" [{ci[0]:.3f}, {ci[1]:.3f}]"
    return text


def print_run_summary(run_dir: Path, console: Console) -> None:
    """Key metrics of a finished single run, and its folder."""
    run = read_run(run_dir)
    if run is not None:
        res = run.result
        scored = res.lengths_m  # lengths with segments
        parts = []
        for length in dict.fromkeys(scored[:1] + scored[-1:]):  # the shortest and longest
            r = res.relative(length)
            parts.append(f"{length:g} m: {_with_ci(r.rot_deg_mean, r.rot_deg_mean_ci)} deg / "
                         f"{_with_ci(r.trans_m_mean, r.trans_m_mean_ci)} m")
        if res.ape is not None and res.ape.trans_rmse_m is not None:
            parts.append(f"APE {_with_ci(res.ape.trans_rmse_m, res.ape.trans_rmse_m_ci)} m "
                         f"({res.ape.alignment})")
        if res.kitti is not None and res.kitti.n:
            parts.append(f"KITTI {res.kitti.trans_pct:.2f} % / "
                         f"{res.kitti.rot_deg_per_100m:.2f} deg/100 m")
        if res.velocity is not None and res.velocity.norm_mean_mps is not None:
            parts.append(f"velocity error {res.velocity.norm_mean_mps:.3f} m/s "
                         f"({res.velocity.window_s:g} s windows)")
        if res.time_ms.mean is not None:
            parts.append(f"time {res.time_ms.mean:.2f} ms/frame")
        if run.diverged:
            parts.append("DIVERGED")
        if res.fallback_text():
            parts.append(res.fallback_text() + (" [fell back]" if res.fell_back else ""))
        console.print("; ".join(parts) or "no ground truth: no errors", markup=False)
        from bench.report.tables.ape import start_offset_note

        offset = start_offset_note(run)
        if offset:
            console.print(f"note: APE with {offset}", markup=False)
        if parts and scored:
            console.print(f"[low, high]: {100 * res.ci_level:g} % confidence intervals "
                          "(circular block bootstrap over the trajectory)", markup=False,
                          style="dim")
    console.print(f"run folder: {run_dir}", markup=False)


def score_command(console: Console, store: Path, spec, out: Path, force: bool,
                  scoring: dict) -> int:
    """``bench score``: score an external trajectory (``bench.runs.external.score``), print its
    coverage and key metrics."""
    from bench.runs.evaluate import Scoring
    from bench.runs.external.score import score_external
    from metrics.drift_intervals import set_threads

    # scoring alone (nothing else timed meanwhile): the APE resamples on every core we have
    given = {k: v for k, v in scoring.items() if v is not None}
    set_threads(min(len(os.sched_getaffinity(0)), 8))
    try:
        outcome = score_external(store, spec, out, Scoring(**given), force)
    finally:
        set_threads(1)
    c = outcome.coverage
    gap = ("no interpolation" if c["max_gap_s"] is None else
           f"{c['interpolated']} interpolated (--max-gap {c['max_gap_s']:g} s; the widest gap "
           f"bridged {c.get('widest_bridged_s', 0.0):.3g} s)")
    console.print(f"{spec.name}: {c['scored']} of the {c['scans_with_gt']} scans with ground "
                  f"truth scored ({100 * c['share_scored']:.1f} %; {c['matched']} matched within "
                  f"{c['tolerance_s']:g} s, {gap})"
                  + (" (unchanged: not scored again; --force to)" if outcome.status == "skipped"
                     else ""), markup=False)
    console.print(f"clock check: {outcome.clock}", markup=False)
    console.print(f"convention check: {outcome.convention}", markup=False)
    for warning in outcome.warnings:
        console.print(f"warning: {warning}", style="yellow", markup=False)
    console.print(f"poses moved to the sensor frame by T_frame_sensor = {outcome.frame}",
                  markup=False)
    run = read_run(outcome.run_dir)
    if run is not None:
        console.print(f"timing: {run.result.clock_note}", markup=False)
    print_run_summary(outcome.run_dir, console)
    return 0


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
