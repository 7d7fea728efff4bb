"""Paper figures: every kind is written (PDF and PNG, one column wide, slug file names) from run
folders, and the pair figure; what a reviewer checks in each: equal scale of trajectories,
legends outside the axes, log error axes that a diverged run does not squash, seed and no seed
told apart by line style and marker (hatch in box plots), no slot for a length without
segments, visible correspondence lines."""

import json
import re
import shutil

import numpy as np
import pytest
from matplotlib.image import imread
from typer.testing import CliRunner

import bench.report.figures.draw as figures_mod
import bench.report.figures.errors as errors_mod
import bench.report.figures.pair as pair_mod
from bench.cli import app
from bench.report.figures.style import COLUMN_IN, DPI, color, slug
from bench.runs.job import Job
from bench.runs.plan import plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.posefile import read_tum, write_tum
from loaders.store import write_store
from loaders.trajectory import Trajectory

SLUG = re.compile(r"[a-z0-9]+(-[a-z0-9]+)*")
KINDS = ("trajectories", "boxplots", "error-along-path", "frames", "pairs", "velocity",
         "forest")


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Runs on a 40-frame sequence (31 m: segments up to 32 m, none at 40 and 48 m) and a
    diverged run made from one of them."""
    root = tmp_path_factory.mktemp("fig")
    store = write_store(constant_twist_sequence(n_frames=40, n_points=1500, noise_m=0.02,
                                                max_range_m=70), root / "twist.h5")
    jobs = [Job(store=store, method=m, seed=s, out_root=root / "results")
            for m, s in (("doppler", None), ("icp-p2p", True), ("icp-p2p", False))]
    assert all(o.status == "done" for o in run_jobs(plan(jobs), executor="local"))
    good = root / "results" / "twist" / "icp-p2p_seed"
    bad = good.parent / "gicp_seed"
    shutil.copytree(good, bad)
    metrics = json.loads((bad / "metrics.json").read_text())
    (bad / "metrics.json").write_text(json.dumps({**metrics, "method": "gicp",
                                                  "diverged": True}))
    est = read_tum(bad / "est_tum.txt")
    poses = est.poses.copy()
    poses[:, 1, 3] += np.arange(len(poses)) ** 2 * 0.5  # 760 m off sideways at the end
    write_tum(Trajectory(est.stamps, poses), bad / "est_tum.txt")
    return root


@pytest.fixture
def captured(monkeypatch):
    """Every figure saved by the figure modules, drawn, with its file stem (its renderer is
    kept as ``fig.test_renderer``: a closed figure has none)."""
    figs = []
    for mod in (figures_mod, errors_mod, pair_mod):
        original = mod.save

        def capture(fig, stem, original=original):
            fig.canvas.draw()
            fig.test_renderer = fig.canvas.get_renderer()
            figs.append((stem, fig))
            return original(fig, stem)

        monkeypatch.setattr(mod, "save", capture)
    return figs


def test_every_figure_kind_is_written_one_column_wide_with_slug_names(results, tmp_path):
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
    for kind in KINDS:
        pngs = list((out / kind).glob("*.png"))
        assert pngs and all(p.with_suffix(".pdf").exists() for p in pngs), kind
        assert all(SLUG.fullmatch(p.stem) for p in pngs), [p.name for p in pngs]
    assert (out / "speed.png").exists() and (out / "speed.pdf").exists()
    assert (out / "pairs" / "twist-frame-10.png").exists()
    assert (out / "boxplots" / "dense-4d-lidar.png").exists()  # the test sensor is a LiDAR
    for png in out.rglob("*.png"):  # one paper column at the saved resolution
        assert imread(png).shape[1] == pytest.approx(COLUMN_IN * DPI, abs=1), png
    listed = [line.split()[1] for line in res.output.splitlines() if line.startswith("wrote")]
    assert sorted(listed) == sorted(str(p) for p in out.rglob("*.png"))


def test_slugs_are_readable_and_safe():
    assert slug("Baker-Barry Tunnel (Empty)") == "baker-barry-tunnel-empty"
    assert slug("Loop1_0 (GT calibrated on frames 0-124, not scored)") == \
        "loop1-0-gt-calibrated-on-frames-0-124-not-scored"
    assert slug("Semi-Dense 4D Radar") == "semi-dense-4d-radar"
    assert slug("///") == "unnamed"


def _legends_outside(fig) -> None:
    renderer = fig.test_renderer
    assert fig.legends, "a figure legend"
    for ax in fig.axes:
        assert ax.get_legend() is None  # no legend inside any axes
        box = ax.get_window_extent(renderer)
        for legend in fig.legends:
            assert not box.overlaps(legend.get_window_extent(renderer))


def test_trajectories_are_equal_scale_with_the_legend_below(results, tmp_path, captured):
    figures_mod.plot_trajectories(results / "results", tmp_path)
    ((stem, fig),) = captured
    assert stem.name == "twist"
    ax = fig.axes[0]
    box = ax.get_window_extent(fig.test_renderer)
    m_per_px_x = np.ptp(ax.get_xlim()) / box.width
    m_per_px_y = np.ptp(ax.get_ylim()) / box.height
    assert m_per_px_x == pytest.approx(m_per_px_y, rel=0.01)
    assert box.width > 2.5 * box.height  # a 31 m path, 7 m wide: a wide, short figure
    _legends_outside(fig)
    lines = {line.get_label(): line for line in ax.get_lines()}
    seed, noseed = (lines["ICP point-to-point"], lines["ICP point-to-point (no seed)"])
    assert seed.get_color() == noseed.get_color() == color("icp-p2p")
    assert seed.get_linestyle() != noseed.get_linestyle()
    assert seed.get_marker() != noseed.get_marker()
    # the diverged run is cut where it leaves the axes and says so
    assert "Generalized-ICP - Div." in lines
    assert any(t.get_text() == "Div." for t in ax.texts)


def test_error_figures_use_log_axes_a_diverged_run_does_not_squash(results, tmp_path,
                                                                    captured):
    from bench.runs.folders import load_runs

    runs = [r for r in load_runs(results / "results")]
    errors_mod.plot_error_along_path(runs, tmp_path)
    ((_, fig),) = captured
    top = fig.axes[0]
    assert top.get_yscale() == "log"
    good = [r for r in runs if not r.diverged]
    worst_good = max(np.nanmax(errors_mod._errors_along_path(r)[1]) for r in good)
    worst_bad = max(np.nanmax(errors_mod._errors_along_path(r)[1]) for r in runs)
    assert worst_bad > 100 * worst_good
    assert top.get_ylim()[1] < 10 * worst_good  # the axis follows the runs that held
    assert any(t.get_text() == "Div." for t in top.texts)
    _legends_outside(fig)


def test_boxplots_have_slots_only_for_lengths_with_segments(results, tmp_path, captured):
    from bench.runs.folders import load_runs

    runs = load_runs(results / "results")
    assert {x.length_m for r in runs for x in r.result.relative_error if not x.n} >= {40.0, 48.0}
    errors_mod.plot_boxplots(runs, tmp_path)
    ((_, fig),) = captured
    assert [t.get_text() for t in fig.axes[1].get_xticklabels()] == ["8", "16", "24", "32"]
    assert all(ax.get_yscale() == "log" for ax in fig.axes)
    _legends_outside(fig)
    legend = fig.legends[0]
    hatches = {t.get_text(): h.get_hatch() for t, h in zip(legend.get_texts(),
                                                          legend.legend_handles, strict=True)}
    assert hatches["ICP point-to-point (no seed)"] and not hatches["ICP point-to-point"]
    assert "Generalized-ICP" not in hatches  # the diverged run is left out ...
    assert "Not shown (diverged): Generalized-ICP on twist" in " ".join(
        legend.get_title().get_text().split())  # ... and named


def test_frames_figure_has_its_legend_below(results, tmp_path, captured):
    from bench.runs.folders import load_runs

    errors_mod.plot_frames(load_runs(results / "results"), tmp_path)
    ((_, fig),) = captured
    assert fig.axes[0].get_yscale() == "log"
    _legends_outside(fig)


def test_pair_lines_are_visible_and_zoomed(results, tmp_path, captured):
    pair_mod.plot_pair(results / "twist.h5", 10, tmp_path)
    ((stem, fig),) = captured
    assert stem.name == "twist-frame-10"
    for ax in fig.axes:
        (lines,) = ax.collections[-1:]
        n = len(lines.get_segments())
        assert 0 < n <= pair_mod.MAX_LINES
        assert min(lines.get_linewidths()) >= 0.7 and lines.get_alpha() >= 0.8
        assert np.ptp(ax.get_xlim()) <= pair_mod.WINDOW_M + 1e-6  # a zoom, not the scan
    _legends_outside(fig)


def test_a_method_has_one_colour_everywhere():
    assert color("dicp") == color("dicp") != color("doppler")
    assert len({color(m) for m in ("doppler", "dicp", "icp-p2p", "gicp", "kiss-icp",
                                   "doppler-ego", "doppler-icp", "vgicp", "icp-p2plane")}) == 9


def test_pair_of_the_last_frame_is_a_clear_error(results):
    res = CliRunner().invoke(app, ["figures", "--pair", str(results / "twist.h5"), "39"])
    assert res.exit_code != 0 and "has no next frame" in str(res.exception)


def test_labelled_variants_of_one_method_are_told_apart():
    from types import SimpleNamespace

    from bench.report.figures.style import prior_style

    def run(label, seed=True):
        return SimpleNamespace(method="doppler-ego", seed=seed, label=label)

    default, no_seed = prior_style(run(None)), prior_style(run(None, seed=False))
    variants = [prior_style(run(f"ablation {k}")) for k in range(4)]
    styles = [default, no_seed, *variants]
    assert len({s[0] if isinstance(s[0], str) else repr(s[0]) for s in styles}) == len(styles)
    assert len({s[1] for s in styles}) == len(styles)  # markers
    assert len({s[2] for s in variants}) == len(variants) and all(s[2] for s in variants)
    assert prior_style(run("ablation 2")) == variants[2]  # the same in every figure


def test_plugin_methods_get_distinct_colours_and_their_declared_presentation(monkeypatch):
    """Two plugin methods (tests/plugins, DOPPLER_BENCH_METHODS) without a colour each get
    their own, none a built-in's; a plugin that declares a presentation is shown with it."""
    import sys
    from pathlib import Path

    from methods import registry
    from methods.base import Presentation

    sys.path.insert(0, str(Path(__file__).parent / "plugins"))
    try:
        import bench_test_methods as plugins
    finally:
        sys.path.pop(0)
    builtin = {color(m) for m in registry.METHODS}
    monkeypatch.setattr(registry, "_assigned", {})
    for cls in plugins.METHODS:
        monkeypatch.setitem(registry.METHODS, cls.name, cls)
    a, b = color("test-abort"), color("test-sleep")
    assert a != b and not {a, b} & builtin
    assert color("not-registered") not in {a, b, *builtin}

    class Declared(plugins.SleepingMethod):
        name = "test-declared"
        presentation = Presentation("My Method", "#123456", 4.5)

    monkeypatch.setitem(registry.METHODS, Declared.name, Declared)
    assert color("test-declared") == "#123456"
    assert registry.display_name("test-declared") == "My Method"
    assert registry.order_key("dicp") < registry.order_key("test-declared") < \
        registry.order_key("doppler")


def test_figures_for_the_page_are_png_and_never_leave_a_stale_pdf(tmp_path):
    """style.save inside for_the_page (bench report): a new figure as PNG only; a figure
    that already has a PDF (from bench figures) gets both made again, so no old PDF stays
    beside a new PNG; outside it, both as before."""
    import os

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.figures.style import for_the_page, save

    def draw(stem):
        fig, ax = plt.subplots()
        ax.plot([0, 1], [0, 1])
        return save(fig, tmp_path / stem)

    with for_the_page():
        assert [p.suffix for p in draw("new")] == [".png"]
    assert not (tmp_path / "new.pdf").exists()
    assert sorted(p.suffix for p in draw("both")) == [".pdf", ".png"]
    old = tmp_path / "both.pdf"
    os.utime(old, (1.0, 1.0))
    with for_the_page():
        assert sorted(p.suffix for p in draw("both")) == [".pdf", ".png"]
    assert old.stat().st_mtime > 1.0
