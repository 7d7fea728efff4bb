"""Paper figures: every kind is written (PDF and PNG) from run folders, and the pair figure."""


import pytest
from typer.testing import CliRunner

from bench.cli import app
from bench.report.figstyle import color
from bench.runs.job import Job
from bench.runs.plan import plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.store import write_store


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("fig")
    store = write_store(constant_twist_sequence(n_frames=60, n_points=1500, noise_m=0.02,
                                                max_range_m=70), root / "twist.h5")
    jobs = [Job(store=store, method=m, seed=s, out_root=root / "results")
            for m, s in (("doppler", None), ("icp-p2p", True), ("icp-p2p", False))]
    assert all(o.status == "done" for o in run_jobs(plan(jobs), executor="local"))
    return root


def test_every_figure_kind_is_written(results, tmp_path):
    speed_csv = tmp_path / "speed.csv"
    speed_csv.write_text(
        "scenario,points,method,median_ms,mean_ms,p5_ms,p95_ms,repeats,correspondences,"
        "iterations,prep,ratio_to_doppler\n"
        "lidar,1000,doppler,0.05,0.05,0.04,0.06,51,300,1,all points,1\n"
        "lidar,8000,doppler,0.3,0.3,0.25,0.35,51,3000,1,all points,1\n"
        "lidar,1000,icp-p2p,2,2,1.8,2.5,51,400,14,1 in 2 points,40\n"
        "lidar,8000,icp-p2p,25,25,24,27,5,3900,23,1 in 2 points,83\n")
    out = tmp_path / "figs"
    res = CliRunner().invoke(app, ["figures", str(results / "results"), "--out", str(out),
                                   "--speed-csv", str(speed_csv), "--pair",
                                   str(results / "twist.h5"), "10"])
    assert res.exit_code == 0, res.output
    for kind in ("trajectories", "boxplots", "error_along_path", "frames", "pairs"):
        pngs = list((out / kind).glob("*.png"))
        assert pngs and all(p.with_suffix(".pdf").exists() for p in pngs), kind
        assert all(p.stat().st_size > 10_000 for p in pngs), kind
    assert (out / "speed.png").exists() and (out / "speed.pdf").exists()


def test_a_method_has_one_colour_everywhere():
    assert color("dicp") == color("dicp") != color("doppler")
    assert len({color(m) for m in ("doppler", "dicp", "icp-p2p", "gicp", "kiss-icp")}) == 5


def test_pair_of_the_last_frame_is_a_clear_error(results):
    res = CliRunner().invoke(app, ["figures", "--pair", str(results / "twist.h5"), "59"])
    assert res.exit_code != 0
