"""``bench.studies.independent``'s driver in-process, its layers below scripted: which runs
give each method's errors, the plugin's registration, the decisions table, the written
comparison (Markdown and JSON), one experiment step (runs, tables, sweep index), the reference
sweeps read back with their decisions, and ``main``'s steps and exit codes."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench.runs.tuning_rule import Decision
from bench.studies import independent
from methods import registry
from methods.registry import Seed


def _rel(*rows):
    return [SimpleNamespace(length_m=x, n=n, rot_deg_mean=r, trans_m_mean=t)
            for x, n, r, t in rows]


def _record(method, sequence="A", label=None, seed=Seed.WITH, rel=()):
    return SimpleNamespace(method=method, sequence=sequence, result=SimpleNamespace(
        label=label, seed=seed, relative_error=_rel(*rel)))


# errors_by_method -----------------------------------------------------------------------------

def test_errors_by_method_one_unlabelled_seeded_run_each(monkeypatch, tmp_path):
    from bench.runs import folders

    records = [
        _record("vgicp", sequence="B", rel=[(8, 5, 3.0, 4.0)]),
        _record("gicp", rel=[(8, 5, 1.0, 2.0), (16, 5, 9.0, 9.0), (48, 0, 9.0, 9.0)]),
        _record("gicp", label="variant", rel=[(8, 5, 7.0, 7.0)]),
        _record("dicp", seed=Seed.WITHOUT, rel=[(8, 5, 7.0, 7.0)]),
        _record("doppler", seed=Seed.NONE, rel=[(8.0, 3, 0.5, 0.25), (48.0, 4, 1.5, 2.5)])]
    seen = []
    monkeypatch.setattr(folders, "load_runs", lambda d: seen.append(d) or iter(records))
    # lengths 8 and 48 only, and only those with segments; seed WITHOUT and labels left out
    assert independent.errors_by_method(str(tmp_path), sequence="A") == {
        "gicp": {8.0: (1.0, 2.0)}, "doppler": {8.0: (0.5, 0.25), 48.0: (1.5, 2.5)}}
    assert seen == [tmp_path]
    everywhere = independent.errors_by_method(tmp_path, lengths_m=(8.0,))
    assert everywhere == {"vgicp": {8.0: (3.0, 4.0)}, "gicp": {8.0: (1.0, 2.0)},
                          "doppler": {8.0: (0.5, 0.25)}}
    records.append(_record("gicp", rel=[(8, 5, 1.0, 1.0)]))
    with pytest.raises(ValueError, match=f"^{tmp_path}: two runs of gicp$"):
        independent.errors_by_method(tmp_path)


# the plugin -----------------------------------------------------------------------------------

def test_with_plugin_appends_the_references_once(monkeypatch):
    from bench.studies import independent_methods as plugin

    methods = dict(registry.METHODS)
    kept = object()
    first = plugin.METHODS[0].name
    methods[first] = kept
    monkeypatch.setattr(registry, "METHODS", methods)
    monkeypatch.setenv(registry.PLUGINS_ENV, " other.mod , ,")
    independent._with_plugin()
    import os

    assert os.environ[registry.PLUGINS_ENV] == "other.mod,bench.studies.independent_methods"
    independent._with_plugin()
    assert os.environ[registry.PLUGINS_ENV] == "other.mod,bench.studies.independent_methods"
    assert methods[first] is kept  # an entry already there stays
    for cls in plugin.METHODS[1:]:
        assert methods[cls.name] is cls
    monkeypatch.delenv(registry.PLUGINS_ENV)
    independent._with_plugin()
    assert os.environ[registry.PLUGINS_ENV] == "bench.studies.independent_methods"


# tables and files -----------------------------------------------------------------------------

def test_decisions_markdown_one_line_per_decision():
    t = independent.Tuned("ref-x", [{"gate": 1.0}, {"gate": 3.0}], [{}, {}], {
        independent.RULE: Decision(0, 1, [], "gate 3.0 gains 5 %"),
        "A": Decision(0, None, [], "EXTEND THE GRID", extend=True),
        "B": Decision(0, None, [], "a run is missing")})
    assert independent.decisions_markdown({"ref-x": t}) == (
        "| Reference | Decision | Setting | Why |\n|---|---|---|---|\n"
        "| `ref-x` | rule (both folds) | gate=3.0 | gate 3.0 gains 5 % |\n"
        "| `ref-x` | tuned on A alone | gate=1.0 | EXTEND THE GRID |\n"
        "| `ref-x` | tuned on B alone | - | a run is missing |\n")


def _rows():
    b = independent.Baseline("ours-x", "ref-x", "a test reference")
    c = independent.Baseline("ours-y", "ref-y", "another")
    errors = {"ours-x": {8.0: (1.0, 2.0), 48.0: (3.0, 4.0)},
              "ref-x": {8.0: (2.0, 2.0), 48.0: (3.0, 5.0)}, "ours-y": {8.0: (1.0, 1.0)}}
    return independent.compare(errors, [b, c], half="A", tuned_on="B",
                               settings={"ref-x": {"gate": 2.0}})


def test_write_outputs_markdown_and_json(tmp_path):
    rows = _rows()
    text = independent.write_outputs(rows, tmp_path / "out", "DECISIONS\n")
    assert text == independent.table_markdown(rows) + (
        "\nThe references' settings (the tuning rule of configs/splits.yaml, "
        "independent-real-tuning.yaml):\n\nDECISIONS\n")
    assert (tmp_path / "out" / "comparison.md").read_text() == text
    raw = (tmp_path / "out" / "comparison.json").read_text()
    assert raw.endswith("\n")
    x, y = json.loads(raw)
    # ours / reference: 8 m 1/2 and 2/2, 48 m 3/3 and 4/5; worst 1.0 <= 1.15
    assert x == {"method": "ours-x", "reference": "ref-x", "what": "a test reference",
                 "half": "A", "tuned_on": "B", "setting": {"gate": 2.0},
                 "ours": {"8": [1.0, 2.0], "48": [3.0, 4.0]},
                 "reference_errors": {"8": [2.0, 2.0], "48": [3.0, 5.0]},
                 "ratios": {"8": [0.5, 1.0], "48": [1.0, 0.8]}, "worst": 1.0, "limit": 1.15,
                 "passed": True}
    assert y["ours"] == {"8": [1.0, 1.0], "48": None} and y["reference_errors"] is None
    assert y["ratios"] == {"8": [None, None], "48": [None, None]}
    assert (y["worst"], y["passed"], y["setting"]) == (None, False, None)


def test_write_outputs_without_decisions_is_the_table(tmp_path):
    rows = _rows()
    assert independent.write_outputs(rows, tmp_path, "") == independent.table_markdown(rows)


# one experiment step --------------------------------------------------------------------------

def _experiment_layers(monkeypatch, tmp_path, statuses, sweeps):
    from bench.report.tables import paper as paper_tables
    from bench.report.tables import sweep as sweep_tables
    from bench.runs import experiment, job, plan, progress
    from bench.runs import sweep as sweep_mod

    calls, consoles = _Calls(), []
    exp = SimpleNamespace(out_dir=tmp_path / "exp", jobs=3)
    monkeypatch.setattr(experiment, "load_experiment",
                        lambda p: calls.append(("load", p)) or exp)
    monkeypatch.setattr(plan, "jobs_for_experiment",
                        lambda e, console: calls.append(("jobs", e)) or consoles.append(console)
                        or ["j1", "j2"])
    monkeypatch.setattr(plan, "plan", lambda jobs: calls.append(("plan", jobs)) or ["p1", "p2"])
    monkeypatch.setattr(sweep_mod, "sweep_index",
                        lambda e, jobs: calls.append(("index", e, jobs)) or sweeps)
    monkeypatch.setattr(sweep_mod, "write_sweep_index",
                        lambda d, s: calls.append(("write_index", d, s)))
    monkeypatch.setattr(progress, "run_jobs", lambda *a: calls.append(("run", *a)) or [
        SimpleNamespace(status=s) for s in statuses])
    monkeypatch.setattr(job, "summarize", lambda outcomes: f"{len(outcomes)} jobs summarized")
    monkeypatch.setattr(paper_tables, "write_tables",
                        lambda d: calls.append(("tables", d)) or {"md": "THE TABLE"})
    monkeypatch.setattr(sweep_tables, "sweep_markdown",
                        lambda d: calls.append(("sweep_md", d)) or "THE SWEEP")
    calls.consoles = consoles
    return calls, exp


class _Calls(list):
    """A list of calls that also holds the consoles handed down."""


def _console():
    from rich.console import Console

    return Console(record=True, width=300, color_system=None)


@pytest.mark.parametrize(("statuses", "code"), [(["done", "skipped"], 0), (["done", "failed"], 1)])
def test_run_experiment_runs_writes_tables_and_the_sweep(monkeypatch, tmp_path, statuses, code):
    calls, exp = _experiment_layers(monkeypatch, tmp_path, statuses, {"sweeps": []})
    console = _console()
    assert independent.run_experiment(console, Path("x.yaml"), None, True, "local") == code
    assert calls.consoles == [console]
    run = next(c for c in calls if c[0] == "run")
    assert run == ("run", ["p1", "p2"], console, 3, True, "local", None, None)
    assert calls[:4] == [("load", Path("x.yaml")), ("jobs", exp), ("plan", ["j1", "j2"]),
                         ("index", exp, ["p1", "p2"])]
    assert ("tables", exp.out_dir) in calls
    assert ("write_index", exp.out_dir, {"sweeps": []}) in calls
    assert (exp.out_dir / "sweep.md").read_text() == "THE SWEEP"
    text = console.export_text()
    assert "2 jobs summarized" in text and "THE TABLE" in text and "THE SWEEP" in text


def test_run_experiment_jobs_given_and_nothing_finished(monkeypatch, tmp_path):
    calls, exp = _experiment_layers(monkeypatch, tmp_path, ["failed", "failed"], None)
    assert independent.run_experiment(_console(), Path("x.yaml"), 7, False, "process") == 1
    assert ("run", ["p1", "p2"], calls[-1][2], 7, False, "process", None, None) == calls[-1]
    assert not any(c[0] in ("tables", "write_index", "sweep_md") for c in calls)


def test_run_experiment_without_a_sweep_writes_no_sweep_files(monkeypatch, tmp_path):
    calls, exp = _experiment_layers(monkeypatch, tmp_path, ["done"], None)
    assert independent.run_experiment(_console(), Path("x.yaml"), None, False, "dask") == 0
    assert ("tables", exp.out_dir) in calls
    assert not any(c[0] in ("write_index", "sweep_md") for c in calls)
    assert not (exp.out_dir / "sweep.md").exists()


@pytest.mark.parametrize("sweeps", [{"sweeps": [1]}, None])
def test_index_experiment_writes_the_sweep_index_only(monkeypatch, tmp_path, sweeps):
    calls, exp = _experiment_layers(monkeypatch, tmp_path, [], sweeps)
    console = _console()
    independent.index_experiment(console, Path("y.yaml"))
    assert calls.consoles == [console]
    expected = [("load", Path("y.yaml")), ("jobs", exp), ("plan", ["j1", "j2"]),
                ("index", exp, ["p1", "p2"])]
    if sweeps is not None:
        expected.append(("write_index", exp.out_dir, sweeps))
    assert calls == expected


# the reference sweeps -------------------------------------------------------------------------

def _sweep_index(criterion):
    def run(seq, d, seed=True):
        return {"sequence": seq, "dir": d, "seed": seed}

    return {"criterion": criterion, "sweeps": [
        {"method": "ref-x", "points": [
            {"point": {"gate": 1.0}, "runs": [run("A", "x1A"), run("B", "x1B"), run("S", "x1S"),
                                              run("A", "x1A-noseed", False)]},
            {"point": {"gate": 3.0}, "runs": [run("A", "x3A"), run("B", "x3B")]},
            {"point": {"gate": 5.0}, "runs": [run("A", "x5A"), run("B", "missing")]}]}]}


CRITERION = {"lengths_m": [8, 48], "folds": [{"tuning": ["A"], "validation": ["B"]},
                                             {"tuning": ["B"], "validation": ["A"]}],
             "domain": ["S"]}


def test_tuned_references_read_each_points_runs_and_decide(monkeypatch, tmp_path):
    from bench.report.tables import sweep as sweep_tables
    from bench.runs import folders, tuning_rule
    from bench.runs import sweep as sweep_mod

    index = _sweep_index(CRITERION)
    monkeypatch.setattr(sweep_mod, "read_sweep_index", lambda d: (d, index)[1] if d == tmp_path
                        else pytest.fail(f"index of {d}"))
    monkeypatch.setattr(folders, "read_run", lambda d: None if d.name == "missing" else
                        SimpleNamespace(gt=f"gt-{d.name}", est=f"est-{d.name}"))
    monkeypatch.setattr(tuning_rule, "run_errors", lambda gt, est, lengths: (gt, est, lengths))
    monkeypatch.setattr(sweep_tables, "_reference_index", lambda sweep, crit: 0 if (
        sweep is index["sweeps"][0] and crit == CRITERION) else pytest.fail("reference index"))
    seen = []
    monkeypatch.setattr(independent, "half_choices", lambda points, errors, ref, crit: seen.append(
        (points, errors, ref, crit)) or {"rule": Decision(0, 1, [], "why")})
    tuned = independent.tuned_references(tmp_path)
    (t,) = tuned.values()
    assert list(tuned) == ["ref-x"] and t.method == "ref-x"
    assert t.points == [{"gate": 1.0}, {"gate": 3.0}, {"gate": 5.0}]
    assert t.runs == [{"A": tmp_path / "x1A", "B": tmp_path / "x1B", "S": tmp_path / "x1S"},
                      {"A": tmp_path / "x3A", "B": tmp_path / "x3B"},
                      {"A": tmp_path / "x5A", "B": tmp_path / "missing"}]
    ((points, errors, ref, crit),) = seen
    assert points == t.points and ref == 0 and crit == CRITERION
    lengths = [8.0, 48.0]
    assert errors[0] == {n: (f"gt-x1{n}", f"est-x1{n}", lengths) for n in "ABS"}
    assert errors[1] == {n: (f"gt-x3{n}", f"est-x3{n}", lengths) for n in "AB"}
    assert errors[2] is None  # a run on a fold's half missing
    assert all(isinstance(x, float) for x in errors[0]["A"][2])
    assert t.decisions["rule"].text == "why"


@pytest.mark.parametrize("criterion", [None, {}, {"lengths_m": [8], "folds": None}])
def test_tuned_references_need_the_rule_stated(monkeypatch, tmp_path, criterion):
    from bench.runs import sweep as sweep_mod

    monkeypatch.setattr(sweep_mod, "read_sweep_index", lambda d: _sweep_index(criterion))
    with pytest.raises(ValueError, match="the sweep does not state the tuning rule"):
        independent.tuned_references(tmp_path)


def test_run_dir_and_setting_of_a_tuned_sweep(tmp_path):
    t = independent.Tuned("ref-x", [{"gate": 1.0, "k": 2}, {"gate": 3.0, "k": 2}],
                          [{"A": tmp_path / "a1"}, {"A": tmp_path / "a3", "B": tmp_path / "b3"}],
                          {"rule": Decision(0, 1, [], "")})
    assert t.run_dir({"gate": 3.0, "k": 2}, "A") == tmp_path / "a3"
    assert t.run_dir({"gate": 3.0, "k": 2}, "C") is None
    assert t.run_dir({"gate": 4.0, "k": 2}, "A") is None
    assert t.setting("rule") == {"gate": 3.0, "k": 2}


# main -----------------------------------------------------------------------------------------

#: the table main prints: as it is (no markup: "[deg]" stays; no wrapping of a long line)
TEXT = "rotation [deg] / translation [m] " + "x" * 500


def _main_layers(monkeypatch, tmp_path, codes=(0, 0), stale=(), passed=(True, True)):
    from bench.runs import experiment

    calls = []
    folds = [SimpleNamespace(tuning=["A"]), SimpleNamespace(tuning=["B"])]
    exps = {independent.TUNING: SimpleNamespace(out_dir=tmp_path / "tuning", decided={"d": 1},
                                                criterion=SimpleNamespace(folds=folds)),
            independent.OURS: SimpleNamespace(out_dir=tmp_path / "ours")}
    codes = dict(zip((independent.TUNING, independent.OURS), codes, strict=True))
    monkeypatch.setattr(experiment, "load_experiment", lambda p: exps[p])
    monkeypatch.setattr(independent, "_with_plugin", lambda: calls.append("plugin"))
    from rich.console import Console

    def console_of(console):
        assert isinstance(console, Console)

    monkeypatch.setattr(independent, "run_experiment",
                        lambda console, p, jobs, force, ex: console_of(console) or calls.append(
                            ("run", p, jobs, force, ex)) or codes[p])
    monkeypatch.setattr(independent, "index_experiment", lambda console, p: console_of(
        console) or calls.append(("index", p)))
    monkeypatch.setattr(independent, "tuned_references", lambda d: calls.append(("tuned", d))
                        or "TUNED")
    monkeypatch.setattr(independent, "stale_decisions", lambda t, d: calls.append(
        ("stale", t, d)) or list(stale))
    monkeypatch.setattr(independent, "cross_fitted", lambda t, ours, halves: calls.append(
        ("cross", t, ours, halves)) or [SimpleNamespace(passed=p) for p in passed])
    monkeypatch.setattr(independent, "decisions_markdown", lambda t: "DEC" if t == "TUNED"
                        else pytest.fail(f"decisions of {t}"))
    monkeypatch.setattr(independent, "write_outputs", lambda rows, out, dec: calls.append(
        ("write", len(rows), out, dec)) or TEXT)
    monkeypatch.setenv("COLUMNS", "400")
    return calls


def test_main_runs_both_steps_then_the_cross_fitted_table(monkeypatch, tmp_path, capsys):
    calls = _main_layers(monkeypatch, tmp_path)
    assert independent.main([]) == 0
    T, O = independent.TUNING, independent.OURS
    assert calls == ["plugin", ("run", T, None, False, "process"), ("tuned", tmp_path / "tuning"),
                     ("stale", "TUNED", {"d": 1}), ("run", O, None, False, "process"),
                     ("cross", "TUNED", tmp_path / "ours", ["A", "B"]),
                     ("write", 2, independent.OUT, "DEC")]
    out = capsys.readouterr().out
    assert "tuning: configs/experiments/independent-real-tuning.yaml" in out
    assert "ours: configs/experiments/independent-real-ours.yaml" in out
    assert TEXT in out and f"written: {independent.OUT / 'comparison.md'}" in out


def test_main_options_and_no_run(monkeypatch, tmp_path, capsys):
    calls = _main_layers(monkeypatch, tmp_path)
    assert independent.main(["--jobs", "3", "--executor", "local", "--force", "--out",
                             str(tmp_path / "o[x]")]) == 0
    assert calls[1] == ("run", independent.TUNING, 3, True, "local")
    assert calls[-1] == ("write", 2, tmp_path / "o[x]", "DEC")
    assert f"written: {tmp_path / 'o[x]' / 'comparison.md'}" in capsys.readouterr().out
    calls.clear()
    assert independent.main(["--no-run"]) == 0
    assert ("index", independent.TUNING) in calls and ("index", independent.OURS) in calls
    assert not any(c[0] == "run" for c in calls if isinstance(c, tuple))


@pytest.mark.parametrize(("codes", "step"), [((1, 0), "tuning"), ((0, 1), "ours")])
def test_main_stops_on_a_failed_step(monkeypatch, tmp_path, capsys, codes, step):
    calls = _main_layers(monkeypatch, tmp_path, codes=codes)
    assert independent.main([]) == 1
    assert f"{step}: a run failed (see above); no comparison table" in capsys.readouterr().out
    assert not any(c[0] in ("cross", "write") for c in calls if isinstance(c, tuple))
    assert any(c[0] == "tuned" for c in calls if isinstance(c, tuple)) is (step == "ours")


def test_main_stops_on_stale_decisions(monkeypatch, tmp_path, capsys):
    stale = ["ref-x (A): decided records [gate=1]", "ref-x (B): undecided"]
    calls = _main_layers(monkeypatch, tmp_path, stale=stale)
    assert independent.main([]) == 1
    out = capsys.readouterr().out
    assert ("The recorded decisions are not the replay's; update `decided:` in "
            "configs/experiments/independent-real-tuning.yaml:\nref-x (A): decided records "
            "[gate=1]\nref-x (B): undecided") in out
    # nothing after the tuning step: no run of ours, no table
    assert calls == ["plugin", ("run", independent.TUNING, None, False, "process"),
                     ("tuned", tmp_path / "tuning"), ("stale", "TUNED", {"d": 1})]


def test_main_fails_when_a_baseline_fails(monkeypatch, tmp_path):
    _main_layers(monkeypatch, tmp_path, passed=(True, False))
    assert independent.main([]) == 1


# the comparison table -------------------------------------------------------------------------

def test_table_markdown_every_line_with_halves():
    x = independent.Baseline("ours-x", "ref-x", "a test reference")
    z = independent.Baseline("ours-z", "ref-z", "a third")
    rows = [*_rows(), independent.Comparison(
        z, {8.0: (1.15, 3.0), 48.0: (1.0, 1.0)}, {8.0: (1.0, 2.0), 48.0: (0.0, 1.0)}),
        independent.Comparison(x, {8.0: (1.0, 1.0)}, {8.0: (1.0, 1.0), 48.0: (1.0, 1.0)})]
    head = ("| Baseline (ours) | Reference | Scored on | Reference setting (tuned on) | ours 8 m "
            "| reference 8 m | ours / ref. 8 m | ours 48 m | reference 48 m | ours / ref. 48 m "
            "| within 1.15x |")
    # x: 1/2, 2/2 at 8 m, 3/3, 4/5 at 48 m; z: 1.15 (the limit: not bold), 3/2 = 1.5 (bold),
    # a zero reference: inf; the last: ours without 48 m
    assert independent.table_markdown(rows) == "\n".join([
        head, "|" + "---|" * 11,
        "| `ours-x` | `ref-x` | A | gate=2.0 (B) | 1.000 / 2.000 | 2.000 / 2.000 | 0.50 / 1.00 "
        "| 3.000 / 4.000 | 3.000 / 5.000 | 1.00 / 0.80 | yes (worst 1.00x) |",
        "| `ours-y` | `ref-y` | A | - (B) | 1.000 / 1.000 | - | - / - | - | - | - / - | no run |",
        "| `ours-z` | `ref-z` | - | - (-) | 1.150 / 3.000 | 1.000 / 2.000 | 1.15 / **1.50** "
        "| 1.000 / 1.000 | 0.000 / 1.000 | **inf** / 1.00 | NO (worst infx) |",
        "| `ours-x` | `ref-x` | - | - (-) | 1.000 / 1.000 | 1.000 / 1.000 | 1.00 / 1.00 | - "
        "| 1.000 / 1.000 | - / - | no run |",
        "",
        "Each cell: mean relative rotation [deg] / translation [m] error over the segments of "
        "that length; ratios ours / reference (rotation / translation), above 1.15x in bold. "
        "Ours at its shipped defaults; each reference at the setting the tuning rule of "
        "configs/splits.yaml chose on the other half (cross-fitted). References:",
        "- `ref-x` for `ours-x`: a test reference", "- `ref-y` for `ours-y`: another",
        "- `ref-z` for `ours-z`: a third"]) + "\n"


def test_table_markdown_without_halves_and_other_lengths():
    b = independent.Baseline("ours-x", "ref-x", "a test reference")
    row = independent.Comparison(b, {16.0: (1.0, 2.0)}, {16.0: (1.0, 1.0)}, lengths_m=(16.0,))
    assert independent.table_markdown([row]).splitlines() == [
        "| Baseline (ours) | Reference | ours 16 m | reference 16 m | ours / ref. 16 m "
        "| within 1.15x |", "|---|---|---|---|---|---|",
        "| `ours-x` | `ref-x` | 1.000 / 2.000 | 1.000 / 1.000 | 1.00 / **2.00** "
        "| NO (worst 2.00x) |", "",
        "Each cell: mean relative rotation [deg] / translation [m] error over the segments of "
        "that length; ratios ours / reference (rotation / translation), above 1.15x in bold. "
        "References:", "- `ref-x` for `ours-x`: a test reference"]
    assert independent.table_markdown([]).splitlines()[0] == (
        "| Baseline (ours) | Reference | ours 8 m | reference 8 m | ours / ref. 8 m | ours 48 m "
        "| reference 48 m | ours / ref. 48 m | within 1.15x |")


def test_setting_text_of_several_values():
    assert independent._setting({"gate": 2.0, "on": True, "v": [0.5, 1]}) == \
        "gate=2.0 on=true v=[0.5, 1]"
    assert independent._setting(None) == "-"


def test_run_dir_needs_a_run_list_per_point(tmp_path):
    t = independent.Tuned("ref-x", [{"g": 1}, {"g": 2}], [{"A": tmp_path}], {})
    assert t.run_dir({"g": 1}, "A") == tmp_path
    with pytest.raises(ValueError):
        t.run_dir({"g": 2}, "A")


def test_stale_decisions_name_an_undecided_reference():
    t = independent.Tuned("ref-x", [{"g": 1}], [{}], {"A": Decision(0, None, [], "a run is "
                                                                     "missing")})
    assert independent.stale_decisions({"ref-x": t}, None) == [
        "ref-x (A): undecided (a run is missing)"]


def test_cross_fitted_without_a_sweep_or_a_decision(monkeypatch, tmp_path):
    from bench.runs import folders

    seen = []
    monkeypatch.setattr(independent, "errors_by_method", lambda d, lengths, half: seen.append(
        (d, lengths, half)) or {"ours-x": {8.0: (1.0, 1.0)}})
    monkeypatch.setattr(folders, "read_run", lambda d: pytest.fail(f"read {d}"))
    undecided = independent.Tuned("ref-x", [{"g": 1}], [{"A": tmp_path}],
                                  {"A": Decision(0, None, [], "?"),
                                   "B": Decision(0, None, [], "?")})
    baselines = [independent.Baseline("ours-x", "ref-x", ""),
                 independent.Baseline("ours-x", "ref-none", "")]
    rows = independent.cross_fitted({"ref-x": undecided}, tmp_path / "ours", ["A", "B"],
                                    baselines, (8.0,))
    assert seen == [(tmp_path / "ours", (8.0,), "A"), (tmp_path / "ours", (8.0,), "B")]
    assert [(c.half, c.tuned_on, c.setting, c.reference) for c in rows] == [
        ("A", "B", None, None), ("A", "B", None, None), ("B", "A", None, None),
        ("B", "A", None, None)]
    assert all(c.lengths_m == (8.0,) and c.ours == {8.0: (1.0, 1.0)} for c in rows)


def test_main_help_names_every_option(monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", "400")
    with pytest.raises(SystemExit) as done:
        independent.main(["--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    for words in ("ICP-family baselines against independent implementations on the real radar "
                  "frames, each tuned by the tuning rule (the references' sweep over both "
                  "halves, ours at its defaults, then the cross-fitted table)",
                  "--jobs JOBS parallel runs (default: the YAMLs')",
                  "--executor EXECUTOR local, process or dask",
                  "--force run again even if finished", "--out OUT where the table is written",
                  "--no-run start no run: decide and score from the finished runs (a decision "
                  "whose runs are missing is undecided)"):
        assert words in text


def test_half_choices_hand_the_criterion_to_the_rule(monkeypatch):
    seen = []
    monkeypatch.setattr(independent, "decide", lambda *a, **kw: seen.append((a, kw)) or len(seen))
    crit = {"lengths_m": [8, 48], "folds": [{"tuning": ["A"], "validation": ["B"]},
                                            {"tuning": ["B", "C"], "validation": ["A"]}],
            "domain": ["S"], "level": 0.9, "reps": 50, "min_gain": 0.02}
    out = independent.half_choices(["p"], ["e"], 0, crit)
    assert out == {independent.RULE: 1, "A": 2, "B+C": 3}
    args = {"level": 0.9, "reps": 50, "min_gain": 0.02}
    assert seen == [((["p"], ["e"], 0, [(["A"], ["B"]), (["B", "C"], ["A"])],
                      ["S"], [8.0, 48.0]), args),
                    ((["p"], ["e"], 0, [(["A"], [])], ["S"], [8.0, 48.0]), args),
                    ((["p"], ["e"], 0, [(["B", "C"], [])], ["S"], [8.0, 48.0]), args)]
    seen.clear()
    independent.half_choices(["p"], ["e"], 0, {"lengths_m": [8], "folds": []})
    assert seen == [((["p"], ["e"], 0, [], [], [8.0]),
                     {"level": 0.95, "reps": 1000, "min_gain": 0.0})]


def test_run_experiment_prints_its_texts_as_they_are(monkeypatch, tmp_path, capsys):
    from bench.report.tables import paper as paper_tables
    from bench.runs import job

    _experiment_layers(monkeypatch, tmp_path, ["skipped"], None)
    long = "[deg] " + "y" * 400
    monkeypatch.setattr(job, "summarize", lambda outcomes: "1 [skipped]")
    monkeypatch.setattr(paper_tables, "write_tables", lambda d: {"md": "table [m] " + long})
    console = _console()
    # a skipped run counts as finished: its tables are written
    assert independent.run_experiment(console, Path("x.yaml"), None, False, "local") == 0
    text = console.export_text()
    # as they are: no markup eating "[...]", the table's long line not wrapped
    assert "1 [skipped]" in text and "table [m] " + long in text
