"""``bench convert dataset NAME...``: many sequences converted as jobs, resumable.

Each sequence is one job: its dataset config opened with its loader and streamed into its store
(frame by frame: never a whole bag in memory). Jobs run in this process (``local``), one fresh
worker process each (``process``, at most ``--jobs`` at once, as ``bench run`` does) or on
dask; a progress bar per job. A store is skipped when it carries the conversion key of its
config (``DatasetConfig.conversion_key``: loader, options, frame range, every input's size and
modification time), so an interrupted batch resumes where it stopped and a changed option or
input converts again. A sequence whose raw data are absent is skipped with one line.
"""

from __future__ import annotations

import os
import signal
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from rich.console import Console
from rich.markup import escape

from bench import guard
from bench.data.datasets import DatasetConfig, select_configs
from loaders.errors import DataError

EXECUTORS = ("local", "process", "dask")


@dataclass
class ConvertJob:
    config: dict           # DatasetConfig.model_dump(): picklable
    raw_dir: Path | None
    out: Path
    key: str

    @property
    def name(self) -> str:
        return self.config["name"]


def stored_key(path: Path) -> str | None:
    """The conversion key a finished store carries, or None (absent, unreadable, older)."""
    if not path.exists():
        return None
    try:
        from loaders.store import StoreSequence

        store = StoreSequence(path)
        try:
            return (store.provenance.get("conversion") or {}).get("key")
        finally:
            store.close()
    except DataError:
        return None


def convert_one(job: ConvertJob, queue=None) -> tuple[str, str, str, int, float]:
    """Convert one sequence: (name, status "done"/"failed", message, frames, wall [s]).
    ``queue`` (a multiprocessing queue) receives (name, frames done, total)."""
    from bench.threads import pin_threads

    pin_threads()
    t0 = time.perf_counter()
    try:
        cfg = DatasetConfig.model_validate(job.config)
        seq = cfg.open(job.raw_dir)
        seq.provenance["conversion"] = {"key": job.key, "config": cfg.name}
        n = len(seq)
        last = [0.0]

        def report(i: int) -> None:
            now = time.monotonic()
            if queue is not None and (i == n - 1 or now - last[0] > 0.25):
                last[0] = now
                queue.put((job.name, i + 1, n))

        if queue is not None:
            queue.put((job.name, 0, n))
        # checked when planned (``plan_conversions``): new, or a store (this one's with --force)
        guard.write_store(seq, job.out, guard.is_store, "a store", progress=report)
        seq.close()
        note = ("" if seq.ground_truth is not None else
                " (no ground truth: runs on this store are not scored)")
        return job.name, "done", str(job.out) + note, n, time.perf_counter() - t0
    except DataError as err:
        return job.name, "failed", str(err), 0, time.perf_counter() - t0
    except Exception as err:  # noqa: BLE001 - reported per job, the batch goes on
        tb = traceback.format_exception_only(type(err), err)[-1].strip()
        return job.name, "failed", f"unexpected error: {tb}", 0, time.perf_counter() - t0


def plan_conversions(configs: list[DatasetConfig], data_dir: Path, raw_dir: Path | None,
                     out: Path | None, force: bool, console: Console
                     ) -> tuple[list[ConvertJob], int]:
    """(the jobs to run, how many stores are already up to date); absent raw data: one line."""
    jobs, current = [], 0
    for cfg in configs:
        dest = out or data_dir / "real" / cfg.store
        if len(configs) > 1:
            from loaders.layout import missing_paths

            root = cfg.raw_root(raw_dir)
            missing = missing_paths(root, cfg.raw_files)
            if missing:
                what = ("not found" if not root.is_dir()
                        else f"incomplete (missing {', '.join(missing)})")
                console.print(f"skipped {cfg.name}: raw data {root} {what}", markup=False,
                              soft_wrap=True)
                continue
        cfg.check_raw(raw_dir)
        key = cfg.conversion_key(raw_dir)
        if not force and stored_key(dest) == key:
            console.print(f"{cfg.name}: {dest} is up to date (inputs and options unchanged; "
                          "--force converts again)", markup=False, soft_wrap=True)
            current += 1
            continue
        # a store this command converted (it carries its key) is replaced; any other file at
        # the destination only when it is a store and --force is given (bench.guard)
        guard.replaceable(dest, force or stored_key(dest) is not None, guard.is_store,
                          "a store", "--out", [cfg.raw_root(raw_dir)])
        jobs.append(ConvertJob(cfg.model_dump(mode="json"), raw_dir, dest, key))
    return jobs, current


def convert_datasets(names: list[str], data_dir: Path, raw_dir: Path | None, out: Path | None,
                     workers: int, executor: str, force: bool, console: Console,
                     scheduler: str | None = None) -> int:
    """Convert the named sequences; exit code 0 when every one is done or up to date (absent
    raw data skipped), 1 when any conversion failed."""
    if executor not in EXECUTORS:
        raise DataError(f"unknown executor {executor!r}; choose from {', '.join(EXECUTORS)}")
    configs = select_configs(names)
    if len(configs) > 1 and (out is not None or raw_dir is not None):
        raise DataError("--out and --raw-dir name one sequence's files: give one NAME, or "
                        "set each config's raw_dir")
    jobs, current = plan_conversions(configs, data_dir, raw_dir, out, force, console)
    if not jobs:
        if not current:
            raise DataError("nothing to convert: no raw data found for "
                            f"{', '.join(c.name for c in configs)} (see `bench datasets`)")
        return 0
    if len(jobs) == 1 and executor != "dask":
        executor = "local"  # one sequence: no worker process needed
    results = run_conversions(jobs, executor, workers, console, scheduler)
    failed = [r for r in results if r[1] != "done"]
    for name, status, message, frames, wall in results:
        if status == "done":
            console.print(f"[green]wrote[/] {message}: {frames} frames in {wall:.1f} s "
                          f"({frames / max(wall, 1e-9):.0f} frames/s)")
        else:
            console.print(f"[red]failed[/] {escape(name)}: {escape(message)}", highlight=False,
                          soft_wrap=True)
    console.print(f"{len(results) - len(failed)} converted, {current} up to date, "
                  f"{len(failed)} failed", markup=False)
    return 1 if failed else 0


def run_conversions(jobs: list[ConvertJob], executor: str, workers: int, console: Console,
                    scheduler: str | None = None) -> list[tuple]:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=console) as progress:
        tasks = {j.name: progress.add_task(f"{j.name} -> {Path(j.out).name}", total=None)
                 for j in jobs}

        def update(name: str, done: int, total: int) -> None:
            progress.update(tasks[name], completed=done, total=total)

        if executor == "local":
            class _Queue:
                def put(self, item):
                    update(*item)
            return [convert_one(j, _Queue()) for j in jobs]
        if executor == "dask":
            return _run_dask(jobs, workers, scheduler, update)
        return _run_processes(jobs, workers, update)


def _run_processes(jobs: list[ConvertJob], workers: int, update) -> list[tuple]:
    import queue as queue_mod
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
    from multiprocessing import get_context

    ctx = get_context("spawn")
    with ctx.Manager() as manager:
        q = manager.Queue()
        pool = ProcessPoolExecutor(max_workers=max(1, workers), mp_context=ctx,
                                   initializer=_worker_init, initargs=(os.getpid(),))
        try:
            futures = {pool.submit(convert_one, j, q): j for j in jobs}
            pending, results = set(futures), {}
            while pending:
                done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
                while True:
                    try:
                        update(*q.get_nowait())
                    except queue_mod.Empty:
                        break
                for f in done:
                    job = futures[f]
                    try:
                        results[job.name] = f.result()
                    except Exception as err:  # noqa: BLE001 - a worker that died
                        results[job.name] = (job.name, "failed", f"worker died: {err}", 0, 0.0)
        except KeyboardInterrupt:
            # stores are written atomically: ending the workers leaves no partial store, and
            # the next run resumes from the stores that were finished
            for proc in list(getattr(pool, "_processes", {}).values()):
                proc.kill()
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown()
    return [results[j.name] for j in jobs]


def _worker_init(parent_pid: int) -> None:
    """Conversion workers ignore Ctrl-C (the main process ends them) and die with it (Linux:
    PR_SET_PDEATHSIG, as the run executors' workers)."""
    import contextlib
    import ctypes

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)
    if os.getppid() != parent_pid:  # the parent died before the guard was set
        os._exit(1)


def _run_dask(jobs: list[ConvertJob], workers: int, scheduler: str | None, update) -> list:
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None if scheduler else LocalCluster(n_workers=max(1, workers),
                                                  threads_per_worker=1, processes=True)
    client = Client(scheduler or cluster)
    try:
        futures = {client.submit(convert_one, j, None, pure=False): j for j in jobs}
        results = {}
        for f in as_completed(futures):
            r = f.result()
            results[r[0]] = r
            update(r[0], r[3], max(r[3], 1))
        return [results[j.name] for j in jobs]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
