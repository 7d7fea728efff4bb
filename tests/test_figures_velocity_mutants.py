"""bench/report/figures/velocity.py: per sequence, each shown run's ego-velocity error norm
against the distance travelled (known by hand: a path 10 % too long moves 1.1 x the true speed
of 16 m/s, an error of 1.6 m/s at every window), the GT speed once below, the window in the
title, a run that diverged (or whose poses are not finite) left out and named under the
figure."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

import bench.report.figures.velocity as velocity
from bench.report.figures.style import color, line_kwargs
from bench.report.names import display_name
from helpers_figure_runs import capture, straight
from metrics.velocity import DEFAULT_WINDOW_S

DT = 0.125  # [s]: the windows' stamps are exact in binary
STEP = 2.0  # [m] per frame: 16 m/s


def _run(method, seed=True, scale=1.0, sequence="seq A", n=21, window=0.5, diverged=False):
    gt = straight(n, STEP)
    est = gt.copy()
    est[:, :3, 3] *= scale
    vel = SimpleNamespace(window_s=window) if window is not None else None
    return SimpleNamespace(method=method, seed=seed, label=None, config={}, gt=gt, est=est,
                           stamps=np.arange(n) * DT, display_name=sequence, diverged=diverged,
                           result=SimpleNamespace(velocity=vel))


def test_velocity_error_along_the_path_of_the_runs_shown(tmp_path, monkeypatch):
    figs = capture(monkeypatch, velocity, write=True)
    gone = _run("gicp", diverged=True)
    nan = _run("vgicp")
    nan.est[3:, 0, 3] = np.nan
    runs = [_run("icp-p2p", False, 1.0), _run("icp-p2p", True, 1.1), gone, nan]
    paths = velocity.plot_velocity_along_path(runs, tmp_path)
    assert paths == [tmp_path / "velocity" / "seq-a.pdf", tmp_path / "velocity" / "seq-a.png"]
    assert all(p.exists() for p in paths)
    ((_, fig),) = figs
    ax, speed_ax = fig.axes
    # windows of 0.5 s = 4 frames: frames 0..16 start one, at 0..32 m
    (seed, noseed) = ax.get_lines()  # in the tables' order: seed first
    np.testing.assert_allclose(seed.get_xdata(), np.arange(17) * STEP)
    np.testing.assert_allclose(seed.get_ydata(), 0.1 * STEP / DT, rtol=1e-9)  # 1.6 m/s
    np.testing.assert_allclose(noseed.get_ydata(), 0.0, atol=1e-9)
    want = line_kwargs(runs[1], 0, 2, points=17)
    assert seed.get_color() == color("icp-p2p") and seed.get_marker() == want["marker"]
    assert seed.get_markevery() == want["markevery"]
    assert line_kwargs(runs[0], 1, 2, points=17)["markevery"] == noseed.get_markevery()
    (speed,) = speed_ax.get_lines()  # the GT speed once, not per run
    np.testing.assert_allclose(speed.get_ydata(), STEP / DT)
    np.testing.assert_allclose(speed.get_xdata(), np.arange(17) * STEP)
    assert speed.get_color() == "black"
    assert ax.get_ylabel() == "velocity error [m/s]"
    assert speed_ax.get_ylabel() == "GT speed\n[m/s]"
    assert speed_ax.get_xlabel() == "distance travelled [m]"
    assert " ".join(ax.get_title().split("\n")) == \
        "seq A: ego-velocity error (sensor frame, 0.5 s windows)"
    assert max(len(r) for r in ax.get_title().split("\n")) <= 56
    assert speed_ax.get_shared_x_axes().joined(ax, speed_ax)
    assert fig.get_figheight() == 3.0 and fig.get_figwidth() == 3.5
    assert ax.get_position().height == pytest.approx(3 * speed_ax.get_position().height,
                                                     rel=0.05)
    (legend,) = fig.legends
    icp = display_name("icp-p2p")
    assert [t.get_text() for t in legend.get_texts()] == [icp, f"{icp} (no seed)"]
    assert legend.get_title().get_text().replace("\n", " ") == \
        f"Not shown (diverged): {display_name('gicp')}; {display_name('vgicp')}"


def test_window_is_the_first_recorded_one_else_the_default(tmp_path, monkeypatch):
    figs = capture(monkeypatch, velocity)
    runs = [_run("icp-p2p", window=None), _run("gicp", window=0.25),
            _run("vgicp", window=0.75),
            _run("icp-p2p", window=None, sequence="seq B")]
    velocity.plot_velocity_along_path(runs, tmp_path)
    (_, a), (_, b) = figs
    assert "0.25 s windows" in a.axes[0].get_title()
    # windows of 0.25 s: 2 frames, so frames 0..18 start one
    assert len(a.axes[0].get_lines()[0].get_xdata()) == 19
    assert f"{DEFAULT_WINDOW_S:g} s windows" in b.axes[0].get_title()
    assert len(b.axes[0].get_lines()[0].get_xdata()) == 21 - round(DEFAULT_WINDOW_S / DT)
    assert b.legends[0].get_title().get_text() == ""  # nothing left out: no note
    assert len(b.axes[1].get_lines()) == 1  # one run: its GT speed


def test_a_long_title_wraps_at_56_characters(tmp_path, monkeypatch):
    figs = capture(monkeypatch, velocity)
    name = "Baker-Barry Tunnel (Empty)"
    velocity.plot_velocity_along_path([_run("gicp", sequence=name)], tmp_path)
    ((_, fig),) = figs
    # 54 characters up to "(sensor"; " frame," would make 61
    assert fig.axes[0].get_title() == (f"{name}: ego-velocity error (sensor\n"
                                       "frame, 0.5 s windows)")
    name = "A" * 29  # "(sensor" would end at character 57: one too many
    velocity.plot_velocity_along_path([_run("gicp", sequence=name)], tmp_path)
    assert figs[-1][1].axes[0].get_title() == (f"{name}: ego-velocity error\n"
                                               "(sensor frame, 0.5 s windows)")


def test_no_figure_without_a_run_to_show_and_sequences_in_order(tmp_path, monkeypatch):
    figs = capture(monkeypatch, velocity)
    runs = [_run("icp-p2p", sequence="run10"), _run("icp-p2p", sequence="run2"),
            _run("icp-p2p", sequence="diverged", diverged=True),
            _run("icp-p2p", sequence="short", n=2), _run("gicp", sequence="run2", n=2)]
    paths = velocity.plot_velocity_along_path(runs, tmp_path)
    assert [p.name for p in paths] == ["run2.pdf", "run2.png", "run10.pdf", "run10.png"]
    assert len(figs[0][1].axes[0].get_lines()) == 1  # the 2-frame run has no window
    three = [_run("icp-p2p", sequence="three", n=3, window=0.125)]
    assert [p.name for p in velocity.plot_velocity_along_path(three, tmp_path)] == \
        ["three.pdf", "three.png"]
