"""``bench.studies.speed`` with injected timings: the structure of ``bench speed``'s rows, the
arithmetic of its ratios, the printed tables and written CSVs, the memory probe's parsing and
its errors, the small synthetic sequences and stores it times on. No wall-clock value is
asserted: every figure is scripted and every expected value worked out by hand."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rich.console import Console

from bench import guard
from bench.studies import harness as harness_study
from bench.studies import speed
from conftest import constant_twist_sequence
from loaders.store import StoreSequence


def _console() -> Console:
    return Console(record=True, width=400, color_system=None)


def _text(console: Console) -> str:
    text = console.export_text(clear=False)
    # the tables' rules and borders as blanks
    return " ".join("".join(" " if 0x2500 <= ord(ch) <= 0x257F else ch for ch in text).split())


# sequences, subsampling, stores --------------------------------------------------------------

def test_subsample_keeps_a_seeded_subset_in_order():
    scan = constant_twist_sequence(n_frames=1, n_points=400)[0]
    assert speed.subsample(scan, len(scan), 0) is scan
    assert speed.subsample(scan, len(scan) + 5, 0) is scan
    a, b, c = (speed.subsample(scan, 50, s) for s in (3, 3, 4))
    assert len(a) == 50
    rows = {tuple(p): i for i, p in enumerate(scan.points)}
    idx = [rows[tuple(p)] for p in a.points]
    assert idx == sorted(idx) and len(set(idx)) == 50
    np.testing.assert_array_equal(a.doppler, scan.doppler[idx])
    np.testing.assert_array_equal(a.points, b.points)
    assert not np.array_equal(a.points, c.points)


def test_make_sequence_is_the_generators_and_dense_enough():
    from loaders.synthetic import SyntheticSequence

    seq = speed.make_sequence("loop", "radar-semidense", 2)
    ref = SyntheticSequence("loop", "radar-semidense", frames=2, seed=0)
    assert seq.name == ref.name and len(seq) == 2 and seq.sensor.kind == ref.sensor.kind
    for a, b in zip(seq, ref, strict=True):
        np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_allclose(seq.ground_truth.poses, ref.ground_truth.poses)
    other = speed.make_sequence("loop", "radar-semidense", 2, seed=1)
    assert not np.array_equal(other[0].points, seq[0].points)
    dense = speed.make_sequence("campus", "lidar-dense", 2, 700)
    # dense enough, from about 1.6 rays a point (a scan has at most a point per ray)
    assert min(len(s) for s in dense) >= 700 and max(len(s) for s in dense) <= 1120


def test_memory_store_writes_scans_of_the_asked_size(tmp_path):
    path, what = speed.memory_store(tmp_path / "m.h5", points=300, frames=3)
    assert path == tmp_path / "m.h5"
    store = StoreSequence(path)
    assert len(store) == 3 and list(store.points_per_frame()) == [300, 300, 300]
    assert store.sensor.kind == "lidar"
    assert what == "3 frames of 300 points"


def test_scenarios_radar_then_each_lidar_size_from_stores(tmp_path):
    found = [(s, n, len(seq), seq.sensor.kind, list(seq.points_per_frame()))
             for s, n, seq in speed._scenarios([200, 350], True, 3, tmp_path)]
    (radar, n_r, len_r, kind_r, pts_r), *lidar = found
    assert (radar, len_r, kind_r) == ("radar", 3, "radar")
    assert n_r == int(np.median(pts_r))
    assert [(s, n, k, kind, pts) for s, n, k, kind, pts in lidar] == [
        ("lidar", 200, 3, "lidar", [200] * 3), ("lidar", 350, 3, "lidar", [350] * 3)]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lidar-200.h5", "lidar-350.h5",
                                                          "radar.h5"]
    only_lidar = [s for s, _, _ in speed._scenarios([200], False, 2, tmp_path / "b")]
    assert only_lidar == ["lidar"]


# one method -----------------------------------------------------------------------------------

def _method(name="icp-p2p", **params):
    return SimpleNamespace(name=name, params=SimpleNamespace(**params))


@pytest.mark.parametrize(("method", "note"), [
    (_method(downsample=4), "1 in 4 points"),
    (_method(downsample=1, voxel_downsample_m=0.5), "voxel grid 0.5 m"),
    (_method(downsample=1, voxel_m=0.25), "voxel grid 0.25 m"),
    (_method(voxel_downsample_m=None, voxel_m=0.3), "voxel grid 0.3 m"),
    (_method(), "all points"),
    (SimpleNamespace(name="x"), "all points"),
    (_method("vgicp", voxel_size_m=1.0), "all points, VGICP voxels 1 m"),
    (_method("small-vgicp", downsample=2, voxel_size_m=0.5), "1 in 2 points, VGICP voxels 0.5 m"),
    (_method("gicp", voxel_size_m=1.0), "all points"),
    (SimpleNamespace(params=SimpleNamespace(voxel_size_m=1.0)), "all points")])
def test_prep_note(method, note):
    assert speed._prep_note(method) == note


def test_time_method_adds_the_prep_note_and_threads(monkeypatch):
    calls = []
    made = _method(downsample=3)
    made.threads = 2
    monkeypatch.setattr(speed, "method_params", lambda n, t: {"num_threads": t})
    monkeypatch.setattr(speed, "make_method", lambda n, p, s: calls.append((n, p, s)) or made)
    monkeypatch.setattr(speed, "time_frames", lambda m, seq: calls.append((m, seq)) or
                        {"median_ms": 1.5})
    seq = SimpleNamespace(sensor="SENSOR")
    r = speed.time_method("icp-p2p", seq, threads=2)
    assert r == {"median_ms": 1.5, "prep": "1 in 3 points", "threads": 2}
    assert calls == [("icp-p2p", {"num_threads": 2}, "SENSOR"), (made, seq)]
    speed.time_method("icp-p2p", seq)
    assert calls[2][1] == {"num_threads": 1}


def test_compare_with_run_writes_a_store_without_ground_truth(monkeypatch, tmp_path):
    import bench.runs.plan as plan

    seen = []

    def run_single(name, store, seed, params, out, force):
        s = StoreSequence(store)
        seen.append((name, Path(store).name, seed, params, out, force, len(s),
                     s.ground_truth is None))
        s.close()
        return SimpleNamespace(result=SimpleNamespace(time_ms=SimpleNamespace(median=4.0)))

    monkeypatch.setattr(plan, "run_single", run_single)
    seq = constant_twist_sequence(n_frames=3, n_points=50)
    monkeypatch.setattr(speed, "time_method", lambda n, s: {"median_ms": 3.0} if (
        n == "gicp" and s is seq) else pytest.fail("arguments"))
    assert speed.compare_with_run("gicp", seq, tmp_path) == (3.0, 4.0)
    assert seen == [("gicp", "gicp.h5", True, {}, tmp_path / "gicp", True, 3, True)]
    # its own scratch store is replaced; a file it did not write is refused
    assert speed.compare_with_run("gicp", seq, tmp_path) == (3.0, 4.0)
    (tmp_path / "dicp.h5").write_text("someone else's\n")
    with pytest.raises(guard.Refused, match="is not a scratch store the harness wrote"):
        speed.compare_with_run("dicp", seq, tmp_path)


# the memory probe -----------------------------------------------------------------------------

def _probe(monkeypatch, stdout, returncode=0, stderr="boom"):
    calls = []

    def run(cmd, **kw):
        calls.append((cmd, kw))
        return subprocess.CompletedProcess(cmd, returncode, stdout, stderr)

    monkeypatch.setattr(speed.subprocess, "run", run)
    monkeypatch.setattr(speed, "method_params", lambda n, t: {"num_threads": t} if n in (
        "kiss-icp", "gicp", "doppler") else pytest.fail(n))
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    return calls


def test_peak_memory_of_run_reads_both_marks_of_the_child(monkeypatch, tmp_path):
    calls = _probe(monkeypatch, "noise\nBASE_KB 2048 kB\nEXIT 0\nPEAK_KB 5120 kB\n")
    peak, base = speed.peak_memory_of_run("kiss-icp", tmp_path / "s.h5", threads=3)
    assert (peak, base) == (5.0, 2.0)
    ((cmd, kw),) = calls
    assert cmd[:2] == [sys.executable, "-c"]
    code = cmd[2]
    compile(code, "probe", "exec")
    assert code.startswith("import sys, bench.cli, methods.registry, bench.commands, "
                           "bench.runs.job, loaders.store\n")
    assert "'--method','kiss-icp','--data'," + repr(str(tmp_path / "s.h5")) in code
    assert "'--executor','local',*['-p', 'num_threads=3']]" in code
    assert "VmHWM" in code and "\nprint('BASE_KB', hwm())\nsys.argv=['bench','run'," in code
    assert "\ntry:\n    bench.cli.main()\nexcept SystemExit as e:\n" in code
    assert re.search(r"'--out','/[^']+/run','--executor'", code)
    assert "print('PEAK_KB', hwm())" in code and "print('EXIT', e.code or 0)" in code
    root = str(Path(speed.__file__).resolve().parents[2])
    assert kw["env"]["PYTHONPATH"] == root + os.pathsep + "/elsewhere"
    assert kw["timeout"] == 1800 and kw["capture_output"] is True and kw["text"] is True


def test_peak_memory_probe_without_thread_parameters(monkeypatch, tmp_path):
    calls = _probe(monkeypatch, "BASE_KB 1024\nPEAK_KB 1024\n")
    monkeypatch.setattr(speed, "method_params", lambda n, t: {})
    assert speed.peak_memory_of_run("doppler", tmp_path / "s.h5") == (1.0, 1.0)
    assert "'--executor','local',*[]]" in calls[0][0][2]


@pytest.mark.parametrize(("stdout", "code", "exit_shown"), [
    ("BASE_KB 1\nEXIT 2\nPEAK_KB 3\n", 0, "2"),
    ("BASE_KB 1\nPEAK_KB 3\n", 1, "1"),
    ("BASE_KB 1\nEXIT 0\n", 0, "0")])
def test_a_failed_memory_probe_is_an_error(monkeypatch, tmp_path, stdout, code, exit_shown):
    _probe(monkeypatch, stdout, code, "x" * 10 + "y" * 2000)
    with pytest.raises(RuntimeError) as err:
        speed.peak_memory_of_run("gicp", tmp_path / "s.h5")
    assert str(err.value) == (f"memory probe of gicp: `bench run` failed (exit {exit_shown}):\n"
                              + "y" * 2000)


def test_memory_table_and_csv(monkeypatch, tmp_path):
    monkeypatch.setattr(speed, "memory_store", lambda path: (path, "20 frames of 64000 points"))
    figures = {"doppler": (300.4, 156.2), "gicp": (400.0, 158.9)}
    seen = []
    monkeypatch.setattr(speed, "peak_memory_of_run", lambda n, store, threads: seen.append(
        (n, store.name, threads)) or figures[n])
    console = _console()
    speed._memory(["doppler", "gicp"], tmp_path, console, 2)
    assert seen == [("doppler", "lidar64k.h5", 2), ("gicp", "lidar64k.h5", 2)]
    assert (tmp_path / "memory.csv").read_text() == (
        "method,peak_rss_mb,imports_rss_mb,run_mb,store\n"
        "doppler,300.4,156.2,144.2,\"20 frames of 64000 points\"\n"
        "gicp,400.0,158.9,241.1,\"20 frames of 64000 points\"\n")
    text = _text(console)
    assert "Peak memory of `bench run` [MB], LiDAR store (20 frames of 64000 points)" in text
    # peak rounded, and what the run added above the imports
    assert "doppler 300 144" in text and "gicp 400 241" in text
    assert "method peak RSS above the imports" in text
    assert ("the imports of every run (bench.cli, methods.registry, bench.commands, "
            "bench.runs.job, loaders.store: Python, NumPy, SciPy, numba, small_gicp, h5py, ...) "
            "take 156-159 MB before a scan is read") in text
    (row,) = [ln for ln in console.export_text().splitlines() if "doppler" in ln]
    # figures right-aligned under their (wider) headers
    assert row.split("\u2502")[2:4] == ["      300 ", "               144 "]
    speed._memory(["doppler"], tmp_path, _console(), 2)  # its own memory.csv: replaced
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "memory.csv").write_text("someone else's\n")
    with pytest.raises(guard.Refused, match="is not a table of memory the harness wrote"):
        speed._memory(["doppler"], tmp_path / "other", _console(), 2)


# bench speed ----------------------------------------------------------------------------------

def _row(median, register=0.5):
    return {"median_ms": median, "register_median_ms": register, "p5_ms": median / 2,
            "p95_ms": median * 2, "repeats": 2, "iterations": 3, "prep": "all points",
            "threads": 1, "clock": "CPU"}


class _Seq(str):
    """A scripted scenario's sequence: its name, and ``frames`` frames."""

    def __new__(cls, name, frames):
        self = super().__new__(cls, name)
        self.frames = frames
        return self

    def __len__(self):
        return self.frames


def _fake_speed(monkeypatch, times, with_threads=("doppler", "gicp")):
    calls = {"scenarios": [], "time": [], "harness": [], "memory": [], "vs_run": []}

    def scenarios(sizes, radar, frames, folder):
        calls["scenarios"].append((list(sizes), radar, frames))
        if radar:
            yield "radar", 4000, _Seq("SEQ-radar", frames)
        for n in sizes:
            yield "lidar", n, _Seq(f"SEQ-{n}", frames)

    def time_method(name, seq, threads=1):
        calls["time"].append((name, seq, threads))
        return _row(times[(name, str(seq))] * (1 if threads == 1 else 0.5))

    monkeypatch.setattr(speed, "_scenarios", scenarios)
    monkeypatch.setattr(speed, "time_method", time_method)
    monkeypatch.setattr(speed, "method_params",
                        lambda n, t: {"num_threads": t} if n in with_threads else {})
    monkeypatch.setattr(speed, "_plot", lambda rows, names, path: None)
    monkeypatch.setattr(speed, "_memory", lambda names, out, console, threads: calls[
        "memory"].append((list(names), out, threads)))
    monkeypatch.setattr(speed, "_print_vs_run", lambda names, seq, what, console: calls[
        "vs_run"].append((list(names), seq, what)))
    monkeypatch.setattr(harness_study, "scenario_row", lambda s, seq, frames: calls[
        "harness"].append((s, seq, frames)) or {"scenario": s, "x": 1.0})
    monkeypatch.setattr(harness_study, "report", lambda rows, out, console: calls[
        "harness"].append(("report", list(rows))))
    return calls


def test_run_speed_rows_ratios_to_doppler_and_the_harness_rows(monkeypatch, tmp_path):
    times = {("doppler", "SEQ-radar"): 2.0, ("gicp", "SEQ-radar"): 8.0,
             ("doppler", "SEQ-64000"): 4.0, ("gicp", "SEQ-64000"): 2.0,
             ("doppler", "SEQ-1000"): 1.0, ("gicp", "SEQ-1000"): 3.0}
    calls = _fake_speed(monkeypatch, times)
    console = _console()
    rows = speed.run_speed([1000, 64000], ["gicp", "doppler"], 1, tmp_path, console,
                           memory=False)
    # doppler first (the base of every ratio), whatever the order asked for
    assert [(r["scenario"], r["points"], r["method"], r["threads_setting"]) for r in rows] == [
        ("radar", 4000, "doppler", 1), ("radar", 4000, "gicp", 1),
        ("lidar", 1000, "doppler", 1), ("lidar", 1000, "gicp", 1),
        ("lidar", 64000, "doppler", 1), ("lidar", 64000, "gicp", 1)]
    assert [r["ratio_to_doppler"] for r in rows] == pytest.approx([1, 4, 1, 3, 1, 0.5])
    assert calls["scenarios"] == [([1000, 64000], True, 3)]  # max(1, 2) + 1 frames
    # harness figures on the radar scan and the 64k-point LiDAR scan only
    assert calls["harness"] == [("radar", "SEQ-radar", 300), ("lidar", "SEQ-64000", 40),
                                ("report", [{"scenario": "radar", "x": 1.0},
                                            {"scenario": "lidar", "x": 1.0}])]
    assert calls["memory"] == [] and calls["vs_run"] == []
    lines = (tmp_path / "speed.csv").read_text().splitlines()
    assert lines[0].split(",")[:5] == ["scenario", "points", "method", "threads_setting",
                                       "median_ms"]
    assert lines[0].split(",")[-1] == "ratio_to_doppler"
    assert lines[2].startswith("radar,4000,gicp,1,8,") and lines[2].endswith(",4")
    text = _text(console)
    assert "generating synthetic radar and LiDAR sequences (up to 64000 points)" in text
    assert "radar N= 4000 gicp 8.000 ms (registration 0.500 ms; 2 frames, 3 it, all points, " \
           "1 thr., CPU time)" in text
    assert f"wrote {tmp_path}/speed.csv and speed.png" in text


def test_run_speed_threads_memory_vs_run_and_no_harness(monkeypatch, tmp_path):
    times = {("doppler", "SEQ-500"): 2.0, ("gicp", "SEQ-500"): 6.0, ("icp-p2p", "SEQ-500"): 4.0}
    calls = _fake_speed(monkeypatch, times)
    rows = speed.run_speed([500], ["icp-p2p", "gicp"], 5, tmp_path, _console(), radar=False,
                           threads=4, harness=False, vs_run=True)
    # every method on 1 thread, then on 4 only those with a thread count (doppler, gicp: half
    # their 1-thread time in the fake), each ratio to doppler's figure of the same setting
    assert [(r["method"], r["threads_setting"]) for r in rows] == [
        ("doppler", 1), ("icp-p2p", 1), ("gicp", 1), ("doppler", 4), ("gicp", 4)]
    assert calls["time"][-1] == ("gicp", "SEQ-500", 4)
    assert [r["ratio_to_doppler"] for r in rows] == pytest.approx([1, 2, 3, 1, 3])
    assert [r["median_ms"] for r in rows[3:]] == pytest.approx([1.0, 3.0])
    assert calls["harness"] == []
    assert calls["scenarios"] == [([500], False, 6), ([500], False, 6)]
    assert calls["memory"] == [(["doppler", "icp-p2p", "gicp"], tmp_path, 4)]
    assert calls["vs_run"] == [(["doppler", "icp-p2p", "gicp"], "SEQ-500",
                                "lidar, 500 points, 5 frames")]


def test_run_speed_every_method_by_default(monkeypatch, tmp_path):
    from methods.registry import METHODS

    times = {(n, "SEQ-100"): 1.0 for n in METHODS}
    calls = _fake_speed(monkeypatch, times)
    speed.run_speed([100], None, 1, tmp_path, _console(), memory=False, radar=False,
                    harness=False)
    names = [n for n, _, _ in calls["time"]]
    assert names[0] == "doppler" and sorted(names) == sorted(METHODS)


def test_print_vs_run_table(monkeypatch):
    monkeypatch.setattr(speed, "compare_with_run", lambda name, seq, folder: {
        "doppler": (2.0, 1.0), "gicp": (3.0, 4.0)}[name] if seq == "SEQ" and folder.is_dir()
        else pytest.fail("arguments"))
    console = _console()
    speed._print_vs_run(["doppler", "gicp"], "SEQ", "lidar, 500 points, 5 frames", console)
    text = _text(console)
    assert ("bench speed against bench run on the same scans (lidar, 500 points, 5 frames): "
            "median time_ms [ms]") in text
    assert "method bench speed bench run speed / run" in text
    assert "doppler 2.000 1.000 2.00" in text and "gicp 3.000 4.000 0.75" in text
    (row,) = [ln for ln in console.export_text().splitlines() if "gicp" in ln]
    cells = row.split("\u2502")[1:-1]
    assert cells[0].startswith(" gicp ") and cells[3].endswith(" 0.75 ")


def test_print_table_cells_and_missing_thread_settings():
    rows = [{"scenario": "lidar", "points": 1000, "threads_setting": 1, "method": "doppler",
             "median_ms": 2.0, "register_median_ms": 1.0, "ratio_to_doppler": 1.0,
             "prep": "all points"},
            {"scenario": "lidar", "points": 1000, "threads_setting": 1, "method": "gicp",
             "median_ms": 7.0, "register_median_ms": 5.5, "ratio_to_doppler": 3.5,
             "prep": "voxel grid 0.5 m"},
            {"scenario": "lidar", "points": 1000, "threads_setting": 4, "method": "gicp",
             "median_ms": 3.0, "register_median_ms": 2.0, "ratio_to_doppler": 1.5,
             "prep": "voxel grid 0.5 m"}]
    console = _console()
    speed._print_table(rows, ["doppler", "gicp"], console)
    text = _text(console)
    assert "scan input points threads doppler gicp" in text
    assert ("Time per frame, median [ms]: total (all per-frame work) / registration call, and "
            "total x doppler; input points per scan, before each method's own downsampling") \
        in text
    assert ("clock: CPU time on 1 thread, wall time on more (threads: the count asked for; a "
            "method without a thread count runs on 1); preparation") in text
    (row,) = [ln for ln in console.export_text().splitlines() if "3.00 / 2.00" in ln]
    cells = row.split("\u2502")[1:-1]
    assert cells[1] == "         1000 " and cells[2] == "       4 "
    assert "lidar 1000 1 2.00 / 1.00 (1.0x) 7.00 / 5.50 (3.5x)" in text
    assert "lidar 1000 4 - 3.00 / 2.00 (1.5x)" in text
    assert "preparation (timed in the total): doppler: all points; gicp: voxel grid 0.5 m" in text
    assert "clock: CPU time on 1 thread, wall time on more" in text


# written files ---------------------------------------------------------------------------------

def test_write_csv_six_digits_and_quoted_commas(tmp_path):
    speed.write_csv([{"a": 1.23456789, "b": "x, y", "c": 3, "d": "plain"},
                     {"a": 2.0, "b": "z", "c": 4, "d": "q"}], tmp_path / "t.csv")
    assert (tmp_path / "t.csv").read_text() == (
        'a,b,c,d\n1.23457,"x, y",3,plain\n2,z,4,q\n')


def test_check_outputs_refuses_a_folder_holding_an_input(tmp_path):
    with pytest.raises(guard.Refused, match="holds an input"):
        speed.check_outputs(tmp_path, inputs=[tmp_path / "in.h5"])


def test_check_outputs_refuses_a_speed_file_it_did_not_write(tmp_path):
    speed.check_outputs(tmp_path / "new")
    speed.check_outputs(tmp_path)
    speed.write_csv([{"a": 1}], tmp_path / "speed.csv")
    speed.check_outputs(tmp_path)  # its own file: replaced
    for name in ("speed.png", "memory.csv", "harness.csv", "scale.csv", "scale_executors.csv",
                 "speed_reference.csv"):
        d = tmp_path / name.replace(".", "_")
        d.mkdir()
        (d / name).write_text("someone else's\n")
        with pytest.raises(guard.Refused, match=f"{name}: exists and is not a speed table or "
                                                "plot this command wrote"):
            speed.check_outputs(d)


def test_plot_draws_the_one_thread_lidar_curves(monkeypatch, tmp_path):
    import matplotlib.colors

    from bench.report.names import display_name

    saved = []
    monkeypatch.setattr(speed.guard, "savefig", lambda fig, path, fmt, own, what, dpi: saved.append(
        (fig, path, fmt, dpi)))

    def row(method, n, ms, scenario="lidar", setting=1):
        return {"method": method, "points": n, "median_ms": ms, "p5_ms": ms / 2,
                "p95_ms": 2 * ms, "scenario": scenario, "threads_setting": setting}

    rows = [row("doppler", 4000, 1.0), row("doppler", 1000, 0.5), row("gicp", 1000, 2.0),
            row("gicp", 1000, 9.0, "radar"), row("gicp", 4000, 9.0, setting=4)]
    # kiss-icp has no 1-thread LiDAR point: no curve, the next method still drawn
    speed._plot(rows, ["doppler", "kiss-icp", "gicp"], tmp_path / "speed.png")
    ((fig, path, fmt, dpi),) = saved
    assert (path, fmt, dpi) == (tmp_path / "speed.png", "png", 120)
    (ax,) = fig.axes
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    lines = ax.get_lines()
    assert [ln.get_label() for ln in lines] == [display_name("doppler"), display_name("gicp")]
    np.testing.assert_allclose(lines[0].get_xdata(), [1000, 4000])
    np.testing.assert_allclose(lines[0].get_ydata(), [0.5, 1.0])
    np.testing.assert_allclose(lines[1].get_xdata(), [1000])
    assert ax.get_xlabel() == "input points per scan"
    assert ax.get_ylabel() == "time per frame, all per-frame work [ms]"
    assert ax.get_title() == "median with p5-p95 band, 1 thread (synthetic FMCW LiDAR)"
    # a p5-p95 band under each curve, in its colour: doppler's from 0.25 to 2 ms
    bands = ax.collections
    assert len(bands) == 2
    ys = bands[0].get_paths()[0].vertices[:, 1]
    np.testing.assert_allclose([ys.min(), ys.max()], [0.25, 2.0])
    np.testing.assert_allclose(bands[0].get_facecolor()[0][:3],
                               matplotlib.colors.to_rgb(lines[0].get_color()))
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [
        display_name("doppler"), display_name("gicp")]


def test_run_speed_reference_rows_per_scenario_at_the_asked_threads(monkeypatch, tmp_path):
    from bench.studies import speed_reference

    times = {("doppler", "SEQ-radar"): 2.0, ("gicp", "SEQ-radar"): 8.0,
             ("doppler", "SEQ-1000"): 1.0, ("gicp", "SEQ-1000"): 3.0}
    calls = _fake_speed(monkeypatch, times)
    console = _console()
    seen = {"plot": [], "ref": [], "table": []}
    monkeypatch.setattr(speed, "_plot", lambda rows, names, path: seen["plot"].append(
        (len(rows), list(names), path)))
    monkeypatch.setattr(speed_reference, "available_libraries",
                        lambda c: "LIBS" if c is console else pytest.fail("console"))
    monkeypatch.setattr(speed_reference, "reference_rows", lambda s, n, seq, rows, threads,
                        libs: seen["ref"].append((s, n, str(seq), [
                            (r["scenario"], r["points"], r["method"], r["threads_setting"])
                            for r in rows], threads, libs)) or [{"scenario": s, "n": n}])
    monkeypatch.setattr(speed_reference, "print_reference_table", lambda rows, libs, c: seen[
        "table"].append((list(rows), libs, c is console)))
    monkeypatch.setattr(harness_study, "report", lambda rows, out, c: calls["harness"].append(
        ("report", out, c is console)))
    speed.run_speed([1000], ["gicp"], 1, tmp_path, console, memory=False, threads=4,
                    reference=True)
    # each scenario's pairs at the asked thread count (4) only, right after its methods
    assert seen["ref"] == [
        ("radar", 4000, "SEQ-radar", [("radar", 4000, "doppler", 4), ("radar", 4000, "gicp", 4)],
         4, "LIBS"),
        ("lidar", 1000, "SEQ-1000", [("lidar", 1000, "doppler", 4), ("lidar", 1000, "gicp", 4)],
         4, "LIBS")]
    assert seen["table"] == [([{"scenario": "radar", "n": 4000},
                               {"scenario": "lidar", "n": 1000}], "LIBS", True)]
    assert (tmp_path / "speed_reference.csv").read_text() == "scenario,n\nradar,4000\nlidar,1000\n"
    assert seen["plot"] == [(8, ["doppler", "gicp"], tmp_path / "speed.png")]
    assert calls["harness"][-1] == ("report", tmp_path, True)
    assert f"wrote {tmp_path}/speed_reference.csv" in _text(console)


def test_run_speed_reference_without_counterparts(monkeypatch, tmp_path):
    from bench.studies import speed_reference

    calls = _fake_speed(monkeypatch, {("doppler", "SEQ-100"): 1.0})
    monkeypatch.setattr(speed_reference, "available_libraries", lambda c: "LIBS")
    monkeypatch.setattr(speed_reference, "reference_rows", lambda *a: [])
    monkeypatch.setattr(speed_reference, "COUNTERPARTS", {"ref[a]": 1, "b": 2})
    monkeypatch.setattr(speed, "time_method", lambda name, seq, threads=1: {
        **_row(1.0), "prep": "voxel [grid]"})
    console = _console()
    speed.run_speed([100], ["doppler"], 1, tmp_path, console, memory=False, radar=False,
                    harness=False, reference=True)
    text = _text(console)
    assert "--reference: none of these methods has a library counterpart (ref[a], b)" in text
    assert "voxel [grid], 1 thr., CPU time)" in text
    assert not (tmp_path / "speed_reference.csv").exists() and calls["harness"] == []
