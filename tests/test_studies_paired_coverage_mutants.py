"""The paired-comparison level study (bench.studies.paired_coverage) on tiny runs: what it
passes to each step (seeds, lengths, resamples, speed), how it counts (a pair of clearly
different methods is called different and split by the marks on every drive; a method against
itself never), the rates and the printed table (hand-made counts, the markdown written out) and
its command line."""

import sys

import numpy as np
import pytest

from bench.studies import paired_coverage as pc
from bench.studies.coverage import NOISE_MODELS, NoiseModel, noisy_estimate
from metrics.intervals import REPS

FIGURES = ["relative 8 m rotation", "relative 8 m translation", "relative 24 m rotation",
           "relative 24 m translation"]


def test_false_alarms_rates_are_the_counts_over_the_drives():
    r = pc.FalseAlarms("f", 8, 2, 6)
    assert r.paired_rate == pytest.approx(0.25) and r.marks_rate == pytest.approx(0.75)


def test_the_lengths_are_the_shortest_and_a_long_one():
    assert pc.PAIRED_LENGTHS_M == (8.0, 24.0)


def test_clearly_different_methods_are_called_different_on_every_drive(monkeypatch):
    """The second of each pair has fifty times the noise: every paired interval excludes 0 and
    every pair of marks splits; the noise seeds are first_seed, first_seed + 1, ..."""
    seeds = []
    loud = NoiseModel(rot_noise_deg=2.5, trans_noise_m=0.5)

    def estimate(gt, noise, seed):
        seeds.append(seed)
        return noisy_estimate(gt, noise if seed % 2 == 0 else loud, seed)

    monkeypatch.setattr(pc, "noisy_estimate", estimate)
    rows = pc.paired_study(3, 240, NoiseModel(), first_seed=100, reps=60)
    assert seeds == [100, 101, 102, 103, 104, 105]
    assert [r.figure for r in rows] == FIGURES
    for r in rows:
        assert (r.drives, r.paired, r.marks_split) == (3, 3, 3), r


def test_a_method_against_itself_is_never_called_different(monkeypatch):
    monkeypatch.setattr(pc, "noisy_estimate",
                        lambda gt, noise, seed: noisy_estimate(gt, noise, seed // 2))
    rows = pc.paired_study(2, 160, NoiseModel(), first_seed=10, reps=40, lengths_m=(8.0,))
    assert [r.figure for r in rows] == FIGURES[:2]
    assert [(r.drives, r.paired, r.marks_split) for r in rows] == [(2, 0, 0), (2, 0, 0)]


class Spy:
    """Stands in for the study's steps, recording what it is given."""

    def __init__(self, monkeypatch):
        self.calls = []
        for name in ("ground_truth", "noisy_estimate", "relative_units", "unit_intervals",
                     "paired_interval", "interval_marks"):
            monkeypatch.setattr(pc, name, getattr(self, name))

    def ground_truth(self, n, speed):
        self.calls.append(("gt", n, speed))
        return "gt"

    def noisy_estimate(self, gt, noise, seed):
        self.calls.append(("est", gt, noise, seed))
        return f"est{seed}"

    def relative_units(self, gt, est, length):
        self.calls.append(("units", gt, est, length))
        rng = np.random.default_rng(len(self.calls))
        values = {"rot_deg": rng.normal(size=5), "trans_m": rng.normal(size=5)}
        return type("Units", (), {"anchor": np.arange(5), "end": np.arange(5) + 3,
                                  "values": values, "est": est})

    def unit_intervals(self, n, anchor, end, values, reps):
        self.calls.append(("intervals", n, reps))
        iv = type("Iv", (), {"low": -1.0, "high": 1.0, "n_independent": 5})
        return {"rot_deg": iv, "trans_m": iv}

    def paired_interval(self, n, anchor, end, a, b, reps):
        self.calls.append(("paired", n, reps))
        return type("D", (), {"excludes_zero": a[0] > b[0]})

    def interval_marks(self, stats):
        self.calls.append(("marks", [(s.value, s.ci, s.n_independent) for s in stats]))
        return [1, 2]


def test_paired_study_defaults_and_what_each_step_is_given(monkeypatch):
    spy = Spy(monkeypatch)
    rows = pc.paired_study(2, 30, "noise")
    assert spy.calls[0] == ("gt", 30, 5.0)
    ests = [c for c in spy.calls if c[0] == "est"]
    assert ests == [("est", "gt", "noise", 50_000), ("est", "gt", "noise", 50_001),
                    ("est", "gt", "noise", 50_002), ("est", "gt", "noise", 50_003)]
    units = [c[1:] for c in spy.calls if c[0] == "units"]
    assert units == [("gt", f"est{50_000 + 2 * k + j}", length) for k in range(2)
                     for length in (8.0, 24.0) for j in (0, 1)]
    assert {c[1:] for c in spy.calls if c[0] in ("intervals", "paired")} == {(30, REPS)}
    marks = [c[1] for c in spy.calls if c[0] == "marks"]
    assert len(marks) == 8 and all(len(m) == 2 for m in marks)
    for m in marks:
        assert [s[1:] for s in m] == [((-1.0, 1.0), 5), ((-1.0, 1.0), 5)]
    assert [r.figure for r in rows] == FIGURES
    assert all(r.marks_split == 2 and r.drives == 2 for r in rows)


def test_paired_study_passes_its_options_on(monkeypatch):
    spy = Spy(monkeypatch)
    pc.paired_study(1, 40, "noise", first_seed=7, lengths_m=(12.0,), reps=33, speed_mps=2.5)
    assert spy.calls[0] == ("gt", 40, 2.5)
    assert [c[3] for c in spy.calls if c[0] == "est"] == [7, 8]
    assert {c[3] for c in spy.calls if c[0] == "units"} == {12.0}
    assert {c[1:] for c in spy.calls if c[0] in ("intervals", "paired")} == {(40, 33)}


def test_paired_study_marks_use_the_mean_of_each_figure(monkeypatch):
    spy = Spy(monkeypatch)
    pc.paired_study(1, 40, "noise", lengths_m=(8.0,))
    # rebuild the spy's values: the generator seeded with the call count at each units call
    counts = [k + 1 for k, c in enumerate(spy.calls) if c[0] == "units"]
    values = [np.random.default_rng(n) for n in counts]
    values = [{"rot_deg": g.normal(size=5), "trans_m": g.normal(size=5)} for g in values]
    marks = [c[1] for c in spy.calls if c[0] == "marks"]
    for m, q in zip(marks, ("rot_deg", "trans_m"), strict=True):
        np.testing.assert_allclose([s[0] for s in m], [np.mean(v[q]) for v in values])


def test_paired_study_counts_the_paired_calls_per_figure(monkeypatch):
    spy = Spy(monkeypatch)
    rows = pc.paired_study(3, 40, "noise", lengths_m=(8.0,))
    calls = [c for c in spy.calls if c[0] == "units"]
    counts = [k + 1 for k, c in enumerate(spy.calls) if c[0] == "units"]
    gens = [np.random.default_rng(n) for n in counts]
    vals = [{"rot_deg": g.normal(size=5), "trans_m": g.normal(size=5)} for g in gens]
    assert len(calls) == 6
    want = [sum(vals[2 * k]["rot_deg"][0] > vals[2 * k + 1]["rot_deg"][0] for k in range(3)),
            sum(vals[2 * k]["trans_m"][0] > vals[2 * k + 1]["trans_m"][0] for k in range(3))]
    assert [r.paired for r in rows] == want


def test_paired_table_has_a_rate_pair_per_noise_model():
    rows = {"white": [pc.FalseAlarms("relative 8 m rotation", 200, 10, 20),
                      pc.FalseAlarms("relative 8 m translation", 200, 5, 0)],
            "correlated": [pc.FalseAlarms("relative 8 m rotation", 200, 3, 1),
                           pc.FalseAlarms("relative 8 m translation", 200, 200, 7)]}
    assert pc.paired_table(rows).split("\n") == [
        "| figure | paired interval, white | marks split, white | paired interval, correlated | "
        "marks split, correlated |",
        "|---|---|---|---|---|",
        "| relative 8 m rotation | 5.0 % | 10.0 % | 1.5 % | 0.5 % |",
        "| relative 8 m translation | 2.5 % | 0.0 % | 100.0 % | 3.5 % |"]


def run_main(monkeypatch, capsys, *args):
    seen = []

    def study(trials, frames, noise, first_seed, reps, speed_mps):
        seen.append((trials, frames, noise, first_seed, reps, speed_mps))
        return [pc.FalseAlarms("relative 8 m rotation", trials, 1, 2)]

    monkeypatch.setattr(pc, "paired_study", study)
    monkeypatch.setattr(sys, "argv", ["paired_coverage", *args])
    pc.main()
    return seen, capsys.readouterr().out.split("\n")


def test_main_defaults_run_both_noise_models(monkeypatch, capsys):
    seen, out = run_main(monkeypatch, capsys)
    assert seen == [(300, 240, NOISE_MODELS["white"], 50_000, REPS, 5.0),
                    (300, 240, NOISE_MODELS["correlated"], 50_000, REPS, 5.0)]
    assert out[0] == (f"300 pairs of equal methods on drives of 240 poses (120 m), noise seeds "
                      f"from 50000, {REPS} resamples")
    assert out[1].startswith("| figure | paired interval, white | marks split, white | "
                             "paired interval, correlated |")
    assert out[3] == "| relative 8 m rotation | 0.3 % | 0.7 % | 0.3 % | 0.7 % |"


def test_main_options_reach_the_study(monkeypatch, capsys):
    seen, out = run_main(monkeypatch, capsys, "--trials", "20", "--frames", "100", "--speed",
                         "2.5", "--first-seed", "9", "--noise", "correlated", "--reps", "50")
    assert seen == [(20, 100, NOISE_MODELS["correlated"], 9, 50, 2.5)]
    assert out[0] == ("20 pairs of equal methods on drives of 100 poses (25 m), noise seeds "
                      "from 9, 50 resamples")
    assert out[1] == "| figure | paired interval, correlated | marks split, correlated |"
    assert out[3] == "| relative 8 m rotation | 5.0 % | 10.0 % |"


def test_main_help_describes_the_study(monkeypatch, capsys):
    monkeypatch.setattr(sys, "argv", ["paired_coverage", "--help"])
    with pytest.raises(SystemExit):
        pc.main()
    out = " ".join(capsys.readouterr().out.split())
    # the description is the docstring's first paragraph only
    assert "Does the paired comparison hold its level?" in out and "Each drive" not in out
    for option, words in (("--trials TRIALS", "pairs of equal methods"),
                          ("--frames FRAMES", "poses per drive (10 Hz)"),
                          ("--speed SPEED", "driving speed [m/s]"),
                          ("--first-seed FIRST_SEED", "the first noise seed"),
                          ("--noise {white,correlated,both}", "--reps REPS"),
                          ("--reps REPS", "bootstrap resamples")):
        assert f"{option} {words} " in out + " ", (option, out)


def test_main_noise_both_is_a_choice(monkeypatch, capsys):
    seen, _ = run_main(monkeypatch, capsys, "--noise", "both", "--trials", "3")
    assert [s[2] for s in seen] == [NOISE_MODELS["white"], NOISE_MODELS["correlated"]]
