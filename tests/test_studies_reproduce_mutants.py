"""Mutation-testing kills for bench/studies/reproduce.py (its code changed since 942ccd0): the
output checks made before anything runs, the removal of a stale table (ours only), and the
tables' plans (quiet each, one union that runs a shared run once)."""

from __future__ import annotations

import io
import warnings

import numpy as np
import pytest
from rich.console import Console

from bench import guard
from bench.runs.experiment import Experiment
from bench.studies.reproduce import TABLES, _check_outputs, _remove_stale, plan_tables
from conftest import SAMPLE_STORE


def _console() -> tuple[Console, io.StringIO]:
    buf = io.StringIO()
    return Console(file=buf, width=300), buf


def _said(buf: io.StringIO) -> str:
    return " ".join(buf.getvalue().split())


def _regenerated_names() -> list[str]:
    """Every file a reproduction may replace, from the module's documented layout: each
    table's .md/.tex/.csv (with the KITTI-drift and velocity variants), the page, the
    fidelity report and the record."""
    names = [f"{n}.{fmt}" for _, stem, _ in TABLES.values()
             for n in (stem, f"{stem}_kitti", f"{stem}_velocity") for fmt in ("md", "tex", "csv")]
    return names + ["report.html", "fidelity.md", "fidelity.csv", "reproduction.json"]


def test_the_tables_are_the_papers_three():
    assert list(TABLES) == ["table3", "table4", "table5"]
    assert [stem for _, stem, _ in TABLES.values()] == ["table3", "table4", "table5"]


def test_an_output_folder_of_no_such_files_or_of_our_own_files_passes(tmp_path):
    _check_outputs(tmp_path / "new")  # a folder not made yet
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.md").write_text("mine\n")  # a user's file of another name is no concern
    for name in _regenerated_names():
        guard.write_text(out / name, "ours\n", guard.derived, "a table")
    _check_outputs(out)


@pytest.mark.parametrize("name, what", [
    ("table3.md", "a table"), ("table3.tex", "a table"), ("table3.csv", "a table"),
    ("table3_kitti.md", "a table"), ("table4_velocity.csv", "a table"),
    ("table5.tex", "a table"), ("table5_kitti.csv", "a table"),
    ("report.html", "a report page"),
    ("fidelity.md", "a reproduction record"), ("fidelity.csv", "a reproduction record"),
    ("reproduction.json", "a reproduction record"),
])
def test_a_users_file_where_a_reproduction_writes_is_refused_naming_what(tmp_path, name, what):
    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_text("a user's own file\n")
    with pytest.raises(guard.Refused) as err:
        _check_outputs(out)
    said = str(err.value)
    assert f"--out {out / name}: exists and is not {what} this command wrote" in said


def test_an_output_that_is_a_file_is_refused(tmp_path):
    out = tmp_path / "out"
    out.write_text("x\n")
    with pytest.raises(guard.Refused) as err:
        _check_outputs(out)
    assert str(err.value) == f"--out {out}: is a file; expected a folder to write into"


def test_a_stale_table_of_ours_is_removed_and_said_a_users_is_left(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    for fmt in ("md", "tex", "csv"):
        guard.write_text(out / f"table5.{fmt}", "old\n", guard.derived, "a table")
    guard.write_text(out / "table4.md", "other table\n", guard.derived, "a table")
    console, buf = _console()
    _remove_stale(out, "table5", console)
    assert not any((out / f"table5.{fmt}").exists() for fmt in ("md", "tex", "csv"))
    assert (out / "table4.md").exists()  # another table's files stay
    assert _said(buf) == (f"removed {out}/table5.* of an earlier reproduction (not part of "
                          "this one)")


@pytest.mark.parametrize("fmt", ["md", "tex", "csv"])
def test_each_format_of_a_stale_table_is_removed_alone(tmp_path, fmt):
    out = tmp_path / "out"
    out.mkdir()
    guard.write_text(out / f"table5.{fmt}", "old\n", guard.derived, "a table")
    console, buf = _console()
    _remove_stale(out, "table5", console)
    assert not (out / f"table5.{fmt}").exists()
    assert "removed" in _said(buf)


def test_nothing_to_remove_or_a_users_file_says_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "table5.md").write_text("the user's notes\n")
    console, buf = _console()
    _remove_stale(out, "table5", console)
    assert (out / "table5.md").read_text() == "the user's notes\n"
    assert buf.getvalue() == ""


def _experiments(out, names=("table3", "table4")):
    return {name: Experiment.model_validate({
        "name": name, "sequences": [{"path": str(SAMPLE_STORE)}],
        "methods": [{"name": "doppler"}], "out": str(out)}) for name in names}


def test_tables_sharing_a_run_plan_it_once_and_the_per_table_plans_are_quiet(tmp_path):
    experiments = _experiments(tmp_path / "out")
    console, _ = _console()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        per_table, union = plan_tables(experiments, console)
    assert set(per_table) == {"table3", "table4"}
    assert len(per_table["table3"]) == len(per_table["table4"]) == 1
    # the two tables name the same run folder: the union runs it once
    assert per_table["table3"][0].run_dir_override == per_table["table4"][0].run_dir_override
    assert len(union) == 1
    assert union[0].run_dir_override == per_table["table3"][0].run_dir_override
    # each warning the union's plan gives is said once (per-table plans ignored theirs)
    said = [str(w.message) for w in caught]
    assert said and len(said) == len(set(said))


def test_tables_of_different_runs_plan_them_all(tmp_path):
    experiments = _experiments(tmp_path / "a", names=("table3",))
    experiments |= {"table4": _experiments(tmp_path / "b", names=("table4",))["table4"]}
    console, _ = _console()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        per_table, union = plan_tables(experiments, console)
    assert len(union) == 2
    assert ({j.run_dir_override for j in union}
            == {per_table[n][0].run_dir_override for n in ("table3", "table4")})


PAPER_SEQUENCES = {"Campus1", "Campus2", "CurvedWall", "StraightWall", "Tunnel_Empty",
                   "Tunnel_Vehicles", "Loop1_0", "Loop1_1", "Loop1_2", "Loop1_3", "Loop1_4"}


def test_paper_sequences_found_and_missing_by_their_store_under_real(tmp_path):
    from bench.studies.reproduce import missing_sequences, real_sequences

    (tmp_path / "real").mkdir()
    assert real_sequences(tmp_path) == []
    assert set(missing_sequences(tmp_path)) == PAPER_SEQUENCES
    assert len(missing_sequences(tmp_path)) == 11
    # a paper sequence's store and a public route's (paper: false) store
    (tmp_path / "real" / "Tunnel_Empty.h5").write_bytes(b"")
    (tmp_path / "real" / "NTU4DRadLM_loop1.h5").write_bytes(b"")
    (tmp_path / "Loop1_0.h5").write_bytes(b"")  # not under real/: not found
    found = real_sequences(tmp_path)
    assert [s.name for s in found] == ["Tunnel_Empty"]
    assert found[0].path == tmp_path / "real" / "Tunnel_Empty.h5"
    assert found[0].display_name == "Baker-Barry Tunnel (Empty)"
    assert found[0].sensor_class == "Dense 4D LiDAR"
    assert set(missing_sequences(tmp_path)) == PAPER_SEQUENCES - {"Tunnel_Empty"}


def test_a_tables_sequences_are_its_methods_in_the_yamls_order_once():
    from bench.studies.reproduce import _columns, table_sequences

    assert table_sequences("table5") == ["Tunnel_Empty", "Tunnel_Vehicles"]
    assert table_sequences("table4") == ["Loop1_0", "Loop1_1", "Loop1_3", "Loop1_4"]
    from bench.paths import EXPERIMENTS
    from bench.runs.experiment import load_experiment

    assert _columns(load_experiment(EXPERIMENTS / "table4.yaml")) == [
        "Loop1_0", "Loop1_1", "Loop1_3", "Loop1_4"]


def test_table_experiments_keep_the_tables_with_rows_pointed_at_out(tmp_path):
    from bench.runs.experiment import SequenceEntry
    from bench.studies.reproduce import table_experiments

    out, data = tmp_path / "out", tmp_path / "data"
    synthetic = table_experiments(out, data, [])
    assert list(synthetic) == ["table3", "table4", "table5"]
    assert all(e.out == out and e.data_dir == data and e.suite == "synthetic-paper"
               for e in synthetic.values())
    tunnel = SequenceEntry(path=data / "real" / "Tunnel_Empty.h5", name="Tunnel_Empty")
    real = table_experiments(out, data, [tunnel])
    # table4 names no tunnel: left out; table3 and table5 keep only the tunnel
    assert list(real) == ["table3", "table5"]
    for exp in real.values():
        assert exp.suite is None and [s.name for s in exp.sequences] == ["Tunnel_Empty"]
        assert exp.methods and all(m.sequences == ["Tunnel_Empty"] for m in exp.methods)
    assert len(real["table5"].methods) == 8


@pytest.fixture(scope="module")
def twist_store(tmp_path_factory):
    """10 LiDAR frames 0.1 s apart at 8 m/s: 0.9 s, a ground-truth path of 7.2 m."""
    from conftest import constant_twist_sequence
    from loaders.store import write_store

    path = tmp_path_factory.mktemp("store") / "twist.h5"
    write_store(constant_twist_sequence(n_frames=10, n_points=200, w=(0, 0, 0)), path)
    return path


def _cfg(kind, period_s, path_m):
    from types import SimpleNamespace

    return SimpleNamespace(name="X", sensor_class="Dense 4D LiDAR", expected=SimpleNamespace(
        sensor_kind=kind, period_s=period_s, path_m=path_m, source="src"))


def test_check_store_describes_it_and_is_silent_when_it_matches(twist_store):
    from bench.studies.reproduce import check_store

    described, warns = check_store(_cfg("lidar", 0.1, 7.2), twist_store)
    assert described == "X: 10 frames, 0.9 s, lidar (test), period 0.1000 s, GT path 7 m"
    assert warns == []
    # nothing expected: nothing checked
    assert check_store(_cfg("", 0.0, 0.0), twist_store)[1] == []


def test_check_store_warns_of_kind_period_path_and_speed_far_off(twist_store):
    from bench.studies.reproduce import check_store

    _, warns = check_store(_cfg("radar", 0.2, 100.0), twist_store)
    p = twist_store
    assert warns[0] == (f"{p}: a lidar store, but X is a radar sequence (Dense 4D LiDAR): is "
                        "it the right store?")
    assert warns[1] == f"{p}: scans 0.1000 s apart, but X's sensor scans every 0.2000 s (src)"
    assert warns[2] == (f"{p}: its ground truth's path is 7 m (1 s), far from X's about "
                        "100 m (src): a part of the sequence, or another one? Its numbers are "
                        "not the paper's")
    # 100 m in 0.9 s: 111.1 m/s
    assert warns[3] == (f"{p}: 1 s of scans, but X covers about 100 m: that would be "
                        "111.1 m/s (expected 0.3-40 m/s), so the store's duration is far off: "
                        "a part of the sequence, or another one?")
    assert len(warns) == 4


@pytest.mark.parametrize("period_s, far", [(0.126, False), (0.14, True), (0.081, False),
                                           (0.075, True)])
def test_check_store_period_tolerance_is_a_quarter(twist_store, period_s, far):
    from bench.studies.reproduce import check_store

    warns = check_store(_cfg("lidar", period_s, 0.0), twist_store)[1]
    assert bool(warns) is far


@pytest.mark.parametrize("path_m, far", [(21.0, False), (23.0, True), (2.5, False),
                                         (2.3, True)])
def test_check_store_path_within_a_factor_three(twist_store, path_m, far):
    from bench.studies.reproduce import check_store

    warns = check_store(_cfg("lidar", 0.1, path_m), twist_store)[1]
    assert any("far from X's" in w for w in warns) is far


def test_a_tables_plan_says_a_skipped_optional_store_on_the_console(tmp_path):
    absent = tmp_path / "absent.h5"
    exp = Experiment.model_validate({
        "name": "table3", "out": str(tmp_path / "out"), "methods": [{"name": "doppler"}],
        "sequences": [{"path": str(SAMPLE_STORE)}, {"path": str(absent), "optional": True}]})
    console, buf = _console()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        per_table, union = plan_tables({"table3": exp}, console)
    said = _said(buf)
    assert "table3: skipped" in said and "absent.h5" in said and "not found" in said
    assert len(per_table["table3"]) == len(union) == 1


def test_a_removed_tables_message_shows_a_folder_name_with_brackets_as_it_is(tmp_path):
    out = tmp_path / "[red]run"
    out.mkdir()
    guard.write_text(out / "table5.md", "old\n", guard.derived, "a table")
    console, buf = _console()
    _remove_stale(out, "table5", console)
    assert f"removed {out}/table5.*" in _said(buf)


def test_check_store_speed_is_path_over_duration(twist_store):
    from bench.studies.reproduce import check_store

    # 0.3 m in 0.9 s is 0.33 m/s, a speed (far path aside)
    warns = check_store(_cfg("lidar", 0.1, 0.3), twist_store)[1]
    assert not any("m/s" in w for w in warns) and len(warns) == 1


def _store(tmp_path, n_frames, gt=True, model="test"):
    from conftest import constant_twist_sequence
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.store import write_store

    seq = constant_twist_sequence(n_frames=n_frames, n_points=200, w=(0, 0, 0))
    scans = [seq.scan(i) for i in range(len(seq))]
    seq = MemorySequence("s", SensorInfo("lidar", 0.1, model=model), scans,
                         seq.ground_truth if gt else None, {})
    path = tmp_path / "s.h5"
    write_store(seq, path)
    return path


def test_check_store_of_one_frame_has_no_duration_and_no_path(tmp_path):
    from bench.studies.reproduce import check_store

    path = _store(tmp_path, 1)
    described, warns = check_store(_cfg("lidar", 0.1, 100.0), path)
    assert described == "X: 1 frames, 0.0 s, lidar (test), period 0.1000 s, GT path none"
    assert warns == [f"{path}: no ground truth: X gives no table row"]


def test_check_store_of_two_frames_and_no_model_or_ground_truth(tmp_path):
    from bench.studies.reproduce import check_store

    path = _store(tmp_path, 2, gt=False, model="")
    described, warns = check_store(_cfg("", 0.0, 0.0), path)
    assert described == ("X: 2 frames, 0.1 s, lidar (model not recorded), period 0.1000 s, "
                         "GT path none")
    assert warns == [f"{path}: no ground truth: X gives no table row"]


def test_check_store_of_two_late_frames_uses_their_stamps_not_the_nominal_period(tmp_path):
    """Two frames at 5.0 and 5.1 s, 8 m/s apart (0.8 m of ground truth), a sensor whose
    nominal period (0.2 s) is not the stamps' spacing."""
    import dataclasses

    from bench.studies.reproduce import check_store
    from conftest import constant_twist_sequence
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.store import write_store
    from loaders.trajectory import Trajectory

    seq = constant_twist_sequence(n_frames=2, n_points=200, w=(0, 0, 0))
    scans = [dataclasses.replace(seq.scan(i), stamp=5.0 + 0.1 * i) for i in range(2)]
    gt = Trajectory(np.array([5.0, 5.1]), seq.ground_truth.poses)
    path = tmp_path / "late.h5"
    write_store(MemorySequence("s", SensorInfo("lidar", 0.2, model="test"), scans, gt, {}),
                path)
    described, warns = check_store(_cfg("", 0.0, 0.0), path)
    assert described == "X: 2 frames, 0.1 s, lidar (test), period 0.1000 s, GT path 1 m"
    assert warns == []


@pytest.fixture(scope="module")
def exact_store(tmp_path_factory):
    """Two frames 0.625 s apart, 3 m of ground truth: binary-exact numbers, so that each
    tolerance can be met exactly at its end."""
    import dataclasses

    from conftest import constant_twist_sequence
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.store import write_store
    from loaders.trajectory import Trajectory

    seq = constant_twist_sequence(n_frames=2, n_points=200, w=(0, 0, 0))
    scans = [dataclasses.replace(seq.scan(i), stamp=0.625 * i) for i in range(2)]
    poses = np.stack([np.eye(4), np.eye(4)])
    poses[1, 0, 3] = 3.0
    path = tmp_path_factory.mktemp("exact") / "exact.h5"
    write_store(MemorySequence("s", SensorInfo("lidar", 0.625, model="test"), scans,
                               Trajectory(np.array([0.0, 0.625]), poses), {}), path)
    return path


@pytest.mark.parametrize("period_s, path_m, far", [
    (0.5, 0.0, ()),                   # 0.625 / 0.5 - 1 = 0.25: the tolerance's end holds
    (0.0, 9.0, ()),                   # 3 m = 9 m / 3: the factor's end holds
    (0.0, 1.0, ()),                   # 3 m = 1 m * 3
    (0.0, 25.0, ("far from",)),       # 25 m in 0.625 s = 40 m/s: the top speed holds
    (0.0, 0.1875, ("far from",)),     # 0.1875 m in 0.625 s = 0.3 m/s: the lowest holds
])
def test_check_store_tolerances_hold_their_ends(exact_store, period_s, path_m, far):
    from bench.studies.reproduce import check_store

    described, warns = check_store(_cfg("lidar", period_s, path_m), exact_store)
    assert described.endswith("0.6 s, lidar (test), period 0.6250 s, GT path 3 m")
    assert len(warns) == len(far) and all(f in w for f, w in zip(far, warns, strict=True))


def test_choose_data_synthetic_when_asked_or_when_no_store(tmp_path, twist_store):
    from bench.studies.reproduce import _choose_data

    data = tmp_path / "[red]data"  # a bracket in a path is shown as it is (no markup)
    real_dir = data / "real"
    real_dir.mkdir(parents=True)
    console, buf = _console()
    assert _choose_data(data, True, console) == ([], [])
    assert _said(buf) == "synthetic only (as asked): using the synthetic suite 'synthetic-paper'"
    console, buf = _console()
    assert _choose_data(data, False, console) == ([], [])
    assert _said(buf) == (f"no real stores under {real_dir} (the paper's sequences, "
                          "configs/datasets/*.yaml): using the synthetic suite "
                          "'synthetic-paper'")
    import shutil

    shutil.copy(twist_store, real_dir / "Loop1_0.h5")
    shutil.copy(twist_store, real_dir / "Loop1_1.h5")
    console, buf = _console()
    assert _choose_data(data, True, console) == ([], [])
    assert _said(buf) == ("synthetic only (as asked): using the synthetic suite "
                          f"'synthetic-paper' (ignoring 2 real store(s) under {real_dir}: "
                          "Loop1_0, Loop1_1)")


def test_choose_data_uses_the_real_stores_and_notes_the_missing_and_far_off(tmp_path,
                                                                           twist_store):
    import shutil

    from bench.studies.reproduce import _choose_data

    data = tmp_path / "[red]data"  # a bracket in a path is shown as it is (no markup)
    real_dir = data / "real"
    real_dir.mkdir(parents=True)
    shutil.copy(twist_store, real_dir / "Loop1_0.h5")
    shutil.copy(twist_store, real_dir / "Loop1_1.h5")
    console, buf = _console()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found, notes = _choose_data(data, False, console)
    said = _said(buf)
    assert [s.name for s in found] == ["Loop1_0", "Loop1_1"]
    missing = sorted(PAPER_SEQUENCES - {"Loop1_0", "Loop1_1"})
    assert notes[0] == (f"missing (9 of 11): {', '.join(missing)}; the tables hold only the "
                        "sequences found (configs/datasets/NAME.yaml says how to convert each)")
    assert (f"real stores under {real_dir}: 2 of the paper's 11 sequences found (Loop1_0, "
            "Loop1_1)") in said
    assert notes[0] in said
    # the 7 m LiDAR store is far from Loop1_0 (a radar sequence of about 1.4 km)
    assert "Loop1_0: 10 frames, 0.9 s, lidar (test)" in said
    far = notes[1:]
    assert far and any("a lidar store, but Loop1_0 is a radar sequence" in w for w in far)
    assert [str(w.message) for w in caught if str(w.message) in far] == far
