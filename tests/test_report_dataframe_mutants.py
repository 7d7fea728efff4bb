"""bench/report/dataframe.py, the notebook API's frames: each run's statistics in the columns
named after them (a CI's low and high end in ``_ci_low`` / ``_ci_high``, missing parts as
None, no KITTI part as 0 segments), one row per scored length in ``results_frame``, and every
other statistic of the run flattened as "<field>.<statistic>" (lists per index)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bench.report import dataframe
from bench.runs.folders import RunRecord
from bench.runs.result import (
    ApeResult,
    KittiResult,
    RelativeError,
    RunResult,
    Spread,
    TimingStats,
    VelocityResult,
)
from helpers_figure_runs import straight, write_run


def _full(tmp_path: Path) -> RunRecord:
    result = RunResult(
        sequence="seq", method="gicp", seed=False, label="lab", display_name="Seq A",
        sensor_class="Dense 4D LiDAR", frames=20, diverged=False, frames_replaced=2,
        frames_unconverged=3,
        ape=ApeResult(alignment="se3", trans_rmse_m=1.5, rot_rmse_deg=2.5,
                      trans_rmse_m_ci=[1.0, 2.0]),
        kitti=KittiResult(lengths_m=[8.0], trans_pct=3.5, rot_deg_per_100m=4.5, n=7,
                          trans_pct_ci=[3.0, 4.0], rot_deg_per_100m_ci=[4.0, 5.0],
                          spread=Spread(n_independent=6)),
        velocity=VelocityResult(window_s=0.5, norm_mean_mps=0.25, norm_rmse_mps=0.3,
                                norm_mean_mps_ci=[0.2, 0.35]),
        velocity_own=VelocityResult(source="doppler", window_s=0.5, norm_mean_mps=0.125),
        time_ms=TimingStats(mean=9.0, median=8.0),
        relative_error=[
            RelativeError(length_m=8.0, rot_deg_mean=0.5, rot_deg_median=0.4,
                          trans_m_mean=0.1, trans_m_median=0.09, n=12,
                          rot_deg_mean_ci=[0.45, 0.55], trans_m_mean_ci=[0.08, 0.12],
                          spread=Spread(n_independent=4)),
            RelativeError(length_m=16.0, rot_deg_mean=0.7, trans_m_mean=0.3, n=5)])
    config = {"sequence": {"doppler_kind": "gt-reconstructed"}}
    return RunRecord(tmp_path / "run", result, config)


def test_run_row_puts_each_statistic_in_its_column(tmp_path):
    row = dataframe.run_row(_full(tmp_path))
    assert list(row) == dataframe.RUN_COLUMNS
    assert row == {
        "sequence": "seq", "display_name": "Seq A", "sensor_class": "Dense 4D LiDAR",
        "doppler_kind": "gt-reconstructed", "method": "gicp", "label": "lab", "seed": False,
        "ape_trans_m": 1.5, "ape_trans_m_ci_low": 1.0, "ape_trans_m_ci_high": 2.0,
        "ape_rot_deg": 2.5, "ape_alignment": "se3",
        "kitti_trans_pct": 3.5, "kitti_trans_pct_ci_low": 3.0, "kitti_trans_pct_ci_high": 4.0,
        "kitti_rot_deg_per_100m": 4.5, "kitti_rot_deg_per_100m_ci_low": 4.0,
        "kitti_rot_deg_per_100m_ci_high": 5.0, "kitti_segments": 7,
        "kitti_independent_segments": 6, "velocity_err_mps": 0.25,
        "velocity_err_mps_ci_low": 0.2, "velocity_err_mps_ci_high": 0.35,
        "velocity_rmse_mps": 0.3, "velocity_window_s": 0.5, "velocity_own_err_mps": 0.125,
        "time_ms_mean": 9.0, "time_ms_median": 8.0, "diverged": False, "frames": 20,
        "frames_replaced": 2, "frames_unconverged": 3, "run_dir": str(tmp_path / "run")}


def test_run_row_of_a_run_without_parts_has_none_and_no_segments(tmp_path):
    run = RunRecord(tmp_path / "bare", RunResult(sequence="s", method="doppler", seed=True),
                    {})
    row = dataframe.run_row(run)
    assert row["seed"] is True and row["doppler_kind"] == "radial"
    assert row["kitti_segments"] == 0
    none = [k for k in dataframe.RUN_COLUMNS[7:] if k not in (
        "kitti_segments", "diverged", "frames_replaced", "frames_unconverged", "run_dir")]
    assert {k: row[k] for k in none} == dict.fromkeys(none)
    assert row["frames_replaced"] == row["frames_unconverged"] == 0
    assert dataframe.run_row(RunRecord(tmp_path, RunResult(sequence="s", method="x"), {}))[
        "seed"] is None


def test_results_frame_has_one_row_per_length_with_the_run_repeated(tmp_path):
    run = _full(tmp_path)
    df = dataframe.results_frame([run])
    assert list(df.columns) == dataframe.COLUMNS
    assert dataframe.COLUMNS[:7] == dataframe.RUN_COLUMNS[:7]
    assert dataframe.COLUMNS[18:] == dataframe.RUN_COLUMNS[7:]
    assert list(df["length_m"]) == [8.0, 16.0]
    first = df.iloc[0]
    assert (first["rot_deg_mean"], first["rot_deg_mean_ci_low"], first["rot_deg_mean_ci_high"],
            first["trans_m_mean"], first["trans_m_mean_ci_low"], first["trans_m_mean_ci_high"],
            first["rot_deg_median"], first["trans_m_median"], first["segments"],
            first["independent_segments"]) == (0.5, 0.45, 0.55, 0.1, 0.08, 0.12, 0.4, 0.09,
                                               12, 4)
    second = df.iloc[1]
    assert second["segments"] == 5 and second["trans_m_mean"] == 0.3
    assert second[["rot_deg_mean_ci_low", "trans_m_mean_ci_high", "independent_segments",
                   "rot_deg_median"]].isna().all()
    assert list(df["ape_trans_m"]) == [1.5, 1.5] and list(df["method"]) == ["gicp"] * 2
    assert dataframe.results_frame([]).columns.tolist() == dataframe.COLUMNS


def test_flat_names_every_statistic_by_field_and_lists_by_index(tmp_path):
    out = dataframe.flat(_full(tmp_path))
    assert out["kitti.n"] == 7 and out["kitti.trans_pct"] == 3.5
    assert out["kitti.lengths_m.0"] == 8.0 and "kitti.lengths_m" not in out
    assert out["ape.trans_rmse_m_ci.0"] == 1.0 and out["ape.trans_rmse_m_ci.1"] == 2.0
    assert out["velocity.axis_mean_mps.2"] is None
    assert out["time_ms.mean"] == 9.0
    assert "kitti.spread" not in out and not any(k.startswith("kitti.per_length") for k in out)
    assert not any(k.startswith("relative_error") for k in out)  # a list of records: rows
    assert "sequence" not in out and "method" not in out  # plain fields are RUN_COLUMNS


def test_frames_from_a_results_folder(tmp_path):
    gt = straight(31)
    est = gt.copy()
    est[:, 1, 3] = 0.01 * np.arange(31)
    write_run(tmp_path, "seq A", "gicp", True, gt, est, lengths=(8.0,))
    write_run(tmp_path, "seq B", "icp-p2p", False, gt, gt, lengths=(8.0, 16.0))
    runs = dataframe.load_runs_frame(tmp_path)
    assert list(runs.columns[:len(dataframe.RUN_COLUMNS)]) == dataframe.RUN_COLUMNS
    assert {"time_ms.mean", "frames_scored"} - set(runs.columns) == {"frames_scored"}
    assert sorted(runs["method"]) == ["gicp", "icp-p2p"]
    assert len(set(runs.columns)) == len(runs.columns)  # no column twice
    df = dataframe.load_results(str(tmp_path))
    assert sorted(zip(df["method"], df["length_m"], strict=True)) == [
        ("gicp", 8.0), ("icp-p2p", 8.0), ("icp-p2p", 16.0)]
    assert all(math.isclose(x, 1.0) for x in df["time_ms_mean"])


def test_frames_of_a_folder_without_runs_still_have_their_columns(tmp_path):
    assert list(dataframe.load_runs_frame(tmp_path).columns) == dataframe.RUN_COLUMNS
    assert list(dataframe.load_results(tmp_path).columns) == dataframe.COLUMNS
