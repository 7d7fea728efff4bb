"""bench score: a trajectory made elsewhere scored as a run of its own.

The consistency check: the harness's own `doppler` run, written out as a TUM file and scored
with `bench score` against the same store, gives the same metrics (to 1e-9: same stamps, same
scoring path); resampled at another rate on another clock it agrees within the stated 2 % at
8 m and 0.5 % beyond; evo's evo_rpe / evo_ape on the external run folder give its numbers.
Every reader (table, compare, report, regress, figures) shows an external run beside a harness
run."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import run_bench as _bench
from scipy.spatial.transform import Rotation, Slerp

from bench.runs.external.score import ExternalSpec, score_external
from bench.runs.folders import read_run
from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.posefile import read_tum
from loaders.scan import MemorySequence, SensorInfo
from loaders.se3 import inv_T, tum_from_T
from loaders.store import write_store


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """A store and the harness's doppler run on it, in results/twist/doppler."""
    root = tmp_path_factory.mktemp("score")
    base = constant_twist_sequence(n_frames=60, n_points=1500, noise_m=0.02, max_range_m=70)
    seq = MemorySequence("twist", base.sensor, [s for s in base], base.ground_truth)
    store = write_store(seq, root / "twist.h5")
    results = root / "results"
    outcome = run_job(Job(store=store, method="doppler", seed=None, out_root=results))
    assert outcome.status == "done", outcome.message
    return store, results, outcome.run_dir


def write_tum(path: Path, stamps, poses, times=None) -> Path:
    xyz, quat = tum_from_T(np.asarray(poses))
    cols = [np.asarray(stamps)[:, None], xyz, quat] + ([np.asarray(times)[:, None]]
                                                        if times is not None else [])
    np.savetxt(path, np.hstack(cols), fmt="%.17g", header="t x y z qx qy qz qw")
    return path


def resample(stamps, poses, query):
    """Independent SE(3) resampling (scipy's Slerp, np.interp), not the harness's."""
    slerp = Slerp(stamps, Rotation.from_matrix(poses[:, :3, :3]))
    out = np.repeat(np.eye(4)[None], len(query), axis=0)
    out[:, :3, :3] = slerp(query).as_matrix()
    out[:, :3, 3] = np.column_stack([np.interp(query, stamps, poses[:, k, 3]) for k in range(3)])
    return out


def assert_same_metrics(a, b, rel):
    assert [r.length_m for r in a.relative_error] == [r.length_m for r in b.relative_error]
    for ra, rb in zip(a.relative_error, b.relative_error, strict=True):
        assert ra.n == rb.n > 0
        for key in ("rot_deg_mean", "trans_m_mean", "rot_deg_median", "trans_m_median",
                    "rot_deg_rmse", "trans_m_rmse"):
            assert getattr(rb, key) == pytest.approx(getattr(ra, key), rel=rel), (ra.length_m,
                                                                                  key)


def test_the_tum_file_of_a_harness_run_scores_the_same(data, tmp_path):
    store, results, doppler_dir = data
    out = score_external(store, ExternalSpec(doppler_dir / "est_tum.txt", "doppler-tum"),
                         results)
    assert out.status == "done" and out.run_dir == results / "twist" / "doppler-tum"
    assert out.coverage["share_scored"] == 1.0 and out.coverage["matched"] == 60
    own, ext = read_run(doppler_dir).result, read_run(out.run_dir).result
    assert_same_metrics(own, ext, rel=1e-9)
    assert ext.ape.trans_rmse_m == pytest.approx(own.ape.trans_rmse_m, rel=1e-9)
    assert ext.ape.rot_rmse_deg == pytest.approx(own.ape.rot_rmse_deg, rel=1e-9)
    assert ext.velocity.norm_mean_mps == pytest.approx(own.velocity.norm_mean_mps, rel=1e-9)
    assert (ext.frames_scored, ext.diverged, ext.frames) == (own.frames_scored, False, 60)
    # its own name and label; not timed by anyone
    assert ext.method == "doppler-tum" and ext.label == "doppler-tum (external)"
    assert ext.time_ms.mean is None and ext.clock is None
    assert ext.clock_note.startswith("not timed")
    config = read_run(out.run_dir).config
    assert config["external"]["timing"] == "not timed"
    assert set(config["identity"]) >= {"trajectory_sha256", "store_sha256", "code_sha256"}


def test_resampled_on_another_clock_agrees_within_the_stated_tolerance(data, tmp_path):
    """The run's trajectory resampled at 27 Hz (every scan stamp but the first between two
    poses) on a clock 12.345 s behind: scored with --time-offset and --max-gap (interpolation
    is asked for, never the default), the relative errors agree
    within 2 % at 8 m and 0.5 % from 16 m (resampling twice smooths the frame-to-frame jitter
    of the estimate, which the shortest segments feel most: 1.2 % in rotation at 8 m); evo
    computes the same numbers from the external run folder."""
    store, results, doppler_dir = data
    est = read_tum(doppler_dir / "est_tum.txt")
    grid = est.stamps[0] + np.arange(0, est.stamps[-1] - est.stamps[0] + 1e-9, 1 / 27)
    grid = np.append(grid, est.stamps[-1]) if grid[-1] < est.stamps[-1] - 1e-9 else grid
    path = write_tum(tmp_path / "resampled.tum", grid - 12.345,
                     resample(est.stamps, est.poses, grid))
    out = score_external(store, ExternalSpec(path, "doppler-27hz", time_offset_s=12.345,
                                             max_gap_s=3 / 27), tmp_path / "r")
    c = out.coverage
    assert c["share_scored"] == 1.0 and c["matched"] + c["interpolated"] == 60
    assert c["interpolated"] >= 20  # the scans without a pose within 0.01 s
    own, ext = read_run(doppler_dir).result, read_run(out.run_dir).result
    for ra, rb in zip(own.relative_error, ext.relative_error, strict=True):
        tol = 0.02 if ra.length_m < 16 else 0.005  # measured: 1.2 % at 8 m, <= 0.4 % beyond
        assert rb.trans_m_mean == pytest.approx(ra.trans_m_mean, rel=tol)
        assert rb.rot_deg_mean == pytest.approx(ra.rot_deg_mean, rel=tol)
    rel8 = ext.relative(8.0)
    rpe = ["-d", "8", "-u", "m", "-t", "0.2", "--all_pairs", "--pairs_from_reference"]
    assert _evo("evo_rpe", ["-r", "trans_part", *rpe], out.run_dir) == \
        pytest.approx(rel8.trans_m_mean, rel=1e-6)
    assert _evo("evo_rpe", ["-r", "angle_deg", *rpe], out.run_dir) == \
        pytest.approx(rel8.rot_deg_mean, rel=1e-6)
    assert _evo("evo_ape", ["-a"], out.run_dir, "rmse") == \
        pytest.approx(ext.ape.trans_rmse_m, rel=1e-6)


def _evo(tool: str, args: list[str], cwd: Path, stat: str = "mean") -> float:
    """evo's statistic at full precision (its saved results; the printout has 6 decimals)."""
    import zipfile

    exe = Path(sys.executable).parent / tool
    exe = str(exe) if exe.exists() else shutil.which(tool)
    assert exe, f"{tool} missing: evo is a dependency (reinstall the package)"
    saved = cwd / f"evo_{len(list(cwd.glob('evo_*.zip')))}.zip"
    out = subprocess.run([exe, "tum", "gt_tum.txt", "est_tum.txt", *args, "--save_results",
                          str(saved)], cwd=cwd, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    with zipfile.ZipFile(saved) as z:
        return float(json.loads(z.read("stats.json"))[stat])


def test_a_partial_estimate_reports_its_share_and_scores_only_those_scans(data, tmp_path):
    store, results, doppler_dir = data
    est = read_tum(doppler_dir / "est_tum.txt")
    path = write_tum(tmp_path / "half.tum", est.stamps[:30], est.poses[:30])
    with pytest.raises(DataError, match=r"half.tum covers 30 of the 60 scans of .*twist.h5 with "
                                        r"ground truth \(50.0 %\), below --min-coverage 0.9"):
        score_external(store, ExternalSpec(path, "half"), tmp_path / "r")
    assert not (tmp_path / "r").exists()
    out = score_external(store, ExternalSpec(path, "half", min_coverage=0.5), tmp_path / "r")
    assert out.coverage["scored"] == 30 and out.coverage["share_scored"] == pytest.approx(0.5)
    run = read_run(out.run_dir)
    assert run.result.frames_scored == 30 and len(read_tum(out.run_dir / "gt_tum.txt")) == 30
    assert any("30 of the 60 scans with ground truth scored (50.0 %)" in n
               for n in run.result.notes)


def test_no_overlap_is_a_clear_refusal(data, tmp_path):
    store, _, doppler_dir = data
    est = read_tum(doppler_dir / "est_tum.txt")
    path = write_tum(tmp_path / "utc8.tum", est.stamps + 8 * 3600.0, est.poses)
    with pytest.raises(DataError, match=r"utc8.tum does not overlap the scans of .*twist.h5.*"
                                        r"try --time-offset -28800 \(the estimate's clock is 8 h "
                                        r"ahead of the scans'"):
        score_external(store, ExternalSpec(path, "late"), tmp_path / "r")
    assert not (tmp_path / "r").exists()


def test_times_the_method_reported_are_recorded_as_such_and_not_ranked(data, tmp_path):
    store, results, doppler_dir = data
    est = read_tum(doppler_dir / "est_tum.txt")
    times = np.linspace(0.001, 0.01, len(est))  # faster than any method: it must not be bold
    path = write_tum(tmp_path / "timed.tum", est.stamps, est.poses, times)
    out = score_external(store, ExternalSpec(path, "timed"), results)
    res = read_run(out.run_dir).result
    assert res.clock == "reported by the method" and "not measured by the harness" in \
        res.clock_note
    assert res.time_ms.mean == pytest.approx(times.mean()) and res.register_ms.mean is None
    frames = (out.run_dir / "frames.csv").read_text().splitlines()
    assert float(frames[2].split(",")[2]) == pytest.approx(times[1], abs=1e-6)  # 6 decimals
    from bench.report.tables.model import OTHER
    from bench.report.tables.paper import relative_table, runs

    rows = runs(results)
    table = relative_table(rows, [8.0])
    row = next(r for r, rr in zip(table.rows, rows, strict=True) if rr.method == "timed")
    time_cell = row.cells[-1].parts[0]
    assert time_cell.text.endswith("[reported]") and time_cell.rank == OTHER  # not ranked
    assert "not measured by the harness: not ranked" in table.caption
    assert "MIXED HOSTS" not in table.caption
    shutil.rmtree(out.run_dir)


def test_poses_of_the_body_frame_with_the_stores_extrinsic(tmp_path):
    T_bs = np.array([[0, -1, 0, 1.2], [1, 0, 0, 0.1], [0, 0, 1, 1.5], [0, 0, 0, 1.0]])
    base = constant_twist_sequence(n_frames=40, n_points=600, max_range_m=70)
    seq = MemorySequence("ext", SensorInfo("lidar", 0.1, T_bs, "test"), list(base),
                         base.ground_truth)
    store = write_store(seq, tmp_path / "ext.h5")
    body = base.ground_truth.poses @ inv_T(T_bs)  # a perfect odometry of the body frame
    path = write_tum(tmp_path / "body.tum", base.ground_truth.stamps, body)
    good = read_run(score_external(store, ExternalSpec(path, "body", pose_frame="body"),
                                   tmp_path / "r").run_dir).result
    assert good.relative(8.0).trans_m_mean < 1e-9 and good.relative(8.0).rot_deg_mean < 1e-6
    ext = "1.2 0.1 1.5 0 0 0.7071067811865476 0.7071067811865476"  # the same, given
    given = read_run(score_external(store, ExternalSpec(path, "given", extrinsic=ext),
                                    tmp_path / "r").run_dir).result
    assert given.relative(8.0).trans_m_mean < 1e-9
    wrong = read_run(score_external(store, ExternalSpec(path, "wrong"),  # taken as the sensor's
                                    tmp_path / "r").run_dir).result
    assert wrong.relative(8.0).trans_m_mean > 0.01
    # the same body poses as a ROS1 bag's nav_msgs/Odometry topic: `bench export` writes the
    # GT that way (T_world_body of base_link)
    from bench.data.export import export_store

    bag = export_store(store, "ros1", tmp_path / "ext.bag").path
    odom = score_external(store, ExternalSpec(bag, "odom", topic="/ground_truth",
                                              pose_frame="body"), tmp_path / "r")
    assert odom.coverage["matched"] == 40 and odom.frame == "the store's T_body_sensor"
    res = read_run(odom.run_dir).result
    assert res.relative(8.0).trans_m_mean < 1e-9 and res.ape.trans_rmse_m < 1e-9


def test_a_kitti_file_with_its_stamps_scores_as_its_tum_twin(data, tmp_path):
    store, _, doppler_dir = data
    est = read_tum(doppler_dir / "est_tum.txt")
    stamps = tmp_path / "times.txt"
    stamps.write_text("".join(f"{t:.17g}\n" for t in est.stamps))
    out = score_external(store, ExternalSpec(doppler_dir / "est_kitti.txt", "kitti",
                                             stamps=stamps), tmp_path / "r")
    assert_same_metrics(read_run(doppler_dir).result, read_run(out.run_dir).result, rel=1e-9)


def test_identity_reuses_an_unchanged_run_and_rescores_a_changed_file(data, tmp_path):
    store, _, doppler_dir = data
    path = shutil.copy(doppler_dir / "est_tum.txt", tmp_path / "est.tum")
    spec = ExternalSpec(Path(path), "again")
    first = score_external(store, spec, tmp_path / "r")
    key = read_run(first.run_dir).config["run_key"]
    assert score_external(store, spec, tmp_path / "r").status == "skipped"
    assert score_external(store, spec, tmp_path / "r", force=True).status == "done"
    est = read_tum(path)
    poses = est.poses.copy()
    poses[30:, 0, 3] += 0.5
    write_tum(Path(path), est.stamps, poses)
    assert score_external(store, spec, tmp_path / "r").status == "done"
    assert read_run(first.run_dir).config["run_key"] != key
    other = ExternalSpec(Path(path), "again", time_offset_s=1e-5)  # a setting: another key
    assert score_external(store, other, tmp_path / "r").status == "done"


def test_a_name_of_the_harness_is_refused(data, tmp_path):
    store, _, doppler_dir = data
    with pytest.raises(DataError, match="'doppler' is a method of the harness"):
        score_external(store, ExternalSpec(doppler_dir / "est_tum.txt", "doppler"), tmp_path)


def test_every_reader_shows_the_external_run(data, tmp_path):
    store, results, doppler_dir = data
    folder = tmp_path / "both"
    shutil.copytree(doppler_dir, folder / "twist" / "doppler")
    score_external(store, ExternalSpec(doppler_dir / "est_tum.txt", "doppler-tum"), folder)
    from bench.report.compare import compare, to_markdown
    from bench.report.figures.draw import plot_trajectories
    from bench.report.html.page import write_page
    from bench.report.tables.paper import write_tables
    from bench.studies.regress import check, snapshot

    md = write_tables(folder)["md"]
    assert "| doppler-tum (external) |" in md and "Doppler Correspondence" in md
    cells = compare(folder, folder)
    assert "doppler-tum (external)" in set(cells["run"])
    from bench.report.compare import compare_run_metrics, compare_times

    text = to_markdown(cells, compare_times(folder, folder), folder, folder, 0.1,
                       compare_run_metrics(folder, folder))
    assert "doppler-tum (external)" in text
    snap = snapshot(folder)
    assert set(snap) == {"twist/doppler/-", "twist/doppler-tum/-"}
    assert snap["twist/doppler-tum/-"]["trans_m"] == pytest.approx(
        snap["twist/doppler/-"]["trans_m"], rel=1e-9)
    assert not check(snap, snap)
    page, info = write_page(folder)
    html = page.read_text()
    assert "doppler-tum (external)" in html and info
    figs = plot_trajectories(folder, tmp_path / "figs")
    assert figs and all(p.exists() for p in figs)


def test_cli_scores_and_bad_input_is_one_message(data, tmp_path, capsys, monkeypatch):
    store, _, doppler_dir = data
    code, out = _bench(["score", str(doppler_dir / "est_tum.txt"), "--store", str(store),
                        "--name", "cli-ext", "--out", str(tmp_path / "r")], capsys, monkeypatch)
    assert code == 0, out
    assert "cli-ext: 60 of the 60 scans with ground truth scored (100.0 %" in out
    assert "timing: not timed" in out and "8 m: " in out
    assert "T_frame_sensor = identity (poses of the sensor)" in out
    metrics = json.loads((tmp_path / "r" / "twist" / "cli-ext" / "metrics.json").read_text())
    assert metrics["label"] == "cli-ext (external)"
    bad = tmp_path / "bad.tum"
    bad.write_text("0 0 0 0 0 0 0 1\n0.1 0 0 0 0 0 0\n")
    code, out = _bench(["score", str(bad), "--store", str(store), "--name", "x"], capsys,
                       monkeypatch)
    assert code == 2 and "bad.tum, line 2: expected 8 values" in out and "Traceback" not in out
    code, out = _bench(["score", str(doppler_dir / "est_tum.txt"), "--store", str(store),
                        "--name", "x", "--pose-frame", "world"], capsys, monkeypatch)
    assert code == 2 and "--pose-frame 'world': expected sensor or body" in out


def test_an_experiment_scores_its_external_trajectories(data, tmp_path, capsys, monkeypatch):
    import yaml

    store, _, doppler_dir = data
    est = shutil.copy(doppler_dir / "est_tum.txt", tmp_path / "odom.tum")
    exp = tmp_path / "exp.yaml"
    entry = {"name": "odom", "trajectory": "odom.tum", "store": str(store)}
    exp.write_text(yaml.safe_dump({
        "name": "e", "out": "out", "sequences": [{"path": str(store), "name": "twist-exp"}],
        "methods": [{"name": "doppler"}], "external": [entry]}))
    code, out = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 0, out
    assert "external odom: done: " in out and "(100.0 %)" in out
    assert "| odom (external) |" in out  # in the experiment's table
    runs = tmp_path / "out" / "twist-exp"
    assert_same_metrics(read_run(runs / "doppler").result, read_run(runs / "odom").result,
                        rel=1e-9)
    assert read_run(runs / "odom").result.sequence == "twist-exp"
    code, out = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 0 and "external odom: skipped" in out  # unchanged: reused
    Path(est).unlink()
    code, out = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 2 and "external[0] (odom): trajectory" in out and "not found" in out
    exp.write_text(yaml.safe_dump({"name": "e", "sequences": [{"path": str(store)}],
                                   "methods": [], "external": [{**entry, "name": "doppler"}]}))
    code, out = _bench(["run", str(exp)], capsys, monkeypatch)
    assert code == 2 and "'doppler' is a method of the harness" in out


def test_figures_of_scored_runs_alone_leave_out_the_per_frame_plot(data, tmp_path, capsys,
                                                                   monkeypatch):
    """A folder holding only trajectories scored without per-frame times (no time_ms, no
    correspondences: nothing to draw on the per-frame plot's log axes, which raised a math
    domain error): `bench figures` exits 0, draws the error figures and no per-frame figure;
    beside a harness run the per-frame figure shows the harness run."""
    store, _, doppler_dir = data
    alone = tmp_path / "alone"
    score_external(store, ExternalSpec(doppler_dir / "est_tum.txt", "mine"), alone)
    code, out = _bench(["figures", str(alone), "--out", str(tmp_path / "f1")], capsys,
                       monkeypatch)
    assert code == 0 and "Traceback" not in out, out
    assert any((tmp_path / "f1").rglob("*.png")) and not (tmp_path / "f1" / "frames").exists()
    both = tmp_path / "both"
    shutil.copytree(alone, both)
    shutil.copytree(doppler_dir, both / "twist" / "doppler")
    from bench.report.figures.errors import plot_frames
    from bench.runs.folders import load_runs

    drawn = plot_frames(load_runs(both), tmp_path / "f2")  # the per-frame plot alone
    assert [p.parent.name for p in drawn if p.suffix == ".png"] == ["frames"]


def test_a_log_axis_with_nothing_positive_on_it_keeps_matplotlibs_ticks():
    """bench.report.figures.style.log_y on an axis that holds no positive value (its limits may
    not be positive) returns instead of taking the log of a negative ratio."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.figures.style import log_y

    fig, ax = plt.subplots()
    ax.plot([0, 1], [np.nan, np.nan])
    ax.set_ylim(-1.0, 1.0)
    log_y(ax)  # no ValueError
    plt.close(fig)
