"""CI regression: every method on small synthetic sequences of every sensor class against the
committed baseline (configs/ci/baseline.json). Accept a deliberate change with
`bench regress --update`."""

import copy

import pytest
from typer.testing import CliRunner

from bench import regress as rg
from bench.api import run_method
from bench.experiment import load_experiment
from bench.progress import run_jobs
from bench.run import plan
from bench.runplan import jobs_for_experiment


@pytest.fixture(scope="module")
def current(tmp_path_factory):
    exp = load_experiment(rg.CI_EXPERIMENT)
    exp.out = tmp_path_factory.mktemp("ci")
    outcomes = run_jobs(plan(jobs_for_experiment(exp)), workers=2)
    assert all(o.status == "done" for o in outcomes), [o.message for o in outcomes]
    return rg.snapshot(exp.out)


def test_no_method_regressed_against_the_committed_baseline(current):
    findings = rg.check(rg.read_baseline(), current)
    bad = [str(f) for f in findings if f.regression]
    assert not bad, "\n".join(bad) + "\n(deliberate? accept it with `bench regress --update`)"


def test_doppler_ego_is_best_or_second_on_every_radar_sequence_and_never_diverges(current):
    """Issue 10's synthetic check, on the CI sequences: among every method of the harness,
    doppler-ego's rotation and translation errors rank first or second at every length on the
    sparse, semi-dense and U-turn radar sequences, and it diverges nowhere."""
    assert not any(v["diverged"] for k, v in current.items() if "/doppler-ego/" in k)
    for seq in ("ci-sparse", "ci-semidense", "ci-uturn"):
        runs = {k: v for k, v in current.items() if k.startswith(seq + "/")}
        ours = runs[f"{seq}/doppler-ego/seed"]
        for kind in ("rot_deg", "trans_m"):
            for length, value in ours[kind].items():
                better = [k for k, v in runs.items()
                          if not v["diverged"] and v[kind][length] < value]
                assert len(better) <= 1, (seq, kind, length, value, better)


def test_a_deliberately_degraded_method_is_caught(current, tmp_path):
    baseline = rg.read_baseline()
    # doppler with a feature gate 100x too tight: fewer, worse correspondences
    exp = load_experiment(rg.CI_EXPERIMENT)
    store = exp.data_dir / "synthetic-ci" / "ci-semidense.h5"
    run_method("doppler", store, params={"tau_doppler": 0.05},
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


def test_regress_update_rewrites_the_baseline_and_prints_the_diff(tmp_path, monkeypatch):
    from bench.cli import app

    old = rg.read_baseline()
    stale = copy.deepcopy(old)
    stale["ci-sparse/doppler/-"]["trans_m"]["8"] *= 0.5
    path = tmp_path / "baseline.json"
    rg.write_baseline(stale, path)
    monkeypatch.setattr(rg, "BASELINE", path)
    res = CliRunner().invoke(app, ["regress"])
    assert res.exit_code == 1 and "REGRESSION  ci-sparse/doppler/-  trans_m at 8 m" in res.output
    res = CliRunner().invoke(app, ["regress", "--update"])
    assert res.exit_code == 0 and "ci-sparse/doppler/-  trans_m at 8 m" in res.output
    assert rg.read_baseline(path)["ci-sparse/doppler/-"] == old["ci-sparse/doppler/-"]
