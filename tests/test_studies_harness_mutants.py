"""``bench.studies.harness`` with injected clocks: the arithmetic of the per-frame costs
(``phases``, ``read_cost``, ``whole_run``), the child ``bench run`` it times, the printed table
and line, harness.csv and the wiring of ``bench speed --harness``. No wall-clock value is
asserted: every time is scripted, every expected figure worked out by hand below."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from rich.console import Console

from bench import guard
from bench.studies import harness
from conftest import constant_twist_sequence
from loaders.scan import MemorySequence
from loaders.store import StoreSequence
from methods.base import FrameRecord, OdometryResult


def _console() -> Console:
    return Console(record=True, width=400, color_system=None)


def _text(console: Console) -> str:
    text = console.export_text(clear=False)
    # the table's rules and borders as blanks
    return " ".join("".join(" " if 0x2500 <= ord(ch) <= 0x257F else ch for ch in text).split())


def _fake_time(monkeypatch, cpu: list[float], wall: list[float]) -> None:
    monkeypatch.setattr(harness, "time", SimpleNamespace(process_time=iter(cpu).__next__,
                                                         perf_counter=iter(wall).__next__))


def _scripted_clock(monkeypatch, values: list[tuple[float, float]]) -> list:
    """``harness._clock`` replaced: the k-th clock measures ``values[k]`` (cpu, wall)."""
    it = iter(values)
    used = []

    @contextmanager
    def clock():
        c = harness._Clock()
        yield c
        c.cpu_s, c.wall_s = next(it)
        used.append(c)

    monkeypatch.setattr(harness, "_clock", clock)
    return used


def _sized_store(path: Path, sizes: list[int]) -> Path:
    base = constant_twist_sequence(n_frames=len(sizes), n_points=800)
    scans = [s.select(np.arange(k)) for s, k in zip(base, sizes, strict=True)]
    seq = MemorySequence("sized", base.sensor, scans, base.ground_truth)
    return guard.write_store(seq, path, guard.is_store, "a scratch store")


# clocks ---------------------------------------------------------------------------------------

def test_clock_measures_the_differences_of_both_clocks(monkeypatch):
    _fake_time(monkeypatch, [1.0, 1.25], [10.0, 10.75])
    with harness._clock() as c:
        pass
    assert c.cpu_s == pytest.approx(0.25) and c.wall_s == pytest.approx(0.75)


@pytest.mark.parametrize(("frames", "n", "median"), [(None, 5, 100), (3, 3, 300), (2, 2, 200),
                                                     (9, 5, 100)])
def test_read_cost_per_scan_and_the_median_scan_of_the_frames_read(tmp_path, monkeypatch,
                                                                   frames, n, median):
    # sizes 100, 300, 500, 50, 60: median of all 100, of the first 3 300, of the first 2 200
    store = _sized_store(tmp_path / "s.h5", [100, 300, 500, 50, 60])
    _fake_time(monkeypatch, [2.0, 2.5], [7.0, 9.0])
    r = harness.read_cost(store, None, frames)
    assert r["read_ms"] == pytest.approx(1e3 * 0.5 / n)
    assert r["read_wall_ms"] == pytest.approx(1e3 * 2.0 / n)
    assert r["points"] == median and isinstance(r["points"], int)


# phases ---------------------------------------------------------------------------------------

#: scripted clocks of ``phases`` in its order: start-up, loop, two evaluations, the write, the
#: fixed write
CLOCKS = [(0.5, 0.6), (0.08, 0.1), (0.05, 0.07), (0.02, 0.03), (0.03, 0.05), (0.01, 0.02)]
#: the same but the second evaluation slower than the first and the fixed write slower than the
#: whole (both clamped at 0)
CLOCKS_CLAMPED = [(0.5, 0.6), (0.08, 0.1), (0.02, 0.03), (0.05, 0.07), (0.01, 0.02),
                  (0.03, 0.05)]


class _Method:
    """Stands in for the configured method: the ground truth as its poses, scripted times."""

    def __init__(self, times):
        self.times, self.calls = times, []

    def warm_up(self, seq):
        self.calls.append(("warm_up", len(seq)))

    def run(self, seq, seed, progress):
        self.calls.append(("run", len(seq), seed))
        gt = seq.ground_truth
        frames = [FrameRecord(i, float(t), ms, 10, 10, 1, True)
                  for i, (t, ms) in enumerate(zip(gt.stamps, self.times, strict=True))]
        return OdometryResult(np.asarray(gt.stamps), np.asarray(gt.poses), frames)


def _phases(tmp_path, monkeypatch, clocks):
    import bench.runs.folders as folders
    import bench.runs.job as job
    from methods.registry import get_method

    store = harness.tiled_store(constant_twist_sequence(n_frames=4, n_points=200), 8,
                                tmp_path / "t.h5")
    method = _Method([float("nan")] + [2.0] * 7)  # 7 timed frames of 2 ms
    real_prepare, real_write = job.prepare, folders.write_run
    writes, reads = [], []
    monkeypatch.setattr(job, "prepare",
                        lambda j: dataclasses.replace(real_prepare(j), method=method))

    def write_run(run_dir, result, gt, config, metrics, warnings):
        writes.append((len(result.frames), gt is None, dict(metrics)))
        return real_write(run_dir, result, gt, config, metrics, warnings)

    monkeypatch.setattr(folders, "write_run", write_run)

    def read_cost(path, fields, frames=None):
        reads.append((Path(path), fields, frames))
        return {"read_ms": 1.0, "read_wall_ms": 1.5, "points": 123}

    monkeypatch.setattr(harness, "read_cost", read_cost)
    _scripted_clock(monkeypatch, clocks)
    out = harness.phases(store, "icp-p2p")
    # icp-p2p has a seed option: the job with seed hands the method seed=True
    assert method.calls == [("warm_up", 8), ("run", 8, True)]
    assert reads == [(store, get_method("icp-p2p").reads_fields, None)]
    return out, writes


def test_phases_per_frame_costs_from_the_clocks(tmp_path, monkeypatch):
    r, writes = _phases(tmp_path, monkeypatch, CLOCKS)
    # n = 8 frames, 7 timed at 2 ms: method 2 ms; loop 80 ms / 8 = 10 (wall 12.5); evaluate: the
    # second clock, 2.5 (3.75); write: (30 - 10) / 8 = 2.5, wall (50 - 20) / 8 = 3.75;
    # start-up 0.5 + fixed write 0.01 + first evaluation's excess 0.03 = 0.54 (wall 0.66);
    # the loop besides the timed method: 10 - 2 * 7 / 8 = 8.25 = read 1 + driver 7.25, harness
    # 8.25 + 2.5 + 2.5 = 13.25; wall 12.5 - 1.75 = 10.75 = 1.5 + 9.25, 10.75 + 3.75 + 3.75
    expected = {"method": "icp-p2p", "frames": 8, "points": 123, "method_ms": 2.0,
                "startup_s": 0.54, "startup_wall_s": 0.66, "read_ms": 1.0, "read_wall_ms": 1.5,
                "loop_ms": 10.0, "loop_wall_ms": 12.5, "evaluate_ms": 2.5,
                "evaluate_wall_ms": 3.75, "write_ms": 2.5, "write_wall_ms": 3.75,
                "driver_ms": 7.25, "harness_ms": 13.25, "driver_wall_ms": 9.25,
                "harness_wall_ms": 18.25}
    assert set(r) == set(expected)
    for k, v in expected.items():
        assert r[k] == pytest.approx(v), k
    # the run's folder with its ground truth and metrics, then the fixed part: 2 frames, no GT
    (n, no_gt, metrics), (n2, no_gt2, metrics2) = writes
    assert (n, no_gt, n2, no_gt2) == (8, False, 2, True)
    assert metrics == metrics2
    assert (metrics["sequence"], metrics["method"], metrics["frames"]) == ("twist-tiled", "icp-p2p",
                                                                           8)
    assert metrics["seed"] is True


def test_phases_clamp_a_fixed_cost_larger_than_the_whole(tmp_path, monkeypatch):
    r, _ = _phases(tmp_path, monkeypatch, CLOCKS_CLAMPED)
    # write 10 ms < fixed write 30 ms: 0 per frame; the first evaluation 20 ms < the second
    # 50 ms: no excess; start-up 0.5 + 0.03 (wall 0.6 + 0.05); evaluate 50 / 8 = 6.25
    assert r["write_ms"] == 0.0 and r["write_wall_ms"] == 0.0
    assert r["startup_s"] == pytest.approx(0.53) and r["startup_wall_s"] == pytest.approx(0.65)
    assert r["evaluate_ms"] == pytest.approx(6.25) and r["evaluate_wall_ms"] == pytest.approx(
        1e3 * 0.07 / 8)
    assert r["harness_ms"] == pytest.approx(8.25 + 6.25)


# whole_run and its child bench run -----------------------------------------------------------

@pytest.mark.parametrize(("frames", "short"), [(8, 4), (104, 50)])
def test_whole_run_marginal_and_issue_costs(tmp_path, monkeypatch, frames, short):
    store = harness.tiled_store(constant_twist_sequence(n_frames=3, n_points=60), frames,
                                tmp_path / "t.h5")
    full_stamps = StoreSequence(store).stamps
    seen = []

    def bench_run(path, method, out):
        s = StoreSequence(path)
        seen.append((Path(out).name, method, len(s), np.asarray(s.stamps)))
        s.close()
        if Path(out).name == "full":
            Path(out).mkdir(parents=True)
            Path(out, "frames.csv").write_text("index,time_ms\n0,1.0\n1,3.0\n")
            return 5.0, 4.0
        return 2.0, 1.5

    monkeypatch.setattr(harness, "_bench_run", bench_run)
    r = harness.whole_run(store, "icp-p2p")
    (name_s, m_s, n_s, stamps_s), (name_f, m_f, n_f, _) = seen
    assert (name_s, m_s, n_s, name_f, m_f, n_f) == ("short", "icp-p2p", short, "full",
                                                    "icp-p2p", frames)
    np.testing.assert_allclose(stamps_s, full_stamps[:short])
    assert (r["method"], r["frames"], r["short_frames"]) == ("icp-p2p", frames, short)
    assert (r["wall_s"], r["cpu_s"], r["short_wall_s"], r["short_cpu_s"]) == (5.0, 4.0, 2.0, 1.5)
    assert r["method_ms"] == pytest.approx(2.0)
    assert r["marginal_wall_ms"] == pytest.approx(1e3 * 3.0 / (frames - short) - 2.0)
    assert r["marginal_cpu_ms"] == pytest.approx(1e3 * 2.5 / (frames - short) - 2.0)
    assert r["issue_wall_ms"] == pytest.approx(1e3 * 2.0 / frames - 2.0)
    assert r["issue_cpu_ms"] == pytest.approx(1e3 * 1.0 / frames - 2.0)


def _fake_child(monkeypatch, returncode=0, stdout="", stderr=""):
    calls = []

    def run(cmd, **kw):
        calls.append((cmd, kw))
        return subprocess.CompletedProcess(cmd, returncode, stdout, stderr)

    usage = iter([SimpleNamespace(ru_utime=1.0, ru_stime=0.5),
                  SimpleNamespace(ru_utime=3.0, ru_stime=0.75)])
    kinds = []

    def getrusage(who):
        kinds.append(who)
        return next(usage)

    monkeypatch.setattr(harness.subprocess, "run", run)
    monkeypatch.setattr(harness.resource, "getrusage", getrusage)
    monkeypatch.setattr(harness, "time", SimpleNamespace(perf_counter=iter([4.0, 6.5]).__next__))
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    return calls, kinds


def test_bench_run_times_the_cli_in_a_child_with_this_checkout_first(monkeypatch, tmp_path):
    import resource

    calls, kinds = _fake_child(monkeypatch)
    wall, cpu = harness._bench_run(tmp_path / "s.h5", "gicp", tmp_path / "out")
    # wall 6.5 - 4; CPU of the children: (3 - 1) + (0.75 - 0.5)
    assert wall == pytest.approx(2.5) and cpu == pytest.approx(2.25)
    assert kinds == [resource.RUSAGE_CHILDREN] * 2
    ((cmd, kw),) = calls
    assert cmd == [sys.executable, "-m", "bench.cli", "run", "--method", "gicp", "--data",
                   str(tmp_path / "s.h5"), "--out", str(tmp_path / "out"), "--force"]
    root = str(Path(harness.__file__).resolve().parents[2])
    assert kw["env"]["PYTHONPATH"] == root + os.pathsep + "/elsewhere"
    assert kw["capture_output"] is True and kw["text"] is True


def test_bench_run_failing_child_is_an_error_with_its_output_tail(monkeypatch, tmp_path):
    _fake_child(monkeypatch, 1, "o" * 100 + "O" * 1500, "e" * 100 + "E" * 1500)
    with pytest.raises(RuntimeError) as err:
        harness._bench_run(tmp_path / "s.h5", "gicp", tmp_path / "out")
    msg = str(err.value)
    assert msg == (f"bench run --method gicp --data {tmp_path / 's.h5'} failed:\n"
                   + "O" * 1500 + "E" * 1500)


# stores and scenarios -------------------------------------------------------------------------

def test_tiled_store_named_after_the_sequence_on_a_straight_line(tmp_path):
    base = constant_twist_sequence(n_frames=3, n_points=100)
    store = StoreSequence(harness.tiled_store(base, 7, tmp_path / "t.h5"))
    assert store.name == "twist-tiled" and len(store) == 7
    np.testing.assert_allclose(store.stamps, np.arange(7) * 0.1)
    np.testing.assert_array_equal(store[4].points, base[1].points.astype(np.float32))
    poses = store.ground_truth.poses
    np.testing.assert_allclose(poses[:, :3, :3], np.broadcast_to(np.eye(3), (7, 3, 3)),
                               atol=1e-12)
    np.testing.assert_allclose(poses[:, :3, 3], np.column_stack(
        [np.arange(7), np.zeros(7), np.zeros(7)]), atol=1e-9)


def test_scenario_row_tiles_to_300_frames_by_default(monkeypatch):
    seen = []

    def phases(store, method):
        seen.append((len(StoreSequence(store)), method))
        return {"method": method, "frames": 0}

    monkeypatch.setattr(harness, "phases", phases)
    base = constant_twist_sequence(n_frames=2, n_points=30)
    assert harness.scenario_row("radar", base) == {"scenario": "radar", "method": "doppler",
                                                   "frames": 0}
    assert harness.scenario_row("lidar", base, 5, "gicp")["scenario"] == "lidar"
    assert seen == [(300, "doppler"), (5, "gicp")]


@pytest.mark.parametrize(("scenario", "points", "sizes", "expected"), [
    ("radar", 5, [1000], True), ("lidar", 64000, [1000, 64000, 128000], True),
    ("lidar", 128000, [1000, 64000, 128000], False), ("lidar", 8000, [1000, 8000], True),
    ("lidar", 1000, [1000, 8000], False)])
def test_wanted_radar_and_the_64k_lidar_else_the_largest(scenario, points, sizes, expected):
    assert harness.wanted(scenario, points, sizes) is expected


def test_synthetic_scenarios_radar_then_subsampled_lidar():
    from loaders.synthetic import SyntheticSequence

    (r_name, radar), (l_name, lidar) = harness.synthetic_scenarios(lidar_points=300, frames=2)
    assert (r_name, l_name) == ("radar", "lidar")
    ref = SyntheticSequence("loop", "radar-semidense", frames=2, seed=0)
    assert len(radar) == 2 and radar.name == ref.name
    for a, b in zip(radar, ref, strict=True):
        np.testing.assert_array_equal(a.points, b.points)
    full = SyntheticSequence("campus", "lidar-dense", frames=2, seed=0, points=480)
    assert len(lidar) == 2 and lidar.name == full.name
    for a, b in zip(lidar, full, strict=True):
        assert len(b) > 300 and len(a) == 300
        # a subset of the full scan in its order
        rows = {tuple(p): i for i, p in enumerate(b.points)}
        idx = [rows[tuple(p)] for p in a.points]
        assert idx == sorted(idx) and len(set(idx)) == 300
    np.testing.assert_allclose(lidar.ground_truth.poses, full.ground_truth.poses)


def test_synthetic_scenarios_default_eight_frames():
    name, radar = next(harness.synthetic_scenarios())
    assert name == "radar" and len(radar) == 8


# printed and written figures ------------------------------------------------------------------

ROW = {"scenario": "radar", "method": "doppler", "points": 4321, "frames": 300,
       "method_ms": 2.0, "read_ms": 0.5, "read_wall_ms": 0.625, "driver_ms": 0.25,
       "driver_wall_ms": 0.375, "evaluate_ms": 1.0, "evaluate_wall_ms": 1.125, "write_ms": 0.75,
       "write_wall_ms": 0.875, "harness_ms": 3.0, "harness_wall_ms": 3.5, "startup_s": 1.234,
       "startup_wall_s": 2.3456}


def test_print_rows_has_every_phase_and_the_ratios_to_the_method():
    console = _console()
    harness.print_rows([ROW], console)
    text = _text(console)
    for col in ("scan", "points", "frames", "method", "read", "driver", "evaluate", "write",
                "harness", "harness / method", "read / method", "fixed [s]"):
        assert col in text
    # harness 3 / method 2 = 1.50x, read 0.5 / 2 = 0.25x
    assert ("radar (doppler) 4321 300 2.000 0.500 (0.625) 0.250 (0.375) 1.000 (1.125) "
            "0.750 (0.875) 3.000 (3.500) 1.50x 0.25x 1.23 (2.35)") in text
    assert ("scan points frames method read driver evaluate write harness harness / method "
            "read / method fixed [s]") in text
    assert ("The harness's own cost per frame beside the method's [ms, CPU time] (wall time in "
            "brackets)") in text
    assert ("read: a scan from the store (the arrays the method reads); driver: the loop around "
            "the method; fixed: start-up (store, method, warm-up) and the part of writing the run "
            "folder that does not grow with the frames; limits (issue 29): harness <= 1.5x and "
            "read <= 2.0x the method") in text


def test_print_rows_scan_left_and_figures_right():
    console = _console()
    short = {**ROW, "scenario": "a", "method": "b", "points": 7}
    harness.print_rows([ROW, short], console)
    (row,) = [ln for ln in console.export_text().splitlines() if "a (b)" in ln]
    cells = row.split("\u2502")[1:-1]
    # "radar (doppler)" sets the scan column's width: "a (b)" padded on the right; the points
    # column is as wide as its header ("points"): 7 padded on the left
    assert cells[0].startswith(" a (b) ") and cells[0].endswith("  ")
    assert cells[1] == "      7 "


def test_print_whole_run_line():
    r = {"method": "doppler", "frames": 400, "wall_s": 12.34, "cpu_s": 10.0, "short_frames": 50,
         "short_wall_s": 3.0, "short_cpu_s": 2.5, "method_ms": 2.0, "marginal_cpu_ms": 1.0,
         "marginal_wall_ms": 3.0, "issue_cpu_ms": 0.5, "issue_wall_ms": 4.0}
    console = _console()
    harness.print_whole_run(r, console)
    assert _text(console) == (
        "bench run --method doppler: 400 frames in 12.3 s wall / 10.0 s CPU (50 frames: 3.0 s "
        "/ 2.5 s); method 2.000 ms/frame; besides it per frame: marginal 1.000 ms CPU (0.50x), "
        "3.000 ms wall (1.50x); (total - 3 s) / frames - method: 0.500 ms CPU (0.25x), 4.000 "
        "ms wall (2.00x); limit 1.5x")


def test_report_writes_harness_csv_with_six_significant_digits(tmp_path, monkeypatch):
    rows = [{"scenario": "radar", "frames": 300, "method_ms": 1.23456789},
            {"scenario": "a.h5", "frames": 7, "method_ms": 2.0}]
    printed = []
    console = _console()
    monkeypatch.setattr(harness, "print_rows", lambda r, c: printed.append(r) if c is console
                        else pytest.fail("another console"))
    harness.report(rows, tmp_path / "out", console)
    assert (tmp_path / "out" / "harness.csv").read_text() == (
        "scenario,frames,method_ms\nradar,300,1.23457\na.h5,7,2\n")
    assert printed == [rows]
    harness.report(rows[:1], tmp_path / "out", console)  # its own file: replaced
    assert (tmp_path / "out" / "harness.csv").read_text() == "scenario,frames,method_ms\n" \
                                                            "radar,300,1.23457\n"
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "harness.csv").write_text("someone else's\n")
    with pytest.raises(guard.Refused, match="is not a harness table the harness wrote"):
        harness.report(rows, tmp_path / "other", console)
    assert f"wrote {tmp_path / 'out'}/harness.csv" in _text(console)


# bench speed --harness ------------------------------------------------------------------------

def test_run_harness_on_the_synthetic_scenes(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(harness, "synthetic_scenarios",
                        lambda n: calls.append(("scenes", n)) or iter([("radar", "R"),
                                                                       ("lidar", "L")]))
    monkeypatch.setattr(harness, "scenario_row", lambda s, seq, frames, method: calls.append(
        (s, seq, frames, method)) or {"scenario": s})
    monkeypatch.setattr(harness, "report", lambda rows, out, console: calls.append(
        ("report", list(rows), out)))
    monkeypatch.setattr(harness, "whole_run", lambda *a: pytest.fail("no whole run"))
    console = _console()
    rows = harness.run_harness(tmp_path, console, method="gicp", lidar_points=1234)
    assert rows == [{"scenario": "radar"}, {"scenario": "lidar"}]
    assert calls == [("scenes", 1234), ("radar", "R", 300, "gicp"), ("lidar", "L", 40, "gicp"),
                     ("report", rows, tmp_path)]
    assert "generating synthetic radar and 1234-point LiDAR scans" in _text(console)


def test_run_harness_on_a_store_with_a_whole_run(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(harness, "synthetic_scenarios", lambda n: pytest.fail("no scenes"))
    monkeypatch.setattr(harness, "phases", lambda store, method: calls.append(
        ("phases", store, method)) or {"method": method})
    monkeypatch.setattr(harness, "report", lambda rows, out, console: calls.append(
        ("report", list(rows), out)))
    monkeypatch.setattr(harness, "whole_run", lambda store, method: calls.append(
        ("whole", store, method)) or "R")
    monkeypatch.setattr(harness, "print_whole_run", lambda r, console: calls.append(("print", r)))
    console = _console()
    store = tmp_path / "data" / "seq.h5"
    rows = harness.run_harness(tmp_path / "out", console, store=str(store), method="dicp")
    assert rows == [{"scenario": "seq.h5", "method": "dicp"}]
    assert calls == [("phases", store, "dicp"), ("report", rows, tmp_path / "out"),
                     ("whole", store, "dicp"), ("print", "R")]
    assert (f"timing `bench run --method dicp` on {store} and on its first 50 frames (child "
            "processes)") in _text(console)


def test_run_harness_defaults_and_its_console(monkeypatch, tmp_path):
    calls = []
    console = _console()
    monkeypatch.setattr(harness, "synthetic_scenarios",
                        lambda n: calls.append(("scenes", n)) or iter([("radar", "R")]))
    monkeypatch.setattr(harness, "scenario_row", lambda s, seq, frames, method: calls.append(
        (s, frames, method)) or {"scenario": s})
    monkeypatch.setattr(harness, "report", lambda rows, out, c: calls.append(
        ("report", c is console)))
    harness.run_harness(tmp_path, console)
    assert calls == [("scenes", 64000), ("radar", 300, "doppler"), ("report", True)]


def test_run_harness_store_line_as_it_is(monkeypatch, tmp_path):
    console = _console()
    seen = []
    monkeypatch.setattr(harness, "phases", lambda store, method: {"method": method})
    monkeypatch.setattr(harness, "report", lambda rows, out, c: None)
    monkeypatch.setattr(harness, "whole_run", lambda store, method: seen.append(method) or "R")
    monkeypatch.setattr(harness, "print_whole_run", lambda r, c: seen.append(c is console))
    store = tmp_path / "d[x]" / "s.h5"
    harness.run_harness(tmp_path / "out", console, store=store)
    assert seen == ["doppler", True]
    assert f"timing `bench run --method doppler` on {store} and on its first 50 frames" \
        in _text(console)


def test_whole_run_default_method(tmp_path, monkeypatch):
    store = harness.tiled_store(constant_twist_sequence(n_frames=2, n_points=30), 4,
                                tmp_path / "t.h5")
    seen = []

    def bench_run(path, method, out):
        seen.append(method)
        Path(out).mkdir(parents=True)
        Path(out, "frames.csv").write_text("time_ms\n1.0\n")
        return 1.0, 1.0

    monkeypatch.setattr(harness, "_bench_run", bench_run)
    assert harness.whole_run(store)["method"] == "doppler" and seen == ["doppler", "doppler"]


def test_tiled_store_keeps_each_scans_arrays_and_owns_its_file(tmp_path):
    base = constant_twist_sequence(n_frames=2, n_points=40)
    path = tmp_path / "t.h5"
    harness.tiled_store(base, 3, path)
    harness.tiled_store(base, 4, path)  # its own scratch store: replaced
    store = StoreSequence(path)
    assert len(store) == 4
    np.testing.assert_allclose(store[3].doppler, base[1].doppler, rtol=1e-6)
    np.testing.assert_allclose(store[3].fields["power"], base[1].fields["power"], rtol=1e-6)
    store.close()
    (tmp_path / "x.h5").write_text("someone else's\n")
    with pytest.raises(guard.Refused, match="is not a scratch store the harness wrote"):
        harness.tiled_store(base, 3, tmp_path / "x.h5")


def test_synthetic_scenarios_are_the_same_on_every_call():
    first = [(name, seq) for name, seq in harness.synthetic_scenarios(lidar_points=200,
                                                                        frames=2)]
    again = [(name, seq) for name, seq in harness.synthetic_scenarios(lidar_points=200,
                                                                        frames=2)]
    for (_, a), (_, b) in zip(first, again, strict=True):
        assert a.sensor.kind == b.sensor.kind and a.ground_truth is not None
        for sa, sb in zip(a, b, strict=True):
            np.testing.assert_array_equal(sa.points, sb.points)
    assert [seq.sensor.kind for _, seq in first] == ["radar", "lidar"]
