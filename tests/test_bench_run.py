"""End to end: stores -> runs (resume, failures) -> metrics.json -> paper-shaped tables."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from bench.cli import app
from bench.report.tables import collect_rows, to_latex, to_markdown, write_tables
from bench.runs.job import Job, run_job
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.store import write_store

METRIC_KEYS = {"sequence", "method", "seed", "frames", "frames_scored", "diverged",
               "relative_error", "ape", "time_ms", "register_ms", "wall_ms", "clock",
               "threads", "cpu", "cpu_process_to_thread", "timing_outliers", "timing_clean"}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    # 60 frames at 8 m/s and 0.1 s: 47 m of travel (48 m segments fit within 20 %)
    seq = constant_twist_sequence(n_frames=60, n_points=2500, noise_m=0.01, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def test_run_folder_has_every_file_and_exact_metric_keys(store, tmp_path):
    job = Job(store=store, method="doppler", seed=None, out_root=tmp_path)
    out = run_job(job)
    assert out.status == "done", out.message
    run_dir = tmp_path / "twist" / "doppler"
    for name in ("est_tum.txt", "est_kitti.txt", "gt_tum.txt", "frames.csv", "config.yaml",
                 "meta.json", "metrics.json"):
        assert (run_dir / name).exists(), name
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert set(metrics) == METRIC_KEYS
    assert metrics["frames"] == 60 and metrics["diverged"] is False
    assert set(metrics["relative_error"]["8"]) == {"rot_deg_mean", "trans_m_mean",
                                                   "rot_deg_median", "trans_m_median", "n"}
    assert metrics["relative_error"]["8"]["trans_m_mean"] < 0.1
    assert metrics["relative_error"]["8"]["n"] > 0
    assert set(metrics["time_ms"]) == {"median", "mean", "p95"}
    meta = json.loads((run_dir / "meta.json").read_text())
    assert {"git", "packages", "cpu", "threads", "date"} <= set(meta)
    header = (run_dir / "frames.csv").read_text().splitlines()[0]
    assert header == ("index,stamp,time_ms,register_ms,wall_ms,points,correspondences,"
                      "iterations,converged")
    assert metrics["clock"] == "cpu" and metrics["threads"] == 1
    assert metrics["cpu"] == meta["cpu"] and 0.99 < metrics["cpu_process_to_thread"] <= 1.05
    assert metrics["timing_clean"] is True
    assert set(metrics["register_ms"]) == {"median", "mean", "p95"}
    assert metrics["register_ms"]["mean"] <= metrics["time_ms"]["mean"]
    est = np.loadtxt(run_dir / "est_tum.txt")
    assert est.shape == (60, 8)


def test_finished_runs_are_skipped_unless_forced(store, tmp_path):
    job = Job(store=store, method="doppler", seed=None, out_root=tmp_path)
    assert run_job(job).status == "done"
    assert run_job(job).status == "skipped"
    assert run_job(job, force=True).status == "done"


def test_a_failed_job_is_recorded_and_the_others_carry_on(store, tmp_path):
    broken = tmp_path / "broken.h5"
    broken.write_bytes(store.read_bytes()[:5000])
    jobs = [Job(store=broken, method="doppler", seed=None, out_root=tmp_path / "r"),
            Job(store=store, method="doppler", seed=None, out_root=tmp_path / "r",
                params={"tau_spatial_m": -1.0}),
            Job(store=store, method="icp-p2p", seed=True, out_root=tmp_path / "r")]
    outcomes = run_jobs(jobs)
    assert [o.status for o in outcomes] == ["failed", "failed", "done"]
    assert "broken.h5" in outcomes[0].message
    failed = json.loads((tmp_path / "r" / "twist" / "doppler" / "failed.json").read_text())
    assert "tau_spatial_m" in failed["error"]
    assert (tmp_path / "r" / "twist" / "icp-p2p_seed" / "metrics.json").exists()


def test_tables_mark_best_and_second_and_show_divergence(store, tmp_path):
    for method, seed in (("doppler", None), ("icp-p2p", True), ("icp-p2p", False)):
        assert run_job(Job(store=store, method=method, seed=seed, out_root=tmp_path)).status \
            == "done"
    # make the no-seed run look diverged
    m_path = tmp_path / "twist" / "icp-p2p_noseed" / "metrics.json"
    m = json.loads(m_path.read_text())
    m["diverged"] = True
    m_path.write_text(json.dumps(m))
    rows, lengths = collect_rows(tmp_path)
    assert [r.label for r in rows] == ["(With Seed) ICP point-to-point",
                                       "(No Seed) ICP point-to-point",
                                       "(No initial guess) Doppler Correspondence (Ours)"]
    assert lengths == ["8", "16", "24", "32", "40", "48"]
    md = to_markdown(rows, lengths)
    lines = [line for line in md.splitlines() if "point-to-point" in line or "Ours" in line]
    assert "Div." in lines[1] and "**" not in lines[1] and "<u>" not in lines[1]
    assert lines[1].rstrip(" |").split("|")[-1].strip().replace(".", "").isdigit()  # time
    # two ranked rows per column: each 8 m cell has one bold and one underlined value
    cells8 = [line.split("|")[4] for line in (lines[0], lines[2])]
    assert sum(c.count("**") // 2 for c in cells8) == 2
    assert sum(c.count("<u>") for c in cells8) == 2
    tex = to_latex(rows, lengths)
    assert r"\textbf{" in tex and r"\underline{" in tex and "Div." in tex
    texts = write_tables(tmp_path)
    assert (tmp_path / "table.csv").read_text() == texts["csv"]
    assert texts["csv"].splitlines()[0].startswith("sensor_class,sequence,method,seed")


def test_cli_run_table_inspect(store, tmp_path):
    runner = CliRunner()
    out_dir = tmp_path / "one"
    res = runner.invoke(app, ["run", "--method", "icp-p2p", "--no-seed", "--data", str(store),
                              "--out", str(out_dir)])
    assert res.exit_code == 0, res.output
    assert json.loads((out_dir / "metrics.json").read_text())["seed"] is False
    res = runner.invoke(app, ["table", str(tmp_path), "--format", "csv"])
    assert res.exit_code == 0, res.output
    assert "icp-p2p" in res.output and res.output.count("\n") >= 2

    def csv_header(output: str) -> list[str]:
        return next(ln for ln in output.splitlines() if ln.startswith("sensor_class")).split(",")

    header = csv_header(res.output)
    res = runner.invoke(app, ["table", str(tmp_path), "-f", "csv", "--lengths", "8,16",
                              "--out", str(tmp_path / "short")])
    assert res.exit_code == 0, res.output
    short = csv_header(res.output)
    per_length = [c for c in short if c.endswith("m") and c[0] in "rt"]
    assert per_length == ["rot_deg_8m", "trans_m_8m", "rot_deg_16m", "trans_m_16m"]
    assert set(short) < set(header)
    res = runner.invoke(app, ["table", str(tmp_path), "--lengths", "8,1000", "--out",
                              str(tmp_path / "short")])
    # a DataError: `bench` (main) prints it as one line and exits 2
    assert type(res.exception).__name__ == "DataError" and "no results at 1000 m" in str(
        res.exception)
    res = runner.invoke(app, ["table", str(tmp_path), "--pivot", "--lengths", "8",
                              "--out", str(tmp_path / "short")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "short" / "pivot.md").read_text().startswith("| 8 m |")
    res = runner.invoke(app, ["table", str(tmp_path), "-f", "csv", "--methods", "doppler",
                              "--out", str(tmp_path / "short")])
    assert type(res.exception).__name__ == "DataError" and "no run matches" in str(res.exception)
    res = runner.invoke(app, ["table", str(tmp_path), "-f", "csv", "--methods", "icp-p2p",
                              "--no-variants", "--out", str(tmp_path / "short")])
    assert res.exit_code == 0 and "icp-p2p" in res.output
    # the folder's own table.* is its whole table: a filtered or merged view never replaces it
    whole = (tmp_path / "table.md").read_text()
    for view in (["--lengths", "8"], ["--methods", "icp-p2p"], ["--pivot"],
                 [str(out_dir)]):  # a second folder: a merged view
        res = runner.invoke(app, ["table", str(tmp_path), *view])
        assert res.exit_code == 0 and "not written" in res.output, res.output
        assert (tmp_path / "table.md").read_text() == whole
    res = runner.invoke(app, ["inspect", str(store)])
    assert res.exit_code == 0, res.output
    assert "points per frame" in res.output and "confirmed" in res.output
    res = runner.invoke(app, ["figures", str(tmp_path)])
    assert res.exit_code == 0, res.output
    pngs = list((tmp_path / "figures" / "trajectories").glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
    res = runner.invoke(app, ["list"])
    assert res.exit_code == 0 and "doppler" in res.output and "npy-frames" in res.output


def test_experiment_yaml_is_validated(tmp_path):
    from bench.runs.experiment import load_experiment
    from loaders.errors import DataError

    bad = tmp_path / "exp.yaml"
    bad.write_text("name: x\nsequences: [{path: a.h5}]\nmethods: [{name: doppler, "
                   "params: {tau_dopler: 5}}]\n")
    with pytest.raises(DataError, match="tau_dopler"):
        load_experiment(bad)
    bad.write_text("name: x\nsequences: [{path: a.h5}]\nmethods: [{name: nope}]\n")
    with pytest.raises(DataError, match="unknown method 'nope'"):
        load_experiment(bad)


def test_labelled_variants_are_told_apart_from_plain_methods():
    from bench.report.names import run_label as method_label
    from bench.report.tables import Row, is_variant

    plain = Row("c", "s", "doppler-ego", None, method_label("doppler-ego", None), {}, {}, 1, False)
    ablation = Row("c", "s", "doppler-ego", None, method_label("doppler-ego", None, "w/o map"),
                   {}, {}, 1, False)
    assert not is_variant(plain) and is_variant(ablation)


def test_pivot_table_ranks_methods_per_sequence():
    from bench.report.tables import Row
    from bench.report.tables_pivot import to_pivot_markdown, to_pivot_time_markdown

    def row(seq, label, rot, trans, diverged=False, time_ms=1.0):
        return Row("Semi-Dense 4D Radar", seq, label, True, label, {"48": rot}, {"48": trans},
                   time_ms, diverged)

    rows = [row("A", "m1", 0.5, 2.0, time_ms=12.345), row("A", "m2", 0.2, 3.0, time_ms=3.21),
            row("A", "m3", 9.0, 0.001, time_ms=0.5), row("B", "m1", 1.5, 0.1),
            row("B", "m2", 0.0, 0.0, diverged=True, time_ms=7.0)]
    lines = to_pivot_markdown(rows, "48").splitlines()
    assert lines[0] == "| 48 m | A | B |"
    cells = {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:4]]
             for ln in lines[2:5]}
    # the main table's format: three decimals whatever the size
    assert cells["m1"] == ["<u>0.500</u> / <u>2.000</u>", "**1.500** / **0.100**"]
    assert cells["m2"] == ["**0.200** / 3.000", "Div."]  # diverged: not ranked
    assert cells["m3"] == ["9.000 / **0.001**", ""]      # not run on B
    times = to_pivot_time_markdown(rows).splitlines()
    assert times[0] == "| Time (ms) | A | B |"
    tcells = {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:4]]
              for ln in times[2:5]}
    # the Time column's format (2 decimals below 10 ms, 1 above); a diverged run's time is
    # shown but not ranked
    assert tcells == {"m1": ["12.3", "**1.00**"], "m2": ["<u>3.21</u>", "7.00"],
                      "m3": ["**0.50**", ""]}


def test_pivot_cells_read_as_the_main_table():
    from bench.report.tables import Row, to_markdown
    from bench.report.tables_pivot import to_pivot_markdown

    rows = [Row("Dense 4D LiDAR", "Straight Wall", "dicp", True, "(With Seed) DICP",
                {"8": 0.05}, {"8": 12.3456}, 29.1, False),
            Row("Dense 4D LiDAR", "Straight Wall", "doppler", None, "Ours",
                {"8": 0.486}, {"8": 0.068}, 7.8, False)]
    main = [ln for ln in to_markdown(rows, ["8"]).splitlines() if "DICP" in ln][0]
    pivot = [ln for ln in to_pivot_markdown(rows, "8").splitlines() if "DICP" in ln][0]
    assert main.split(" | ")[3] == pivot.split(" | ")[1].rstrip(" |") == \
        "**0.050** / <u>12.346</u>"


def test_a_single_run_takes_its_sensor_class_from_the_store(tmp_path):
    """A store of the Oculii Eagle is "Semi-Dense 4D Radar" in a single run, as in the
    reproduction's tables (one store, one sequence in a merged folder), not "4D Radar"."""
    from bench.runs.job import prepare
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, sensor_class

    twist = constant_twist_sequence(n_frames=12, n_points=400, max_range_m=60)
    eagle = SensorInfo("radar", 0.0833, model="radar-semidense (Oculii Eagle)")
    store = write_store(MemorySequence("Loop1_0", eagle, list(twist), twist.ground_truth, {}),
                        tmp_path / "Loop1_0.h5")
    prep = prepare(Job(store=store, method="doppler", seed=None, out_root=tmp_path / "r"))
    prep.sequence.close()
    assert prep.config["sequence"]["sensor_class"] == SEMI_DENSE_RADAR
    assert sensor_class(SensorInfo("lidar", 0.1, model="lidar-fmcw (CARLA)")) == DENSE_LIDAR
    assert sensor_class(SensorInfo("radar", 0.1, model="npy-frames")) == "4D Radar"
