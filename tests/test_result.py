"""The typed run result: metrics.json round trip, the Seed enum, doppler-ego's own velocity
scored, and results folders of the previous format still loading (re-scored once, said once)."""

import json

import pytest

from bench.runs.folders import load_runs, read_run, run_dir_name
from bench.runs.job import Job, run_job
from bench.runs.result import RunResult
from conftest import constant_twist_sequence
from loaders.store import write_store
from methods.registry import Seed


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=50, n_points=1500, noise_m=0.01, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def test_seed_owns_its_option_suffix_tag_and_style():
    assert [Seed.of(x) for x in (True, False, None)] == [Seed.WITH, Seed.WITHOUT, Seed.NONE]
    assert [s.option for s in Seed] == [True, False, None]
    assert run_dir_name("icp-p2p", True) == "icp-p2p_seed"
    assert run_dir_name("icp-p2p", Seed.WITHOUT) == "icp-p2p_noseed"
    assert run_dir_name("doppler", None) == "doppler"
    assert Seed.WITH.tag("kiss-icp") == "With Seed, own model"
    assert Seed.WITH.tag("dicp") == "With Seed" and Seed.NONE.tag("doppler") == \
        "No initial guess"
    assert len({Seed.WITH.style("dicp"), Seed.WITHOUT.style("dicp"),
                Seed.NONE.style("doppler")}) == 3


def test_doppler_ego_scores_its_own_doppler_velocity(store, tmp_path):
    out = run_job(Job(store=store, method="doppler-ego", seed=None, out_root=tmp_path))
    assert out.status == "done", out.message
    res = read_run(out.run_dir).result
    assert res.velocity.source == "trajectory" and res.velocity_own.source == "doppler"
    # exact Doppler on static points at 8 m/s: its own velocity is right to a few cm/s
    assert res.velocity_own.n > 30 and res.velocity_own.norm_mean_mps < 0.1
    assert res.velocity.norm_mean_mps < 0.2
    text = (out.run_dir / "metrics.json").read_text()
    assert RunResult.model_validate_json(text) == res and json.loads(text)["seed"] is None


def _as_schema_1(run_dir):
    """metrics.json rewritten as the previous version wrote it."""
    m = json.loads((run_dir / "metrics.json").read_text())
    old = {k: m[k] for k in ("sequence", "method", "seed", "frames", "frames_scored",
                             "diverged", "time_ms", "register_ms", "wall_ms", "clock",
                             "threads")}
    old["relative_error"] = {f"{r['length_m']:g}": {k: r[k] for k in (
        "rot_deg_mean", "trans_m_mean", "rot_deg_median", "trans_m_median", "n")}
        for r in m["relative_error"]}
    old["ape"] = {k: m["ape"][k] for k in ("trans_rmse_m", "rot_rmse_deg", "alignment")}
    (run_dir / "metrics.json").write_text(json.dumps(old))
    return m


def test_an_old_results_folder_is_rescored_from_its_files_with_one_message(store, tmp_path,
                                                                            capsys):
    runs = [run_job(Job(store=store, method=m, seed=s, out_root=tmp_path)).run_dir
            for m, s in (("icp-p2p", True), ("icp-p2p", False))]
    new = {d: _as_schema_1(d) for d in runs}
    capsys.readouterr()
    loaded = load_runs(tmp_path)
    err = capsys.readouterr().err
    assert err.count("note:") == 1 and "2 re-scored from their trajectory files" in err
    assert {run.dir for run in loaded} == set(new)
    for run in loaded:
        res, m = run.result, new[run.dir]
        assert res.schema_version == 2 and res.kitti is not None and res.velocity is not None
        for a, b in zip(res.relative_error, m["relative_error"], strict=True):
            assert a.length_m == b["length_m"] and a.n == b["n"]
            assert a.trans_m_mean == pytest.approx(b["trans_m_mean"], rel=1e-9)
        assert res.ape.trans_rmse_m == pytest.approx(m["ape"]["trans_rmse_m"], rel=1e-9)
        assert res.velocity.norm_mean_mps == pytest.approx(m["velocity"]["norm_mean_mps"],
                                                           rel=1e-9)
        assert res.time_ms.mean == m["time_ms"]["mean"]
    load_runs(tmp_path)
    assert "note:" not in capsys.readouterr().err  # said once


def test_an_old_metrics_json_without_trajectories_is_read_as_it_is(tmp_path, capsys):
    d = tmp_path / "s" / "dicp_seed"
    d.mkdir(parents=True)
    (d / "metrics.json").write_text(json.dumps({
        "sequence": "s", "method": "dicp", "seed": True, "diverged": False,
        "relative_error": {"8": {"rot_deg_mean": 1.0, "trans_m_mean": 0.5,
                                 "rot_deg_median": 1.0, "trans_m_median": 0.5, "n": 4}},
        "ape": {"trans_rmse_m": 2.0, "rot_rmse_deg": 1.0, "alignment": "se3"},
        "time_ms": None}))
    (run,) = load_runs(tmp_path)
    assert run.result.relative(8.0).trans_m_mean == 0.5 and run.result.ape.requested == "se3"
    assert run.seed is Seed.WITH and run.result.kitti is None
    assert "1 read as they are" in capsys.readouterr().err


def test_fell_back_is_more_than_five_percent_of_the_registered_frames():
    def run(frames, replaced=0, unconverged=0, seed=True):
        return RunResult(sequence="s", method="m", seed=seed, frames=frames,
                         frames_replaced=replaced, frames_unconverged=unconverged)

    # 21 frames are 20 registrations: 1 of them is exactly 5 %, not more
    assert run(21, 1).fallback_share == pytest.approx(0.05) and not run(21, 1).fell_back
    assert run(20, 1).fell_back  # 1 of 19
    assert run(20, 0, 1).fell_back  # a frame not converged counts as well
    assert run(41, 1, 1).fallback_share == pytest.approx(2 / 40)
    assert run(1).fallback_share == 0.0 and not run(1).fell_back
    assert run(20, 1, seed=False).fallback_text() == (
        "1 of 19 frames replaced by the identity (no usable registration)")
    assert run(20, 0, 2).fallback_text() == "2 of 19 frames not converged (last iterate kept)"
