"""End to end: stores -> runs (resume, failures) -> metrics.json -> paper-shaped tables."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from bench.cli import app
from bench.report.tables.model import to_latex, to_markdown
from bench.report.tables.paper import relative_table, runs, scored_lengths, write_tables
from bench.runs.job import Job, run_job
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.store import write_store

METRIC_KEYS = {"schema", "status", "error", "sequence", "method", "seed", "label",
               "display_name", "sensor_class", "frames", "frames_scored", "diverged",
               "relative_error", "ape", "kitti", "velocity", "velocity_own", "time_ms",
               "register_ms", "wall_ms", "clock", "threads", "notes", "cpu",
               "cpu_process_to_thread", "cpu_process_to_thread_first", "clock_note",
               "timing_outliers", "timing_clean", "ci_level", "frames_replaced",
               "frames_unconverged"}


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
    for name in ("est_tum.txt", "est_kitti.txt", "gt_tum.txt", "gt_kitti.txt", "frames.csv",
                 "config.yaml", "meta.json", "metrics.json"):
        assert (run_dir / name).exists(), name
    metrics = json.loads((run_dir / "metrics.json").read_text())
    assert set(metrics) == METRIC_KEYS
    assert metrics["frames"] == 60 and metrics["diverged"] is False
    rel8 = metrics["relative_error"][0]
    assert [r["length_m"] for r in metrics["relative_error"]] == [8.0, 16.0, 24.0, 32.0, 40.0,
                                                                   48.0]
    assert set(rel8) == {"length_m", "rot_deg_mean", "trans_m_mean", "rot_deg_median",
                         "trans_m_median", "rot_deg_rmse", "trans_m_rmse", "n",
                         "rot_deg_mean_ci", "trans_m_mean_ci", "spread"}
    assert rel8["trans_m_mean"] < 0.1 and rel8["n"] > 0
    assert metrics["ape"]["requested"] == metrics["ape"]["alignment"] == "se3"
    assert metrics["kitti"]["n"] == 0 and metrics["kitti"]["too_long"][0] == 100.0  # 47 m
    assert metrics["velocity"]["window_s"] == 1.0 and metrics["velocity"]["n"] > 0
    assert metrics["velocity"]["norm_mean_mps"] < 1.0  # 8 m/s, a good estimate
    assert set(metrics["time_ms"]) == {"median", "mean", "p95"}
    meta = json.loads((run_dir / "meta.json").read_text())
    assert {"git", "packages", "cpu", "threads", "date"} <= set(meta)
    header = (run_dir / "frames.csv").read_text().splitlines()[0]
    assert header == ("index,stamp,time_ms,register_ms,wall_ms,points,correspondences,"
                      "iterations,converged,replaced")
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
    # the failed run stays in the table as a "failed" row, its reason in a footnote
    texts = write_tables(tmp_path / "r")
    row = next(ln for ln in texts["md"].splitlines() if "Doppler Correspondence" in ln)
    assert "failed [1]" in row and "failed" in row.split("|")[-2]
    assert "[1] (No initial guess) Doppler Correspondence (Ours) on twist: failed:" in texts["md"]
    assert "tau_spatial_m" in texts["md"] and r"failed\textsuperscript{1}" in texts["tex"]


def test_tables_mark_best_and_second_and_show_divergence(store, tmp_path):
    for method, seed in (("doppler", None), ("icp-p2p", True), ("icp-p2p", False)):
        assert run_job(Job(store=store, method=method, seed=seed, out_root=tmp_path)).status \
            == "done"
    # make the no-seed run look diverged
    m_path = tmp_path / "twist" / "icp-p2p_noseed" / "metrics.json"
    m = json.loads(m_path.read_text())
    m["diverged"] = True
    m_path.write_text(json.dumps(m))
    rows = runs(tmp_path)
    lengths = scored_lengths(rows)
    assert [r.label for r in rows] == ["(With Seed) ICP point-to-point",
                                       "(No Seed) ICP point-to-point",
                                       "(No initial guess) Doppler Correspondence (Ours)"]
    assert lengths == [8.0, 16.0, 24.0, 32.0, 40.0, 48.0]
    md = to_markdown(relative_table(rows, lengths))
    lines = [line for line in md.splitlines() if "point-to-point" in line or "Ours" in line]
    assert "Div." in lines[1] and "**" not in lines[1] and "<u>" not in lines[1]
    assert lines[1].rstrip(" |").split("|")[-1].strip().replace(".", "").isdigit()  # time
    # two ranked rows per column: each 8 m cell has one bold and one underlined value
    cells8 = [line.split("|")[4] for line in (lines[0], lines[2])]
    assert sum(c.count("**") // 2 for c in cells8) == 2
    assert sum(c.count("<u>") for c in cells8) == 2
    tex = to_latex(relative_table(rows, lengths))
    assert r"\textbf{" in tex and r"\underline{" in tex and "Div." in tex
    assert r"\caption{" in tex and r"\toprule" in tex and r"\bottomrule" in tex
    texts = write_tables(tmp_path)
    assert (tmp_path / "table.csv").read_text() == texts["csv"]
    assert texts["csv"].splitlines()[0].startswith("sequence,sensor_class,method,seed")


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

    def columns(output: str) -> list[str]:
        lines = output[output.index("sequence,sensor_class"):].splitlines()
        return list(dict.fromkeys(ln.split(",")[-4] for ln in lines[1:] if ln.count(",") > 8))

    assert columns(res.output) == ["8 m", "16 m", "24 m", "32 m", "40 m", "48 m", "Time (ms)"]
    res = runner.invoke(app, ["table", str(tmp_path), "-f", "csv", "--lengths", "8,16",
                              "--out", str(tmp_path / "short")])
    assert res.exit_code == 0, res.output
    assert columns(res.output) == ["8 m", "16 m", "Time (ms)"]
    res = runner.invoke(app, ["table", str(tmp_path), "--lengths", "8,1000", "--out",
                              str(tmp_path / "short")])
    # a DataError: `bench` (main) prints it as one line and exits 2; it says how to get them
    assert type(res.exception).__name__ == "DataError" and "no results at 1000 m" in str(
        res.exception) and "bench run --lengths" in str(res.exception)
    for metric, title in (("kitti", "Trans. drift (%)"), ("velocity", "Norm mean (m/s)"),
                          ("ape", "twist")):
        res = runner.invoke(app, ["table", str(tmp_path), "--metric", metric, "--out",
                                  str(tmp_path / "short")])
        assert res.exit_code == 0 and title in res.output, res.output
        assert (tmp_path / "short" / f"table_{metric}.tex").exists()
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


def _fake(tmp_path, seq, method, seed, rel, time_ms=1.0, diverged=False, label=None,
          klass="Semi-Dense 4D Radar"):
    """A run folder holding a metrics.json (schema 2) and a config.yaml."""
    import yaml

    from bench.runs.folders import run_dir_name
    from bench.runs.result import RelativeError, RunResult, TimingStats

    d = tmp_path / seq / run_dir_name(method, seed, label)
    d.mkdir(parents=True)
    res = RunResult(sequence=seq, method=method, seed=seed, label=label, display_name=seq,
                    sensor_class=klass, diverged=diverged, time_ms=TimingStats(mean=time_ms),
                    relative_error=[RelativeError(length_m=L, rot_deg_mean=r, trans_m_mean=t,
                                                  n=5) for L, (r, t) in rel.items()])
    (d / "metrics.json").write_text(res.dump())
    (d / "config.yaml").write_text(yaml.safe_dump({"label": label}))
    return d


def test_labelled_variants_are_told_apart_from_plain_methods(tmp_path):
    _fake(tmp_path, "s", "doppler-ego", None, {8.0: (1, 1)})
    _fake(tmp_path, "s", "doppler-ego", None, {8.0: (1, 1)}, label="w/o map")
    plain, ablation = runs(tmp_path)
    assert not plain.is_variant and ablation.is_variant
    assert ablation.label == "(No initial guess) w/o map"


def test_pivot_table_ranks_methods_per_sequence(tmp_path):
    from bench.report.tables.pivot import pivot_tables

    for seq, method, rot, trans, diverged, t in (
            ("A", "icp-p2p", 0.5, 2.0, False, 12.345), ("A", "gicp", 0.2, 3.0, False, 3.21),
            ("A", "dicp", 9.0, 0.001, False, 0.5), ("B", "icp-p2p", 1.5, 0.1, False, 1.0),
            ("B", "gicp", 0.0, 0.0, True, 7.0)):
        _fake(tmp_path, seq, method, True, {48.0: (rot, trans)}, t, diverged)
    length, times = (to_markdown(t) for t in pivot_tables(runs(tmp_path), [48.0]))
    lines = length.splitlines()
    assert lines[0] == "| 48 m | A | B |"
    cells = {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:4]]
             for ln in lines[2:5]}
    p2p, gicp, dicp = "(With Seed) ICP point-to-point", "(With Seed) Generalized-ICP", \
        "(With Seed) DICP"
    # the main table's format: three decimals whatever the size
    assert cells[p2p] == ["<u>0.500</u> / <u>2.000</u>", "**1.500** / **0.100**"]
    assert cells[gicp] == ["**0.200** / 3.000", "Div."]  # diverged: not ranked
    assert cells[dicp] == ["9.000 / **0.001**", ""]      # not run on B
    times = times.splitlines()
    assert times[0] == "| Time (ms) | A | B |"
    tcells = {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:4]]
              for ln in times[2:5]}
    # the Time column's format (2 decimals below 10 ms, 1 above); a diverged run's time is
    # shown but not ranked
    assert tcells == {p2p: ["12.3", "**1.00**"], gicp: ["<u>3.21</u>", "7.00"],
                      dicp: ["**0.50**", ""]}


def test_scoring_options_on_the_command_line_and_in_an_experiment(store, tmp_path):
    from bench.runs.experiment import load_experiment
    from loaders.errors import DataError

    runner = CliRunner()
    out_dir = tmp_path / "one"
    res = runner.invoke(app, ["run", "--method", "doppler", "--data", str(store), "--out",
                              str(out_dir), "--lengths", "8,40", "--kitti-lengths", "20,30",
                              "--alignment", "sim3"])
    assert res.exit_code == 0, res.output
    m = json.loads((out_dir / "metrics.json").read_text())
    assert [r["length_m"] for r in m["relative_error"]] == [8.0, 40.0]
    assert m["kitti"]["lengths_m"] == [20.0, 30.0] and m["kitti"]["n"] > 0
    assert m["ape"]["requested"] == "sim3" and "KITTI" in res.output
    res = runner.invoke(app, ["run", "--method", "doppler", "--data", str(store), "--out",
                              str(out_dir), "--alignment", "sim5"])
    assert type(res.exception).__name__ == "DataError" and "--alignment" in str(res.exception)
    exp = tmp_path / "exp.yaml"
    exp.write_text(f"name: x\nsequences: [{{path: {store}}}]\nmethods: [{{name: doppler}}]\n"
                   "alignment: first-10\nkitti_lengths_m: [20]\n")
    e = load_experiment(exp)
    assert e.alignment == "se3-first-10" and e.kitti_lengths_m == [20.0]
    exp.write_text(f"name: x\nsequences: [{{path: {store}}}]\nmethods: [{{name: doppler}}]\n"
                   "alignment: sideways\n")
    with pytest.raises(DataError, match="alignment"):
        load_experiment(exp)


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
