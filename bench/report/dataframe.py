"""Finished runs as a pandas DataFrame: one row per sequence x method x seed x segment length
(the notebook API's ``load_results`` and ``bench compare``)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from bench.runs.folders import load_runs

COLUMNS = ["sequence", "display_name", "sensor_class", "doppler_kind", "method", "label", "seed",
           "length_m",
           "rot_deg_mean", "trans_m_mean", "rot_deg_median", "trans_m_median", "segments",
           "ape_trans_m", "ape_rot_deg", "time_ms_mean", "time_ms_median", "diverged",
           "frames", "run_dir"]


def load_results(results_dir: str | Path) -> pd.DataFrame:
    """Every finished run under ``results_dir`` as a DataFrame with one row per sequence x
    method x seed x segment length (``COLUMNS``)."""
    rows = []
    for run in load_runs(Path(results_dir)):
        base = {"sequence": run.sequence, "display_name": run.display_name,
                "sensor_class": run.sensor_class, "doppler_kind": run.doppler_kind,
                "method": run.method, "label": run.label,
                "seed": run.seed, "ape_trans_m": run.ape.get("trans_rmse_m"),
                "ape_rot_deg": run.ape.get("rot_rmse_deg"),
                "time_ms_mean": run.time_ms.get("mean"),
                "time_ms_median": run.time_ms.get("median"), "diverged": run.diverged,
                "frames": run.metrics.get("frames"), "run_dir": str(run.dir)}
        for length, r in run.relative_error.items():
            rows.append({**base, "length_m": float(length), "rot_deg_mean": r["rot_deg_mean"],
                         "trans_m_mean": r["trans_m_mean"], "rot_deg_median": r["rot_deg_median"],
                         "trans_m_median": r["trans_m_median"], "segments": r["n"]})
    return pd.DataFrame(rows, columns=COLUMNS)
