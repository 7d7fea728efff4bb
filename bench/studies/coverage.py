"""How often the harness's 95 % intervals contain the long-run mean: a coverage study on
synthetic trajectories with exact ground truth and known noise.

The ground truth is a smooth drive (``speed_mps`` forward, yaw following a sum of slow
sinusoids, ``rate_hz`` poses). An *estimate* is the ground truth's frame-to-frame motions, each
perturbed by noise of known size (rotation: a random axis-angle of ``rot_noise_deg`` per axis;
translation: ``trans_noise_m`` per axis) and chained, so its errors drift exactly as an
odometry's do: the segment errors of one trajectory are correlated along it and overlapping
segments share frames. Two noise processes (``NOISE_MODELS``): independent from step to step
("white"), and correlated from step to step (an AR(1) of coefficient 0.9 per component,
"correlated"), so that a rule tuned to one process shows on the other. Every figure a table
prints is checked (``FIGURES``: relative error at 8-48 m, APE RMSE, KITTI drift, velocity
error), and that each interval holds its own figure. For one noise model the *long-run mean*
of a figure (the mean relative error at a length, the APE RMSE ...) is the mean of that figure
over ``truth_seeds`` independent estimates; each of ``trials`` further estimates (new noise
seeds) gets its interval from ``bench.runs.uncertainty`` exactly as a run's ``metrics.json``
does, and the coverage is the share of trials whose interval contains the long-run mean.

``python -m bench.studies.coverage`` prints the coverage per figure and noise model (and the
median interval width and block length; "no interval" where no drive gives one, e.g. KITTI's
100-800 m segments on a short drive); ``--frames`` and ``--speed`` set the drive (750 m by
default; ``--frames 250 --speed 4.4``: 110 m, like the real 250-frame sample, where few whole
blocks remain; ``--block-factor``: the study with another ``metrics.intervals.BLOCK_FACTOR``,
how the factor was chosen); ``tests/test_intervals.py`` runs a smaller version
(150 drives of 300 m per noise model) and fails below 95 % less two binomial standard
deviations.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

import metrics.intervals as _intervals
from bench.runs.uncertainty import intervals
from metrics.intervals import REPS
from metrics.units import Units, ape_units, kitti_units, relative_units, velocity_units

#: the relative-error lengths of the tables [m]
LENGTHS_M = (8.0, 16.0, 24.0, 32.0, 40.0, 48.0)


@dataclass(frozen=True)
class NoiseModel:
    """Per-step noise of the synthetic odometry: rotation [deg] and translation [m] per axis;
    ``correlation``: each component is an AR(1) process from step to step with this
    coefficient (0: independent steps), its per-step sd kept as stated."""

    rot_noise_deg: float = 0.05
    trans_noise_m: float = 0.01
    correlation: float = 0.0

    @property
    def label(self) -> str:
        kind = (f"correlated from step to step (AR(1), {self.correlation:g})"
                if self.correlation else "independent from step to step")
        return (f"{self.rot_noise_deg:g} deg and {100 * self.trans_noise_m:g} cm per step and "
                f"axis, {kind}")


#: the study's two noise processes: white per-step noise, and per-step noise correlated from
#: step to step (an AR(1) of coefficient 0.9, a correlation time of about 1 s at 10 Hz)
NOISE_MODELS = {"white": NoiseModel(), "correlated": NoiseModel(correlation=0.9)}


def ground_truth(n_frames: int, speed_mps: float = 5.0, rate_hz: float = 10.0,
                 seed: int = 7) -> np.ndarray:
    """(n, 4, 4) ``T_world_sensor`` of a smooth planar drive."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / rate_hz
    amps = rng.uniform(0.05, 0.25, size=3)
    periods = rng.uniform(8.0, 30.0, size=3)
    yaw_rate = sum(a * np.sin(2 * np.pi * t / p) for a, p in zip(amps, periods, strict=True))
    yaw = np.concatenate(([0.0], np.cumsum(yaw_rate[:-1]) / rate_hz))
    step = speed_mps / rate_hz
    pos = np.zeros((n_frames, 3))
    pos[1:, 0] = np.cumsum(step * np.cos(yaw[:-1]))
    pos[1:, 1] = np.cumsum(step * np.sin(yaw[:-1]))
    poses = np.repeat(np.eye(4)[None], n_frames, axis=0)
    poses[:, :3, :3] = Rotation.from_euler("z", yaw[:, None]).as_matrix()
    poses[:, :3, 3] = pos
    return poses


def _ar1(rng: np.random.Generator, sd: float, phi: float, shape: tuple[int, int]) -> np.ndarray:
    """(n, d) AR(1) noise of coefficient ``phi`` and stationary sd ``sd`` (white for 0)."""
    w = rng.normal(0.0, sd, shape)
    if phi == 0.0:
        return w
    out = np.empty(shape)
    out[0] = w[0]
    c = np.sqrt(1.0 - phi**2)
    for k in range(1, shape[0]):
        out[k] = phi * out[k - 1] + c * w[k]
    return out


def noisy_estimate(gt: np.ndarray, noise: NoiseModel, seed: int) -> np.ndarray:
    """The ground truth's frame-to-frame motions with noise, chained from the first pose."""
    rng = np.random.default_rng(seed)
    n = len(gt)
    steps = np.linalg.inv(gt[:-1]) @ gt[1:]
    rot_deg = _ar1(rng, noise.rot_noise_deg, noise.correlation, (n - 1, 3))
    trans_m = _ar1(rng, noise.trans_noise_m, noise.correlation, (n - 1, 3))
    rot = Rotation.from_rotvec(np.radians(rot_deg))
    noisy = steps.copy()
    noisy[:, :3, :3] = rot.as_matrix() @ steps[:, :3, :3]
    noisy[:, :3, 3] += trans_m
    est = np.empty_like(gt)
    est[0] = gt[0]
    for k in range(1, n):
        est[k] = est[k - 1] @ noisy[k - 1]
    return est


def _stamps(n: int, rate_hz: float = 10.0) -> np.ndarray:
    return np.arange(n) / rate_hz


def _relative(length_m: float):
    return lambda g, e: relative_units(g, e, length_m)


def _ape(g: np.ndarray, e: np.ndarray) -> Units:
    return ape_units(g, e, "se3")


def _kitti(g: np.ndarray, e: np.ndarray) -> Units:
    return kitti_units(g, e)


def _velocity(g: np.ndarray, e: np.ndarray) -> Units:
    return velocity_units(g, e, _stamps(len(g)))


_RELATIVE = {L: _relative(L) for L in LENGTHS_M}

#: the figures the study checks, every figure a table prints: name -> (units of (gt, est),
#: quantity); figures of the same units share one maker (a run scores them in one call)
FIGURES = {
    **{f"relative {L:g} m {q}": (_RELATIVE[L], key)
       for L in LENGTHS_M for q, key in (("rotation", "rot_deg"), ("translation", "trans_m"))},
    "APE translation RMSE": (_ape, "trans_m"),
    "APE rotation RMSE": (_ape, "rot_deg"),
    "KITTI translation drift": (_kitti, "trans_pct"),
    "KITTI rotation drift": (_kitti, "rot_deg_per_100m"),
    "velocity error": (_velocity, "norm_mps"),
}


@dataclass(frozen=True)
class Coverage:
    figure: str
    truth: float
    coverage: float
    trials: int
    median_width: float
    median_block: float
    median_independent: float
    contains_own: float = 1.0


def _units_by_maker(gt: np.ndarray, est: np.ndarray, figures) -> dict:
    """Each figure's units, computed once per distinct maker (both quantities share them)."""
    made: dict[int, Units] = {}
    out = {}
    for f in figures:
        make, key = FIGURES[f]
        if id(make) not in made:
            made[id(make)] = make(gt, est)
        out[f] = (made[id(make)], key)
    return out


def _scored_together(figure: str) -> dict[str, str]:
    """The quantities whose intervals a run computes in one call with ``figure``'s (every
    quantity of the same units, as ``bench.runs.evaluate.score`` does: the block is the
    longest any of them asks for), as ``intervals``' keys."""
    make = FIGURES[figure][0]
    return {key: key for m, key in FIGURES.values() if m is make}


def study(n_frames: int = 1500, trials: int = 200, truth_seeds: int = 400,
          noise: NoiseModel = NoiseModel(), figures: tuple[str, ...] = tuple(FIGURES),
          first_seed: int = 10_000, reps: int = REPS,
          speed_mps: float = 5.0) -> list[Coverage]:
    """The coverage of each figure's interval (see the module docstring); ``reps`` bootstrap
    resamples per interval (a run's ``REPS`` by default); drives of ``n_frames`` poses at
    ``speed_mps`` (10 Hz)."""
    gt = ground_truth(n_frames, speed_mps=speed_mps)
    truth: dict[str, list[float]] = {f: [] for f in figures}
    for s in range(truth_seeds):
        est = noisy_estimate(gt, noise, first_seed + trials + s)
        for f, (units, key) in _units_by_maker(gt, est, figures).items():
            truth[f].append(units.statistic(key))
    hits: dict[str, list] = {f: [] for f in figures}
    for s in range(trials):
        est = noisy_estimate(gt, noise, first_seed + s)
        done: dict[int, dict] = {}
        for f, (units, key) in _units_by_maker(gt, est, figures).items():
            if id(units) not in done:
                done[id(units)] = intervals(units, n_frames, _scored_together(f), reps=reps)
            part = done[id(units)]
            hits[f].append((part[key], part["spread"], units.statistic(key)))
    out = []
    for f in figures:
        mean = float(np.mean(truth[f]))
        cis = [(c, sp, x) for c, sp, x in hits[f] if c is not None]
        if not cis:  # no interval on any drive (e.g. KITTI's 100 m segments on a 110 m drive)
            out.append(Coverage(f, mean, math.nan, 0, math.nan, math.nan, math.nan, math.nan))
            continue
        inside = [c[0] <= mean <= c[1] for c, _, _ in cis]
        own = [c[0] <= x <= c[1] for c, _, x in cis]
        out.append(Coverage(f, mean, float(np.mean(inside)), len(cis),
                            float(np.median([c[1] - c[0] for c, _, _ in cis])),
                            float(np.median([sp.block_frames for _, sp, _ in cis])),
                            float(np.median([sp.n_independent for _, sp, _ in cis])),
                            float(np.mean(own))))
    return out


def table(rows: dict[str, list[Coverage]]) -> str:
    """The Markdown table of the coverage per figure (a column per noise model)."""
    names = list(rows)
    head = ("| figure | " + " | ".join(f"coverage, {n} noise" for n in names)
            + " | " + " | ".join(f"median width, {n}" for n in names)
            + " | median block [frames] | median independent pieces |")
    lines = [head, "|---" * (1 + 2 * len(names) + 2) + "|"]
    first = rows[names[0]]
    for i, r in enumerate(first):
        cov = " | ".join(f"{100 * rows[n][i].coverage:.1f} %" if rows[n][i].trials
                         else "no interval" for n in names)
        wid = " | ".join(f"{rows[n][i].median_width:.4g}" for n in names)
        blk = " / ".join(f"{rows[n][i].median_block:g}" for n in names)
        ind = " / ".join(f"{rows[n][i].median_independent:g}" for n in names)
        lines.append(f"| {r.figure} | {cov} | {wid} | {blk} | {ind} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=1500, help="poses per trajectory")
    parser.add_argument("--speed", type=float, default=5.0,
                        help="driving speed [m/s] (10 Hz poses); e.g. --frames 250 --speed 4.4 "
                             "for a drive like the real 250-frame sample (110 m)")
    parser.add_argument("--trials", type=int, default=400, help="trajectories checked")
    parser.add_argument("--truth-seeds", type=int, default=800,
                        help="trajectories averaged for the long-run mean")
    parser.add_argument("--first-seed", type=int, default=10_000,
                        help="the first noise seed (trials, then the long-run mean's drives)")
    parser.add_argument("--noise", choices=[*NOISE_MODELS, "both"], default="both")
    parser.add_argument("--reps", type=int, default=REPS, help="bootstrap resamples")
    parser.add_argument("--block-factor", type=float, default=None,
                        help="metrics.intervals.BLOCK_FACTOR for this study (default: the "
                             f"harness's, {_intervals.BLOCK_FACTOR:g}): how it was chosen")
    args = parser.parse_args()
    if args.block_factor is not None:  # read at call time by every interval rule
        _intervals.BLOCK_FACTOR = args.block_factor
    models = NOISE_MODELS if args.noise == "both" else {args.noise: NOISE_MODELS[args.noise]}
    rows = {name: study(args.frames, args.trials, args.truth_seeds, noise,
                        first_seed=args.first_seed, reps=args.reps, speed_mps=args.speed)
            for name, noise in models.items()}
    print(f"{args.trials} trajectories of {args.frames} poses ({args.speed:g} m/s, 10 Hz: "
          f"{args.frames * args.speed / 10:g} m) per noise model, long-run mean from "
          f"{args.truth_seeds} more, noise seeds from {args.first_seed}, {args.reps} resamples, "
          f"block factor {_intervals.BLOCK_FACTOR:g}")
    for name, noise in models.items():
        print(f"- {name}: {noise.label}")
    print(table(rows))
    short = [(n, r.figure) for n, rs in rows.items() for r in rs if r.contains_own < 1.0]
    if short:
        print("intervals not holding their own figure:", short)


if __name__ == "__main__":
    main()
