"""A small Python API for notebooks: the functions the command line uses.

    from bench.api import load_store, run_method, load_results
    seq = load_store("data/synthetic-paper/Loop1_0.h5")        # scans, stamps, ground truth
    metrics = run_method("dicp", "data/synthetic-paper/Loop1_0.h5", out="results/nb/dicp")
    df = load_results("results/paper-synthetic")                # pandas, one row per
                                                                # sequence x method x seed x length
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from bench.results import load_runs
from bench.run import Job, plan, run_job
from loaders.errors import DataError
from loaders.store import StoreSequence

COLUMNS = ["sequence", "display_name", "sensor_class", "method", "label", "seed", "length_m",
           "rot_deg_mean", "trans_m_mean", "rot_deg_median", "trans_m_median", "segments",
           "ape_trans_m", "ape_rot_deg", "time_ms_mean", "time_ms_median", "diverged",
           "frames", "run_dir"]


def load_store(path: str | Path) -> StoreSequence:
    """A store as a sequence: ``len``, ``seq[i]`` (a Scan), ``seq.stamps``,
    ``seq.ground_truth`` (poses T_world_sensor), ``seq.sensor``. Close it when done."""
    return StoreSequence(Path(path))


def run_method(method: str, store: str | Path, seed: bool = True, params: dict | None = None,
               out: str | Path | None = None, force: bool = False) -> dict:
    """Run ``method`` on ``store`` exactly as ``bench run`` does; returns its metrics.json
    (the run folder is ``out``, default results/runs/<sequence>/<method_seed>)."""
    from methods.registry import get_method

    seed_opt = seed if get_method(method).uses_initial_guess else None
    job = plan([Job(store=Path(store), method=method, seed=seed_opt,
                    out_root=Path("results/runs"), params=dict(params or {}),
                    run_dir_override=Path(out) if out is not None else None)])[0]
    outcome = run_job(job, force)
    if outcome.status not in ("done", "skipped"):
        raise DataError(f"{method} on {store}: {outcome.message}")
    return json.loads((outcome.run_dir / "metrics.json").read_text())


def load_results(results_dir: str | Path) -> pd.DataFrame:
    """Every finished run under ``results_dir`` as a DataFrame with one row per sequence x
    method x seed x segment length (``COLUMNS``)."""
    rows = []
    for run in load_runs(Path(results_dir)):
        m, cfg = run["metrics"], run["config"]
        seq = cfg.get("sequence", {})
        ape = m.get("ape") or {}
        t = m.get("time_ms") or {}
        base = {"sequence": m["sequence"], "display_name": seq.get("display_name"),
                "sensor_class": seq.get("sensor_class"), "method": m["method"],
                "label": cfg.get("label"), "seed": m["seed"],
                "ape_trans_m": ape.get("trans_rmse_m"), "ape_rot_deg": ape.get("rot_rmse_deg"),
                "time_ms_mean": t.get("mean"), "time_ms_median": t.get("median"),
                "diverged": m.get("diverged"), "frames": m.get("frames"),
                "run_dir": str(run["dir"])}
        for length, r in (m.get("relative_error") or {}).items():
            rows.append({**base, "length_m": float(length), "rot_deg_mean": r["rot_deg_mean"],
                         "trans_m_mean": r["trans_m_mean"], "rot_deg_median": r["rot_deg_median"],
                         "trans_m_median": r["trans_m_median"], "segments": r["n"]})
    return pd.DataFrame(rows, columns=COLUMNS)
