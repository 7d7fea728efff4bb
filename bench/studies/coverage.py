"""How often the harness's 95 % intervals contain the long-run mean: a coverage study on
synthetic trajectories with exact ground truth and known noise.

The ground truth is a smooth drive (``speed_mps`` forward, yaw following a sum of slow
sinusoids, ``rate_hz`` poses). An *estimate* is the ground truth's frame-to-frame motions, each
perturbed by noise of known size (rotation: a random axis-angle of ``rot_noise_deg`` per axis;
translation: ``trans_noise_m`` per axis) and chained, so its errors drift exactly as an
odometry's do: the segment errors of one trajectory are correlated along it and overlapping
segments share frames. For one noise model the *long-run mean* of a figure (the mean relative
error at a length, the APE RMSE ...) is the mean of that figure over ``truth_seeds`` independent
estimates; each of ``trials`` further estimates (new noise seeds) gets its interval from
``bench.runs.uncertainty`` exactly as a run's ``metrics.json`` does, and the coverage is the
share of trials whose interval contains the long-run mean.

``python -m bench.studies.coverage`` prints the coverage per figure (and the median interval
width and block length); ``tests/test_intervals.py`` runs a smaller version and holds the
coverage near 95 %.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from bench.runs.uncertainty import intervals
from metrics.units import Units, ape_units, relative_units


@dataclass(frozen=True)
class NoiseModel:
    """Per-step noise of the synthetic odometry: rotation [deg] and translation [m] per axis."""

    rot_noise_deg: float = 0.05
    trans_noise_m: float = 0.01


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


def noisy_estimate(gt: np.ndarray, noise: NoiseModel, seed: int) -> np.ndarray:
    """The ground truth's frame-to-frame motions with noise, chained from the first pose."""
    rng = np.random.default_rng(seed)
    n = len(gt)
    steps = np.linalg.inv(gt[:-1]) @ gt[1:]
    rot = Rotation.from_rotvec(np.radians(rng.normal(0.0, noise.rot_noise_deg, (n - 1, 3))))
    noisy = steps.copy()
    noisy[:, :3, :3] = rot.as_matrix() @ steps[:, :3, :3]
    noisy[:, :3, 3] += rng.normal(0.0, noise.trans_noise_m, (n - 1, 3))
    est = np.empty_like(gt)
    est[0] = gt[0]
    for k in range(1, n):
        est[k] = est[k - 1] @ noisy[k - 1]
    return est


#: the figures the study checks: name -> (units of (gt, est), quantity, metrics.json field)
FIGURES = {
    "relative 8 m rotation": (lambda g, e: relative_units(g, e, 8.0), "rot_deg"),
    "relative 8 m translation": (lambda g, e: relative_units(g, e, 8.0), "trans_m"),
    "relative 48 m rotation": (lambda g, e: relative_units(g, e, 48.0), "rot_deg"),
    "relative 48 m translation": (lambda g, e: relative_units(g, e, 48.0), "trans_m"),
    "APE translation RMSE": (lambda g, e: ape_units(g, e, "se3"), "trans_m"),
    "APE rotation RMSE": (lambda g, e: ape_units(g, e, "se3"), "rot_deg"),
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


def study(n_frames: int = 1500, trials: int = 200, truth_seeds: int = 400,
          noise: NoiseModel = NoiseModel(), figures: tuple[str, ...] = tuple(FIGURES),
          first_seed: int = 10_000) -> list[Coverage]:
    """The coverage of each figure's interval (see the module docstring)."""
    gt = ground_truth(n_frames)
    truth: dict[str, list[float]] = {f: [] for f in figures}
    for s in range(truth_seeds):
        est = noisy_estimate(gt, noise, first_seed + trials + s)
        for f in figures:
            make, key = FIGURES[f]
            truth[f].append(make(gt, est).statistic(key))
    hits: dict[str, list] = {f: [] for f in figures}
    for s in range(trials):
        est = noisy_estimate(gt, noise, first_seed + s)
        for f in figures:
            make, key = FIGURES[f]
            units: Units = make(gt, est)
            part = intervals(units, n_frames, {key: "ci"})
            hits[f].append((part["ci"], part["spread"]))
    out = []
    for f in figures:
        mean = float(np.mean(truth[f]))
        cis = [(c, sp) for c, sp in hits[f] if c is not None]
        inside = [c[0] <= mean <= c[1] for c, _ in cis]
        out.append(Coverage(f, mean, float(np.mean(inside)), len(cis),
                            float(np.median([c[1] - c[0] for c, _ in cis])),
                            float(np.median([sp.block_frames for _, sp in cis])),
                            float(np.median([sp.n_independent for _, sp in cis]))))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=1500, help="poses per trajectory")
    parser.add_argument("--trials", type=int, default=400, help="trajectories checked")
    parser.add_argument("--truth-seeds", type=int, default=800,
                        help="trajectories averaged for the long-run mean")
    args = parser.parse_args()
    rows = study(args.frames, args.trials, args.truth_seeds)
    print(f"{args.trials} trajectories of {args.frames} poses (5 m/s, 10 Hz: "
          f"{args.frames * 0.5:g} m), noise {NoiseModel()}; long-run mean from "
          f"{args.truth_seeds} more")
    print("| figure | long-run mean | coverage of the 95 % interval | median width | "
          "median block [frames] | median independent segments |")
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r.figure} | {r.truth:.4f} | {100 * r.coverage:.1f} % ({r.trials}) | "
              f"{r.median_width:.4f} | {r.median_block:g} | {r.median_independent:g} |")


if __name__ == "__main__":
    main()
