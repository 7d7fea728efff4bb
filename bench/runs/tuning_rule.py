"""The tuning rule of configs/splits.yaml: when a sweep's point may replace a method's
reference setting (the library's or paper's value), decided the same way for every method.

Criterion ``C`` of a point on one sequence: the mean, over the reported segment lengths and
over both errors (rotation [deg], translation [m]), of the point's mean relative error divided
by the reference setting's at that length::

    C(point) = mean_{L, e in (rot, trans)} mean_err(point, L, e) / mean_err(reference, L, e)

so ``C(reference) = 1`` and lower is better; on several sequences, the mean of their ``C``.
Its interval: every sequence resampled by its own circular block bootstrap
(``metrics.intervals.block_counts``; one draw of frame blocks for every length and for both
settings, so the comparison is paired; blocks as long as the longest length's segments),
``C`` recomputed from the weighted per-length means of each draw, then averaged over the
sequences; the percentile interval at ``level``.

The decision (:func:`decide`): a point *qualifies* when in every fold its ``C`` on the fold's
tuning sequences is significantly below 1 (the interval's top below 1) and by at least
``min_gain`` (``C <= 1 - min_gain``: a gain smaller than the bench reproduces between rounds
is no reason to leave a library's value), its ``C`` on the fold's
validation sequences is below 1 (the improvement does not reverse), and on the ``domain``
sequences (a second domain, e.g. synthetic) its ``C`` is not significantly above 1 (the
domain only vetoes, so its runs are needed only for the points the folds admit: a point the
folds admit without them leaves the decision open if it could be the choice; a fold
without validation sequences, one half's own choice that is scored on the held-out half
elsewhere, as ``bench.studies.independent`` cross-fits, has no reversal check). Of the
qualifying points the one with the lowest ``C`` over every fold's sequences is chosen; none
qualifying, the reference stays. A chosen point on the edge of its grid (the first or last
value of a swept axis along which it leaves the reference) is not believed: the decision is
"extend the grid".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from metrics.intervals import block_counts, block_frames
from metrics.units import Units, relative_units

ERRORS = ("rot_deg", "trans_m")


@dataclass(frozen=True)
class RunErrors:
    """One run's per-segment errors (``metrics.units.relative_units``) per length [m], over
    its ``n_frames`` scored frames."""

    n_frames: int
    units: dict[float, Units]


def run_errors(gt_poses: np.ndarray, est_poses: np.ndarray, lengths_m) -> RunErrors:
    """The per-segment errors of a run's scored poses (N,4,4 T_world_sensor, row-aligned)."""
    return RunErrors(len(gt_poses), {float(x): relative_units(gt_poses, est_poses, float(x))
                                     for x in lengths_m})


@dataclass(frozen=True)
class Estimate:
    """``C`` of a point on some sequences, with its ``level`` interval [low, high]."""

    value: float
    low: float
    high: float
    level: float

    @property
    def better(self) -> bool:
        """Significantly below the reference's 1."""
        return bool(np.isfinite(self.high) and self.high < 1.0)

    @property
    def worse(self) -> bool:
        """Significantly above the reference's 1."""
        return bool(np.isfinite(self.low) and self.low > 1.0)

    def __str__(self) -> str:
        return f"{self.value:.3f} [{self.low:.3f}, {self.high:.3f}]"


def _block(errors: RunErrors) -> int:
    """Block length [frames]: the median span of the longest length's segments."""
    spans = [np.median(u.end - u.anchor) for _, u in sorted(errors.units.items()) if len(u)]
    return block_frames(errors.n_frames, float(spans[-1]) if spans else 1.0)


def sequence_draws(point: RunErrors, reference: RunErrors, lengths_m, reps: int, seed: int,
                   name: str = "") -> tuple[float, np.ndarray]:
    """``C`` of ``point`` against ``reference`` on one sequence, and its ``reps`` block
    bootstrap draws. Lengths without segments are left out; both runs must have the same
    segments (the same ground truth and scored frames)."""
    counts = block_counts(reference.n_frames, _block(reference), reps, seed)
    ratios, draws = [], []
    for length in (float(x) for x in lengths_m):
        p, r = point.units.get(length), reference.units.get(length)
        if p is None or r is None or not len(r):
            continue
        if len(p) != len(r) or not np.array_equal(p.anchor, r.anchor):
            raise ValueError(f"{name}: the point's {length:g} m segments are not the "
                             "reference's (different ground truth or scored frames)")
        w = counts[:, r.anchor]
        for key in ERRORS:
            ratios.append(float(np.mean(p.values[key]) / np.mean(r.values[key])))
            with np.errstate(invalid="ignore", divide="ignore"):  # a draw without segments
                draws.append((w @ p.values[key]) / (w @ r.values[key]))
    if not ratios:
        raise ValueError(f"{name}: no segment of {', '.join(f'{x:g}' for x in lengths_m)} m")
    with np.errstate(invalid="ignore"):
        return float(np.mean(ratios)), np.nanmean(np.array(draws), axis=0)


def estimate(pairs: list[tuple[RunErrors, RunErrors]], lengths_m, level: float = 0.95,
             reps: int = 1000, seed: int = 0, names: list[str] | None = None) -> Estimate:
    """``C`` over several sequences (``pairs``: (point, reference) per sequence), each
    resampled independently, averaged per draw."""
    values, draws = [], []
    for k, (point, ref) in enumerate(pairs):
        v, d = sequence_draws(point, ref, lengths_m, reps, seed + k,
                              names[k] if names else str(k))
        values.append(v)
        draws.append(d)
    mean = np.mean(np.array(draws), axis=0)
    mean = mean[np.isfinite(mean)]
    if mean.size == 0:
        return Estimate(float(np.mean(values)), math.nan, math.nan, level)
    alpha = 0.5 * (1.0 - level)
    low, high = np.quantile(mean, [alpha, 1.0 - alpha])
    return Estimate(float(np.mean(values)), float(low), float(high), level)


@dataclass
class Verdict:
    """A point's estimates per group of sequences (``"tune A"``-style labels, in order), its
    ``C`` over every fold's sequences (``overall``), whether it qualifies and why (not)."""

    point: dict
    estimates: dict[str, Estimate] = field(default_factory=dict)
    overall: float | None = None
    qualifies: bool = False
    why: str = ""


@dataclass
class Decision:
    """A sweep's decision: ``chosen`` (index of the point; the reference when none
    qualifies; None when the grid must be extended first or a run is missing) and why."""

    reference: int
    chosen: int | None
    verdicts: list[Verdict]
    text: str
    extend: bool = False


def _edges(points: list[dict], index: int, reference: int) -> list[str]:
    """The swept values of point ``index`` that are the first or last of their axis, on the
    axes along which it leaves the ``reference`` point (an axis it shares with the reference
    is not where the grid found its gain)."""
    out = []
    for key, value in points[index].items():
        if value == points[reference][key]:
            continue
        axis = list(dict.fromkeys(p[key] for p in points))
        try:
            ordered = sorted(axis)
        except TypeError:
            continue
        if len(ordered) > 1 and value in (ordered[0], ordered[-1]):
            side = "smallest" if value == ordered[0] else "largest"
            out.append(f"{key}={value} is the grid's {side}")
    return out


def decide(points: list[dict], errors: list[dict[str, RunErrors] | None], reference: int,
           folds: list[tuple[list[str], list[str]]], domain: list[str], lengths_m,
           level: float = 0.95, reps: int = 1000, seed: int = 0, min_gain: float = 0.0
           ) -> Decision:
    """The rule of this module over a sweep's ``points`` (their swept values), ``errors``
    (per point: sequence name -> RunErrors; None when a run is missing), the ``reference``
    point's index, the ``folds`` ((tuning names, validation names) each; validation may be
    empty) and the ``domain``
    sequences; ``min_gain`` the least improvement on a tuning half that counts."""
    ref = errors[reference]
    if ref is None:
        return Decision(reference, None, [Verdict(p) for p in points],
                        "undecided: a run of the reference point is missing")
    everything = list(dict.fromkeys(n for tune, val in folds for n in tune + val))

    def est(i: int, names: list[str]) -> Estimate:
        return estimate([(errors[i][n], ref[n]) for n in names], lengths_m, level, reps,
                        seed, names)

    verdicts, pending = [], []
    for i, p in enumerate(points):
        v = Verdict(p)
        verdicts.append(v)
        if errors[i] is None:
            v.why = "a run is missing"
            continue
        v.overall = est(i, everything).value
        if i == reference:
            v.why = "the reference"
            continue
        reasons = []
        for k, (tune, val) in enumerate(folds, 1):
            t, w = est(i, tune), est(i, val) if val else None
            v.estimates[f"fold {k} tune ({', '.join(tune)})"] = t
            if w is not None:
                v.estimates[f"fold {k} validate ({', '.join(val)})"] = w
            if t.value >= 1.0:
                reasons.append(f"fold {k}: no better on {', '.join(tune)} (C {t})")
            elif not t.better:
                reasons.append(f"fold {k}: not significant on {', '.join(tune)} (C {t})")
            elif t.value > 1.0 - min_gain:
                reasons.append(f"fold {k}: less than {100 * min_gain:g} % better on "
                               f"{', '.join(tune)} (C {t})")
            elif w is not None and w.value >= 1.0:
                reasons.append(f"fold {k}: reverses on {', '.join(val)} (C {w.value:.3f})")
        if domain and not all(n in errors[i] and n in ref for n in domain):
            # the domain can only veto: its runs matter only for a point the folds admit
            if not reasons:
                pending.append(i)
                reasons.append("qualifies on the folds; its second-domain runs are missing")
        elif domain:
            d = est(i, domain)
            v.estimates[f"domain ({', '.join(domain)})"] = d
            if d.worse:
                reasons.append(f"the second domain contradicts it (C {d})")
        v.qualifies = not reasons
        v.why = "; ".join(reasons) if reasons else "qualifies: significant in every fold" + (
            ", holds on validation" if any(val for _, val in folds) else "") + (
            ", not contradicted by the second domain" if domain else "")
    qualified = [i for i, v in enumerate(verdicts) if v.qualifies]
    best_c = min((verdicts[i].overall for i in qualified), default=math.inf)
    if any(verdicts[i].overall < best_c for i in pending):
        return Decision(reference, None, verdicts, "undecided: a point the folds admit, "
                        "better than every qualifying one, has no second-domain runs")
    if not qualified:
        missing = [i for i, v in enumerate(verdicts) if v.overall is None]
        if missing:
            return Decision(reference, None, verdicts, "undecided: a run is missing")
        return Decision(reference, reference, verdicts,
                        "the reference stays: no point qualifies")
    best = min(qualified, key=lambda i: verdicts[i].overall)
    edges = _edges(points, best, reference)
    if edges:
        return Decision(reference, None, verdicts,
                        f"EXTEND THE GRID: the best qualifying point lies on its edge "
                        f"({'; '.join(edges)}); it is not believed until the grid goes past it",
                        extend=True)
    return Decision(reference, best, verdicts,
                    f"the best qualifying point replaces the reference (C over every fold's "
                    f"sequences {verdicts[best].overall:.3f})")
