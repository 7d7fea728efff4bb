"""One page across datasets (bench.report.summary): mean significance-aware ranks per sensor
class, failures counted, a method that cannot run on a class says why, every sequence's
source listed, and the HTML report showing it all with intervals."""

from __future__ import annotations

import numpy as np
import pytest

from bench.report.html import render_page
from bench.report.summary import cross_dataset, summary_table
from bench.report.table import to_markdown
from bench.report.tables import select
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult


def _write(root, seq, cls, kind, name, method, seed, gt, est, dataset=None):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 48.0))
    config = {"method": method, "seed": seed,
              "sequence": {"name": seq, "display_name": seq, "sensor_class": cls,
                           "doppler_kind": kind, "dataset": dataset or f"{seq} dataset"}}
    write_run(root / seq / name, result, ev.gt, config,
              {**ev.metrics, "sequence": seq, "method": method, "seed": seed, "frames": n,
               "status": "done"})


@pytest.fixture(scope="module")
def two_datasets(tmp_path_factory):
    root = tmp_path_factory.mktemp("across")
    gt = ground_truth(900)
    good = noisy_estimate(gt, NoiseModel(), 1)
    bad = noisy_estimate(gt, NoiseModel(0.3, 0.06), 2)
    # a radar sequence (radial Doppler): doppler good, icp-p2p bad
    _write(root, "RadarSeq", "Semi-Dense 4D Radar", "radial", "doppler", "doppler", None, gt,
           good)
    _write(root, "RadarSeq", "Semi-Dense 4D Radar", "radial", "icp-p2p-seed", "icp-p2p", True,
           gt, bad)
    # a LiDAR sequence with ego-compensated Doppler: only the geometric method ran
    _write(root, "LidarSeq", "Dense 4D LiDAR", "ego-compensated", "icp-p2p-seed", "icp-p2p",
           True, gt, good)
    return root


def test_mean_rank_ties_and_why_a_method_did_not_run(two_datasets):
    rows, _ = select(two_datasets)
    table = summary_table(rows)
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}
    radar_doppler = by[("Semi-Dense 4D Radar", "doppler")]
    radar_icp = by[("Semi-Dense 4D Radar", "icp-p2p")]
    assert radar_doppler.cells[1].values["mean_rank"] == 1.0
    assert radar_icp.cells[1].values["mean_rank"] == 2.0  # significantly worse everywhere
    assert radar_doppler.cells[1].parts[0].rank == 0
    lidar_doppler = by[("Dense 4D LiDAR", "doppler")]
    assert "needs raw (radial) Doppler" in lidar_doppler.cells[0].status
    assert "ego-compensated" in lidar_doppler.cells[0].status
    assert by[("Dense 4D LiDAR", "icp-p2p")].cells[1].values["mean_rank"] == 1.0


def test_the_page_across_datasets_has_a_table_per_dataset_with_intervals(two_datasets):
    made = dict(cross_dataset(two_datasets))
    assert "Across datasets: mean rank per method" in made
    assert "Sources of the sequences" in made
    per_dataset = [t for title, t in made.items() if title.startswith("Dataset: ")]
    assert len(per_dataset) == 2
    assert all("[" in to_markdown(t) for t in per_dataset)  # intervals shown
    page, counts = render_page(two_datasets)
    assert "Across datasets" in page and "needs raw (radial) Doppler" in page
    assert counts["tables"] >= 4
