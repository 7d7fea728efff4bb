"""The independent reference pipelines of the ICP-family baselines (bench/studies/
independent_methods.py, a plugin) and the driver's comparison table (bench/studies/
independent.py). Open3D is a dev dependency: these tests fail without it, never skip."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from bench.studies import independent
from bench.studies import independent_methods as plugin
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import inv_T, make_T, rotation_angle_deg, transform_points
from methods import registry

ROOT = Path(__file__).resolve().parents[1]
REFERENCES = [cls.name for cls in plugin.METHODS]


@pytest.fixture
def registered(monkeypatch):
    for cls in plugin.METHODS:
        monkeypatch.setitem(registry.METHODS, cls.name, cls)


def test_plugin_registers_every_reference_through_the_environment():
    """``DOPPLER_BENCH_METHODS=bench.studies.independent_methods`` registers the five
    references (in a fresh process, as a worker loads them), each the reference of a
    baseline of the driver's table."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), registry.PLUGINS_ENV: independent.PLUGIN}
    code = ("import bench; from methods.registry import METHODS; "
            "print(' '.join(m for m in METHODS if m.startswith('ref-')))")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    assert sorted(out) == sorted(REFERENCES)
    assert {b.reference for b in independent.BASELINES} == set(REFERENCES)
    assert {b.method for b in independent.BASELINES} == {
        "icp-p2plane", "gicp", "vgicp", "dicp", "doppler-icp", "kiss-icp"}
    assert all(m in registry.METHODS for b in independent.BASELINES for m in [b.method])


def test_references_are_tuned_by_the_rule_over_both_halves_and_ours_run_at_defaults(
        registered):
    """The tuning YAML sweeps every reference on both halves of the real sample and the
    synthetic radar domain and decides by the tuning rule of configs/splits.yaml (its lengths,
    folds A -> B and B -> A, level, draws, least gain; the radar domain), against each
    reference's own default, which is a point of its grid; the ours YAML runs ours at their
    defaults on both halves, all with seed."""
    import yaml

    from bench.runs.experiment import load_experiment
    from bench.runs.sweep import format_value
    from methods.registry import make_method

    splits = yaml.safe_load((ROOT / "configs" / "splits.yaml").read_text())
    rule, halves = splits["rule"], splits["real"]["halves"]
    tuning = load_experiment(independent.TUNING)
    ours = load_experiment(independent.OURS)
    half_of = {s.name: next(h for h, v in halves.items()
                            if (v["start"], v["frames"]) == (s.start, s.frames))
               for s in tuning.sequences}
    assert sorted(half_of.values()) == ["A", "B"]
    c = tuning.criterion
    assert c.cross_validated and c.reference == {}
    assert c.lengths_m == rule["lengths_m"] and c.level == rule["level"]
    assert c.reps == rule["reps"] and c.min_gain == rule["min_gain"]
    assert [{"tuning": [half_of[n] for n in f.tuning],
             "validation": [half_of[n] for n in f.validation]} for f in c.folds] == rule["folds"]
    domain = splits["synthetic"]["radar_domain"]
    by_name = {s.name: s for s in tuning.synthetic}
    assert sorted(by_name[n].seed for n in c.domain) == domain["seeds"]
    assert all((by_name[n].scene, by_name[n].sensor, by_name[n].frames)
               == (domain["scene"], domain["sensor"], domain["frames"]) for n in c.domain)
    assert {m.name for m in tuning.methods} == set(REFERENCES)
    for m in tuning.methods:
        assert m.sweep and m.seeds == [True]
        default = make_method(m.name, {}, None, True).params
        points = [{k: format_value(v) for k, v in p.point.items()} for p in m.variants()]
        assert {k: format_value(getattr(default, k)) for k in m.sweep} in points, \
            f"{m.name}: its own default is not a point of its grid"
    assert [(s.start, s.frames) for s in ours.sequences] == sorted(
        (h["start"], h["frames"]) for h in halves.values())
    assert [s.name for s in ours.sequences] == [s.name for s in tuning.sequences]
    assert sorted(m.name for m in ours.methods) == sorted(
        {b.method for b in independent.BASELINES})
    for m in ours.methods:
        assert m.seeds == [True] and m.label is None and not m.sweep
        assert m.params == {}, f"{m.name} must run at its defaults"


def test_recorded_decisions_name_a_grid_point_for_every_reference_and_half(registered):
    """``decided:`` of the tuning YAML: per reference the rule's decision over both folds and
    each half's own choice, each a point of the reference's grid."""
    from bench.runs.experiment import load_experiment
    from bench.runs.sweep import format_value

    tuning = load_experiment(independent.TUNING)
    assert tuning.decided is not None
    keys = {independent.RULE} | {f.tuning[0] for f in tuning.criterion.folds}
    for m in tuning.methods:
        recorded = tuning.decided[m.name]
        assert set(recorded) == keys, m.name
        points = [{k: format_value(v) for k, v in p.point.items()} for p in m.variants()]
        for key, point in recorded.items():
            assert {k: format_value(v) for k, v in point.items()} in points, (m.name, key)


def _room_pair(frames: int = 3) -> tuple[MemorySequence, np.ndarray]:
    """Static structure (a floor, four walls, four pillars) seen from a sensor moving 0.8 m
    and turning 1.5 deg per 0.1 s frame, with exact radial Doppler (positive receding);
    returns the sequence and the true motion T_curr_prev of each step."""
    rng = np.random.default_rng(7)

    def plane(n, fixed_axis, value, lo, hi):
        p = rng.uniform(lo, hi, (n, 3))
        p[:, fixed_axis] = value
        return p

    parts = [plane(2500, 2, -1.5, [-30, -30, 0], [30, 30, 0]),
             plane(700, 0, 25.0, [0, -22, -1.5], [0, 22, 4]),
             plane(700, 0, -25.0, [0, -22, -1.5], [0, 22, 4]),
             plane(700, 1, 22.0, [-25, 0, -1.5], [25, 0, 4]),
             plane(700, 1, -22.0, [-25, 0, -1.5], [25, 0, 4])]
    for cx, cy in [(8, 6), (-6, 9), (10, -7), (-9, -5)]:
        a, z = rng.uniform(0, 2 * np.pi, 250), rng.uniform(-1.5, 3, 250)
        parts.append(np.c_[cx + 0.6 * np.cos(a), cy + 0.6 * np.sin(a), z])
    world = np.vstack(parts)
    period_s, yaw = 0.1, np.radians(1.5)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    T_prev_curr = make_T(R, np.array([0.8, 0.05, 0.0]))  # the sensor's motion per frame
    scans, T_world_sensor = [], np.eye(4)
    for k in range(frames):
        pts = transform_points(inv_T(T_world_sensor), world)
        # sensor velocity in its own frame (the motion over the period): Doppler of a static
        # point = -(unit direction) . v
        v = T_prev_curr[:3, 3] / period_s
        doppler = -(pts / np.linalg.norm(pts, axis=1, keepdims=True)) @ v
        scans.append(Scan(k * period_s, pts, doppler))
        T_world_sensor = T_world_sensor @ T_prev_curr
    sensor = SensorInfo("radar", period_s, np.eye(4), "test-room")
    return MemorySequence("room", sensor, scans), inv_T(T_prev_curr)


@pytest.mark.parametrize("name", REFERENCES)
def test_each_reference_pipeline_recovers_a_known_motion(name, registered):
    """Each library's pipeline, run by the harness's driver with seed, recovers the true
    frame-to-frame motion (0.8 m, 1.5 deg) of a static scene within 2 cm and 0.05 deg per
    step (a method that does not move is 0.8 m off)."""
    seq, T_true = _room_pair()
    method = registry.make_method(name, {}, seq.sensor, True)
    result = method.run(seq, seed=True)
    for k in range(1, len(seq)):
        T_curr_prev = inv_T(result.poses[k]) @ result.poses[k - 1]
        D = inv_T(T_true) @ T_curr_prev
        assert np.linalg.norm(D[:3, 3]) < 0.02, (name, k, D[:3, 3])
        assert rotation_angle_deg(D[:3, :3]) < 0.05, (name, k)
    assert all(f.points > 100 for f in result.frames)


def test_dicp_reference_is_open3d_dicp_with_the_sequence_extrinsic(registered):
    """The DICP reference is ``methods.dicp`` on Open3D's backend (not a copy), keeps its
    class and backend when the sensor's extrinsic is resolved, and refuses the other
    backend."""
    from pydantic import ValidationError

    from methods.dicp import Dicp

    T = make_T(np.eye(3), np.array([1.0, 0.0, 0.5]))
    method = registry.make_method("ref-open3d-dicp", {}, SensorInfo("radar", 0.1, T), True)
    assert isinstance(method, Dicp) and type(method).name == "ref-open3d-dicp"
    assert method.params.backend == "open3d"
    assert np.allclose(method.T_vehicle_sensor, T)
    with pytest.raises(ValidationError):
        registry.make_method("ref-open3d-dicp", {"backend": "numba"})


def test_kiss_reference_takes_kiss_icps_default_config_and_voxel_rule(registered):
    """kiss-icp's own defaults (KISSConfig) but the ranges, and its voxel rule max_range /
    100 unless a voxel is given."""
    from kiss_icp.config import KISSConfig

    default = KISSConfig()
    config = registry.make_method("ref-kiss-icp", {"max_range_m": 200.0}).config()
    assert config.data.max_range == 200.0 and config.mapping.voxel_size == 2.0
    assert config.adaptive_threshold == default.adaptive_threshold
    assert config.data.deskew == default.data.deskew
    assert config.registration.max_num_iterations == default.registration.max_num_iterations
    assert config.mapping.max_points_per_voxel == default.mapping.max_points_per_voxel
    given = registry.make_method("ref-kiss-icp", {"voxel_size_m": 0.5}).config()
    assert given.data.max_range == 100.0 and given.mapping.voxel_size == 0.5


def _errors(rot8, trans8, rot48, trans48):
    return {8.0: (rot8, trans8), 48.0: (rot48, trans48)}


def test_comparison_table_computes_ours_over_reference_and_the_limit():
    """On hand-made errors: each ratio is ours / reference per length and error, a baseline
    passes only when all four are at most 1.15, a missing run or length is no pass, and the
    table shows each ratio (over the limit in bold) and the verdict."""
    errors = {"icp-p2plane": _errors(1.0, 0.5, 2.0, 2.0),
              "ref-open3d-p2plane": _errors(1.0, 0.5, 2.0, 1.6),       # 48 m translation 1.25x
              "gicp": _errors(0.9, 0.45, 1.9, 2.3),
              "ref-open3d-gicp": _errors(1.0, 0.5, 2.0, 2.0),          # 1.15x exactly: passes
              "vgicp": _errors(0.5, 0.5, 1.0, 1.0),
              "ref-small-gicp-vgicp": {8.0: (0.5, 0.5)},               # no 48 m segments
              "dicp": _errors(0.6, 0.6, 1.2, 3.0),
              "ref-open3d-dicp": _errors(0.5, 0.6, 1.2, 3.0),          # rotation 8 m 1.2x
              "doppler-icp": _errors(0.45, 0.5, 1.0, 2.0),             # better: at most 0.9x
              "ref-kiss-icp": _errors(1.0, 1.0, 1.0, 1.0)}             # kiss-icp: no run
    rows = {c.baseline.method: c for c in independent.compare(errors)}
    p2plane = rows["icp-p2plane"]
    assert p2plane.ratios() == pytest.approx([1.0, 1.0, 1.0, 1.25])
    assert p2plane.worst == pytest.approx(1.25) and not p2plane.passed
    assert rows["gicp"].ratio(48.0, 1) == pytest.approx(1.15) and rows["gicp"].passed
    assert rows["gicp"].ratio(8.0, 0) == pytest.approx(0.9)
    assert rows["vgicp"].ratio(48.0, 0) is None and rows["vgicp"].worst is None
    assert not rows["vgicp"].passed
    assert rows["dicp"].ratio(8.0, 0) == pytest.approx(1.2) and not rows["dicp"].passed
    assert rows["doppler-icp"].worst == pytest.approx(0.9) and rows["doppler-icp"].passed
    assert rows["kiss-icp"].ours is None and not rows["kiss-icp"].passed
    text = independent.table_markdown(list(rows.values()))
    assert "| `icp-p2plane` | `ref-open3d-p2plane` |" in text
    assert "1.00 / **1.25**" in text and "NO (worst 1.25x)" in text
    assert "yes (worst 1.15x)" in text and "no run" in text
    assert "NOT the same algorithm" in text  # doppler-icp's reference says what it is


def _tuned(factor_a: float, factor_b: float):
    """A reference sweep of three points (the default, gate 1.0; 3.0; 5.0) on halves A, B
    and a domain S: gate 3.0 has ``factor_a`` / ``factor_b`` times the default's errors, 5.0
    1.3 times everywhere."""
    from bench.runs.tuning_rule import RunErrors
    from metrics.units import Units

    rng = np.random.default_rng(3)

    def errors(factor: float) -> RunErrors:
        units = {}
        for length, span in ((8.0, 10), (48.0, 60)):
            anchor = np.arange(200 - span)
            base = {k: np.abs(1 + 0.2 * rng.standard_normal(anchor.size)) for k in
                    ("rot_deg", "trans_m")}
            units[length] = Units(anchor, anchor + span, base)
        return RunErrors(200, units)

    ref = {n: errors(1.0) for n in ("A", "B", "S")}

    def scaled(e, f):
        return RunErrors(e.n_frames, {x: Units(u.anchor, u.end, {k: v * f for k, v in
                                                                 u.values.items()})
                                      for x, u in e.units.items()})

    point = {"A": scaled(ref["A"], factor_a), "B": scaled(ref["B"], factor_b), "S": ref["S"]}
    worse = {n: scaled(e, 1.3) for n, e in ref.items()}
    criterion = {"lengths_m": [8, 48], "folds": [{"tuning": ["A"], "validation": ["B"]},
                                                 {"tuning": ["B"], "validation": ["A"]}],
                 "domain": ["S"], "reps": 200, "min_gain": 0.01}
    points = [{"gate": 1.0}, {"gate": 3.0}, {"gate": 5.0}]
    return independent.Tuned("ref-x", points, [{}, {}, {}], independent.half_choices(
        points, [ref, point, worse], 0, criterion))


def test_each_half_chooses_alone_and_the_rule_needs_both():
    """Gate 3.0 is 20 % better on A and 5 % worse on B: A's own choice is 3.0, B's the
    default, and the rule over both folds keeps the default (it reverses on B). Better on
    both: every decision takes 3.0. A decision that asks for a wider grid leaves the default
    in use; an undecided one, nothing."""
    from bench.runs.tuning_rule import Decision

    t = _tuned(0.8, 1.05)
    assert t.setting("A") == {"gate": 3.0} and t.setting("B") == {"gate": 1.0}
    assert t.setting(independent.RULE) == {"gate": 1.0}
    assert "reverses on B" in t.decisions[independent.RULE].verdicts[1].why
    both = _tuned(0.8, 0.8)
    assert all(both.setting(k) == {"gate": 3.0} for k in ("A", "B", independent.RULE))
    extend = Decision(0, None, [], "EXTEND THE GRID", extend=True)
    assert independent.effective(extend, t.points) == {"gate": 1.0}
    assert independent.effective(Decision(0, None, [], "undecided"), t.points) is None


def test_stale_decisions_name_a_recorded_setting_the_runs_do_not_decide():
    t = _tuned(0.8, 1.05)
    good = {"ref-x": {"rule": {"gate": 1.0}, "A": {"gate": 3.0}, "B": {"gate": 1.0}}}
    assert independent.stale_decisions({"ref-x": t}, good) == []
    bad = {"ref-x": {"rule": {"gate": 1.0}, "A": {"gate": 1.0}}}
    stale = independent.stale_decisions({"ref-x": t}, bad)
    assert len(stale) == 2
    assert stale[0].startswith("ref-x (A): decided records gate=1.0 but the runs decide gate=3.0")
    assert stale[1].startswith("ref-x (B): decided records - but")


def test_cross_fitted_rows_score_each_half_against_the_other_half_s_choice(tmp_path,
                                                                         monkeypatch):
    """Each half's row uses the reference's run at the setting chosen on the other half."""
    from types import SimpleNamespace

    t = _tuned(0.8, 1.05)  # A chooses gate 3.0, B the default 1.0
    t.runs = [{"A": tmp_path / "d1-A", "B": tmp_path / "d1-B"},
              {"A": tmp_path / "d3-A", "B": tmp_path / "d3-B"}, {}]
    values = {"d1-A": 2.0, "d1-B": 3.0, "d3-A": 4.0, "d3-B": 5.0}

    def read_run(path):
        v = values[Path(path).name]
        rel = [SimpleNamespace(length_m=x, n=5, rot_deg_mean=v, trans_m_mean=10 * v)
               for x in (8.0, 48.0)]
        return SimpleNamespace(result=SimpleNamespace(relative_error=rel))

    from bench.runs import folders

    monkeypatch.setattr(folders, "read_run", read_run)
    monkeypatch.setattr(independent, "errors_by_method", lambda _d, _l, half: {
        "ours-x": {8.0: (1.0, 10.0), 48.0: (1.0, 10.0)}})
    baseline = independent.Baseline("ours-x", "ref-x", "a test reference")
    rows = independent.cross_fitted({"ref-x": t}, tmp_path, ["A", "B"], [baseline])
    by_half = {c.half: c for c in rows}
    # half A is scored against B's choice (1.0): d1-A; half B against A's (3.0): d3-B
    assert by_half["A"].tuned_on == "B" and by_half["A"].setting == {"gate": 1.0}
    assert by_half["A"].ratio(8.0, 0) == pytest.approx(1.0 / 2.0)
    assert by_half["B"].tuned_on == "A" and by_half["B"].setting == {"gate": 3.0}
    assert by_half["B"].ratio(48.0, 1) == pytest.approx(10.0 / 50.0)
    text = independent.table_markdown(rows)
    assert "| `ours-x` | `ref-x` | B | gate=3.0 (A) |" in text
