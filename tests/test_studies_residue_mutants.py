"""Residual mutants of bench/studies: the speed ranges of score_cases.synthetic_bases and
reproduce._choose_data's store lines printed without markup."""

from __future__ import annotations

import dataclasses
import io
import warnings

import numpy as np
from rich.console import Console

from bench.studies.reproduce import _choose_data
from bench.studies.score_cases import synthetic_bases

#: the documented draw of each synthetic drive's speed (m/s), make_profile's ``speed``
RANGES = {"curve": (4.0, 6.0), "gentle turns": (3.0, 8.0), "U-turn": (6.0, 9.0)}


def _speeds(base) -> np.ndarray:
    """Speed (m/s) between consecutive exact GT poses."""
    p = base.gt.poses[:, :3, 3]
    return np.linalg.norm(np.diff(p, axis=0), axis=1) / np.diff(base.gt.stamps)


def _drives(seeds: int) -> dict[str, list[np.ndarray]]:
    out: dict[str, list[np.ndarray]] = {}
    for seed in range(seeds):
        for base in synthetic_bases(np.random.default_rng(seed))[::2]:
            out.setdefault(base.name.removeprefix("synthetic "), []).append(_speeds(base))
    return out


def test_synthetic_speed_draws_span_their_ranges():
    """The start speed is uniform on the drive's range: over 25 draws the curve's stays at
    most 6 m/s and goes below 5 m/s (all above 5: chance 2**-25), the gentle drive's goes below
    4 m/s (chance none does 0.8**25 < 0.4 %), the U-turn's below 7 m/s (chance (2/3)**25).
    Kills synthetic_bases 14 (curve from 5), 15 (curve to 7), 21 (gentle from 4), 29 (U-turn
    from 7)."""
    drives = _drives(25)
    for name, (lo, hi) in RANGES.items():
        start = np.array([v[:3].mean() for v in drives[name]])
        assert np.all(start >= lo - 0.05), name
        assert np.all(start <= hi + 0.05), name
    curve = np.array([v[:3].mean() for v in drives["curve"]])
    assert curve.min() < 5.0
    assert max(v.max() for v in drives["curve"]) <= 6.0 + 0.05
    assert min(v[:3].mean() for v in drives["gentle turns"]) < 4.0
    assert min(v[:3].mean() for v in drives["U-turn"]) < 7.0


def test_a_store_line_shows_a_bracketed_sensor_model_as_it_is(tmp_path):
    """A real store whose recorded sensor model is "Eagle [rev b]": the line describing it
    shows the model with its brackets (rich markup would take "[rev b]" for a style tag and
    drop it). Kills _choose_data 62 (markup=None: the console's default, markup on), 65 (no
    markup argument) and 67 (markup=True)."""
    from conftest import constant_twist_sequence
    from loaders.store import write_store

    seq = constant_twist_sequence(n_frames=10, n_points=200, w=(0, 0, 0))
    seq.sensor = dataclasses.replace(seq.sensor, model="Eagle [rev b]")
    real_dir = tmp_path / "data" / "real"
    real_dir.mkdir(parents=True)
    write_store(seq, real_dir / "Loop1_0.h5")
    buf = io.StringIO()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        found, _ = _choose_data(tmp_path / "data", False, Console(file=buf, width=300))
    assert [s.name for s in found] == ["Loop1_0"]
    said = " ".join(buf.getvalue().split())
    assert "Loop1_0: 10 frames, 0.9 s, lidar (Eagle [rev b])" in said
