"""Jobs (one sequence x method x seed option) and their execution, serial or in processes.

A finished job (its ``metrics.json`` exists) is skipped unless ``force``; a job that raises is
recorded in ``failed.json`` and the others carry on.
"""

from __future__ import annotations

import os
import queue as queue_mod
import time
import traceback
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
)

from bench.evaluate import evaluate_run
from bench.results import is_finished, run_dir_name, write_failure, write_run
from loaders.errors import DataError
from loaders.store import StoreSequence
from methods.registry import get_method, make_method
from metrics.relative import DEFAULT_LENGTHS_M

SENSOR_CLASSES = {
    "radar-sparse": "Sparse 4D Radar",
    "radar-semidense": "Semi-Dense 4D Radar",
    "lidar-dense": "Dense 4D LiDAR",
}


@dataclass(frozen=True)
class Job:
    store: Path
    method: str
    seed: bool | None
    out_root: Path
    params: dict = field(default_factory=dict)
    lengths_m: tuple[float, ...] = DEFAULT_LENGTHS_M
    name: str | None = None
    display_name: str | None = None
    sensor_class: str | None = None
    run_dir_override: Path | None = None

    @property
    def label(self) -> str:
        return f"{self.name or self.store.stem} / {run_dir_name(self.method, self.seed)}"

    def run_dir(self, sequence_name: str) -> Path:
        if self.run_dir_override is not None:
            return self.run_dir_override
        return self.out_root / sequence_name / run_dir_name(self.method, self.seed)


@dataclass
class JobOutcome:
    job: Job
    status: str  # "done", "skipped", "failed"
    message: str = ""
    frames: int = 0
    wall_s: float = 0.0


def sequence_labels(seq: StoreSequence, job: Job) -> tuple[str, str, str]:
    """(name, display name, sensor class) from the job, else the store's provenance."""
    prov = seq.provenance
    name = job.name or seq.name
    display = job.display_name or prov.get("display_name") or name
    klass = (job.sensor_class or prov.get("sensor_class") or prov.get("class")
             or SENSOR_CLASSES.get(seq.sensor.model)
             or ("Dense 4D LiDAR" if seq.sensor.kind == "lidar" else "4D Radar"))
    return name, display, klass


def run_job(job: Job, force: bool = False,
            on_frame: Callable[[int, int], None] | None = None) -> JobOutcome:
    """Run one job and write its folder. ``on_frame(done, total)`` reports progress."""
    t0 = time.perf_counter()
    try:
        seq = StoreSequence(job.store)
    except DataError as err:
        return JobOutcome(job, "failed", str(err))
    name, display, klass = sequence_labels(seq, job)
    run_dir = job.run_dir(name)
    if is_finished(run_dir) and not force:
        return JobOutcome(job, "skipped", str(run_dir))
    method_cls = get_method(job.method)
    config = {
        "sequence": {"name": name, "display_name": display, "sensor_class": klass,
                     "store": str(job.store), "frames": len(seq),
                     "sensor_kind": seq.sensor.kind, "sensor_model": seq.sensor.model,
                     "period_s": seq.sensor.period_s},
        "method": {"name": job.method, "description": method_cls.description,
                   "uses_initial_guess": method_cls.uses_initial_guess},
        "seed": job.seed,
        "lengths_m": list(job.lengths_m),
    }
    try:
        method = make_method(job.method, job.params, seq.sensor)
        params = getattr(method, "params", None)
        config["method"]["params"] = params.model_dump() if params is not None else {}
        total = len(seq)
        result = method.run(seq, seed=bool(job.seed),
                            on_frame=(lambda i: on_frame(i + 1, total)) if on_frame else None)
        evaluation = evaluate_run(seq.ground_truth, result, job.lengths_m, name=str(job.store))
        metrics = {"sequence": name, "method": job.method, "seed": job.seed,
                   "frames": len(seq), **evaluation.metrics}
        write_run(run_dir, result, evaluation.gt, config, metrics)
        return JobOutcome(job, "done", str(run_dir), len(seq), time.perf_counter() - t0)
    except Exception as err:  # noqa: BLE001 - record any failure and carry on
        write_failure(run_dir, config, f"{type(err).__name__}: {err}", traceback.format_exc())
        return JobOutcome(job, "failed", f"{type(err).__name__}: {err}",
                          wall_s=time.perf_counter() - t0)
    finally:
        seq.close()


def _worker(job: Job, force: bool, q) -> JobOutcome:
    last = [0.0]

    def report(done: int, total: int) -> None:
        now = time.monotonic()
        if done == total or now - last[0] > 0.2:
            last[0] = now
            q.put((job.label, done, total))

    return run_job(job, force, report)


def _progress(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}", style="bold"), BarColumn(),
                    MofNCompleteColumn(), TaskProgressColumn(),
                    TextColumn("{task.fields[fps]} frames/s"), TimeElapsedColumn(),
                    console=console, transient=False)


def execute(jobs: list[Job], workers: int = 1, force: bool = False,
            console: Console | None = None) -> list[JobOutcome]:
    """Run ``jobs`` with a progress bar (frames per second); serial or in ``workers`` processes."""
    console = console or Console()
    outcomes: list[JobOutcome] = []
    with _progress(console) as progress:
        overall = progress.add_task(f"{len(jobs)} runs", total=len(jobs), fps="-")
        tasks: dict[str, tuple[int, float]] = {}

        def update(label: str, done: int, total: int) -> None:
            if label not in tasks:
                tasks[label] = (progress.add_task(label, total=total, fps="-"), time.monotonic())
            task, start = tasks[label]
            fps = done / max(time.monotonic() - start, 1e-9)
            progress.update(task, completed=done, fps=f"{fps:6.1f}")

        def finish(outcome: JobOutcome) -> None:
            outcomes.append(outcome)
            progress.advance(overall)
            if outcome.job.label in tasks:
                progress.remove_task(tasks.pop(outcome.job.label)[0])
            style = {"done": "green", "skipped": "dim", "failed": "red"}[outcome.status]
            extra = (f"{outcome.frames / outcome.wall_s:.1f} frames/s"
                     if outcome.status == "done" and outcome.wall_s > 0 else outcome.message)
            progress.console.print(f"[{style}]{outcome.status:>7}[/] {outcome.job.label}  {extra}")

        if workers <= 1:
            for job in jobs:
                finish(run_job(job, force, lambda d, t, j=job: update(j.label, d, t)))
            return outcomes
        # separate processes; one BLAS thread each so workers do not fight over the cores
        for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ.setdefault(var, "1")
        # longest jobs first (iterative methods on large stores), so workers finish together
        jobs = sorted(jobs, key=_expected_cost, reverse=True)
        ctx = get_context("spawn")
        with ctx.Manager() as manager, ProcessPoolExecutor(workers, mp_context=ctx) as pool:
            q = manager.Queue()
            pending = {pool.submit(_worker, job, force, q): job for job in jobs}
            while pending:
                try:
                    while True:
                        update(*q.get(timeout=0.1))
                except queue_mod.Empty:
                    pass
                for fut in [f for f in pending if f.done()]:
                    job = pending.pop(fut)
                    try:
                        finish(fut.result())
                    except Exception as err:  # noqa: BLE001 - a crashed worker process
                        finish(JobOutcome(job, "failed", f"worker crashed: {err}"))
    return outcomes


def _expected_cost(job: Job) -> float:
    size = job.store.stat().st_size if job.store.exists() else 0
    return size * (20.0 if get_method(job.method).uses_initial_guess else 1.0)


def summarize(outcomes: list[JobOutcome]) -> str:
    counts = {s: sum(o.status == s for o in outcomes) for s in ("done", "skipped", "failed")}
    return ", ".join(f"{v} {k}" for k, v in counts.items() if v or k == "failed")
