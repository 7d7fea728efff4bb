"""bench/studies/regress.py in-process on tiny hand-made snapshots: the two-sided threshold
(10 % + a floor of 0.01 deg / 1 mm), how each finding prints, what fails CI, the baseline
file, and ``regress_command`` with the experiment runner replaced by stubs."""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench.studies import regress as rg


def _run(rot: dict, trans: dict, diverged: bool = False) -> dict:
    return {"diverged": diverged, "rot_deg": rot, "trans_m": trans}


def _one(old: float, new: float, q: str = "rot_deg", **kw) -> list:
    other = "trans_m" if q == "rot_deg" else "rot_deg"
    base = {"r": {"diverged": False, q: {"8": old}, other: {}}}
    cur = {"r": {"diverged": False, q: {"8": new}, other: {}}}
    return rg.check(base, cur, **kw)


@pytest.mark.parametrize(("q", "new", "kind"), [
    # rot: 1.0 * 1.1 + 0.01 = 1.11 above, 1.0 * 0.9 - 0.01 = 0.89 below
    ("rot_deg", 1.115, rg.REGRESSION), ("rot_deg", 1.105, rg.CHANGED),
    ("rot_deg", 0.885, rg.IMPROVED), ("rot_deg", 0.895, rg.CHANGED),
    # trans: floor 1 mm, so 1.101 above and 0.899 below
    ("trans_m", 1.1015, rg.REGRESSION), ("trans_m", 1.1005, rg.CHANGED),
    ("trans_m", 0.8985, rg.IMPROVED), ("trans_m", 0.8995, rg.CHANGED),
])
def test_default_tolerance_and_floor_either_way(q, new, kind):
    (f,) = _one(1.0, new, q)
    assert f.kind == kind and f.run == "r" and f.what == f"{q} at 8 m"
    assert f.baseline == 1.0 and f.current == new


def test_tolerance_argument_moves_the_threshold():
    assert _one(1.0, 1.3, tolerance=0.5)[0].kind == rg.CHANGED
    assert _one(1.0, 1.6, tolerance=0.5)[0].kind == rg.REGRESSION
    assert _one(1.0, 0.45, tolerance=0.5)[0].kind == rg.IMPROVED


def test_tiny_differences_and_non_finite_values_are_no_finding():
    assert _one(1.0, 1.0 + 1e-10) == []
    assert _one(1.0, 1.0) == []
    assert _one(1.0, 1.0 + 1e-6)[0].kind == rg.CHANGED
    assert _one(math.nan, 5.0) == [] and _one(1.0, math.inf) == []


def test_runs_missing_new_or_diverging():
    base = {"a": _run({}, {}), "b": _run({}, {}, diverged=True), "c": _run({}, {})}
    cur = {"b": _run({}, {}), "c": _run({}, {}, diverged=True), "d": _run({}, {})}
    got = [(f.run, f.what, f.baseline, f.current, f.kind) for f in rg.check(base, cur)]
    assert got == [("a", "run", "present", None, rg.REGRESSION),
                   ("b", "diverged", True, False, rg.IMPROVED),
                   ("c", "diverged", False, True, rg.REGRESSION),
                   ("d", "run", None, "present", rg.NEW_RUN)]


def test_missing_or_new_lengths_in_numeric_order():
    base = {"r": _run({"100": 1.0, "8": 1.0}, {"16": 2.0})}
    cur = {"r": _run({"16": 3.0, "8": 1.0}, {"16": 2.0})}
    got = [(f.what, f.baseline, f.current, f.kind) for f in rg.check(base, cur)]
    assert got == [("rot_deg at 16 m", None, 3.0, rg.NEW_RUN),
                   ("rot_deg at 100 m", 1.0, None, rg.REGRESSION)]


def test_finding_kinds_and_what_fails():
    reg, imp, new, chg = (rg.Finding("r", "w", 1.0, 2.0, k)
                          for k in (rg.REGRESSION, rg.IMPROVED, rg.NEW_RUN, rg.CHANGED))
    assert rg.Finding("r", "w", 1.0, 2.0).kind == rg.CHANGED
    assert [f.regression for f in (reg, imp, new, chg)] == [True, False, False, False]
    assert [f.review for f in (reg, imp, new, chg)] == [False, True, True, False]
    assert rg.failing([reg, imp, new, chg]) == [reg, imp, new]
    assert rg.failing([reg, imp, new, chg], accept_improvements=True) == [reg, new]


def test_findings_print_mark_values_and_placeholders():
    assert str(rg.Finding("s/m/seed", "rot_deg at 8 m", 1.0, 1.23456, rg.REGRESSION)) == \
        "REGRESSION  s/m/seed  rot_deg at 8 m: 1.0000 -> 1.2346"
    assert str(rg.Finding("x", "run", None, "present", rg.NEW_RUN)) == \
        "! new run, not in baseline  x  run: - -> present"
    assert str(rg.Finding("x", "diverged", True, False, rg.IMPROVED)) == \
        "! improved: review  x  diverged: True -> False"
    assert str(rg.Finding("x", "w", 0.5, 0.25)) == "   changed  x  w: 0.5000 -> 0.2500"


def test_baseline_round_trip_and_recognition(tmp_path):
    path = tmp_path / "sub" / "baseline.json"
    with pytest.raises(FileNotFoundError, match="no CI baseline yet; run `bench regress"):
        rg.read_baseline(path)
    runs = {"s/m/-": _run({"8": 0.5}, {"8": 0.25})}
    rg.write_baseline(runs, path)
    assert rg.read_baseline(path) == runs and rg.is_baseline(path)
    assert path.read_text().endswith("}\n")
    assert json.loads(path.read_text())["about"].startswith("bench regress baseline")
    rg.write_baseline({}, path)  # its own file: replaced
    assert rg.read_baseline(path) == {}


def test_default_baseline_path_is_the_configured_one(tmp_path, monkeypatch):
    path = tmp_path / "b.json"
    monkeypatch.setattr(rg, "BASELINE", path)
    with pytest.raises(FileNotFoundError, match="b.json"):
        rg.read_baseline()
    path.write_text(json.dumps({"runs": {"k": 1}}))
    assert rg.read_baseline() == {"k": 1}


@pytest.mark.parametrize("text", [
    None, "not json", "[1, 2]", '{"about": 3}', '{"runs": {}}', '{"about": "my baseline"}',
])
def test_is_baseline_refuses_what_write_baseline_did_not_write(tmp_path, text):
    path = tmp_path / "b.json"
    if text is not None:
        path.write_text(text)
    assert rg.is_baseline(path) is False


def test_is_baseline_accepts_a_str_path(tmp_path):
    path = tmp_path / "b.json"
    path.write_text('{"about": "bench regress baseline: x"}')
    assert rg.is_baseline(str(path)) is True


class _Console:
    def __init__(self):
        self.lines = []

    def print(self, text, markup=True):
        assert markup is False
        self.lines.append(text)


def _stub_runner(monkeypatch, tmp_path, current, status="done", console=None):
    """Replace the experiment and its runner, each checking what it is handed; returns the
    experiment and what the runner and snapshot saw."""
    import bench.runs.experiment as experiment
    import bench.runs.job as job
    import bench.runs.plan as plan
    import bench.runs.progress as progress

    exp = SimpleNamespace(data_dir=None, out=None, out_dir=tmp_path / "out")
    seen = {}

    def load_experiment(path):
        assert path == rg.CI_EXPERIMENT
        return exp

    def jobs_for_experiment(e, con):
        assert e is exp and isinstance(con, _Console)
        seen["console"] = con
        return ["job"]

    def plan_jobs(jobs):
        assert jobs == ["job"]
        return ["planned"]

    def run_jobs(jobs, con, n):
        assert jobs == ["planned"] and con is seen["console"]
        seen["jobs"] = n
        return [SimpleNamespace(status=status, run_dir=tmp_path / "r1"),
                SimpleNamespace(status="skipped", run_dir=tmp_path / "r2")]

    def snapshot(out_dir, only):
        seen["snapshot"] = (out_dir, only)
        return current

    monkeypatch.setattr(experiment, "load_experiment", load_experiment)
    monkeypatch.setattr(plan, "jobs_for_experiment", jobs_for_experiment)
    monkeypatch.setattr(plan, "plan", plan_jobs)
    monkeypatch.setattr(progress, "run_jobs", run_jobs)
    monkeypatch.setattr(job, "summarize", lambda outcomes: f"SUMMARY of {len(outcomes)}")
    monkeypatch.setattr(rg, "snapshot", snapshot)
    monkeypatch.setattr(rg, "BASELINE", tmp_path / "baseline.json")
    return exp, seen


def _command(tmp_path, update=False, accept=False, tolerance=0.10):
    console = _Console()
    code = rg.regress_command(console, update, tolerance, 3, data_dir=str(tmp_path / "d"),
                              out=str(tmp_path / "o"), accept_improvements=accept)
    return code, console.lines


def test_command_passes_on_an_equal_baseline(tmp_path, monkeypatch):
    current = {"s/m/-": _run({"8": 1.0}, {"8": 1.0})}
    exp, seen = _stub_runner(monkeypatch, tmp_path, current)
    rg.write_baseline(current, rg.BASELINE)
    code, lines = _command(tmp_path)
    assert code == 0
    assert exp.data_dir == tmp_path / "d" and exp.out == tmp_path / "o"
    assert isinstance(exp.data_dir, Path) and isinstance(exp.out, Path)
    assert seen["jobs"] == 3
    assert seen["snapshot"] == (tmp_path / "out", {tmp_path / "r1", tmp_path / "r2"})
    assert lines == ["1 runs, 0 changes, 0 regressions, 0 improvements to review, "
                     "0 new runs or lengths not in the baseline"]


def test_command_fails_when_a_run_fails(tmp_path, monkeypatch):
    _stub_runner(monkeypatch, tmp_path, {}, status="failed")
    code, lines = _command(tmp_path)
    assert code == 1 and lines == ["SUMMARY of 2"]


def test_command_reports_and_advises(tmp_path, monkeypatch):
    base = {"a/m/-": _run({"8": 1.0}, {}), "b/m/-": _run({"8": 1.0}, {})}
    current = {"a/m/-": _run({"8": 2.0}, {}), "b/m/-": _run({"8": 0.5}, {}),
               "c/m/-": _run({}, {})}
    _stub_runner(monkeypatch, tmp_path, current)
    rg.write_baseline(base, rg.BASELINE)
    code, lines = _command(tmp_path)
    assert code == 1
    assert lines == [
        "REGRESSION  a/m/-  rot_deg at 8 m: 1.0000 -> 2.0000",
        "! improved: review  b/m/-  rot_deg at 8 m: 1.0000 -> 0.5000",
        "! new run, not in baseline  c/m/-  run: - -> present",
        "3 runs, 3 changes, 1 regressions, 1 improvements to review, "
        "1 new runs or lengths not in the baseline",
        f"regression: {rg.ADVICE[rg.REGRESSION]}",
        f"improved: {rg.ADVICE[rg.IMPROVED]}",
        f"new run: {rg.ADVICE[rg.NEW_RUN]}",
    ]
    assert "bench regress --update" in rg.ADVICE[rg.REGRESSION]
    assert "--accept-improvements" in rg.ADVICE[rg.IMPROVED]
    assert "bench regress --update" in rg.ADVICE[rg.NEW_RUN]


def test_command_accepts_improvements_when_asked(tmp_path, monkeypatch):
    base = {"b/m/-": _run({"8": 1.0}, {})}
    _stub_runner(monkeypatch, tmp_path, {"b/m/-": _run({"8": 0.5}, {})})
    rg.write_baseline(base, rg.BASELINE)
    code, lines = _command(tmp_path, accept=True)
    assert code == 0
    assert lines[-1] == ("1 runs, 1 changes, 0 regressions, 1 improvements to review "
                         "(accepted), 0 new runs or lengths not in the baseline")
    code, lines = _command(tmp_path, accept=False)
    assert code == 1 and lines[-1] == f"improved: {rg.ADVICE[rg.IMPROVED]}"


def test_command_passes_tolerance_through(tmp_path, monkeypatch):
    base = {"b/m/-": _run({"8": 1.0}, {})}
    _stub_runner(monkeypatch, tmp_path, {"b/m/-": _run({"8": 1.3}, {})})
    rg.write_baseline(base, rg.BASELINE)
    assert _command(tmp_path, tolerance=0.5)[0] == 0
    assert _command(tmp_path, tolerance=0.1)[0] == 1


def test_command_update_writes_the_baseline_new_or_replaced(tmp_path, monkeypatch):
    current = {"s/m/-": _run({"8": 1.0}, {"8": 2.0})}
    _stub_runner(monkeypatch, tmp_path, current)
    code, lines = _command(tmp_path, update=True)  # no baseline yet
    assert code == 0 and rg.read_baseline(rg.BASELINE) == current
    assert lines == ["! new run, not in baseline  s/m/-  run: - -> present",
                     f"baseline updated: {rg.BASELINE} (1 changes)"]
    rg.write_baseline({}, rg.BASELINE)
    code, lines = _command(tmp_path, update=True)  # an old one: replaced
    assert code == 0 and rg.read_baseline(rg.BASELINE) == current
    assert lines[-1] == f"baseline updated: {rg.BASELINE} (1 changes)"


def test_command_update_compares_with_the_old_baseline_first(tmp_path, monkeypatch):
    current = {"s/m/-": _run({"8": 1.0}, {})}
    _stub_runner(monkeypatch, tmp_path, current)
    rg.write_baseline({"s/m/-": _run({"8": 2.0}, {})}, rg.BASELINE)
    code, lines = _command(tmp_path, update=True)
    assert code == 0 and rg.read_baseline(rg.BASELINE) == current
    assert lines == ["! improved: review  s/m/-  rot_deg at 8 m: 2.0000 -> 1.0000",
                     f"baseline updated: {rg.BASELINE} (1 changes)"]


def test_command_improvements_fail_by_default(tmp_path, monkeypatch):
    _stub_runner(monkeypatch, tmp_path, {"b/m/-": _run({"8": 0.5}, {})})
    rg.write_baseline({"b/m/-": _run({"8": 1.0}, {})}, rg.BASELINE)
    assert rg.regress_command(_Console(), False, 0.10, 1) == 1


def test_run_keys_name_sequence_method_and_seed_option():
    from methods.registry import Seed

    def key(seed):
        return rg._key(SimpleNamespace(sequence="seq", method="meth", seed=seed))

    assert [key(s) for s in (Seed.WITH, Seed.WITHOUT, Seed.NONE)] == \
        ["seq/meth/seed", "seq/meth/noseed", "seq/meth/-"]


def test_snapshot_keeps_scored_lengths_of_the_selected_runs(tmp_path, monkeypatch):
    from methods.registry import Seed

    def length(m, n, rot, trans):
        return SimpleNamespace(length_m=m, n=n, rot_deg_mean=rot, trans_m_mean=trans)

    def run(seq, diverged, errors):
        return SimpleNamespace(result=SimpleNamespace(
            sequence=seq, method="m", seed=Seed.NONE, diverged=diverged,
            relative_error=errors))

    seen = {}

    def load_runs(results_dir, only):
        seen["args"] = (results_dir, only)
        return [run("z", 0, [length(8.0, 2, 0.5, 0.25)]),
                run("a", 1, [length(16.0, 4, 1.5, 0.75), length(24.0, 0, 9.0, 9.0),
                             length(2.5, 1, 0.1, 0.2)])]

    monkeypatch.setattr(rg, "load_runs", load_runs)
    only = {tmp_path / "r"}
    snap = rg.snapshot(tmp_path, only)
    assert seen["args"] == (tmp_path, only)
    assert list(snap) == ["a/m/-", "z/m/-"]
    assert snap["a/m/-"] == {"diverged": True, "rot_deg": {"16": 1.5, "2.5": 0.1},
                             "trans_m": {"16": 0.75, "2.5": 0.2}}
    assert snap["a/m/-"]["diverged"] is True and snap["z/m/-"]["diverged"] is False
    assert snap["z/m/-"] == {"diverged": False, "rot_deg": {"8": 0.5}, "trans_m": {"8": 0.25}}


def test_check_goes_on_past_a_non_finite_length_and_a_new_run():
    base = {"b": _run({"8": math.nan, "16": 1.0}, {})}
    cur = {"a": _run({}, {}), "b": _run({"8": 1.0, "16": 2.0}, {})}
    got = [(f.run, f.what, f.kind) for f in rg.check(base, cur)]
    assert got == [("a", "run", rg.NEW_RUN), ("b", "rot_deg at 16 m", rg.REGRESSION)]


def test_a_missing_length_names_its_run():
    (f,) = rg.check({"s/m/-": _run({"8": 1.0}, {})}, {"s/m/-": _run({}, {})})
    assert f.run == "s/m/-" and f.kind == rg.REGRESSION


def test_exactly_at_the_threshold_is_not_beyond_it():
    # from the definition: beyond old * (1 +- tolerance) +- floor, so the edge itself is not
    up, down = 1.0 * (1 + 0.5) + 0.01, 1.0 * (1 - 0.5) - 0.01
    assert _one(1.0, up, tolerance=0.5)[0].kind == rg.CHANGED
    assert _one(1.0, down, tolerance=0.5)[0].kind == rg.CHANGED
    # a difference of exactly 1e-9 is rounding, not a change
    assert _one(0.0, 1e-9) == []


def test_write_baseline_refuses_a_foreign_file_naming_what_it_writes(tmp_path):
    from bench.guard import Refused

    path = tmp_path / "b.json"
    path.write_text('{"runs": {}}')
    with pytest.raises(Refused, match="is not a regress baseline the harness wrote"):
        rg.write_baseline({}, path)
    assert path.read_text() == '{"runs": {}}'


def test_rewriting_the_committed_baseline_gives_the_same_bytes(tmp_path):
    """The committed file, read and written back: byte for byte (its layout, one value a line,
    and its ``about``), so an --update with nothing changed leaves no diff to review."""
    committed = rg.BASELINE.read_text()
    path = tmp_path / "b.json"
    rg.write_baseline(rg.read_baseline(), path)
    assert path.read_text() == committed
