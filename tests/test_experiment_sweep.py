"""Parameter sweeps in experiments (bench/runs/sweep.py) and their table
(bench/report/tables/sweep.py): expansion into labelled variants, the list-valued parameter
rule, validation, and the choice of the best point."""

import json

import pytest
import yaml

from bench.report.tables.sweep import sweep_choices, sweep_markdown
from bench.runs.experiment import Experiment, load_experiment
from bench.runs.plan import jobs_for_experiment
from bench.runs.sweep import sweep_index, write_sweep_index
from conftest import SAMPLE_STORE
from loaders.errors import DataError


def _exp(methods, **extra):
    return Experiment.model_validate({"name": "s", "sequences": [{"path": str(SAMPLE_STORE)}],
                                      "methods": methods, **extra})


def _variants(exp):
    return [v for m in exp.methods for v in m.variants()]


def test_a_list_for_a_scalar_parameter_is_a_sweep_of_labelled_variants():
    exp = _exp([{"name": "doppler", "params": {"tau_spatial_m": [2.0, 3.0, 4.0],
                                                "tau_doppler": 5.0}}])
    vs = _variants(exp)
    assert [v.label for v in vs] == ["doppler tau_spatial_m=2.0", "doppler tau_spatial_m=3.0",
                                     "doppler tau_spatial_m=4.0"]
    assert [v.params for v in vs] == [{"tau_spatial_m": x, "tau_doppler": 5.0}
                                      for x in (2.0, 3.0, 4.0)]
    assert all(v.group == "doppler" for v in vs)


def test_a_grid_over_several_keys_gives_every_combination_with_the_label_prefix():
    exp = _exp([{"name": "doppler-ego", "label": "ego", "params": {"voxel_m": [0.5, 1.0]},
                 "sweep": {"map_seconds": [0.5, 1.0, 2.0]}}])
    vs = _variants(exp)
    assert len(vs) == 6
    assert vs[0].label == "ego voxel_m=0.5 map_seconds=0.5"
    assert vs[-1].label == "ego voxel_m=1.0 map_seconds=2.0"
    assert {(v.params["voxel_m"], v.params["map_seconds"]) for v in vs} == {
        (a, b) for a in (0.5, 1.0) for b in (0.5, 1.0, 2.0)}


def test_a_list_valued_parameter_is_a_value_in_params_and_a_sweep_only_under_sweep():
    one = _variants(_exp([{"name": "doppler-ego", "params": {"angle_noise_deg": [0.4, 2.6]}}]))
    assert len(one) == 1 and one[0].label is None
    assert one[0].params == {"angle_noise_deg": [0.4, 2.6]}
    two = _variants(_exp([{"name": "doppler-ego",
                           "sweep": {"angle_noise_deg": [[0.4, 2.6], [0.3, 1.0]]}}]))
    assert [v.label for v in two] == ["doppler-ego angle_noise_deg=[0.4, 2.6]",
                                      "doppler-ego angle_noise_deg=[0.3, 1.0]"]


@pytest.mark.parametrize("entry, message", [
    ({"name": "doppler", "params": {"tau_spatial_m": [2.0, -1.0]}}, "tau_spatial_m"),
    ({"name": "doppler", "params": {"tau_spatial_m": []}}, "no values"),
    ({"name": "doppler", "params": {"tau_spatial_m": [2.0, 2.0]}}, "twice"),
    ({"name": "doppler", "params": {"tau_spatial_m": 3.0}, "sweep": {"tau_spatial_m": [1.0]}},
     "both"),
    ({"name": "doppler", "sweep": {"tau_spatail_m": [1.0]}}, "tau_spatail_m"),
])
def test_a_bad_sweep_is_one_clear_error(tmp_path, entry, message):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"name": "bad", "sequences": [{"path": str(SAMPLE_STORE)}],
                                    "methods": [entry]}))
    with pytest.raises(DataError, match=message):
        load_experiment(path)


def test_two_sweeps_with_the_same_labels_are_rejected():
    with pytest.raises(ValueError, match="listed twice"):
        _exp([{"name": "doppler", "params": {"tau_spatial_m": [2.0, 3.0]}},
              {"name": "doppler", "params": {"tau_spatial_m": [3.0, 4.0]}}])


def test_criterion_lengths_must_be_evaluated():
    with pytest.raises(ValueError, match="criterion lengths"):
        _exp([{"name": "doppler"}], lengths_m=[8, 16],
             criterion={"error": "rotation", "lengths_m": [48]})


def test_jobs_of_a_sweep_on_a_frame_range(tmp_path):
    exp = _exp([{"name": "doppler-ego", "seeds": [True], "params": {"voxel_m": [0.5, 1.0]}}],
               out=str(tmp_path))
    exp.sequences[0] = exp.sequences[0].model_copy(update={"start": 10, "frames": 20})
    jobs = jobs_for_experiment(exp)
    assert [(j.label, j.params, j.frame_range, j.seed) for j in jobs] == [
        ("doppler-ego voxel_m=0.5", {"voxel_m": 0.5}, (10, 20), True),
        ("doppler-ego voxel_m=1.0", {"voxel_m": 1.0}, (10, 20), True)]


# --- the table and the choice, on hand-made finished runs ---------------------------------

def _fake_runs(tmp_path, errors, criterion, defaults=(2.0,), tie_within=0.0, missing=(),
               keep=0.0):
    """A finished sweep of doppler tau_spatial_m over len(errors) points on two sequences:
    errors[i] = (rot at 8 m, trans at 8 m, rot at 48 m) of point i (the same on both)."""
    points = []
    for i, (r8, t8, r48) in enumerate(errors):
        value = float(i + 1)
        runs = []
        for seq in ("a", "b"):
            rel = f"{seq}/p{i}"
            runs.append({"sequence": seq, "seed": None, "dir": rel})
            if i in missing:
                continue
            d = tmp_path / rel
            d.mkdir(parents=True)
            rel_err = {"8": {"rot_deg_mean": r8, "trans_m_mean": t8, "n": 5},
                       "48": {"rot_deg_mean": r48, "trans_m_mean": 9.0, "n": 2}}
            (d / "metrics.json").write_text(json.dumps(
                {"sequence": seq, "method": "doppler", "seed": None,
                 "relative_error": rel_err}))
        points.append({"label": f"doppler tau_spatial_m={value}",
                       "point": {"tau_spatial_m": value}, "runs": runs})
    seqs = "ab"[:len(defaults)]
    write_sweep_index(tmp_path, {
        "experiment": "s", "criterion": {"error": criterion, "lengths_m": [8.0, 48.0],
                                         "tie_within": tie_within,
                                         "keep_default_within": keep},
        "default_differs": None,
        "sweeps": [{"method": "doppler", "group": "doppler", "keys": ["tau_spatial_m"],
                    "defaults": {s: {"tau_spatial_m": d}
                                 for s, d in zip(seqs, defaults, strict=True)},
                    "points": points}]})


def test_the_choice_is_the_lowest_mean_over_the_criterion_lengths(tmp_path):
    # rotation means over 8 and 48 m: 2.0, 1.5, 1.75 -> point 2 (tau 2.0), the default
    _fake_runs(tmp_path, [(1.0, 0.1, 3.0), (1.0, 0.3, 2.0), (0.5, 0.2, 3.0)], "rotation",
               defaults=(2.0, 2.0))
    (c,) = sweep_choices(tmp_path)
    assert c.point == {"tau_spatial_m": 2.0} and c.value == pytest.approx(1.5)
    assert c.agrees
    text = sweep_markdown(tmp_path)
    assert "agrees" in text and "**1.5000 chosen**" in text
    # best per length in bold: 8 m rotation is point 3's, 48 m rotation point 2's
    rows = [ln for ln in text.splitlines() if ln.startswith("| tau_spatial_m")]
    assert "**0.500**" in rows[2] and "**2.000**" in rows[1] and "(default)" in rows[1]
    assert "**0.100**" in rows[0]  # translation at 8 m: point 1


def test_translation_criterion_ties_and_a_differing_default(tmp_path):
    # translation at 8 and 48 m: (0.1+9)/2, (0.105+9)/2, (0.3+9)/2: point 1 wins outright
    _fake_runs(tmp_path, [(1, 0.1, 1), (1, 0.105, 1), (1, 0.3, 1)], "translation",
               defaults=(2.0, 2.0))
    (c,) = sweep_choices(tmp_path)
    assert c.point == {"tau_spatial_m": 1.0} and not c.agrees
    assert "DIFFERS" in sweep_markdown(tmp_path)


def test_tie_within_takes_the_first_listed_of_the_near_best(tmp_path):
    _fake_runs(tmp_path, [(1.004, 0, 1.004), (1.0, 0, 1.0), (2, 0, 2)], "rotation",
               tie_within=0.01)
    assert sweep_choices(tmp_path)[0].point == {"tau_spatial_m": 1.0}


def test_a_missing_run_is_never_chosen_and_is_named(tmp_path):
    _fake_runs(tmp_path, [(1, 0, 1), (0.1, 0, 0.1), (2, 0, 2)], "rotation", missing=(1,))
    (c,) = sweep_choices(tmp_path)
    assert c.point == {"tau_spatial_m": 1.0}
    assert c.missing == ["doppler tau_spatial_m=2.0"]
    assert "failed or not run" in sweep_markdown(tmp_path)


def test_the_index_names_each_point_s_runs_and_the_resolved_default(tmp_path):
    from bench.runs.plan import plan

    exp = _exp([{"name": "doppler-ego", "seeds": [True], "params": {"voxel_m": [0.5, 1.0]}}],
               out=str(tmp_path))
    jobs = plan(jobs_for_experiment(exp))
    index = sweep_index(exp, jobs)
    (s,) = index["sweeps"]
    assert s["keys"] == ["voxel_m"]
    assert s["defaults"] == {"ntu4dradlm-loop1": {"voxel_m": 0.5}}  # radar default resolved
    assert [p["runs"][0]["dir"] for p in s["points"]] == [
        "ntu4dradlm-loop1/doppler-ego-voxel_m-0.5_seed",
        "ntu4dradlm-loop1/doppler-ego-voxel_m-1.0_seed"]


def test_both_weighs_rotation_and_translation_by_their_means_over_the_points(tmp_path):
    # rot 8/48: (1, 1), (2, 2); trans 8/48: (0.1, 9), (0.05, 9) -> means rot 1.5, 1.5,
    # trans 0.075, 9: point 1: (1/1.5 + 1/1.5 + 0.1/0.075 + 1) / 4 = 0.9167, point 2:
    # (2/1.5 * 2 + 0.05/0.075 + 1) / 4 = 1.0833
    _fake_runs(tmp_path, [(1.0, 0.1, 1.0), (2.0, 0.05, 2.0)], "both")
    (c,) = sweep_choices(tmp_path)
    assert c.point == {"tau_spatial_m": 1.0} and c.value == pytest.approx(0.9166667)


def test_the_default_stays_unless_beaten_by_more_than_keep_default_within(tmp_path):
    # rotation means: 1.0, 0.995 (the default, tau 2.0), 0.98: 0.98 beats it by 1.5 %
    _fake_runs(tmp_path, [(1.0, 0, 1.0), (0.995, 0, 0.995), (0.98, 0, 0.98)], "rotation",
               keep=0.02)
    assert sweep_choices(tmp_path)[0].point == {"tau_spatial_m": 2.0}
    _fake_runs(tmp_path / "b", [(1.0, 0, 1.0), (0.995, 0, 0.995), (0.98, 0, 0.98)], "rotation",
               keep=0.01)
    assert sweep_choices(tmp_path / "b")[0].point == {"tau_spatial_m": 3.0}
