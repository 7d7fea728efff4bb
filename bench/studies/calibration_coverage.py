"""``bench calibrate-coverage``: how often the intervals ``bench calibrate`` states cover a known
mounting rotation. Synthetic sequences (``loaders.synthetic``, one scene and sensor, one seed
per sequence: its own trajectory, scene and noise) get their ground truth rotated by a known
``R_gt_sensor``; the Doppler estimate of ``bench.data.calibration.estimate`` is run on each, and for
every angle it observes we count whether its stated interval contains the truth. The coverage
of a level-95 % interval should be about 95 %; with ``n`` sequences its own standard error is
``sqrt(0.95 * 0.05 / n)`` (2.2 % at 100). The mean error and the mean stated standard
deviation per angle show whether a miss comes from a bias (error beside a small sd) or from too
narrow an interval. The sequences are generated with the option ``edge_band`` (the
generator's default, stated here as this study depends on it: the field of view's edge cuts
measured angles, so scatterers just beyond it are detected too); without it
the loop's Doppler ego velocity is tilted up by about 0.05 deg, a bias of the generator that
no interval of the estimator should cover.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from bench.data.calibration.estimate import ANGLES, CorrectedSequence, calibrate_sequence

#: the default mounting rotation [deg]: different in every angle, none zero
TRUTH_DEG = {"roll": 1.0, "pitch": 2.0, "yaw": -1.5}


def rotated_gt(sequence, truth_deg: dict[str, float] = TRUTH_DEG) -> CorrectedSequence:
    """``sequence`` whose GT frame is rotated against the sensor by R_gt_sensor = Rz(yaw)
    Ry(pitch) Rx(roll) of ``truth_deg``: GT poses ``T_world_sensor @ R^T``."""
    R = Rotation.from_euler("ZYX", [truth_deg["yaw"], truth_deg["pitch"], truth_deg["roll"]],
                            degrees=True).as_matrix()
    return CorrectedSequence(sequence, R.T)


@dataclass
class Coverage:
    """Per angle: sequences where it was observable, how many intervals covered the truth,
    the errors (estimate - truth) and the stated standard deviations [deg]."""

    level: float
    truth_deg: dict[str, float]
    tried: dict[str, int] = field(default_factory=lambda: dict.fromkeys(ANGLES, 0))
    covered: dict[str, int] = field(default_factory=lambda: dict.fromkeys(ANGLES, 0))
    errors_deg: dict[str, list[float]] = field(default_factory=lambda: {a: [] for a in ANGLES})
    sd_deg: dict[str, list[float]] = field(default_factory=lambda: {a: [] for a in ANGLES})
    blocks: list[int] = field(default_factory=list)

    def add(self, cal) -> None:
        self.blocks.append(cal.block.frames if cal.block is not None else 0)
        for ax in ANGLES:
            if ax in cal.not_observable:
                continue
            lo, hi = cal.interval_deg[ax]
            truth = self.truth_deg[ax]
            self.tried[ax] += 1
            self.covered[ax] += int(lo <= truth <= hi)
            self.errors_deg[ax].append(cal.angles_deg[ax] - truth)
            self.sd_deg[ax].append(cal.std_deg[ax])

    def rate(self, ax: str | None = None) -> float:
        """The fraction covered for angle ``ax``, or over all angles."""
        axes = ANGLES if ax is None else (ax,)
        tried = sum(self.tried[a] for a in axes)
        return sum(self.covered[a] for a in axes) / tried if tried else float("nan")

    def lines(self) -> list[str]:
        out = []
        for ax in ANGLES:
            n = self.tried[ax]
            if not n:
                out.append(f"  {ax:<5} not observable in any sequence")
                continue
            err, sd = np.array(self.errors_deg[ax]), np.array(self.sd_deg[ax])
            spread = 100 * np.sqrt(self.level * (1 - self.level) / n)
            rms = np.sqrt(np.mean(err**2))
            out.append(f"  {ax:<5} {self.covered[ax]}/{n} covered ({100 * self.rate(ax):.1f} %, "
                       f"binomial sd {spread:.1f} %); error mean {err.mean():+.3f} deg, rms "
                       f"{rms:.3f}; stated sd mean {sd.mean():.3f} deg")
        b = np.array(self.blocks)
        out.append(f"  all angles: {100 * self.rate():.1f} % covered; block length median "
                   f"{np.median(b):.0f} frames (range {b.min()}-{b.max()})")
        return out


def calibration_coverage(seeds: range | list[int], frames: int = 125, scene: str = "loop",
                         sensor: str = "radar-semidense", bootstrap: int = 200,
                         truth_deg: dict[str, float] = TRUTH_DEG,
                         progress: Callable[[int, object], None] | None = None) -> Coverage:
    """Run the Doppler calibration on one synthetic sequence per seed (see the module
    docstring); ``progress(seed, result)`` after each."""
    from loaders.synthetic import SyntheticSequence

    cov = None
    for seed in seeds:
        seq = SyntheticSequence(scene, sensor, frames, seed=int(seed), noise=True,
                                edge_band=True)
        cal = calibrate_sequence(rotated_gt(seq, truth_deg), bootstrap=bootstrap,
                                 seed=int(seed))
        if cov is None:
            cov = Coverage(cal.level, dict(truth_deg))
        cov.add(cal)
        if progress is not None:
            progress(int(seed), cal)
    if cov is None:
        raise ValueError("calibration coverage needs at least one seed")
    return cov
