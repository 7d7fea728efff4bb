"""A small Python API for notebooks: the functions the command line uses.

    from bench.api import load_store, run_method, load_results
    seq = load_store("data/synthetic-paper/Loop1_0.h5")        # scans, stamps, ground truth
    metrics = run_method("dicp", "data/synthetic-paper/Loop1_0.h5", out="results/nb/dicp")
    df = load_results("results/paper-synthetic")                # pandas, one row per
                                                                # sequence x method x seed x length
    runs = load_runs_frame("results/paper-synthetic")           # one row per run (APE, KITTI
                                                                # drift, velocity error, time)
    result = read_result("results/nb/dicp")                     # a run's typed RunResult
"""

from __future__ import annotations

from pathlib import Path

from bench.report.dataframe import COLUMNS, RUN_COLUMNS, load_results, load_runs_frame
from bench.runs.folders import read_run
from bench.runs.plan import run_single
from bench.runs.result import RunResult
from loaders.store import StoreSequence

__all__ = ["COLUMNS", "RUN_COLUMNS", "RunResult", "load_results", "load_runs_frame", "load_store",
           "read_result", "run_method"]


def load_store(path: str | Path) -> StoreSequence:
    """A store as a sequence: ``len``, ``seq[i]`` (a Scan), ``seq.stamps``,
    ``seq.ground_truth`` (poses T_world_sensor), ``seq.sensor``. Close it when done."""
    return StoreSequence(Path(path))


def run_method(method: str, store: str | Path, seed: bool = True, params: dict | None = None,
               out: str | Path | None = None, force: bool = False) -> RunResult:
    """Run ``method`` on ``store`` exactly as ``bench run`` does; returns its result (the
    typed metrics.json; the run folder is ``out``, default
    results/runs/<sequence>/<method_seed>)."""
    return run_single(method, Path(store), seed, params, out, force).result


def read_result(run_dir: str | Path) -> RunResult:
    """The result of a finished run folder (its metrics.json, typed)."""
    run = read_run(Path(run_dir))
    if run is None:
        raise FileNotFoundError(f"{run_dir}: no metrics.json (not a finished run)")
    return run.result
