"""``bench.studies.speed``: how ``make_sequence`` densifies, what ``memory_store``,
``_scenarios``, ``time_method`` and the memory probe ask for, and how ``run_speed`` hands on
its thread settings, scratch folder and console: tests reaching the survivors the first
mutation pass left."""

from __future__ import annotations

import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from bench.studies import speed
from conftest import constant_twist_sequence
from loaders.store import StoreSequence

# make_sequence ---------------------------------------------------------------------------------


def _generator(monkeypatch, size_of):
    """``SyntheticSequence`` replaced: records each ``points`` asked for; its scans hold
    ``size_of(points)`` points."""
    import loaders.synthetic as synthetic

    asked = []

    class Gen:
        def __init__(self, scene, sensor, frames, seed, points=None):
            asked.append(points)
            base = constant_twist_sequence(n_frames=frames, n_points=600)
            self.name, self.sensor, self.ground_truth = base.name, base.sensor, base.ground_truth
            self.scans = [s.select(np.arange(size_of(points))) for s in base]

        def __iter__(self):
            return iter(self.scans)

    monkeypatch.setattr(synthetic, "SyntheticSequence", Gen)
    return asked


def test_make_sequence_four_tries_each_half_again_as_many_rays(monkeypatch):
    asked = _generator(monkeypatch, lambda points: 10)  # never dense enough
    seq = speed.make_sequence("campus", "lidar-dense", 2, 100)
    # 1.6 rays a point asked for first, then 1.5 times more on each of the 3 retries
    assert asked == [160, 240, 360, 540]
    assert len(seq) == 2 and [len(s) for s in seq] == [10, 10]


def test_make_sequence_stops_when_exactly_dense_enough(monkeypatch):
    asked = _generator(monkeypatch, lambda points: 100)
    seq = speed.make_sequence("campus", "lidar-dense", 2, 100)
    assert asked == [160] and [len(s) for s in seq] == [100, 100]


# memory_store, _scenarios, time_method ----------------------------------------------------------

def _recorded_make(monkeypatch, n_points=60):
    calls = []

    def make(*args, **kwargs):
        calls.append((args, kwargs))
        return constant_twist_sequence(n_frames=args[2], n_points=n_points)

    monkeypatch.setattr(speed, "make_sequence", make)
    return calls


def test_memory_store_asks_for_the_tunnel_at_the_points_seed_1(monkeypatch, tmp_path):
    calls = _recorded_make(monkeypatch)
    speed.memory_store(tmp_path / "m.h5", points=40, frames=3)
    assert calls == [(("tunnel", "lidar-dense", 3, 40), {"seed": 1})]


def test_scenarios_lidar_dense_enough_for_the_largest_size_with_ground_truth(monkeypatch,
                                                                             tmp_path):
    calls = _recorded_make(monkeypatch)
    base = constant_twist_sequence(n_frames=3, n_points=60)
    found = []
    for scenario, n, seq in speed._scenarios([20, 30], False, 3, tmp_path):
        found.append((scenario, n, list(seq.points_per_frame())))
        np.testing.assert_allclose(seq.ground_truth.poses, base.ground_truth.poses, atol=1e-9)
        np.testing.assert_allclose(seq.ground_truth.stamps, base.ground_truth.stamps)
    assert calls == [((speed.LIDAR_SCENE, "lidar-dense", 3, 30), {})]
    assert found == [("lidar", 20, [20] * 3), ("lidar", 30, [30] * 3)]
    store = StoreSequence(tmp_path / "lidar-30.h5")
    assert store.ground_truth is not None
    store.close()


def test_time_method_asks_the_methods_own_thread_parameters(monkeypatch):
    made = []

    class Method:
        params, threads = None, 2

    monkeypatch.setattr(speed, "make_method", lambda n, p, s: made.append((n, p)) or Method())
    monkeypatch.setattr(speed, "time_frames", lambda m, seq: {"median_ms": 1.0})
    seq = constant_twist_sequence(n_frames=2, n_points=20)
    speed.time_method("icp-p2p", seq, threads=2)
    # icp-p2p has a num_threads parameter
    assert made == [("icp-p2p", {"num_threads": 2})]


def test_peak_memory_of_run_one_thread_by_default(monkeypatch, tmp_path):
    codes = []

    def run(cmd, **kw):
        codes.append(cmd[2])
        return subprocess.CompletedProcess(cmd, 0, "BASE_KB 1024\nPEAK_KB 2048\n", "")

    monkeypatch.setattr(speed.subprocess, "run", run)
    assert speed.peak_memory_of_run("icp-p2p", tmp_path / "s.h5") == (2.0, 1.0)
    assert "*['-p', 'num_threads=1']]" in codes[0]


# run_speed --------------------------------------------------------------------------------------

class _Seq(list):
    """A scripted scenario's scans (``frames`` of them)."""


def _fake_run_speed(monkeypatch):
    calls = {"scenarios": [], "time": [], "memory": [], "vs_run": []}

    def scenarios(sizes, radar, frames, folder):
        calls["scenarios"].append((frames, folder, Path(folder).is_dir()))
        for n in sizes:
            yield "lidar", n, _Seq(range(frames))

    def time_method(name, seq, threads=1):
        calls["time"].append((name, threads))
        return {"median_ms": 1.0, "register_median_ms": 1.0, "repeats": 1, "iterations": 1,
                "prep": "all points", "threads": threads, "clock": "CPU"}

    monkeypatch.setattr(speed, "_scenarios", scenarios)
    monkeypatch.setattr(speed, "time_method", time_method)
    monkeypatch.setattr(speed, "_plot", lambda rows, names, path: None)
    monkeypatch.setattr(speed, "_memory", lambda names, out, console, threads: calls[
        "memory"].append((console, threads)))
    monkeypatch.setattr(speed, "_print_vs_run", lambda names, seq, what, console: calls[
        "vs_run"].append((console, what)))
    return calls


def test_run_speed_two_threads_only_for_methods_with_a_thread_count(monkeypatch, tmp_path):
    calls = _fake_run_speed(monkeypatch)
    # kiss-icp stands for a method without a thread count (a plugin's): timed on 1 only
    monkeypatch.setattr(speed, "method_params",
                        lambda n, t: {} if n == "kiss-icp" else {"num_threads": t})
    console = Console(record=True, width=200, color_system=None)
    speed.run_speed([50], ["icp-p2p", "kiss-icp"], 1, tmp_path, console, radar=False,
                    threads=2, harness=False, vs_run=True)
    assert calls["time"] == [("doppler", 1), ("icp-p2p", 1), ("kiss-icp", 1), ("doppler", 2),
                             ("icp-p2p", 2)]
    # timed and compared on max(1, 2) + 1 = 3 frames, each from stores in a scratch folder
    assert [(frames, is_dir) for frames, _, is_dir in calls["scenarios"]] == [(3, True),
                                                                              (3, True)]
    folders = {folder for _, folder, _ in calls["scenarios"]}
    assert len(folders) == 1 and not Path(folders.pop()).exists()  # cleaned up afterwards
    assert calls["vs_run"] == [(console, "lidar, 50 points, 2 frames")]
    assert calls["memory"] == [(console, 2)]


def test_run_speed_one_thread_setting_by_default(monkeypatch, tmp_path):
    calls = _fake_run_speed(monkeypatch)
    speed.run_speed([50], ["icp-p2p"], 1, tmp_path, Console(color_system=None), memory=False,
                    radar=False, harness=False)
    assert calls["time"] == [("doppler", 1), ("icp-p2p", 1)]


# _plot ------------------------------------------------------------------------------------------

def _plot_rows():
    def row(method, n, ms):
        return {"method": method, "points": n, "median_ms": ms, "p5_ms": ms / 2,
                "p95_ms": 2 * ms, "scenario": "lidar", "threads_setting": 1}

    return [row("doppler", 1000, 0.5), row("doppler", 4000, 1.0), row("gicp", 1000, 2.0),
            row("gicp", 4000, 3.0)]


def test_plot_replaces_its_own_figure_and_refuses_a_foreign_one(tmp_path):
    from bench import guard

    path = tmp_path / "speed.png"
    speed._plot(_plot_rows(), ["doppler", "gicp"], path)
    speed._plot(_plot_rows(), ["doppler", "gicp"], path)  # its own figure: replaced
    assert guard.derived(path) and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    other = tmp_path / "mine.png"
    other.write_bytes(b"not the harness's")
    with pytest.raises(guard.Refused) as err:
        speed._plot(_plot_rows(), ["doppler", "gicp"], other)
    assert f"{other}: exists and is not a speed plot the harness wrote" in str(err.value)
    assert other.read_bytes() == b"not the harness's"


def test_plot_style(monkeypatch, tmp_path):
    saved = []
    monkeypatch.setattr(speed.guard, "savefig", lambda fig, *a, **kw: saved.append(fig))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # drawn without a warning from matplotlib
        speed._plot(_plot_rows(), ["doppler", "gicp"], tmp_path / "speed.png")
    (fig,) = saved
    (ax,) = fig.axes
    np.testing.assert_allclose(fig.get_size_inches(), [6, 4])
    # each median a line with round markers over a borderless, faint band of its colour
    assert [ln.get_marker() for ln in ax.get_lines()] == ["o", "o"]
    for band in ax.collections:
        assert band.get_alpha() == pytest.approx(0.2)
        np.testing.assert_allclose(band.get_linewidth(), 0)
    assert ax.title.get_fontsize() == pytest.approx(9)
    assert [t.get_fontsize() for t in ax.get_legend().get_texts()] == pytest.approx([7, 7])
    # a faint grid on the major and the minor ticks of both log axes
    fig.canvas.draw()
    for axis in (ax.xaxis, ax.yaxis):
        for ticks in (axis.get_major_ticks(), axis.get_minor_ticks()):
            assert ticks and all(t.gridline.get_visible() for t in ticks)
            assert all(t.gridline.get_alpha() == pytest.approx(0.3) for t in ticks)


# the scratch stores and the CSV: written through the guard --------------------------------------

def test_subsample_draws_distinct_points():
    scan = constant_twist_sequence(n_frames=1, n_points=200)[0]
    picked = speed.subsample(scan, 150, 3)
    # 150 of the 200 points, each once (drawn without replacement), in their order
    assert len(np.unique(picked.points, axis=0)) == 150 == len(picked)
    rows = [np.flatnonzero((scan.points == p).all(axis=1))[0] for p in picked.points]
    assert rows == sorted(rows)


def test_memory_store_is_the_same_every_time_with_ground_truth(tmp_path):
    a, _ = speed.memory_store(tmp_path / "a.h5", points=300, frames=2)
    b, _ = speed.memory_store(tmp_path / "b.h5", points=300, frames=2)
    sa, sb = StoreSequence(a), StoreSequence(b)
    try:
        assert sa.ground_truth is not None and len(sa.ground_truth.stamps) == 2
        for x, y in zip(sa, sb, strict=True):
            np.testing.assert_array_equal(x.points, y.points)
    finally:
        sa.close()
        sb.close()


def test_memory_store_replaces_its_own_store_and_refuses_a_foreign_file(tmp_path):
    from bench import guard

    path = tmp_path / "m.h5"
    speed.memory_store(path, points=100, frames=2)
    speed.memory_store(path, points=120, frames=2)  # its own scratch store: replaced
    store = StoreSequence(path)
    assert list(store.points_per_frame()) == [120, 120]
    store.close()
    other = tmp_path / "x.h5"
    other.write_text("someone else's\n")
    with pytest.raises(guard.Refused) as err:
        speed.memory_store(other, points=100, frames=2)
    assert f"{other}: exists and is not a scratch store the harness wrote" in str(err.value)


def _lidar_points(folder, sizes=(50,)):
    out = []
    for _, _, seq in speed._scenarios(list(sizes), False, 2, folder):
        out.append([s.points.copy() for s in seq])
    return out


def test_scenarios_the_same_scans_every_time_and_their_own_stores_replaced(tmp_path):
    first = _lidar_points(tmp_path)
    again = _lidar_points(tmp_path)  # into the same folder: its own stores replaced
    for a, b in zip(first[0], again[0], strict=True):
        np.testing.assert_array_equal(a, b)


def test_scenarios_refuse_a_foreign_file_in_their_folder(tmp_path):
    from bench import guard

    (tmp_path / "lidar-50.h5").write_text("someone else's\n")
    with pytest.raises(guard.Refused) as err:
        _lidar_points(tmp_path)
    assert (f"{tmp_path / 'lidar-50.h5'}: exists and is not a scratch store the harness "
            "wrote") in str(err.value)


def test_write_csv_refuses_a_foreign_file_naming_a_table_of_times(tmp_path):
    from bench import guard

    path = tmp_path / "speed.csv"
    path.write_text("mine\n")
    with pytest.raises(guard.Refused) as err:
        speed.write_csv([{"a": 1}], path)
    assert f"{path}: exists and is not a table of times the harness wrote" in str(err.value)
    assert path.read_text() == "mine\n"


def test_memory_store_default_twenty_frames_of_64k_points(monkeypatch, tmp_path):
    # the store every memory figure is measured on: 20 frames of 64,000 points
    calls = _recorded_make(monkeypatch)
    speed.memory_store(tmp_path / "m.h5")
    assert calls == [(("tunnel", "lidar-dense", 20, 64_000), {"seed": 1})]


def test_print_table_method_columns_right_aligned():
    def row(method, setting, ms):
        return {"scenario": "lidar", "points": 1000, "threads_setting": setting,
                "method": method, "median_ms": ms, "register_median_ms": ms / 2,
                "ratio_to_doppler": 1.0, "prep": "all points"}

    console = Console(record=True, width=200, color_system=None)
    speed._print_table([row("doppler", 1, 2.0), row("gicp", 1, 20.0), row("gicp", 4, 10.0)],
                       ["doppler", "gicp"], console)
    (line,) = [ln for ln in console.export_text().splitlines() if "10.00 / 5.00" in ln]
    doppler = line.split("\u2502")[1:-1][3]
    # doppler has no 4-thread figure: its "-" at the right of a column as wide as its cells
    assert doppler.strip() == "-" and doppler.endswith("- ") and doppler.startswith("    ")
