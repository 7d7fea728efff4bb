"""bench/report/figures/drift.py: per sequence, six panels (roll / pitch / yaw left,
along / across / vertical right) of each run's drift from the first frame against the
distance travelled, known by hand (a yaw error growing 1 deg per frame, an across-track error
growing 2 cm per frame), a run drawn while its poses are finite, zero lines, labels, title and
the legend with the prior note."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

import bench.report.figures.drift as drift
from bench.report.figures.style import PRIOR_NOTE, color
from bench.report.names import display_name
from helpers_figure_runs import capture, rot_z, straight

N = 11


STEP = 2.0  # [m] between frames: distances are not frame indices


def _run(method, seed=True, est=None, sequence="seq A", diverged=False, n=N):
    gt = straight(n, STEP)
    return SimpleNamespace(method=method, seed=seed, label=None, config={}, gt=gt,
                           est=gt.copy() if est is None else est, display_name=sequence,
                           diverged=diverged)


def _yawing():
    est = straight(N, STEP)
    for k in range(N):
        est[k, :3, :3] = rot_z(float(k))
    return est


def _sliding():
    est = straight(N, STEP)
    est[:, 1, 3] = 0.02 * np.arange(N)
    return est


def test_drift_panels_show_each_axis_error_against_the_distance(tmp_path, monkeypatch):
    figs = capture(monkeypatch, drift, write=True)
    broken = _sliding()
    broken[6:, 0, 3] = np.inf  # drawn while finite: frames 0-5
    runs = [_run("gicp", est=_yawing()), _run("icp-p2p", est=broken, diverged=True)]
    paths = drift.plot_drift(runs, tmp_path)
    assert paths == [tmp_path / "drift" / "seq-a.pdf", tmp_path / "drift" / "seq-a.png"]
    assert all(p.exists() for p in paths)
    ((_, fig),) = figs
    axes = np.array(fig.axes).reshape(3, 2)
    yaw = axes[2, 0].get_lines()
    # runs in the tables' order; each panel: its runs' lines, then the zero line
    order = sorted(["gicp", "icp-p2p"], key=lambda m: drift.run_order(_run(m)))
    k_gicp = order.index("gicp")
    np.testing.assert_allclose(yaw[k_gicp].get_xdata(), STEP * np.arange(N))
    np.testing.assert_allclose(yaw[k_gicp].get_ydata(), np.arange(N), atol=1e-9)
    for a in range(2):  # no roll or pitch
        np.testing.assert_allclose(axes[a, 0].get_lines()[k_gicp].get_ydata(), 0, atol=1e-9)
    k_icp = 1 - k_gicp
    across = axes[1, 1].get_lines()[k_icp]
    np.testing.assert_allclose(across.get_xdata(), STEP * np.arange(6))
    np.testing.assert_allclose(across.get_ydata(), 0.02 * np.arange(6), atol=1e-9)
    np.testing.assert_allclose(axes[0, 1].get_lines()[k_icp].get_ydata(), 0, atol=1e-9)
    np.testing.assert_allclose(axes[2, 1].get_lines()[k_icp].get_ydata(), 0, atol=1e-9)
    assert axes[1, 1].get_lines()[k_gicp].get_color() == color("gicp")
    for k, run in enumerate(sorted(runs, key=drift.run_order)):  # markers at own offsets
        assert axes[0, 0].get_lines()[k].get_markevery() == \
            drift.line_kwargs(run, k, 2)["markevery"]
    for ax in axes.ravel():
        zero = ax.get_lines()[-1]
        np.testing.assert_allclose(zero.get_ydata(), [0, 0])
        assert zero.get_color() == "black"
    assert [axes[a, 0].get_ylabel() for a in range(3)] == ["roll\n[deg]", "pitch\n[deg]",
                                                           "yaw\n[deg]"]
    assert [axes[a, 1].get_ylabel() for a in range(3)] == ["along\n[m]", "across\n[m]",
                                                           "vertical\n[m]"]
    assert [ax.get_xlabel() for ax in axes[-1]] == ["distance travelled [m]"] * 2
    assert axes[0, 0].get_shared_x_axes().joined(axes[0, 0], axes[2, 1])
    assert fig.get_figheight() == 3.9 and fig.get_figwidth() == 3.5
    title = fig.get_suptitle()
    assert " ".join(title.split("\n")) == \
        "seq A: drift from the first frame (estimate - GT, GT body axes)"
    assert max(len(r) for r in title.split("\n")) <= 56
    (legend,) = fig.legends
    names = {"gicp": display_name("gicp"), "icp-p2p": display_name("icp-p2p") + " - Div."}
    assert [t.get_text() for t in legend.get_texts()] == [names[m] for m in order]
    assert [h.get_color() for h in legend.legend_handles] == [color(m) for m in order]
    assert " ".join(legend.get_title().get_text().split("\n")) == PRIOR_NOTE


def test_runs_with_under_two_finite_poses_are_left_out(tmp_path, monkeypatch):
    figs = capture(monkeypatch, drift)
    bad = straight(N, STEP)
    bad[1:, 0, 3] = np.nan  # one finite pose: nothing to draw
    two = straight(N, STEP)
    two[2:, 0, 3] = np.nan  # two finite poses: drawn
    runs = [_run("gicp", True, est=bad), _run("gicp", False), _run("icp-p2p", est=two),
            _run("vgicp", sequence="short", n=1)]
    paths = drift.plot_drift(runs, tmp_path)
    assert [p.name for p in paths] == ["seq-a.pdf", "seq-a.png"]  # none for "short"
    ((_, fig),) = figs
    # the one-pose run is left out; the no-seed run sorted after it is not
    assert sorted(t.get_text() for t in fig.legends[0].get_texts()) == sorted(
        [f"{display_name('gicp')} (no seed)", display_name("icp-p2p")])
    assert len(fig.axes[0].get_lines()) == 3  # their lines and the zero line


def test_one_figure_per_sequence_in_order(tmp_path, monkeypatch):
    capture(monkeypatch, drift)
    runs = [_run("gicp", sequence="run10"), _run("gicp", sequence="run2", n=2),
            _run("gicp", sequence="run2", n=1), _run("gicp", sequence="run1", n=1)]
    paths = drift.plot_drift(runs, tmp_path)  # nothing for run1; two poses are enough
    assert [p.name for p in paths] == ["run2.pdf", "run2.png", "run10.pdf", "run10.png"]
