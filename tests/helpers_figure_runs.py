"""Run folders written directly, without running a method, for the figure tests: a
metrics.json (``RunResult``), gt_tum.txt / est_tum.txt and frames.csv, with poses chosen so that
every error a figure draws is known by hand. Figures are captured in-process (Agg) instead of
being read back as pixels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.runs.result import RelativeError, RunResult, TimingStats, VelocityResult
from loaders.posefile import write_tum
from loaders.se3 import make_T
from loaders.trajectory import Trajectory
from methods.registry import Seed


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])


def straight(n: int, step_m: float = 1.0, y0: float = 0.0) -> np.ndarray:
    """``n`` poses along x, ``step_m`` apart, no rotation."""
    t = np.column_stack([np.arange(n) * step_m, np.full(n, y0), np.zeros(n)])
    return make_T(np.repeat(np.eye(3)[None], n, 0), t)


def write_run(root: Path, sequence: str, method: str, seed, gt: np.ndarray, est: np.ndarray,
              *, dt: float = 0.1, diverged: bool = False, label: str | None = None,
              sensor_class: str = "Dense 4D LiDAR", lengths: tuple = (),
              frames: list[tuple[int, float, float]] | None = None, config: str = "",
              velocity_window_s: float | None = None, folder_name: str = "") -> Path:
    """A finished run folder ``root/sequence/<method><seed suffix>[-label]``; ``frames``:
    (index, time_ms, correspondences) rows of frames.csv (default: every frame 1 ms, 100
    pairs); ``folder_name`` instead of the default one."""
    folder = root / sequence / (folder_name or
                                method + Seed.of(seed).suffix + (f"-{label}" if label else ""))
    folder.mkdir(parents=True)
    stamps = np.arange(len(gt)) * dt
    velocity = (VelocityResult(window_s=velocity_window_s, n=1)
                if velocity_window_s is not None else None)
    result = RunResult(sequence=sequence, method=method, seed=seed, label=label,
                       display_name=sequence, sensor_class=sensor_class, diverged=diverged,
                       frames=len(gt), frames_scored=len(gt),
                       relative_error=[RelativeError(length_m=L, n=1) for L in lengths],
                       time_ms=TimingStats(mean=1.0, median=1.0), velocity=velocity)
    (folder / "metrics.json").write_text(result.dump())
    write_tum(Trajectory(stamps, gt), folder / "gt_tum.txt")
    write_tum(Trajectory(stamps, est), folder / "est_tum.txt")
    rows = frames if frames is not None else [(k, 1.0, 100.0) for k in range(len(gt))]
    (folder / "frames.csv").write_text("index,time_ms,correspondences\n" + "".join(
        f"{i},{t},{c}\n" for i, t, c in rows))
    if config:
        (folder / "config.yaml").write_text(config)
    return folder


def capture(monkeypatch, *modules, write: bool = False) -> list[tuple[Path, object]]:
    """Every figure the ``modules`` save, drawn, with its file stem (the renderer is kept as
    ``fig.test_renderer``: a closed figure has none); the files are written only with
    ``write`` (else the paths ``save`` would return: PDF and PNG), which keeps tests fast."""
    import matplotlib.pyplot as plt

    figs = []
    for mod in modules:
        original = mod.save

        def keep(fig, stem, original=original):
            fig.canvas.draw()
            fig.test_renderer = fig.canvas.get_renderer()
            figs.append((stem, fig))
            if write:
                return original(fig, stem)
            plt.close(fig)
            return [stem.with_name(stem.name + ".pdf"), stem.with_name(stem.name + ".png")]

        monkeypatch.setattr(mod, "save", keep)
    return figs


def lines_by_label(ax) -> dict:
    return {line.get_label(): line for line in ax.get_lines()
            if not line.get_label().startswith("_")}
