"""bench/report/tables/sweep.py, mutation review: the sweep table and each choice's sentence
written out by hand for small hand-made sweeps (every number worked out in the comments), the
tuning rule's arguments and defaults, the reference point, and the helpers' edges."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from bench.report.tables import sweep as tables_sweep
from bench.report.tables.sweep import (
    Choice,
    _choose,
    _criterion_values,
    _default,
    _default_index,
    _reference_index,
    _same,
    sweep_choices,
    sweep_markdown,
)
from bench.runs.sweep import write_sweep_index
from bench.runs.tuning_rule import Decision, Estimate, Verdict
from loaders.errors import DataError


def _metrics(root, rel, seq, seed, errors):
    """A finished run's metrics.json: errors = {length: (rot, trans, n)}."""
    d = root / rel
    d.mkdir(parents=True)
    (d / "metrics.json").write_text(json.dumps({
        "sequence": seq, "method": "doppler", "seed": seed,
        "relative_error": {f"{x:g}": {"rot_deg_mean": r, "trans_m_mean": t, "n": n}
                           for x, (r, t, n) in errors.items()}}))


#: point -> sequence -> {length: (rot, trans, n)}; the 16 m segments exist on "a" only
ERRORS = {1.0: {"a": {8: (1.0, 0.2, 5), 16: (9.0, 9.0, 3), 48: (3.0, 1.0, 2)},
                "b": {8: (2.0, 0.4, 5), 16: (0.0, 0.0, 0), 48: (5.0, 2.0, 2)}},
          2.0: {"a": {8: (0.5, 0.4, 5), 16: (9.0, 9.0, 3), 48: (4.0, 1.0, 2)},
                "b": {8: (1.5, 0.6, 5), 16: (0.0, 0.0, 0), 48: (4.0, 1.0, 2)}}}


def _plain_sweep(root, seed=True, criterion=None, default_differs="  radar: 2.0 \n"):
    points = []
    for value, by_seq in ERRORS.items():
        runs = []
        for seq, errors in by_seq.items():
            rel = f"{seq}/p{value:g}-{seed}"
            _metrics(root, rel, seq, seed, errors)
            runs.append({"sequence": seq, "seed": seed, "dir": rel})
        points.append({"label": f"doppler tau_spatial_m={value}",
                       "point": {"tau_spatial_m": value}, "runs": runs})
    criterion = criterion or {"error": "rotation", "lengths_m": [8.0, 48.0],
                              "tie_within": 0.01, "keep_default_within": 0.05}
    write_sweep_index(root, {
        "experiment": "s", "criterion": criterion, "default_differs": default_differs,
        "sweeps": [{"method": "doppler", "group": "doppler", "keys": ["tau_spatial_m"],
                    "defaults": {"a": {"tau_spatial_m": 2.0}, "b": {"tau_spatial_m": 2.0}},
                    "points": points}]})


def test_the_table_of_a_plain_sweep_written_out_by_hand(tmp_path):
    # means over a and b: tau 1: 8 m (1.5, 0.3), 48 m (4.0, 1.5); tau 2: 8 m (1.0, 0.5),
    # 48 m (4.0, 1.0); 16 m has segments on a only: no column. Rotation criterion over 8 and
    # 48 m: tau 1 (1.5 + 4) / 2 = 2.75, tau 2 (1 + 4) / 2 = 2.5: tau 2, the default
    _plain_sweep(tmp_path)
    assert sweep_markdown(tmp_path) == "\n".join([
        "### doppler: sweep of tau_spatial_m (with seed; mean over a, b)\n",
        "| Point | 8 m | 48 m | Criterion (rotation, 8, 48 m) |",
        "|---|---|---|---|",
        "| tau_spatial_m=1.0 | 1.500 / **0.300** | **4.000** / 1.500 | 2.7500 |",
        "| tau_spatial_m=2.0 (default) | **1.000** / 0.500 | **4.000** / **1.000** "
        "| **2.5000 chosen** |",
        "",
        "Each cell: mean rotation [deg] / translation [m] relative error per segment length, "
        "averaged over the sweep's sequences; best per length in bold.",
        "",
        "chosen (with seed): doppler tau_spatial_m=2.0 (mean rotation error at 8, 48 m: 2.5 deg"
        "; points within 1 % of the best tie, the first listed wins; the default stays unless "
        "beaten by more than 5 %); default tau_spatial_m=2.0: agrees",
        "",
        "Why the default differs: radar: 2.0",
        ""])


@pytest.mark.parametrize("seed, text", [(False, "no seed"), (None, "no initial guess")])
def test_the_heading_names_the_seed_option(tmp_path, seed, text):
    _plain_sweep(tmp_path, seed=seed, default_differs=None)
    lines = sweep_markdown(tmp_path).splitlines()
    assert lines[0] == f"### doppler: sweep of tau_spatial_m ({text}; mean over a, b)"
    chosen = next(line for line in lines if line.startswith("chosen"))
    assert chosen.startswith({False: "chosen (no seed): ", None: "chosen: "}[seed])
    assert not any(line.startswith("Why") for line in lines)


def test_the_translation_criterion_and_its_choice(tmp_path):
    # translation over 8 and 48 m: tau 1 (0.3 + 1.5) / 2 = 0.9, tau 2 (0.5 + 1) / 2 = 0.75
    _plain_sweep(tmp_path, criterion={"error": "translation", "lengths_m": [8.0, 48.0]})
    (c,) = sweep_choices(tmp_path)
    assert (c.method, c.group, c.seed, c.point, c.missing) == (
        "doppler", "doppler", True, {"tau_spatial_m": 2.0}, [])
    assert c.value == pytest.approx(0.75)
    lines = sweep_markdown(tmp_path).splitlines()
    assert lines[4] == "| tau_spatial_m=1.0 | 1.500 / **0.300** | **4.000** / 1.500 | 0.9000 |"


def test_a_run_missing_leaves_its_row_empty_and_is_named(tmp_path):
    _plain_sweep(tmp_path, criterion={"error": "rotation", "lengths_m": [8.0, 48.0]})
    (tmp_path / "b/p2-True/metrics.json").unlink()
    # tau 2 has no finished run on b: tau 1 (2.75) is the only scored point
    (c,) = sweep_choices(tmp_path)
    assert c.point == {"tau_spatial_m": 1.0} and c.value == pytest.approx(2.75)
    assert c.missing == ["doppler tau_spatial_m=2.0"]
    lines = sweep_markdown(tmp_path).splitlines()
    assert lines[4] == "| tau_spatial_m=1.0 | **1.500** / **0.300** | **4.000** / **1.500** " \
                       "| **2.7500 chosen** |"
    assert lines[5] == "| tau_spatial_m=2.0 (default) | - | - | failed or not run |"
    assert lines[-3].endswith("; default tau_spatial_m=2.0: DIFFERS; not finished: doppler "
                              "tau_spatial_m=2.0")


# --- a choice's sentence ------------------------------------------------------------------

CRITERION = {"error": "both", "lengths_m": [8.0, 16.0]}


def test_the_sentence_of_a_choice_by_criterion():
    c = Choice("m", "g", False, {"a": 1.0, "b": "x"}, 0.123456, {"a": 1.0, "b": "y"},
               ["m a=2.0", "m a=3.0"])
    assert c.describe(CRITERION) == (
        'chosen (no seed): m a=1.0 b="x" (mean rotation and translation error at 8, 16 m: '
        '0.1235 (relative to the points\' mean)); default a=1.0 b="y": DIFFERS; not finished: '
        "m a=2.0, m a=3.0")
    c = Choice("m", "g", None, {"a": 1}, 2.0, None, [])
    assert c.describe({"error": "translation", "lengths_m": [48], "tie_within": 0.025}) == (
        "chosen: m a=1 (mean translation error at 48 m: 2 m; points within 2.5 % of the best "
        "tie, the first listed wins); the default differs by sequence")
    c = Choice("m", "g", True, None, None, {"a": 1}, ["m a=1"])
    assert c.describe(CRITERION) == "g: no point has every run finished"


def test_the_sentence_of_a_choice_by_the_tuning_rule():
    rule = dict(CRITERION, folds=[])
    d = SimpleNamespace(text="keeps the reference")
    c = Choice("m", "g", True, {"a": 2.0}, 0.9, {"a": 2.0}, [], d)
    assert c.describe(rule) == ("chosen (with seed): m a=2.0 (the tuning rule of "
                                "configs/splits.yaml: keeps the reference); default a=2.0: "
                                "agrees")
    c = Choice("m", "g", False, None, None, {"a": 2.0}, ["m a=3.0"], d)
    assert c.describe(rule) == ("chosen (no seed): undecided (the tuning rule of "
                                "configs/splits.yaml: keeps the reference); default a=2.0: "
                                "DIFFERS; not finished: m a=3.0")
    c = Choice("m", "g", None, {"a": 2.0}, None, None, [], d)
    assert c.describe(rule).startswith("chosen: m a=2.0 (the tuning rule")


def test_a_choice_agrees_only_with_a_default_at_every_key():
    assert Choice("m", "g", None, {"a": 1.0, "b": 2}, 1, {"a": 1.0 + 1e-12, "b": 2}, []).agrees
    assert not Choice("m", "g", None, {"a": 1.0, "b": 2}, 1, {"a": 1.0}, []).agrees
    assert not Choice("m", "g", None, None, None, {"a": 1.0}, []).agrees
    assert not Choice("m", "g", None, {"a": 1.0}, 1, None, []).agrees


# --- the tuning rule in the table -------------------------------------------------------------

def _rule_sweep(root, monkeypatch, criterion, chosen=1):
    """Three points of gate_m on sequences A and B (seed True), each run's 8 m errors:
    gate 1: (1.0, 0.1), gate 2: (0.8, 0.2), gate 3: (0.9, 0.3); the rule's decision made up
    (``decide`` replaced), its arguments kept in the returned list."""
    points = []
    for value in (1.0, 2.0, 3.0):
        runs = [{"sequence": s, "seed": True, "dir": f"{s}/g{value:g}"} for s in "AB"]
        points.append({"label": f"m gate_m={value}", "point": {"gate_m": value}, "runs": runs})
    write_sweep_index(root, {
        "experiment": "t", "criterion": criterion, "default_differs": None,
        "sweeps": [{"method": "m", "group": "m", "keys": ["gate_m"],
                    "defaults": {"A": {"gate_m": 2.0}, "B": {"gate_m": 2.0}},
                    "points": points}]})
    cells = {1.0: (1.0, 0.1), 2.0: (0.8, 0.2), 3.0: (0.9, 0.3)}

    def read_run(path):
        seq, name = path.relative_to(root).parts
        rot, trans = cells[float(name[1:])]
        rel = SimpleNamespace(n=4, length_m=8, rot_deg_mean=rot, trans_m_mean=trans)
        return SimpleNamespace(gt=f"gt {seq} {name}", est=f"est {seq} {name}",
                               result=SimpleNamespace(relative_error=[rel]))

    tune, val = "fold 1 tune (A)", "fold 1 val (B)"
    verdicts = [
        Verdict({"gate_m": 1.0}, {}, 1.0, False, "the reference"),
        Verdict({"gate_m": 2.0}, {tune: Estimate(0.8, 0.7, 0.9, 0.9),
                                  val: Estimate(0.85, 0.75, 0.95, 0.9)}, 0.825, True,
                "qualifies"),
        Verdict({"gate_m": 3.0}, {tune: Estimate(1.2, 1.1, 1.3, 0.9)}, None, False,
                "not finished")]
    asked = []

    def decide(*args, **kwargs):
        asked.append((args, kwargs))
        return Decision(0, chosen, verdicts, "replaces the reference")

    monkeypatch.setattr(tables_sweep, "read_run", read_run)
    monkeypatch.setattr(tables_sweep, "run_errors",
                        lambda gt, est, lengths: (gt, est, tuple(lengths)))
    monkeypatch.setattr(tables_sweep, "decide", decide)
    return asked


RULE = {"lengths_m": [8.0, 16.0], "folds": [{"tuning": ["A"], "validation": ["B"]}],
        "domain": ["S"], "reference": {"gate_m": 1.0}, "level": 0.9, "reps": 50,
        "min_gain": 0.02}


def test_the_rule_s_table_written_out_by_hand(tmp_path, monkeypatch):
    asked = _rule_sweep(tmp_path, monkeypatch, RULE)
    assert sweep_markdown(tmp_path) == "\n".join([
        "### m: sweep of gate_m (with seed; mean over A, B)\n",
        "| Point | 8 m | C fold 1 tune (A) | C fold 1 val (B) | C all folds | Verdict |",
        "|---|---|---|---|---|---|",
        "| gate_m=1.0 (reference) | 1.000 / **0.100** | - | - | 1.000 | the reference |",
        "| gate_m=2.0 (default) | **0.800** / 0.200 | 0.800 [0.700, 0.900] | "
        "0.850 [0.750, 0.950] | 0.825 | **chosen**: qualifies |",
        "| gate_m=3.0 | 0.900 / 0.300 | 1.200 [1.100, 1.300] | - | - | not finished |",
        "",
        "Each cell: mean rotation [deg] / translation [m] relative error per segment length, "
        "averaged over the sweep's sequences; best per length in bold.",
        "C: mean over 8, 16 m and both errors of the error divided by the reference point's "
        "(1 = the reference, lower is better), 90 % block-bootstrap interval in brackets "
        "(configs/splits.yaml).",
        "",
        "chosen (with seed): m gate_m=2.0 (the tuning rule of configs/splits.yaml: replaces "
        "the reference); default gate_m=2.0: agrees; not finished: m gate_m=3.0",
        ""])
    assert len(asked) == 1  # one decision per sweep and seed option, shared with the choices


def test_the_rule_gets_the_criterion_s_settings(tmp_path, monkeypatch):
    asked = _rule_sweep(tmp_path, monkeypatch, RULE)
    (c,) = sweep_choices(tmp_path)
    (args, kwargs), = asked
    points, errors, reference, folds, domain, lengths, level, reps = args
    assert points == [{"gate_m": 1.0}, {"gate_m": 2.0}, {"gate_m": 3.0}]
    assert errors == [{s: (f"gt {s} g{v:g}", f"est {s} g{v:g}", (8.0, 16.0)) for s in "AB"}
                      for v in (1.0, 2.0, 3.0)]
    assert (reference, folds, domain, lengths, level, reps, kwargs) == (
        0, [(["A"], ["B"])], ["S"], [8.0, 16.0], 0.9, 50, {"min_gain": 0.02})
    assert (c.point, c.value, c.missing, c.seed, c.method) == (
        {"gate_m": 2.0}, 0.825, ["m gate_m=3.0"], True, "m")


def test_the_rule_s_defaults_and_the_method_s_default_as_reference(tmp_path, monkeypatch):
    bare = {"lengths_m": [8.0], "folds": [{"tuning": ["A"], "validation": ["B"]}]}
    asked = _rule_sweep(tmp_path, monkeypatch, bare, chosen=None)
    (c,) = sweep_choices(tmp_path)
    (args, kwargs), = asked
    # the reference: the default gate 2.0 (index 1); 95 %, 1000 draws, no least gain
    assert (args[2], args[4], args[6], args[7], kwargs) == (1, [], 0.95, 1000,
                                                            {"min_gain": 0.0})
    assert (c.point, c.value) == (None, None)
    assert "better), 95 % block-bootstrap" in sweep_markdown(tmp_path)


def test_a_missing_run_leaves_the_rule_a_missing_point(tmp_path, monkeypatch):
    asked = _rule_sweep(tmp_path, monkeypatch, RULE)
    real = tables_sweep.read_run
    monkeypatch.setattr(tables_sweep, "read_run",
                        lambda path: None if path.name == "g2" and path.parent.name == "B"
                        else real(path))
    sweep_choices(tmp_path)
    errors = asked[0][0][1]
    assert errors[1] is None and errors[0] is not None and errors[2] is not None


# --- the reference point, the default, the choice ---------------------------------------------

SWEEP = {"group": "g", "keys": ["a", "b"],
         "defaults": {"s": {"a": 1.0, "b": 2.0}, "t": {"a": 1.0, "b": 2.0}},
         "points": [{"point": {"a": a, "b": b}} for a in (1.0, 3.0) for b in (2.0, 4.0)]}


def test_the_reference_is_the_criterion_s_else_the_default_per_key():
    assert _reference_index(SWEEP, {}) == 0
    assert _reference_index(SWEEP, {"reference": {"b": 4.0}}) == 1
    assert _reference_index(SWEEP, {"reference": {"a": 3.0, "b": 4.0}}) == 3
    differs = dict(SWEEP, defaults={"s": {"a": 1.0, "b": 2.0}, "t": {"a": 3.0, "b": 2.0}})
    assert _reference_index(differs, {"reference": {"a": 3.0, "b": 2.0}}) == 2
    with pytest.raises(DataError) as err:
        _reference_index(differs, {"reference": {"a": 3.0}})
    assert str(err.value) == ("sweep g: its reference point a=3.0 b=null (the criterion's "
                              "reference, else the method's default) is not a point of the grid")
    with pytest.raises(DataError, match="reference point a=5.0 b=2.0 "):
        _reference_index(SWEEP, {"reference": {"a": 5.0}})


def test_the_default_is_the_one_every_sequence_shares():
    assert _default(SWEEP) == {"a": 1.0, "b": 2.0}
    assert _default(dict(SWEEP, defaults={"s": {"a": 1.0}, "t": {"a": 2.0}})) is None
    assert _default(dict(SWEEP, defaults={})) is None
    assert _default_index(SWEEP) == 0
    assert _default_index(dict(SWEEP, defaults={"s": {"a": 9.0, "b": 2.0}})) is None
    assert _default_index(dict(SWEEP, defaults={})) is None


def test_the_choice_takes_the_first_near_best_and_keeps_the_default_within_its_margin():
    assert _choose([None, None], {}) is None
    assert _choose([2.0, 1.0, 1.005], {}) == 1  # no tie_within: the lowest only
    assert _choose([1.005, 1.0], {}) == 1
    assert _choose([1.005, 1.0], {"tie_within": 0.01}) == 0
    assert _choose([None, 1.0, 1.04], {"keep_default_within": 0.05}, default=2) == 2
    assert _choose([None, 1.0, 1.04], {}, default=2) == 1  # no keep_default_within: the best
    assert _choose([None, 1.0, 1.06], {"keep_default_within": 0.05}, default=2) == 1
    assert _choose([1.0, 2.0], {"keep_default_within": 1.0}, default=1) == 1  # 1 * 2 >= 2
    assert _choose([1.0, None], {"keep_default_within": 0.5}, default=1) == 0


def test_criterion_values_by_hand():
    rows = [{8.0: (1.0, 0.2), 48.0: (3.0, 1.0)}, {8.0: (2.0, 0.4)}, None,
            {8.0: (3.0, 0.6), 48.0: (5.0, 3.0)}]
    rot = _criterion_values(rows, {"error": "rotation", "lengths_m": [8, 48]})
    assert rot == [pytest.approx(2.0), None, None, pytest.approx(4.0)]
    trans = _criterion_values(rows, {"error": "translation", "lengths_m": [8, 48]})
    assert trans == [pytest.approx(0.6), None, None, pytest.approx(1.8)]
    # both: means over the complete points: rot 8: 2, rot 48: 4, trans 8: 0.4, trans 48: 2
    both = _criterion_values(rows, {"error": "both", "lengths_m": [8, 48]})
    assert both == [pytest.approx((0.5 + 0.75 + 0.5 + 0.5) / 4), None, None,
                    pytest.approx((1.5 + 1.25 + 1.5 + 1.5) / 4)]
    assert _criterion_values([None, {8.0: (1.0, 1.0)}],
                             {"error": "both", "lengths_m": [48]}) == [None, None]


def test_same_is_equality_within_a_relative_1e_9():
    assert _same(1.0, 1.0 + 5e-10) and not _same(1.0, 1.0 + 2e-9)
    assert _same(0.0, 5e-10) and not _same(0.0, 2e-9)  # at least 1e-9 absolute
    assert _same(0.0, 1e-9) and _same(1e-9, 0.0)  # within: up to and including
    assert _same(1e6, 1e6 + 5e-4) and not _same(1e6, 1e6 + 2e-3)  # relative to the larger
    assert _same(1e6 + 5e-4, 1e6) and not _same(1e6 + 2e-3, 1e6)
    assert _same(2, 2) and not _same(2, 3)
    assert _same("x", "x") and not _same("x", "y") and not _same(1.0, None)
    assert _same([0.4, 2.6], [0.4, 2.6])


def test_same_is_relative_to_the_larger_whichever_side_it_is_on():
    small, large = 2165995.5381073398, 2165995.5402733353  # a pair found by search:
    assert 1e-9 * small < large - small <= 1e-9 * large  # within 1e-9 of the larger only
    assert _same(small, large) and _same(large, small)


# --- second review round ----------------------------------------------------------------------

def _two_key_sweep(root, criterion, drop=()):
    """A plain sweep over two keys (a, b) on sequences s and t: point (1, x) errors 8 m (1, 0.1)
    and 48 m (2, 0.2), point (2, x) 8 m (3, 0.3) and 48 m (4, 0.4); ``drop``: (point, seq,
    length) segments that do not exist there."""
    points = []
    for i, (a, b) in enumerate(((1, "x"), (2, "x"))):
        runs = []
        for seq in "st":
            rel = f"{seq}/{i}"
            errors = {8: (1.0 + 2 * i, 0.1 + 0.2 * i, 3), 48: (2.0 + 2 * i, 0.2 + 0.2 * i, 1)}
            for x in [x for p, q, x in drop if (p, q) == (i, seq)]:
                errors[x] = (0.0, 0.0, 0)
            _metrics(root, rel, seq, None, errors)
            runs.append({"sequence": seq, "seed": None, "dir": rel})
        points.append({"label": f"m a={a} b={b}", "point": {"a": a, "b": b}, "runs": runs})
    write_sweep_index(root, {
        "experiment": "s", "criterion": criterion, "default_differs": None,
        "sweeps": [{"method": "m", "group": "g", "keys": ["a", "b"],
                    "defaults": {"s": {"a": 1, "b": "x"}, "t": {"a": 2, "b": "x"}},
                    "points": points}]})


def test_a_sweep_over_two_keys_names_both_and_a_point_without_a_criterion_length(tmp_path):
    # point (2, x) has no 48 m segments on t: 48 m is its "-", its criterion too; the 48 m
    # column stays (point (1, x) has it on both)
    _two_key_sweep(tmp_path, {"error": "rotation", "lengths_m": [8, 48]}, drop=[(1, "t", 48)])
    assert sweep_markdown(tmp_path).splitlines()[:5] == [
        "### g: sweep of a, b (no initial guess; mean over s, t)",
        "",
        "| Point | 8 m | 48 m | Criterion (rotation, 8, 48 m) |",
        "|---|---|---|---|",
        '| a=1 b="x" | **1.000** / **0.100** | **2.000** / **0.200** | **1.5000 chosen** |']
    assert sweep_markdown(tmp_path).splitlines()[5] == \
        '| a=2 b="x" | 3.000 / 0.300 | - | - |'


def test_no_point_with_every_run_finished_is_no_choice(tmp_path):
    _two_key_sweep(tmp_path, {"error": "rotation", "lengths_m": [8, 48]})
    for seq in "st":
        (tmp_path / seq / "1" / "metrics.json").unlink()
    (tmp_path / "s" / "0" / "metrics.json").unlink()
    (c,) = sweep_choices(tmp_path)
    assert (c.point, c.value, c.missing) == (None, None, ["m a=1 b=x", "m a=2 b=x"])
    assert sweep_markdown(tmp_path).endswith("\n\ng: no point has every run finished\n")


def test_the_rule_decides_each_seed_option(tmp_path, monkeypatch):
    asked = _rule_sweep(tmp_path, monkeypatch, RULE)
    index = json.loads((tmp_path / "sweeps.json").read_text())
    for p in index["sweeps"][0]["points"]:  # each run again without seed
        p["runs"] += [dict(r, seed=False) for r in p["runs"]]
    write_sweep_index(tmp_path, index)
    choices = sweep_choices(tmp_path)
    assert [(c.seed, c.point) for c in choices] == [(True, {"gate_m": 2.0}),
                                                   (False, {"gate_m": 2.0})]
    assert len(asked) == 2


def test_the_rule_s_sentence_names_every_key_of_the_point():
    c = Choice("m", "g", None, {"a": 2.0, "b": "x"}, 0.9, None, [],
               SimpleNamespace(text="keeps the reference"))
    assert c.describe({"folds": []}) == (
        'chosen: m a=2.0 b="x" (the tuning rule of configs/splits.yaml: keeps the reference)'
        "; the default differs by sequence")
