"""Real-sample statistics of a radar sequence, to compare the synthetic semi-dense radar with
the real NTU4DRadLM loop-1 sample (Oculii Eagle, 60 frames, 12 Hz).

Per sequence (sensor frame, x forward, y left, z up; range r [m], elevation asin(z / r) [deg],
Doppler [m/s, positive receding]):

- ``points``: median points per frame;
- ``range_p50_m`` / ``range_p90_m``: median and 90th percentile of the range of all points;
- ``elev_p10_deg`` / ``elev_p90_deg``: 10th and 90th percentiles of the elevation;
- ``elev_iqr_deg``: the elevation's interquartile range (its spread, robust to the mount tilt);
- ``doppler_resid_mps``: median over frames of the RMS Doppler residual of the inliers of the
  ego-velocity fit (``methods.ego_velocity``, threshold 0.5 m/s: the spread of the static
  points around ``-d . v``, i.e. the Doppler and angle noise as the Doppler sees it);
- ``inlier_frac``: median fraction of points that agree with the ego velocity (static share);
- ``kept_frac``: median over consecutive pairs of the fraction of source points ``doppler``
  (the paper's defaults, tau_spatial 3 m, tau_doppler 5 m^2) keeps as correspondences.

Shown beside them (calibration evidence, not in the 20 % check):

- ``feature_resid_<lo>_<hi>_m2``: median |f(p) - g(q)| [m^2] of the pairs ``doppler`` keeps whose
  source point lies at range lo-hi m: the frame-to-frame consistency of the range and Doppler
  of the same scatterer (f - g = 2 r dr + r dT dv to first order; see ``feature_residuals``);
- ``doppler_noise_mps`` / ``azimuth_noise_deg``: the ego-fit residual split into its Doppler and
  azimuth parts by a linear fit of the squared residual on the squared azimuth sensitivity
  |d(-d . v) / d az| of each inlier (``noise_split``).

``python -m bench.studies.realism [--data-dir D] [--frames N]`` prints the real sample and
the synthetic ``Loop1_0`` side by side with the ratios (see ``compare``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from bench.paths import REAL_SAMPLE, REAL_SAMPLE_60
from loaders.scan import Sequence

#: statistic -> allowed relative deviation of synthetic from real (issue 11: each within 20 %)
TOLERANCE = 0.20
STAT_NAMES = ("points", "range_p50_m", "range_p90_m", "elev_iqr_deg", "doppler_resid_mps",
              "inlier_frac", "kept_frac")
#: range bins [m] of the feature residual
RESID_BINS_M = ((0, 20), (20, 50), (50, 100), (100, 250))
EXTRA_NAMES = tuple(f"feature_resid_{lo}_{hi}_m2" for lo, hi in RESID_BINS_M) + (
    "doppler_noise_mps", "azimuth_noise_deg")


def noise_split(points: np.ndarray, doppler: np.ndarray, velocity: np.ndarray,
                inliers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(squared Doppler residual [m^2/s^2], squared azimuth sensitivity [m^2/s^2/rad^2]) of the
    inliers of an ego-velocity fit: residual e = doppler + d . v, sensitivity
    s = |d(-d . v) / d az| = |(-cos el sin az, cos el cos az, 0) . v|. E[e^2] = sd^2 + s^2 saz^2
    (Doppler noise sd, azimuth noise saz [rad]) when the elevation term is small."""
    p = points[inliers]
    r = np.linalg.norm(p, axis=1)
    d = p / r[:, None]
    e = doppler[inliers] + d @ velocity
    az, el = np.arctan2(p[:, 1], p[:, 0]), np.arcsin(np.clip(d[:, 2], -1, 1))
    dd = np.column_stack([-np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.zeros(len(p))])
    return e**2, (dd @ velocity) ** 2


def _fit_noise(e2: np.ndarray, s2: np.ndarray) -> tuple[float, float]:
    """(Doppler noise [m/s], azimuth noise [deg]) from e^2 = a + b s^2 (least squares)."""
    if len(e2) < 10:
        return float("nan"), float("nan")
    a, b = np.linalg.lstsq(np.column_stack([np.ones(len(s2)), s2]), e2, rcond=None)[0]
    return float(np.sqrt(max(a, 0.0))), float(np.degrees(np.sqrt(max(b, 0.0))))


def sequence_stats(seq: Sequence, frames: int | None = None, start: int = 0) -> dict[str, float]:
    """The statistics above over ``frames`` consecutive scans of ``seq`` from ``start``."""
    from methods.doppler import DopplerParams, DopplerScan, doppler_pairs
    from methods.ego_velocity import estimate_ego_velocity

    gates = DopplerParams()  # the paper's defaults (tau_spatial 3 m, tau_doppler 5 m^2)
    n = len(seq) - start if frames is None else min(frames, len(seq) - start)
    counts, ranges, elevs, resid, inl, kept = [], [], [], [], [], []
    e2s, s2s, fres, fr = [], [], [], []
    prev = prev_r = None
    for i in range(start, start + n):
        scan = seq.scan(i)
        p = np.asarray(scan.points, float)
        r = np.linalg.norm(p, axis=1)
        counts.append(len(p))
        ranges.append(r)
        elevs.append(np.degrees(np.arcsin(np.clip(p[:, 2] / np.maximum(r, 1e-9), -1, 1))))
        ego = estimate_ego_velocity(p, scan.doppler, threshold_mps=0.5, seed=i)
        if ego.observable:
            resid.append(ego.sigma_mps)
            inl.append(ego.inliers.mean())
            e2, s2 = noise_split(p, np.asarray(scan.doppler, float), ego.velocity, ego.inliers)
            e2s.append(e2)
            s2s.append(s2)
        cur = DopplerScan(float(scan.stamp), np.ascontiguousarray(p.T, np.float32),
                          np.asarray(scan.doppler, np.float32))
        if prev is not None and len(prev) and len(cur):
            idx, match = doppler_pairs(prev, cur, gates.tau_spatial_m, gates.tau_doppler)
            kept.append(len(idx) / len(prev))
            fres.append(feature_residuals(prev, cur, idx, match))
            fr.append(prev_r[idx])
        prev, prev_r = cur, r
    r_all, e_all = np.concatenate(ranges), np.concatenate(elevs)
    q25, q75 = np.percentile(e_all, [25, 75])
    extra = {}
    fres_all = np.concatenate(fres) if fres else np.zeros(0)
    fr_all = np.concatenate(fr) if fr else np.zeros(0)
    for lo, hi in RESID_BINS_M:
        m = (fr_all >= lo) & (fr_all < hi)
        extra[f"feature_resid_{lo}_{hi}_m2"] = float(np.median(fres_all[m])) if m.any() \
            else float("nan")
    sd, saz = _fit_noise(np.concatenate(e2s), np.concatenate(s2s)) if e2s else (np.nan, np.nan)
    extra["doppler_noise_mps"], extra["azimuth_noise_deg"] = sd, saz
    return {**extra,
        "points": float(np.median(counts)),
        "range_p50_m": float(np.percentile(r_all, 50)),
        "range_p90_m": float(np.percentile(r_all, 90)),
        "elev_p10_deg": float(np.percentile(e_all, 10)),
        "elev_p90_deg": float(np.percentile(e_all, 90)),
        "elev_iqr_deg": float(q75 - q25),
        "doppler_resid_mps": float(np.median(resid)) if resid else float("nan"),
        "inlier_frac": float(np.median(inl)) if inl else float("nan"),
        "kept_frac": float(np.median(kept)) if kept else float("nan"),
    }


def feature_residuals(source, target, src_idx: np.ndarray, tgt_idx: np.ndarray) -> np.ndarray:
    """|f(p) - g(q)| [m^2] of Doppler pairs (source DopplerScan point src_idx[i], target point
    tgt_idx[i]); the features of ``methods.doppler`` (float64 here)."""
    dt = target.stamp - source.stamp
    p = source.points_t[:, src_idx].astype(float)
    q = target.points_t[:, tgt_idx].astype(float)
    rp, rq = np.linalg.norm(p, axis=0), np.linalg.norm(q, axis=0)
    f = rp**2 + rp * source.doppler[src_idx] * dt
    g = rq**2 - rq * target.doppler[tgt_idx] * dt
    return np.abs(f - g)


def real_sample(store: Path = REAL_SAMPLE) -> Sequence:
    """The real 60-frame Oculii Eagle sample: the first 60 frames of the vendored store (12 Hz
    stamps, GT by row; samples/README.md)."""
    from loaders.scan import FrameRange
    from loaders.store import StoreSequence

    return FrameRange(StoreSequence(store), *REAL_SAMPLE_60)


def synthetic_semidense(frames: int = 60, seed: int = 110, **options) -> Sequence:
    """The semi-dense radar of the suite's Loop1_0 entry (same scene, sensor and seed)."""
    from loaders.synthetic.suite import suite_entries

    entry = next(e for e in suite_entries("synthetic-paper") if e.name == "Loop1_0")
    from loaders.synthetic.generate import SyntheticSequence

    return SyntheticSequence(entry.scene, entry.sensor, frames, seed,
                             **{**entry.options, **options})


def compare(real: dict[str, float], synth: dict[str, float]) -> list[tuple[str, float, float,
                                                                           float, bool]]:
    """(name, real, synthetic, ratio synthetic / real, within TOLERANCE) for each statistic of
    ``STAT_NAMES``."""
    rows = []
    for name in STAT_NAMES:
        ratio = synth[name] / real[name] if real[name] else float("nan")
        rows.append((name, real[name], synth[name], ratio, abs(ratio - 1.0) <= TOLERANCE))
    return rows


def format_rows(rows) -> str:
    lines = [f"{'statistic':<20}{'real':>10}{'synthetic':>11}{'ratio':>8}  within 20 %"]
    for name, r, s, ratio, ok in rows:
        lines.append(f"{name:<20}{r:>10.3f}{s:>11.3f}{ratio:>8.2f}  {'yes' if ok else 'NO'}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Real Oculii Eagle sample vs synthetic "
                                 "semi-dense radar (Loop1_0): per-frame statistics")
    ap.add_argument("--real", type=Path, default=REAL_SAMPLE, help="the real sample store")
    ap.add_argument("--frames", type=int, default=60, help="synthetic frames to compare")
    args = ap.parse_args(argv)
    real = sequence_stats(real_sample(args.real))
    synth = sequence_stats(synthetic_semidense(args.frames))
    rows = compare(real, synth)
    print(format_rows(rows))
    for k in ("elev_p10_deg", "elev_p90_deg"):
        print(f"{k:<20}{real[k]:>10.3f}{synth[k]:>11.3f}   (mount tilt: shown, not compared)")
    for k in EXTRA_NAMES:
        print(f"{k:<27}{real[k]:>8.3f}{synth[k]:>9.3f}{synth[k] / real[k]:>6.2f}"
              "   (calibration evidence, not compared)")
    return 0 if all(r[-1] for r in rows) else 1


if __name__ == "__main__":
    raise SystemExit(main())
