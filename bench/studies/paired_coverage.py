"""Does the paired comparison hold its level? Two methods of equal true error, compared by
``metrics.intervals.paired_interval``: how often it declares a difference (its interval
excludes 0), against the nominal 5 %, and how often the tables' marks split the same pair.

Each drive: the study's ground truth (``bench.studies.coverage``), two estimates with the same
noise model and different noise seeds (so equal long-run errors), their relative errors at the
given lengths; per length and quantity the paired interval of the difference of the means, and
both figures' own intervals (``metrics.intervals.unit_intervals``, as a run's) marked by the
tables' rule (``bench.report.tables.significance``). ``python -m bench.studies.paired_coverage``
prints the rates per noise model (the coverage study's drives and noise models, its options);
``tests/test_intervals.py`` runs a small version.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from bench.report.tables.significance import Stat, interval_marks
from bench.studies.coverage import NOISE_MODELS, NoiseModel, ground_truth, noisy_estimate
from metrics.intervals import REPS, paired_interval, unit_intervals
from metrics.units import relative_units

#: the lengths checked [m]: the shortest and a long one a 120 m drive still holds several of
PAIRED_LENGTHS_M = (8.0, 24.0)


@dataclass(frozen=True)
class FalseAlarms:
    """Of ``drives`` pairs of equal methods: how many the paired interval called different,
    and how many the tables' marks split (one bold, the other not)."""

    figure: str
    drives: int
    paired: int
    marks_split: int

    @property
    def paired_rate(self) -> float:
        return self.paired / self.drives

    @property
    def marks_rate(self) -> float:
        return self.marks_split / self.drives


def paired_study(drives: int, n_frames: int, noise: NoiseModel, first_seed: int = 50_000,
                 lengths_m=PAIRED_LENGTHS_M, reps: int = REPS,
                 speed_mps: float = 5.0) -> list[FalseAlarms]:
    """The false alarms of the paired interval and the tables' marks on ``drives`` pairs of
    equal methods (noise seeds ``first_seed`` ...), per length and quantity."""
    gt = ground_truth(n_frames, speed_mps)
    counts: dict[str, list[int]] = {}
    for k in range(drives):
        a = noisy_estimate(gt, noise, first_seed + 2 * k)
        b = noisy_estimate(gt, noise, first_seed + 2 * k + 1)
        for length in lengths_m:
            ua, ub = relative_units(gt, a, length), relative_units(gt, b, length)
            ia = unit_intervals(n_frames, ua.anchor, ua.end, ua.values, reps=reps)
            ib = unit_intervals(n_frames, ub.anchor, ub.end, ub.values, reps=reps)
            for q, word in (("rot_deg", "rotation"), ("trans_m", "translation")):
                d = paired_interval(n_frames, ua.anchor, ua.end, ua.values[q], ub.values[q],
                                    reps=reps)
                marks = interval_marks([
                    Stat(float(np.mean(u.values[q])), (i[q].low, i[q].high), i[q].n_independent)
                    for u, i in ((ua, ia), (ub, ib))])
                c = counts.setdefault(f"relative {length:g} m {word}", [0, 0])
                c[0] += bool(d.excludes_zero)
                c[1] += marks[0] != marks[1]
    return [FalseAlarms(f, drives, p, m) for f, (p, m) in counts.items()]


def paired_table(rows: dict[str, list[FalseAlarms]]) -> str:
    """Markdown: per figure and noise model, the paired interval's and the marks' rates."""
    names = list(rows)
    lines = ["| figure | " + " | ".join(f"paired interval, {n} | marks split, {n}"
                                       for n in names) + " |",
             "|---|" + "---|---|" * len(names)]
    for i, first in enumerate(rows[names[0]]):
        cells = []
        for n in names:
            r = rows[n][i]
            cells += [f"{100 * r.paired_rate:.1f} %", f"{100 * r.marks_rate:.1f} %"]
        lines.append(f"| {first.figure} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--trials", type=int, default=300, help="pairs of equal methods")
    parser.add_argument("--frames", type=int, default=240, help="poses per drive (10 Hz)")
    parser.add_argument("--speed", type=float, default=5.0, help="driving speed [m/s]")
    parser.add_argument("--first-seed", type=int, default=50_000, help="the first noise seed")
    parser.add_argument("--noise", choices=[*NOISE_MODELS, "both"], default="both")
    parser.add_argument("--reps", type=int, default=REPS, help="bootstrap resamples")
    args = parser.parse_args()
    models = NOISE_MODELS if args.noise == "both" else {args.noise: NOISE_MODELS[args.noise]}
    found = {name: paired_study(args.trials, args.frames, noise, args.first_seed,
                                reps=args.reps, speed_mps=args.speed)
             for name, noise in models.items()}
    print(f"{args.trials} pairs of equal methods on drives of {args.frames} poses "
          f"({args.frames * args.speed / 10:g} m), noise seeds from {args.first_seed}, "
          f"{args.reps} resamples")
    print(paired_table(found))


if __name__ == "__main__":
    main()
