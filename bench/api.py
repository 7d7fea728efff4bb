"""A small Python API for notebooks: the functions the command line uses.

    from bench.api import load_store, run_method, load_results
    seq = load_store("data/synthetic-paper/Loop1_0.h5")        # scans, stamps, ground truth
    metrics = run_method("dicp", "data/synthetic-paper/Loop1_0.h5", out="results/nb/dicp")
    df = load_results("results/paper-synthetic")                # pandas, one row per
                                                                # sequence x method x seed x length
"""

from __future__ import annotations

from pathlib import Path

from bench.report.dataframe import COLUMNS, load_results
from bench.runs.plan import run_single
from loaders.store import StoreSequence

__all__ = ["COLUMNS", "load_results", "load_store", "run_method"]


def load_store(path: str | Path) -> StoreSequence:
    """A store as a sequence: ``len``, ``seq[i]`` (a Scan), ``seq.stamps``,
    ``seq.ground_truth`` (poses T_world_sensor), ``seq.sensor``. Close it when done."""
    return StoreSequence(Path(path))


def run_method(method: str, store: str | Path, seed: bool = True, params: dict | None = None,
               out: str | Path | None = None, force: bool = False) -> dict:
    """Run ``method`` on ``store`` exactly as ``bench run`` does; returns its metrics.json
    (the run folder is ``out``, default results/runs/<sequence>/<method_seed>)."""
    return run_single(method, Path(store), seed, params, out, force).metrics
