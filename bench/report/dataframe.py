"""Finished runs as pandas DataFrames (the notebook API's ``load_results``, ``bench compare``).

``load_results``: one row per sequence x method x seed x segment length (``COLUMNS``), with the
run's APE, KITTI drift and ego-velocity error repeated on each of its rows; every figure with
its 95 % confidence interval (``<figure>_ci_low`` / ``_ci_high``) and the independent segments
behind it. ``load_runs_frame``:
one row per run: ``RUN_COLUMNS``, then every other statistic of its ``RunResult`` flattened as
"<field>.<statistic>" (e.g. ``kitti.n``, ``ape.scale``), so a metric added to ``RunResult`` is a
column without a change here. Both read ``bench.runs.result.RunResult`` (nothing is parsed).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from bench.runs.folders import RunRecord, load_runs

RUN_COLUMNS = ["sequence", "display_name", "sensor_class", "doppler_kind", "method", "label",
               "seed",
               "ape_trans_m", "ape_trans_m_ci_low", "ape_trans_m_ci_high", "ape_rot_deg",
               "ape_alignment", "kitti_trans_pct", "kitti_trans_pct_ci_low",
               "kitti_trans_pct_ci_high", "kitti_rot_deg_per_100m",
               "kitti_rot_deg_per_100m_ci_low", "kitti_rot_deg_per_100m_ci_high",
               "kitti_segments", "kitti_independent_segments", "velocity_err_mps",
               "velocity_err_mps_ci_low", "velocity_err_mps_ci_high",
               "velocity_rmse_mps", "velocity_window_s", "velocity_own_err_mps", "time_ms_mean",
               "time_ms_median", "diverged", "frames", "frames_replaced", "frames_unconverged",
               "run_dir"]
COLUMNS = [*RUN_COLUMNS[:7], "length_m", "rot_deg_mean", "rot_deg_mean_ci_low",
           "rot_deg_mean_ci_high", "trans_m_mean", "trans_m_mean_ci_low", "trans_m_mean_ci_high",
           "rot_deg_median", "trans_m_median", "segments", "independent_segments",
           *RUN_COLUMNS[7:]]


def _ci(name: str, part, field: str) -> dict:
    ci = getattr(part, field, None) if part is not None else None
    low, high = (ci if ci else (None, None))
    return {f"{name}_ci_low": low, f"{name}_ci_high": high}


def run_row(run: RunRecord) -> dict:
    """The per-run columns of one run (``RUN_COLUMNS``); ``seed`` is True / False / None."""
    res = run.result
    ape, kitti, vel, own = res.ape, res.kitti, res.velocity, res.velocity_own
    return {"sequence": run.sequence, "display_name": run.display_name,
            "sensor_class": run.sensor_class, "doppler_kind": run.doppler_kind,
            "method": run.method, "label": run.label,
            "seed": run.seed.option,
            "ape_trans_m": ape.trans_rmse_m if ape else None,
            **_ci("ape_trans_m", ape, "trans_rmse_m_ci"),
            "ape_rot_deg": ape.rot_rmse_deg if ape else None,
            "ape_alignment": ape.alignment if ape else None,
            "kitti_trans_pct": kitti.trans_pct if kitti else None,
            **_ci("kitti_trans_pct", kitti, "trans_pct_ci"),
            "kitti_rot_deg_per_100m": kitti.rot_deg_per_100m if kitti else None,
            **_ci("kitti_rot_deg_per_100m", kitti, "rot_deg_per_100m_ci"),
            "kitti_segments": kitti.n if kitti else 0,
            "kitti_independent_segments": kitti.spread.n_independent if kitti else None,
            "velocity_err_mps": vel.norm_mean_mps if vel else None,
            **_ci("velocity_err_mps", vel, "norm_mean_mps_ci"),
            "velocity_rmse_mps": vel.norm_rmse_mps if vel else None,
            "velocity_window_s": vel.window_s if vel else None,
            "velocity_own_err_mps": own.norm_mean_mps if own else None,
            "time_ms_mean": res.time_ms.mean, "time_ms_median": res.time_ms.median,
            "diverged": res.diverged, "frames": res.frames,
            "frames_replaced": res.frames_replaced, "frames_unconverged": res.frames_unconverged,
            "run_dir": str(run.dir)}


def flat(run: RunRecord) -> dict:
    """Every number of the run's result as "<field>.<statistic>" (lists per index)."""
    out = {}
    for key, value in run.result.model_dump(mode="json", by_alias=True).items():
        if isinstance(value, dict):
            for stat, x in value.items():
                if isinstance(x, list) and all(not isinstance(v, dict) for v in x):
                    out.update({f"{key}.{stat}.{i}": v for i, v in enumerate(x)})
                elif not isinstance(x, list | dict):
                    out[f"{key}.{stat}"] = x
    return out


def load_runs_frame(results_dir: str | Path) -> pd.DataFrame:
    """Every finished run under ``results_dir``, one row each (``RUN_COLUMNS``, then the
    flattened statistics of its result)."""
    rows = [{**run_row(r), **flat(r)} for r in load_runs(Path(results_dir))]
    extra = list(dict.fromkeys(k for r in rows for k in r if k not in RUN_COLUMNS))
    return pd.DataFrame(rows, columns=RUN_COLUMNS + extra)


def load_results(results_dir: str | Path) -> pd.DataFrame:
    """Every finished run under ``results_dir`` as a DataFrame with one row per sequence x
    method x seed x segment length (``COLUMNS``)."""
    return results_frame(load_runs(Path(results_dir)))


def results_frame(runs: list[RunRecord]) -> pd.DataFrame:
    """``runs`` as ``load_results``' DataFrame (each run's sequence as tagged among the runs
    it was read with: ``bench.runs.folders.with_sequence_tags``)."""
    rows = []
    for run in runs:
        base = run_row(run)
        for r in run.result.relative_error:
            rows.append({**base, "length_m": r.length_m, "rot_deg_mean": r.rot_deg_mean,
                         **_ci("rot_deg_mean", r, "rot_deg_mean_ci"),
                         "trans_m_mean": r.trans_m_mean, **_ci("trans_m_mean", r,
                                                               "trans_m_mean_ci"),
                         "rot_deg_median": r.rot_deg_median,
                         "trans_m_median": r.trans_m_median, "segments": r.n,
                         "independent_segments": r.spread.n_independent})
    return pd.DataFrame(rows, columns=COLUMNS)
