"""CI regression: every method, seeded and not, on small synthetic sequences of every sensor
class against the committed baseline (configs/ci/baseline.json), two-sided: errors that grow
fail, errors that drop and runs not in the baseline wait for review. Accept a deliberate
change with `bench regress --update`."""

import copy
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bench.api import run_method
from bench.runs.experiment import load_experiment
from bench.runs.plan import jobs_for_experiment, plan
from bench.runs.progress import run_jobs
from bench.studies import regress as rg
from methods.registry import METHODS


@pytest.fixture(scope="module")
def ci_out(tmp_path_factory, ci_data_dir) -> Path:
    """The CI experiment's runs, once per module (the CLI tests below reuse them).

    They run in this process (the ``local`` executor): the metrics are the same whichever
    executor runs them (tests/test_executors.py), and a forked worker per run pays again for
    what this process has loaded already (numba's compiled kernels, the library lookup): 85
    runs took 55-180 s with two workers, about 30 s here."""
    exp = load_experiment(rg.CI_EXPERIMENT)
    exp.data_dir = ci_data_dir
    exp.out = tmp_path_factory.mktemp("ci")
    outcomes = run_jobs(plan(jobs_for_experiment(exp)), executor="local")
    assert all(o.status == "done" for o in outcomes), [o.message for o in outcomes]
    return exp.out


@pytest.fixture(scope="module")
def current(ci_out):
    return rg.snapshot(ci_out)


def test_the_ci_experiment_covers_seeded_and_unseeded_runs(current):
    runs = {tuple(key.split("/")) for key in current}
    sequences = {seq for seq, _, _ in runs}
    for name in (n for n in METHODS if not n.startswith("test-")):
        tags = ("seed", "noseed") if METHODS[name].uses_initial_guess else ("-",)
        for seq in sequences:
            for tag in tags:
                assert (seq, name, tag) in runs, (seq, name, tag)


def test_every_ci_run_is_in_the_committed_baseline(current):
    new = [str(f) for f in rg.check(rg.read_baseline(), current) if f.kind == rg.NEW_RUN]
    assert not new, "\n".join(new) + "\n(checked against nothing: after merging, regenerate " \
        "the baseline with `bench regress --update` and commit it)"


def test_no_method_regressed_against_the_committed_baseline(current):
    findings = rg.check(rg.read_baseline(), current)
    bad = [str(f) for f in findings if f.regression]
    assert not bad, "\n".join(bad) + "\n(deliberate? accept it with `bench regress --update`)"


def test_no_error_dropped_without_review(current):
    """A bug can shrink errors as well as grow them (scoring the wrong frames, a prior taken
    from the ground truth): an error that drops by more than the tolerance fails until it is
    accepted."""
    findings = rg.check(rg.read_baseline(), current)
    improved = [str(f) for f in findings if f.kind == rg.IMPROVED]
    assert not improved, "\n".join(improved) + "\n(review it, then accept it with " \
        "`bench regress --update`)"


def test_a_deliberately_degraded_method_is_caught(current, tmp_path, ci_data_dir):
    baseline = copy.deepcopy(current)
    # doppler with a feature gate 500x too tight: fewer, worse correspondences (on the
    # edge-band data of issue 40, 100x too tight, 0.05, no longer degrades this sequence beyond
    # the tolerance: rotation at 8 m 0.49 -> 0.54 deg; at 0.01 it is 1.08)
    store = ci_data_dir / "synthetic-ci" / "ci-semidense.h5"
    run_method("doppler", store, params={"tau_doppler": 0.01},
               out=tmp_path / "ci-semidense" / "doppler")
    degraded = copy.deepcopy(current)
    degraded.update(rg.snapshot(tmp_path))
    bad = [f for f in rg.check(baseline, degraded) if f.regression]
    assert bad and all(f.run == "ci-semidense/doppler/-" for f in bad)
    # a newly diverged run and a vanished run fail too
    diverged = copy.deepcopy(current)
    diverged["ci-wall/dicp/seed"]["diverged"] = True
    gone = {k: v for k, v in current.items() if k != "ci-tunnel/dicp/seed"}
    assert any(f.regression and f.what == "diverged" for f in rg.check(baseline, diverged))
    assert any(f.regression and f.what == "run" for f in rg.check(baseline, gone))


def _snapshot(trans_8m: float = 0.5, diverged: bool = False) -> dict:
    """A small snapshot of two runs (the shape of ``regress.snapshot``)."""
    run = {"diverged": diverged, "rot_deg": {"8": 0.4, "16": 0.6},
           "trans_m": {"8": trans_8m, "16": 0.9}}
    return {"seq/icp-p2p/noseed": run, "seq/dicp/seed": copy.deepcopy(run)}


@pytest.mark.parametrize("trans_8m, kind", [
    (0.5, None), (0.52, rg.CHANGED), (0.5 * 1.1 + 0.001 - 1e-6, rg.CHANGED),
    (0.5 * 1.1 + 0.001 + 1e-6, rg.REGRESSION), (0.5 * 0.9 - 0.001 + 1e-6, rg.CHANGED),
    (0.5 * 0.9 - 0.001 - 1e-6, rg.IMPROVED), (0.1, rg.IMPROVED)])
def test_the_check_is_two_sided(trans_8m, kind):
    """10 % + 1 mm either way: above is a regression, below an improvement to review, between
    a change that passes; equal is no finding."""
    current = _snapshot()
    current["seq/icp-p2p/noseed"]["trans_m"]["8"] = trans_8m
    findings = rg.check(_snapshot(), current)
    assert [f.kind for f in findings] == ([] if kind is None else [kind])
    if kind is not None:
        assert findings[0].run == "seq/icp-p2p/noseed" and findings[0].what == "trans_m at 8 m"


def test_an_improvement_and_a_new_run_are_flagged_for_review():
    baseline, current = _snapshot(trans_8m=1.0), _snapshot(trans_8m=0.5)
    del baseline["seq/dicp/seed"]
    findings = {(f.run, f.what): f for f in rg.check(baseline, current)}
    improved = findings["seq/icp-p2p/noseed", "trans_m at 8 m"]
    new = findings["seq/dicp/seed", "run"]
    assert improved.kind == rg.IMPROVED and improved.review and not improved.regression
    assert new.kind == rg.NEW_RUN and new.review and not new.regression
    assert "! improved: review" in str(improved)
    assert "new run, not in baseline" in str(new)
    assert {f.kind for f in rg.failing(list(findings.values()))} == {rg.IMPROVED, rg.NEW_RUN}
    assert {f.kind for f in rg.failing(list(findings.values()), accept_improvements=True)} \
        == {rg.NEW_RUN}
    # a run that no longer diverges is an improvement, one that newly diverges a regression
    assert [f.kind for f in rg.check(_snapshot(diverged=True), _snapshot())] == \
        [rg.IMPROVED, rg.IMPROVED]
    assert [f.kind for f in rg.check(_snapshot(), _snapshot(diverged=True))] == \
        [rg.REGRESSION, rg.REGRESSION]
    # a vanished run or length is a regression, a length the baseline lacks is new
    gone = _snapshot()
    del gone["seq/dicp/seed"]
    del gone["seq/icp-p2p/noseed"]["trans_m"]["16"]
    assert {(f.what, f.kind) for f in rg.check(_snapshot(), gone)} == {
        ("run", rg.REGRESSION), ("trans_m at 16 m", rg.REGRESSION)}
    assert {(f.what, f.kind) for f in rg.check(gone, _snapshot())} == {
        ("run", rg.NEW_RUN), ("trans_m at 16 m", rg.NEW_RUN)}


def test_regress_exits_by_the_findings_and_update_rewrites_the_baseline(
        tmp_path, monkeypatch, ci_data_dir, ci_out, current):
    from bench.cli import app

    path = tmp_path / "baseline.json"
    monkeypatch.setattr(rg, "BASELINE", path)
    where = ["--data-dir", str(ci_data_dir), "--out", str(ci_out)]  # every run reused

    def regress(*options):
        return CliRunner().invoke(app, ["regress", *where, *options])

    rg.write_baseline(current, path)
    res = regress()
    assert res.exit_code == 0 and "0 regressions, 0 improvements" in res.output, res.output
    # an error that halved: "! improved: review", exit 1 unless accepted
    stale = copy.deepcopy(current)
    stale["ci-sparse/doppler/-"]["trans_m"]["8"] *= 2.0
    rg.write_baseline(stale, path)
    res = regress()
    assert res.exit_code == 1 and "! improved: review  ci-sparse/doppler/-  trans_m at 8 m" \
        in res.output, res.output
    assert regress("--accept-improvements").exit_code == 0
    # an error that doubled: a regression, whatever is accepted
    stale = copy.deepcopy(current)
    stale["ci-sparse/doppler/-"]["trans_m"]["8"] *= 0.5
    rg.write_baseline(stale, path)
    res = regress("--accept-improvements")
    assert res.exit_code == 1 and "REGRESSION  ci-sparse/doppler/-  trans_m at 8 m" \
        in res.output, res.output
    # a run the baseline lacks: checked against nothing, so it fails with what to do
    stale = copy.deepcopy(current)
    del stale["ci-tunnel/gicp/noseed"]
    rg.write_baseline(stale, path)
    res = regress("--accept-improvements")
    assert res.exit_code == 1 and "new run, not in baseline  ci-tunnel/gicp/noseed" \
        in res.output and "run `bench regress --update`" in res.output, res.output
    # --update accepts all of it and prints the diff
    res = regress("--update")
    assert res.exit_code == 0 and "ci-tunnel/gicp/noseed" in res.output, res.output
    assert rg.read_baseline(path) == current


def test_the_committed_baseline_matches_a_rerun(current):
    """The committed numbers, regenerated here: equal up to cross-CPU rounding (below)."""
    baseline = rg.read_baseline()
    for run in ("ci-sparse/doppler/-", "ci-wall/dicp/seed"):
        _assert_same_run(current[run], baseline[run])


def _assert_same_run(got: dict, expected: dict) -> None:
    """One run's snapshot equals another's: the same divergence flag and lengths, and errors
    equal within 1e-4 relative. The rewritten baseline holds numbers regenerated on this
    machine, the committed one numbers from the machine that made it: compiled code and BLAS
    differ across CPUs in the last digits (the 14th was seen), so never compare them exactly.
    1e-4 is far above that and far below the planted 50 % change (and the 10 % tolerance)."""
    assert got["diverged"] == expected["diverged"]
    for kind in ("rot_deg", "trans_m"):
        assert got[kind].keys() == expected[kind].keys(), kind
        for length, value in expected[kind].items():
            assert got[kind][length] == pytest.approx(value, rel=1e-4), (kind, length)
