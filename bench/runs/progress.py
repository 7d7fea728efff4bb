"""Progress bars of running jobs: an overall bar, a bar per running job (frames/s) and one line
per finished job."""

from __future__ import annotations

import time

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeElapsedColumn,
)

from bench.runs.executors import execute
from bench.runs.job import Job, JobOutcome

#: a running job's bar is updated at most this often (the local executor reports every frame)
REPORT_PERIOD_S = 0.1


def _progress(console: Console) -> Progress:
    return Progress(TextColumn("{task.description}", style="bold"), BarColumn(),
                    MofNCompleteColumn(), TaskProgressColumn(),
                    TextColumn("{task.fields[fps]} frames/s"), TimeElapsedColumn(),
                    console=console, transient=False)


def _rate(frames: int, seconds: float) -> str:
    """Frames per second, once there is a second of it to go by ("-" before)."""
    return f"{frames / seconds:6.1f}" if seconds >= 1.0 and frames > 0 else "-"


def run_jobs(jobs: list[Job], console: Console | None = None, workers: int = 1,
             force: bool = False, executor: str = "process", job_timeout_s: float | None = None,
             scheduler: str | None = None) -> list[JobOutcome]:
    """Run ``jobs`` with an overall bar, a bar per running job and one line per finished job.
    Returns the outcomes in job order; Ctrl-C propagates after the executor cleaned up."""
    console = console or Console()
    finished: list[JobOutcome] = []
    try:
        with _progress(console) as progress:
            overall = progress.add_task(f"{len(jobs)} runs", total=len(jobs), fps="-")
            tasks: dict[str, tuple[int, float, int]] = {}  # title -> (task, first report, done)
            frames_done: dict[str, int] = {}
            reported: dict[str, float] = {}  # title -> when its bar was last updated
            t0 = time.monotonic()

            def report(job: Job, done: int, total: int) -> None:
                now = time.monotonic()
                if (done < total and job.title in tasks
                        and now - reported.get(job.title, 0.0) < REPORT_PERIOD_S):
                    return  # a frame of a fast method must not pay for redrawing the bars
                reported[job.title] = now
                if job.title not in tasks:
                    tasks[job.title] = (progress.add_task(escape(job.title), total=total,
                                                          fps="-"), now, done)
                task, first, done_first = tasks[job.title]
                # the rate since the first report (the frames before it took an unknown time)
                progress.update(task, completed=done, fps=_rate(done - done_first, now - first))
                frames_done[job.title] = done
                progress.update(overall, fps=_rate(sum(frames_done.values()), now - t0))

            def finish(outcome: JobOutcome) -> None:
                finished.append(outcome)
                progress.advance(overall)
                if outcome.job.title in tasks:
                    progress.remove_task(tasks.pop(outcome.job.title)[0])
                style = {"done": "green", "skipped": "dim"}.get(outcome.status, "red")
                extra = (f"{outcome.frames / outcome.wall_s:.1f} frames/s"
                         if outcome.status == "done" and outcome.wall_s > 0 else outcome.message)
                progress.console.print(f"[{style}]{outcome.status:>11}[/] "
                                       f"{escape(outcome.job.title)}  {escape(extra)}")
                for note in outcome.warnings:
                    progress.console.print(f"[yellow]{'warning':>11}[/] {escape(note)}")

            return execute(jobs, executor, workers, force, report, finish, job_timeout_s,
                           scheduler)
    except KeyboardInterrupt:  # after the bars, so the line is the last one printed
        kept = sum(o.status in ("done", "skipped") for o in finished)
        console.print(f"interrupted: {kept} runs finished and kept, "
                      f"{len(jobs) - kept} interrupted or not started", style="red",
                      markup=False)
        raise
