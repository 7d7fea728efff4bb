"""What a reader of the figures tripped over: legends that took half of each figure (the
tables' full row names in one column), "Div." labels printed over each other where several ICPs
leave a tunnel at the same place, and a log axis over 1000-4500 correspondences labelled only
at 2000."""

import json
import shutil

import numpy as np
import pytest

import bench.report.figures.errors as errors_mod
from bench.report.figures.style import PRIOR_NOTE, figure, log_y, run_name, use_paper_style
from bench.runs.folders import load_runs
from bench.runs.job import Job
from bench.runs.plan import plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.posefile import read_tum, write_tum
from loaders.store import write_store
from loaders.trajectory import Trajectory

#: every method of the harness, as in the paper's tunnel rows (and doppler-ego without seed)
METHODS = [("icp-p2p", True), ("icp-p2plane", True), ("gicp", True), ("vgicp", True),
           ("dicp", True), ("doppler", None), ("doppler-icp", True), ("kiss-icp", True),
           ("doppler-ego", True), ("doppler-ego", False)]
DIVERGED = ("icp-p2p", "icp-p2plane", "gicp", "vgicp")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Ten runs of a tunnel (two real runs copied under every method's name); the four
    geometric ICPs diverge at the same place."""
    root = tmp_path_factory.mktemp("legend")
    seq = constant_twist_sequence(n_frames=30, n_points=800, max_range_m=60)
    seq.name = "Baker-Barry Tunnel (Empty)"
    store = write_store(seq, root / "tunnel.h5")
    jobs = [Job(store=store, method="icp-p2p", seed=True, out_root=root / "r")]
    assert all(o.status == "done" for o in run_jobs(plan(jobs), executor="local"))
    source = root / "r" / seq.name / "icp-p2p_seed"
    pristine = root / "pristine"
    shutil.move(source, pristine)
    for method, seed in METHODS:
        folder = source.parent / (method if seed is None else
                                  f"{method}_{'seed' if seed else 'noseed'}")
        shutil.copytree(pristine, folder)
        metrics = json.loads((folder / "metrics.json").read_text())
        metrics.update(method=method, seed=seed, diverged=method in DIVERGED)
        (folder / "metrics.json").write_text(json.dumps(metrics))
        if method in DIVERGED:
            est = read_tum(folder / "est_tum.txt")
            poses = est.poses.copy()
            poses[:, 1, 3] += np.arange(len(poses)) ** 2 * 0.5
            write_tum(Trajectory(est.stamps, poses), folder / "est_tum.txt")
    return load_runs(root / "r")


@pytest.fixture
def figs(monkeypatch):
    drawn = []

    def keep(fig, stem):
        fig.canvas.draw()
        drawn.append(fig)
        return []

    monkeypatch.setattr(errors_mod, "save", keep)
    return drawn


def test_legends_take_two_columns_of_short_names(runs, figs, tmp_path):
    errors_mod.plot_error_along_path(runs, tmp_path)
    (fig,) = figs
    legend = fig.legends[0]
    labels = [t.get_text() for t in legend.get_texts()]
    assert "ICP point-to-point - Div." in labels and "Doppler-Ego (this harness) (no seed)" in \
        labels and "Doppler Correspondence (Ours)" in labels
    assert not any(label.startswith("(") for label in labels)  # no seed tag in front
    assert legend._ncols == 2
    renderer = fig.canvas.get_renderer()
    share = legend.get_window_extent(renderer).height / (fig.get_figheight() * fig.dpi)
    assert share < 0.35, share  # was about half with one column of full row names
    assert PRIOR_NOTE.split()[0] in legend.get_title().get_text()


def test_runs_leaving_at_one_place_share_one_div_label(runs, figs, tmp_path):
    errors_mod.plot_error_along_path(runs, tmp_path)
    (fig,) = figs
    top = fig.axes[0]
    labels = [t.get_text() for t in top.texts]
    assert labels == ["Div. (4)"]  # four ICPs leave within a few metres: one label


def test_run_names_mark_only_no_seed():
    from types import SimpleNamespace

    def run(method, seed, label=None):
        return SimpleNamespace(method=method, seed=seed, label=label)

    assert run_name(run("gicp", True)) == "Generalized-ICP"
    assert run_name(run("gicp", False)) == "Generalized-ICP (no seed)"
    assert run_name(run("doppler", None)) == "Doppler Correspondence (Ours)"
    assert run_name(run("doppler-ego", True, "w/o map")) == "w/o map"


@pytest.mark.parametrize("lo, hi, want", [(1100, 4500, {2000, 3000, 4000}),
                                          (300, 3000, {500, 1000, 2000}),
                                          (0.01, 100, {0.01, 1, 100}),
                                          (2100, 2900, None)])
def test_log_axes_label_at_least_two_values(lo, hi, want):
    use_paper_style()
    fig, ax = figure(2.0)
    ax.plot([1, 2], [lo, hi])
    ax.set_yscale("log")
    ax.set_ylim(lo, hi)
    log_y(ax)
    fig.canvas.draw()
    shown = [t for t in ax.get_yticks() if lo <= t <= hi]
    labelled = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert len(shown) >= 2 and len(labelled) >= 2
    if want is not None:
        assert want <= {float(v) for v in shown}


def test_div_labels_never_print_over_each_other():
    """Exits 0-5 m and 6.5-8 m along 100 m form two clusters whose labels ("Div. (3)" at 5 m,
    "Div. (2)" at 8 m before) overlapped: labels that would touch are merged, counts kept."""
    import re

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bench.report.figures.style import COLUMN_IN

    fig, ax = plt.subplots(figsize=(COLUMN_IN, 2.0))
    ax.plot([0, 100], [0.01, 1.0])
    ax.set_yscale("log")
    exits = [(x, "C0") for x in (0.0, 3.0, 5.0, 6.5, 8.0)] + [(60.0, "C1")]
    errors_mod.label_divergence(ax, exits, 1.0, 100.0)
    texts = ax.texts
    renderer = fig.canvas.get_renderer()
    boxes = [t.get_window_extent(renderer) for t in texts]
    assert not any(boxes[i].overlaps(boxes[j]) for i in range(len(boxes))
                   for j in range(i + 1, len(boxes)))
    counts = [int(m.group(1)) if (m := re.search(r"\((\d+)\)", t.get_text())) else 1
              for t in texts]
    assert sum(counts) == len(exits) and sorted(counts) == [1, 5]
    plt.close(fig)
