"""The tuning rule (bench/runs/tuning_rule.py, configs/splits.yaml) on constructed errors:
the criterion C against a hand computation and a loop-by-loop bootstrap, and the decision: a
significant improvement in both folds replaces the reference, an insignificant one, one that
reverses on validation or one the second domain contradicts keeps it, and a best point on the
grid's edge asks for a wider grid. The table (bench/report/tables/sweep.py) shows it."""

from types import SimpleNamespace

import numpy as np
import pytest

from bench.report.tables import sweep as tables_sweep
from bench.runs.sweep import write_sweep_index
from bench.runs.tuning_rule import RunErrors, decide, estimate, run_errors, sequence_draws
from metrics.intervals import block_counts
from metrics.units import Units

N = 200  # frames per constructed sequence
LENGTHS = (8.0, 48.0)


def _errors(rot8, trans8, rot48, trans48) -> RunErrors:
    """A run's segments: 8 m ones spanning 10 frames, 48 m ones 60, one per anchor."""
    units = {}
    for length, span, rot, trans in ((8.0, 10, rot8, trans8), (48.0, 60, rot48, trans48)):
        anchor = np.arange(N - span)
        units[length] = Units(anchor, anchor + span,
                              {"rot_deg": np.asarray(rot, float), "trans_m": np.asarray(trans,
                                                                                   float)})
    return RunErrors(N, units)


def _noisy(seed: int, factor: float, noise: float, ref: RunErrors | None = None) -> RunErrors:
    """``factor`` times the reference's errors (a fresh positive series when None), each
    segment times (1 + noise * N(0, 1))."""
    rng = np.random.default_rng(seed)
    if ref is None:
        base = [np.abs(1.0 + 0.3 * rng.standard_normal(N - span)) + 0.1
                for span in (10, 10, 60, 60)]
    else:
        base = [ref.units[x].values[k] for x in LENGTHS for k in ("rot_deg", "trans_m")]
    return _errors(*[np.maximum(b * factor * (1 + noise * rng.standard_normal(b.size)), 1e-3)
                     for b in base])


def test_c_is_the_mean_error_ratio_over_lengths_and_both_errors():
    ref = _errors(np.full(190, 1.0), np.full(190, 2.0), np.full(140, 4.0), np.full(140, 8.0))
    point = _errors(np.full(190, 0.5), np.full(190, 2.0), np.full(140, 6.0), np.full(140, 4.0))
    value, draws = sequence_draws(point, ref, LENGTHS, reps=50, seed=1)
    assert value == pytest.approx((0.5 + 1.0 + 1.5 + 0.5) / 4)
    assert np.allclose(draws, value)  # constant errors: every draw the same
    same, _ = sequence_draws(ref, ref, LENGTHS, reps=50, seed=1)
    assert same == pytest.approx(1.0)


def test_the_draws_match_a_loop_over_resamples():
    ref = _noisy(1, 1.0, 0.0)
    point = _noisy(2, 0.9, 0.2, ref)
    reps, seed = 40, 7
    value, draws = sequence_draws(point, ref, LENGTHS, reps, seed)
    counts = block_counts(N, 60, reps, seed)  # block: the 48 m segments' 60-frame span
    for r in range(reps):
        ratios = []
        for x in LENGTHS:
            w = counts[r, ref.units[x].anchor]
            for k in ("rot_deg", "trans_m"):
                p = sum(wi * v for wi, v in zip(w, point.units[x].values[k], strict=True))
                q = sum(wi * v for wi, v in zip(w, ref.units[x].values[k], strict=True))
                ratios.append(p / q)
        assert draws[r] == pytest.approx(sum(ratios) / len(ratios), rel=1e-9)
    assert value == pytest.approx(np.mean(
        [np.mean(point.units[x].values[k]) / np.mean(ref.units[x].values[k])
         for x in LENGTHS for k in ("rot_deg", "trans_m")]))


def test_several_sequences_average_their_c():
    ref_a, ref_b = _noisy(1, 1.0, 0.0), _noisy(2, 1.0, 0.0)
    e = estimate([(_noisy(3, 0.8, 0.0, ref_a), ref_a), (_noisy(4, 1.2, 0.0, ref_b), ref_b)],
                 LENGTHS, reps=100)
    assert e.value == pytest.approx(1.0) and e.low <= 1.0 <= e.high


def test_the_run_errors_of_poses_are_the_relative_units():
    from metrics.units import relative_units

    gt = np.repeat(np.eye(4)[None], 80, axis=0)
    gt[:, 0, 3] = np.arange(80) * 1.0
    est = gt.copy()
    est[:, 1, 3] = 0.01 * np.arange(80)
    e = run_errors(gt, est, [8, 48])
    assert e.n_frames == 80
    assert np.allclose(e.units[48.0].values["trans_m"],
                       relative_units(gt, est, 48.0).values["trans_m"])


# --- the decision -------------------------------------------------------------------------

POINTS = [{"gate_m": g} for g in (1.0, 2.0, 3.0, 4.0)]
FOLDS = [(["A"], ["B"]), (["B"], ["A"])]


def _sweep(factors: dict[str, list[float]], noise: float = 0.05) -> list[dict]:
    """Per point: sequence -> errors, ``factors[seq][i]`` times the reference's (point 0)."""
    refs = {s: _noisy(10 + k, 1.0, 0.0) for k, s in enumerate(factors)}
    out = []
    for i in range(len(POINTS)):
        out.append({s: refs[s] if i == 0 else _noisy(100 * i + k, f[i], noise, refs[s])
                    for k, (s, f) in enumerate(factors.items())})
    return out


def test_a_significant_improvement_in_both_folds_replaces_the_reference():
    errors = _sweep({"A": [1, 0.95, 0.8, 0.9], "B": [1, 0.97, 0.8, 0.9], "S": [1, 1, 1, 1]})
    d = decide(POINTS, errors, 0, FOLDS, ["S"], LENGTHS, reps=300)
    assert d.chosen == 2 and not d.extend
    assert d.verdicts[2].qualifies and "replaces the reference" in d.text
    assert d.verdicts[2].estimates["fold 1 tune (A)"].better


def test_an_insignificant_improvement_keeps_the_reference():
    errors = _sweep({"A": [1, 1.3, 0.97, 1.4], "B": [1, 1.3, 0.97, 1.4]}, noise=0.6)
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=300)
    assert d.chosen == 0 and "no point qualifies" in d.text
    assert "not significant" in d.verdicts[2].why


def test_an_improvement_that_reverses_on_validation_keeps_the_reference():
    # point 2: 20 % better on A, 10 % worse on B: fold 1 reverses, fold 2 not significant
    errors = _sweep({"A": [1, 1.3, 0.8, 1.4], "B": [1, 1.3, 1.1, 1.4]})
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=300)
    assert d.chosen == 0
    assert "fold 1: reverses on B" in d.verdicts[2].why


def test_a_contradicting_second_domain_keeps_the_reference():
    errors = _sweep({"A": [1, 1.3, 0.8, 1.4], "B": [1, 1.3, 0.8, 1.4], "S": [1, 1, 1.3, 1]})
    d = decide(POINTS, errors, 0, FOLDS, ["S"], LENGTHS, reps=300)
    assert d.chosen == 0 and "second domain contradicts" in d.verdicts[2].why


def test_a_best_point_on_the_grid_s_edge_asks_for_a_wider_grid():
    errors = _sweep({"A": [1, 0.9, 0.85, 0.7], "B": [1, 0.9, 0.85, 0.7]})
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=300)
    assert d.chosen is None and d.extend
    assert "EXTEND THE GRID" in d.text and "gate_m=4.0 is the grid's largest" in d.text


def test_a_missing_reference_run_decides_nothing():
    errors = _sweep({"A": [1, 0.8, 0.9, 1.1], "B": [1, 0.8, 0.9, 1.1]})
    errors[0] = None
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=100)
    assert d.chosen is None and "missing" in d.text


def test_a_fold_without_validation_is_one_half_s_own_choice():
    """A fold with no validation sequences (``bench.studies.independent``'s cross-fit: the
    choice on one half, scored on the other elsewhere) has no reversal check: point 2, 20 %
    better on A and 10 % worse on B, is A's own choice though it reverses on B."""
    errors = _sweep({"A": [1, 1.3, 0.8, 1.4], "B": [1, 1.3, 1.1, 1.4], "S": [1, 1, 1, 1]})
    on_a = decide(POINTS, errors, 0, [(["A"], [])], ["S"], LENGTHS, reps=300)
    assert on_a.chosen == 2 and on_a.verdicts[2].qualifies
    assert not any("validate" in k for k in on_a.verdicts[2].estimates)
    assert on_a.verdicts[2].overall == pytest.approx(
        on_a.verdicts[2].estimates["fold 1 tune (A)"].value)  # over A alone
    on_b = decide(POINTS, errors, 0, [(["B"], [])], ["S"], LENGTHS, reps=300)
    assert on_b.chosen == 0 and "no point qualifies" in on_b.text


def test_second_domain_runs_are_needed_only_where_the_folds_admit_a_point():
    """The domain only vetoes: a point that fails on the folds needs no domain runs; one the
    folds admit without them leaves the decision open when it could be the choice, not when a
    qualifying point is better."""
    errors = _sweep({"A": [1, 1.3, 0.8, 0.9], "B": [1, 1.3, 0.8, 0.9], "S": [1, 1, 1, 1]})
    del errors[1]["S"]  # fails on the folds anyway
    d = decide(POINTS, errors, 0, FOLDS, ["S"], LENGTHS, reps=300)
    assert d.chosen == 2 and "no better" in d.verdicts[1].why
    del errors[3]["S"]  # admitted by the folds, but worse than point 2 over both halves
    d = decide(POINTS, errors, 0, FOLDS, ["S"], LENGTHS, reps=300)
    assert d.chosen == 2 and "second-domain runs are missing" in d.verdicts[3].why
    del errors[2]["S"]  # the best admitted point unvetted: undecided
    d = decide(POINTS, errors, 0, FOLDS, ["S"], LENGTHS, reps=300)
    assert d.chosen is None and not d.extend and "undecided" in d.text


# --- the sweep table ----------------------------------------------------------------------

def _trajectories(drift: float, seed: int, n: int = 120):
    """GT along x at 1 m per frame and an estimate whose yaw drifts ``drift`` rad per frame
    (times a positive random factor per frame)."""
    from loaders.se3 import exp_se3

    rng = np.random.default_rng(seed)
    gt = np.repeat(np.eye(4)[None], n, axis=0)
    gt[:, 0, 3] = np.arange(n)
    est = gt.copy()
    step = np.eye(4)
    step[0, 3] = 1.0
    for k in range(1, n):
        wobble = exp_se3(np.array([0, 0, 0, 0, 0, drift * (0.5 + rng.random())]))
        est[k] = est[k - 1] @ step @ wobble
    return gt, est


def test_the_table_prints_c_per_fold_and_the_decision(tmp_path, monkeypatch):
    drifts = {1.0: 0.010, 2.0: 0.006, 3.0: 0.009}  # point 2 clearly better on both halves
    runs = {}
    points = []
    for value, drift in drifts.items():
        rs = []
        for k, seq in enumerate(("A", "B")):
            rel = f"{seq}/p{value}"
            runs[rel] = _trajectories(drift, 10 * k + int(value))
            rs.append({"sequence": seq, "seed": True, "dir": rel})
        points.append({"label": f"m gate_m={value}", "point": {"gate_m": value}, "runs": rs})
    criterion = {"lengths_m": [8.0, 16.0], "folds": [{"tuning": ["A"], "validation": ["B"]},
                                                      {"tuning": ["B"], "validation": ["A"]}],
                 "domain": [], "reference": {"gate_m": 1.0}, "level": 0.95, "reps": 200}
    write_sweep_index(tmp_path, {
        "experiment": "t", "criterion": criterion, "default_differs": None,
        "sweeps": [{"method": "m", "group": "m", "keys": ["gate_m"],
                    "defaults": {"A": {"gate_m": 2.0}, "B": {"gate_m": 2.0}},
                    "points": points}]})

    def fake_read_run(path):
        rel = str(path.relative_to(tmp_path))
        gt, est = runs[rel]
        return SimpleNamespace(gt=gt, est=est)

    monkeypatch.setattr(tables_sweep, "read_run", fake_read_run)
    monkeypatch.setattr(tables_sweep, "_errors", lambda *a: ([None] * 3, []))
    (choice,) = tables_sweep.sweep_choices(tmp_path)
    assert choice.point == {"gate_m": 2.0} and choice.agrees
    text = tables_sweep.sweep_markdown(tmp_path)
    assert "C fold 1 tune (A)" in text and "(reference)" in text
    assert "**chosen**: qualifies" in text
    line = next(ln for ln in text.splitlines() if ln.startswith("chosen"))
    assert "replaces the reference" in line and line.endswith("agrees")


def test_a_significant_but_smaller_gain_than_min_gain_keeps_the_reference():
    # point 2: 0.5 % better on both halves, every segment alike: significant, but below 1 %
    errors = _sweep({"A": [1, 1.3, 0.995, 1.4], "B": [1, 1.3, 0.995, 1.4]}, noise=0.0)
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=200)
    assert d.chosen == 2  # without a least gain the rule takes it
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=200, min_gain=0.01)
    assert d.chosen == 0 and "less than 1 % better on A" in d.verdicts[2].why


def test_an_edge_shared_with_the_reference_is_not_where_the_gain_came_from():
    # a 2 x 3 grid: voxel (0.25 = the reference's, at the axis' edge) x gate; the best
    # point keeps the reference's voxel and moves the gate inside its axis
    points = [{"voxel_m": v, "gate_m": g} for v in (0.25, 1.0) for g in (1.0, 2.0, 3.0)]
    refs = {s: _noisy(10 + k, 1.0, 0.0) for k, s in enumerate("AB")}
    factors = [1.0, 0.8, 0.9, 1.2, 1.2, 1.2]
    errors = [{s: refs[s] if i == 0 else _noisy(50 + i, f, 0.05, refs[s]) for s in "AB"}
              for i, f in enumerate(factors)]
    d = decide(points, errors, 0, FOLDS, [], LENGTHS, reps=200, min_gain=0.01)
    assert d.chosen == 1 and not d.extend


# --- mutation review: the rule's edges ----------------------------------------------------

def test_better_and_worse_are_about_the_interval_not_the_value():
    from bench.runs.tuning_rule import Estimate

    assert Estimate(0.95, 0.90, 0.99, 0.95).better
    assert not Estimate(0.95, 0.90, 1.01, 0.95).better  # lower, not significantly
    assert Estimate(1.10, 1.01, 1.20, 0.95).worse
    assert not Estimate(1.05, 0.98, 1.12, 0.95).worse  # higher, not significantly
    assert not Estimate(0.9, float("nan"), float("nan"), 0.95).better


def test_a_gain_of_exactly_min_gain_qualifies():
    # every error of point 2 exactly half the reference's: C = 0.5 = 1 - min_gain
    errors = _sweep({"A": [1, 1.3, 0.5, 1.4], "B": [1, 1.3, 0.5, 1.4]}, noise=0.0)
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=100, min_gain=0.5)
    assert d.verdicts[2].estimates["fold 1 tune (A)"].value == 0.5
    assert d.chosen == 2 and d.verdicts[2].qualifies


def test_a_validation_just_above_one_reverses():
    errors = _sweep({"A": [1, 1.3, 0.8, 1.4], "B": [1, 1.3, 1.02, 1.4]}, noise=0.0)
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=100)
    assert d.chosen == 0 and "fold 1: reverses on B (C 1.020)" in d.verdicts[2].why


def test_sequences_are_resampled_independently_so_more_of_them_narrow_the_interval():
    # the same sequence twice: independent draws average to an interval about 1/sqrt(2) as
    # wide as one sequence's (the same draws twice would leave it as wide)
    ref = _noisy(1, 1.0, 0.0)
    point = _noisy(2, 0.9, 0.3, ref)
    one = estimate([(point, ref)], LENGTHS, reps=400)
    two = estimate([(point, ref), (point, ref)], LENGTHS, reps=400)
    assert two.value == pytest.approx(one.value)
    assert (two.high - two.low) < 0.85 * (one.high - one.low)


def test_the_interval_is_the_central_percentile_interval_of_the_averaged_draws():
    ref_a, ref_b = _noisy(1, 1.0, 0.0), _noisy(2, 1.0, 0.0)
    pairs = [(_noisy(3, 0.9, 0.3, ref_a), ref_a), (_noisy(4, 1.1, 0.3, ref_b), ref_b)]
    e = estimate(pairs, LENGTHS, level=0.9, reps=300, seed=5)
    draws = np.mean([sequence_draws(p, r, LENGTHS, 300, 5 + k)[1]
                     for k, (p, r) in enumerate(pairs)], axis=0)
    assert (e.low, e.high) == pytest.approx(tuple(np.quantile(draws, [0.05, 0.95])))


def test_a_best_point_on_the_grid_s_smallest_value_asks_for_a_wider_grid_too():
    refs = {s: _noisy(10 + k, 1.0, 0.0) for k, s in enumerate("AB")}
    factors = [0.7, 0.85, 1.0, 1.2]  # the reference is gate 3.0; gate 1.0 is the best
    errors = [{s: refs[s] if i == 2 else _noisy(60 + i, f, 0.05, refs[s]) for s in "AB"}
              for i, f in enumerate(factors)]
    d = decide(POINTS, errors, 2, FOLDS, [], LENGTHS, reps=200)
    assert d.chosen is None and d.extend
    assert "gate_m=1.0 is the grid's smallest" in d.text


def test_a_validation_above_one_reverses_even_when_not_significantly_worse():
    # B at 1.01 with noisy segments: its interval holds 1 (not significantly worse), and the
    # point still reverses there (a rule counting only significant reversals would admit it)
    errors = _sweep({"A": [1, 1.3, 0.7, 1.4], "B": [1, 1.3, 1.01, 1.4]}, noise=0.6)
    d = decide(POINTS, errors, 0, FOLDS, [], LENGTHS, reps=200)
    val = d.verdicts[2].estimates["fold 1 validate (B)"]
    assert val.value > 1.0 and val.low < 1.0 and not val.worse
    assert d.verdicts[2].estimates["fold 1 tune (A)"].better
    assert d.chosen == 0 and "fold 1: reverses on B" in d.verdicts[2].why
