"""bench/commands.py (``bench run``, ``bench score``, ``bench synth``'s dispatch) in-process,
the planner, runner, scorer and table writers replaced by stand-ins that record what they were
asked: the option checks and their messages, the run's path through an experiment or a single
run, the tables and sweep table guarded and printed, the exit codes, and the run summary's
lines worked out by hand."""

from __future__ import annotations

import io
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest
from rich.console import Console

import bench.commands as commands
import bench.report.tables.ape as tables_ape
import bench.report.tables.paper as paper
import bench.report.tables.sweep as tables_sweep
import bench.runs.experiment as experiment
import bench.runs.external.score as external_score
import bench.runs.job as job
import bench.runs.plan as planning
import bench.runs.progress as progress
import bench.runs.sweep as runs_sweep
import metrics.drift_intervals as drift_intervals
from bench import guard
from bench.commands import (
    _with_ci,
    check_external,
    check_tables,
    parse_lengths,
    print_run_summary,
    print_sweeps,
    run_command,
    score_command,
    scoring_options,
    synth_dispatch,
)
from loaders.errors import DataError


def _console() -> Console:
    return Console(file=io.StringIO(), width=1000, color_system=None)


def _out(console) -> list[str]:
    return console.file.getvalue().splitlines()


# --- the option parsers -----------------------------------------------------------------------

def test_lengths_are_positive_numbers_in_metres():
    assert parse_lengths(None) is None
    assert parse_lengths("8,16.5, 48") == (8.0, 16.5, 48.0)
    for text, message in (("8,x", "--lengths '8,x': expected numbers in metres, e.g. 8,48"),
                          ("8,0", "--lengths '8,0': expected positive lengths in metres"),
                          ("-1", "--lengths '-1': expected positive lengths in metres")):
        with pytest.raises(DataError) as err:
            parse_lengths(text)
        assert str(err.value) == message
    with pytest.raises(DataError, match="^--kitti-lengths 'a'"):
        parse_lengths("a", "--kitti-lengths")
    assert parse_lengths("0.001") == (0.001,)


def test_the_scoring_options_given_checked_and_named():
    assert scoring_options(None, None, None) == {"lengths_m": None, "kitti_lengths_m": None,
                                                 "alignment": None}
    assert scoring_options("8,48", "100,200", "SE3") == {
        "lengths_m": (8.0, 48.0), "kitti_lengths_m": (100.0, 200.0), "alignment": "se3"}
    with pytest.raises(DataError) as err:
        scoring_options(None, "0", None)
    assert str(err.value).startswith("--kitti-lengths '0': ")
    with pytest.raises(DataError) as err:
        scoring_options(None, None, "posyaw")
    assert str(err.value).startswith("--alignment: unknown alignment 'posyaw'")


def test_a_value_with_its_interval():
    assert _with_ci(None, [1.0, 2.0]) == "-"
    assert _with_ci(1.23456, None) == "1.235"
    assert _with_ci(1.23456, []) == "1.235"
    assert _with_ci(1.23456, [1.0, None]) == "1.235"
    assert _with_ci(1.23456, [1.0, 2.3456]) == "1.235 [1.000, 2.346]"


# --- bench run --------------------------------------------------------------------------------

@pytest.fixture
def runner(monkeypatch, tmp_path):
    """The planner and runner replaced: ``state.asked`` lists the calls, ``state.outcomes`` is
    what the runs end as, ``state.refused`` what the planner refuses."""
    state = SimpleNamespace(asked=[], outcomes=[SimpleNamespace(status="done", run_dir=None)],
                            refused=[], external=[], jobs=["j1", "j2"], consoles=[],
                            exps=[])
    exp = SimpleNamespace(out_dir=tmp_path / "results", jobs=3, external=[], out=None,
                          name="exp")

    def model_copy(update):
        state.asked.append(("copy", update))
        return exp
    exp.model_copy = model_copy
    state.exp = exp

    def plan(jobs, refused=None, own_only=False):
        state.asked.append(("plan", jobs, own_only))
        if refused is not None:
            refused.extend(state.refused)
        return [] if state.refused and state.jobs == [] else jobs

    def record(name, value=None):
        def fn(*args, **kwargs):
            state.asked.append((name, *args, *kwargs.values()))
            return value
        return fn

    monkeypatch.setattr(experiment, "load_experiment", record("load", exp))
    monkeypatch.setattr(planning, "jobs_for_experiment",
                        lambda e, console: state.asked.append(("jobs", console)) or state.jobs
                        if e is exp else pytest.fail("exp"))
    monkeypatch.setattr(planning, "plan", plan)
    monkeypatch.setattr(planning, "single_job", record("single", "job"))
    monkeypatch.setattr(runs_sweep, "sweep_index", record("sweep_index", {"sweeps": []}))
    monkeypatch.setattr(progress, "run_jobs",
                        lambda jobs, console, workers, *rest: state.asked.append(
                            ("run_jobs", jobs, workers, *rest)) or state.consoles.append(
                                console) or state.outcomes)
    monkeypatch.setattr(job, "summarize", lambda outcomes: f"{len(outcomes)} run(s) [b]done")
    monkeypatch.setattr(paper, "write_tables",
                        lambda d: state.asked.append(("tables", d)) or {"md": "[b]TABLE"})
    monkeypatch.setattr(commands, "print_sweeps", record("print_sweeps"))
    monkeypatch.setattr(commands, "print_run_summary", record("summary"))
    monkeypatch.setattr(commands, "external_runs",
                        lambda e, force, console: state.asked.append(("external", force))
                        or state.consoles.append(console) or state.exps.append(e)
                        or state.external)
    return state


def _run(console, **given):
    args = dict(experiment=None, method=None, data=None, out=None, seed=None, params={},
                jobs=None, force=False, executor="local", scheduler=None, job_timeout=None)
    args.update(given)
    return run_command(console, **args)


def _names(state) -> list[str]:
    return [a[0] for a in state.asked]


def test_an_unknown_executor_is_named_with_the_choices(runner):
    with pytest.raises(DataError) as err:
        _run(_console(), executor="cloud", method="icp", data=Path("s.h5"))
    assert str(err.value) == "unknown executor 'cloud'; choose from local, process, dask"
    assert runner.asked == []


@pytest.mark.parametrize("given, named", [
    ({"method": "icp"}, "--method"), ({"data": Path("d.h5")}, "--data"),
    ({"params": {"a": 1}}, "-p/--param"), ({"seed": False}, "--seed/--no-seed"),
    ({"method": "icp", "seed": True}, "--method, --seed/--no-seed")])
def test_single_run_options_beside_an_experiment_are_refused(runner, given, named):
    with pytest.raises(DataError) as err:
        _run(_console(), experiment=Path("e.yaml"), **given)
    assert str(err.value) == (
        f"{named} set a single run and would be ignored beside e.yaml, which lists its own "
        "methods, stores, parameters and seed options: edit the YAML, or run `bench run "
        "--method M --data STORE.h5` without it")


def test_an_experiment_runs_its_jobs_then_prints_its_tables_and_sweeps(runner, tmp_path):
    console = _console()
    code = _run(console, experiment=Path("e.yaml"), scoring={"lengths_m": (8.0, 48.0),
                                                             "alignment": None},
                out=tmp_path / "o", force=True, job_timeout=5.0, scheduler="s")
    assert code == 0
    assert runner.exp.out == tmp_path / "o"
    assert runner.asked[:2] == [("load", Path("e.yaml")), ("copy", {"lengths_m": [8.0, 48.0]})]
    assert ("plan", ["j1", "j2"], False) in runner.asked
    assert ("run_jobs", ["j1", "j2"], 3, True, "local", 5.0, "s") in runner.asked
    assert ("sweep_index", runner.exp, ["j1", "j2"]) in runner.asked
    assert _names(runner)[-3:] == ["external", "tables", "print_sweeps"]
    assert runner.asked[-2] == ("tables", runner.exp.out_dir)
    assert runner.asked[-1][1:3] == (runner.exp.out_dir, {"sweeps": []})
    assert _out(console) == ["1 run(s) [b]done", "[b]TABLE"]
    assert ("jobs", console) in runner.asked and ("external", True) in runner.asked
    assert runner.consoles == [console, console] and runner.exps == [runner.exp]
    assert runner.asked[-1][3] is console  # print_sweeps prints on the command's console
    assert (tmp_path / "results").is_dir() is False  # checked, not made


def test_jobs_override_the_experiment_s_workers(runner):
    _run(_console(), experiment=Path("e.yaml"), jobs=1)
    assert next(a for a in runner.asked if a[0] == "run_jobs")[2] == 1


def test_without_a_finished_run_no_table_is_printed_and_the_run_fails(runner):
    runner.outcomes = [SimpleNamespace(status="failed", run_dir=None)]
    assert _run(_console(), experiment=Path("e.yaml")) == 1
    assert "tables" not in _names(runner)
    runner.outcomes = [SimpleNamespace(status="skipped", run_dir=None),
                       SimpleNamespace(status="failed", run_dir=None)]
    assert _run(_console(), experiment=Path("e.yaml")) == 1
    assert "tables" in _names(runner)


def test_external_trajectories_count_toward_the_tables_and_the_exit_code(runner):
    runner.outcomes = [SimpleNamespace(status="failed", run_dir=None)]
    runner.external = [("x", "done", "ok")]
    assert _run(_console(), experiment=Path("e.yaml")) == 1  # the run failed
    assert "tables" in _names(runner)
    runner.outcomes = [SimpleNamespace(status="done", run_dir=None)]
    runner.external = [("x", "done", "ok"), ("y", "failed", "no file")]
    assert _run(_console(), experiment=Path("e.yaml")) == 1
    runner.external = [("x", "skipped", "unchanged")]
    assert _run(_console(), experiment=Path("e.yaml")) == 0


def test_refused_runs_are_listed_counted_and_fail_the_command(runner):
    runner.refused = ["doppler on [b]s.h5: no Doppler", "gicp on t.h5: too big"]
    console = _console()
    assert _run(console, experiment=Path("e.yaml")) == 1
    assert _out(console)[-3:] == [
        "refused doppler on [b]s.h5: no Doppler", "refused gicp on t.h5: too big",
        "2 run(s) refused (recorded as failed rows, status refused); the others ran"]
    runner.jobs = []
    with pytest.raises(DataError) as err:
        _run(_console(), experiment=Path("e.yaml"))
    assert str(err.value) == ("every run of the experiment was refused:\ndoppler on [b]s.h5: no "
                              "Doppler\ngicp on t.h5: too big")


def test_the_experiment_s_tables_are_checked_before_anything_runs(runner, tmp_path):
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "sweep.md").write_text("my notes")
    with pytest.raises(guard.Refused):
        _run(_console(), experiment=Path("e.yaml"))
    assert "run_jobs" not in _names(runner)


def test_a_missing_external_file_is_refused_before_anything_runs(runner, tmp_path):
    traj = tmp_path / "t.tum"
    traj.write_text("")
    runner.exp.external = [SimpleNamespace(name="ok", trajectory=traj, store=None, stamps=None,
                                           frame_times=None),
                           SimpleNamespace(name="orb", trajectory=traj, store=None,
                                           stamps=tmp_path / "missing.txt", frame_times=None)]
    with pytest.raises(DataError) as err:
        _run(_console(), experiment=Path("e.yaml"))
    assert str(err.value) == (f"e.yaml: external[1] (orb): stamps {tmp_path / 'missing.txt'} "
                              "not found")
    assert "plan" not in _names(runner)


def test_check_external_names_each_kind_of_file(tmp_path):
    for key in ("trajectory", "store", "stamps", "frame_times"):
        entry = {"name": "e", "trajectory": None, "store": None, "stamps": None,
                 "frame_times": None, key: tmp_path / "no"}
        with pytest.raises(DataError, match=f"external\\[0\\] \\(e\\): {key} "):
            check_external(SimpleNamespace(external=[SimpleNamespace(**entry)]), "x.yaml")
    check_external(SimpleNamespace(external=[]), "x.yaml")


def test_a_single_run_needs_a_method_and_data(runner):
    for given in ({"method": "icp"}, {"data": Path("s.h5")}):
        with pytest.raises(DataError) as err:
            _run(_console(), **given)
        assert str(err.value) == ("give an EXPERIMENT.yaml, or --method M --data PATH.h5 "
                                  "[--out DIR]")


def test_a_single_run_is_planned_for_its_own_folder_and_summarised(runner, tmp_path):
    runner.outcomes = [SimpleNamespace(status="done", run_dir=tmp_path / "run")]
    console = _console()
    code = _run(console, method="icp", data=Path("s.h5"), out=tmp_path, params={"a": 1},
                scoring={"lengths_m": (8.0,), "kitti_lengths_m": None, "alignment": "sim3"})
    assert code == 0
    assert runner.asked[0] == ("single", "icp", Path("s.h5"), True, tmp_path, {"a": 1},
                               {"lengths_m": (8.0,), "alignment": "sim3"})
    assert runner.asked[1] == ("plan", ["job"], True)
    assert runner.asked[2][:3] == ("run_jobs", ["job"], 1)
    assert runner.asked[-1] == ("summary", tmp_path / "run", console)
    assert "external" not in _names(runner) and "tables" not in _names(runner)


def test_no_seed_is_passed_on_and_warned_about_for_a_method_without_a_prior(runner,
                                                                           monkeypatch):
    monkeypatch.setattr(commands, "seed_option",
                        lambda method, seed: None if (method, seed) == ("kiss", False) else 1)
    with pytest.warns(UserWarning, match="^kiss takes no initial guess: --no-seed changes "
                                         "nothing \\(it runs once, as in the paper\\)$"):
        _run(_console(), method="kiss", data=Path("s.h5"), seed=False)
    assert runner.asked[0][3] is False
    monkeypatch.setattr(commands, "seed_option", lambda method, seed: seed)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _run(_console(), method="icp", data=Path("s.h5"), seed=False)
        _run(_console(), method="icp", data=Path("s.h5"))
    seeds = [a[3] for a in runner.asked if a[0] == "single"]
    assert seeds == [False, False, True]  # not given: seeded


def test_a_single_run_that_ended_without_a_folder_prints_no_summary(runner):
    runner.outcomes = [SimpleNamespace(status="failed", run_dir=None)]
    assert _run(_console(), method="icp", data=Path("s.h5")) == 1
    assert "summary" not in _names(runner)
    runner.outcomes = []
    assert _run(_console(), method="icp", data=Path("s.h5")) == 0


# --- the tables' guard and the sweep table ----------------------------------------------------

def test_check_tables_refuses_a_user_s_file_of_each_table_name(tmp_path):
    check_tables(tmp_path / "new")  # nothing there yet: fine
    for name in ("table.md", "table.tex", "table.csv", "sweep.md"):
        folder = tmp_path / name.replace(".", "_")
        folder.mkdir()
        (folder / name).write_text("mine")
        with pytest.raises(guard.Refused, match="is not a table this command wrote"):
            check_tables(folder)
    run = tmp_path / "run"
    run.mkdir()
    (run / "metrics.json").write_text("{}")
    with pytest.raises(guard.Refused, match=f"^--out {run}: is a run folder \\(made by bench run"):
        check_tables(run)


def test_the_sweep_table_is_written_and_printed(tmp_path, monkeypatch):
    monkeypatch.setattr(tables_sweep, "sweep_markdown",
                        lambda d: f"| [bold]sweep[/] of {Path(d).name} |")
    console = _console()
    print_sweeps(tmp_path, {"sweeps": [], "criterion": None}, console)
    assert (tmp_path / "sweep.md").read_text() == f"| [bold]sweep[/] of {tmp_path.name} |"
    assert runs_sweep.read_sweep_index(tmp_path) == {"sweeps": [], "criterion": None}
    assert _out(console) == [f"| [bold]sweep[/] of {tmp_path.name} |"]  # no markup
    print_sweeps(tmp_path, {"sweeps": []}, _console())  # its own table: made again
    (tmp_path / "sweep.md").write_text("my notes")
    with pytest.raises(guard.Refused, match="is not a sweep table the harness wrote"):
        print_sweeps(tmp_path, {"sweeps": []}, _console())


# --- a run's summary --------------------------------------------------------------------------

#: a run folder's name that rich markup would eat
RUN = "[b]run"


def _result(**given):
    rel = {8.0: SimpleNamespace(rot_deg_mean=1.0, rot_deg_mean_ci=[0.5, 1.5], trans_m_mean=0.2,
                                trans_m_mean_ci=None),
           16.0: SimpleNamespace(rot_deg_mean=9.0, rot_deg_mean_ci=None, trans_m_mean=9.0,
                                 trans_m_mean_ci=None),
           48.0: SimpleNamespace(rot_deg_mean=2.0, rot_deg_mean_ci=None, trans_m_mean=1.25,
                                 trans_m_mean_ci=[1.0, 1.5])}
    res = SimpleNamespace(
        lengths_m=[8.0, 16.0, 48.0], relative=rel.get, ci_level=0.95,
        ape=SimpleNamespace(trans_rmse_m=0.5, trans_rmse_m_ci=[0.4, 0.6], alignment="se3"),
        kitti=SimpleNamespace(n=3, trans_pct=1.234, rot_deg_per_100m=0.5678),
        velocity=SimpleNamespace(norm_mean_mps=0.1234, window_s=0.5),
        time_ms=SimpleNamespace(mean=12.345), fallback_text=lambda: "", fell_back=False)
    for k, v in given.items():
        setattr(res, k, v)
    return res


def _summary(monkeypatch, tmp_path, result, diverged=False, offset=""):
    folder = tmp_path / RUN
    run = SimpleNamespace(result=result, diverged=diverged)
    monkeypatch.setattr(commands, "read_run",
                        lambda d: run if result is not None and d == folder else None)
    monkeypatch.setattr(tables_ape, "start_offset_note", lambda r: offset if r is run else "?")
    console = _console()
    print_run_summary(folder, console)
    return _out(console)


def test_the_summary_of_a_scored_run(monkeypatch, tmp_path):
    # the shortest and the longest length only; each value with its interval where given
    assert _summary(monkeypatch, tmp_path, _result()) == [
        "8 m: 1.000 [0.500, 1.500] deg / 0.200 m; 48 m: 2.000 deg / 1.250 [1.000, 1.500] m; "
        "APE 0.500 [0.400, 0.600] m (se3); KITTI 1.23 % / 0.57 deg/100 m; velocity error "
        "0.123 m/s (0.5 s windows); time 12.35 ms/frame",
        "[low, high]: 95 % confidence intervals (circular block bootstrap over the "
        "trajectory)",
        f"run folder: {tmp_path / RUN}"]


def test_the_summary_of_a_diverged_run_that_fell_back(monkeypatch, tmp_path):
    res = _result(lengths_m=[8.0], ape=None, kitti=SimpleNamespace(n=0), velocity=None,
                  time_ms=SimpleNamespace(mean=None), fallback_text=lambda: "3 frames replaced",
                  fell_back=True, ci_level=0.9)
    assert _summary(monkeypatch, tmp_path, res, diverged=True, offset="a [i]start offset") == [
        "8 m: 1.000 [0.500, 1.500] deg / 0.200 m; DIVERGED; 3 frames replaced [fell back]",
        "note: APE with a [i]start offset",
        "[low, high]: 90 % confidence intervals (circular block bootstrap over the "
        "trajectory)",
        f"run folder: {tmp_path / RUN}"]
    res.fell_back = False
    assert _summary(monkeypatch, tmp_path, res)[0].endswith("; 3 frames replaced")


def test_the_summary_of_a_run_without_ground_truth_or_record(monkeypatch, tmp_path):
    res = _result(lengths_m=[], ape=SimpleNamespace(trans_rmse_m=None), kitti=None,
                  velocity=SimpleNamespace(norm_mean_mps=None), time_ms=SimpleNamespace(
                      mean=None))
    assert _summary(monkeypatch, tmp_path, res) == ["no ground truth: no errors",
                                                    f"run folder: {tmp_path / RUN}"]
    res.time_ms = SimpleNamespace(mean=2.0)  # something to say, but no lengths: no CI line
    assert _summary(monkeypatch, tmp_path, res) == ["time 2.00 ms/frame",
                                                    f"run folder: {tmp_path / RUN}"]
    assert _summary(monkeypatch, tmp_path, None) == [f"run folder: {tmp_path / RUN}"]


# --- bench score ------------------------------------------------------------------------------

@pytest.fixture
def scorer(monkeypatch, tmp_path):
    state = SimpleNamespace(asked=[], threads=[], status="done", warnings=[],
                            coverage={"scored": 90, "scans_with_gt": 100, "share_scored": 0.9,
                                      "matched": 80, "tolerance_s": 0.005, "interpolated": 10,
                                      "max_gap_s": 0.25, "widest_bridged_s": 0.123456})

    def score_external(store, spec, out, scoring, force):
        state.asked.append((store, spec.name, out, scoring, force, list(state.threads)))
        return SimpleNamespace(coverage=state.coverage, status=state.status,
                               clock="[i]offset 0.000 s", convention="[i]T_world_sensor",
                               warnings=state.warnings, frame="[i]identity",
                               run_dir=tmp_path / "run")

    monkeypatch.setattr(external_score, "score_external", score_external)
    monkeypatch.setattr(drift_intervals, "set_threads", state.threads.append)
    monkeypatch.setattr(commands, "read_run", lambda d: SimpleNamespace(
        result=SimpleNamespace(clock_note="[i]CPU time of one thread"))
        if d == tmp_path / "run" else None)
    monkeypatch.setattr(commands, "print_run_summary",
                        lambda d, console: console.print(f"summary of {d.name}"))
    return state


def _score(scoring=None, force=False):
    console = _console()
    code = score_command(console, Path("s.h5"), SimpleNamespace(name="[b]orb"), Path("o"), force,
                         scoring or {"lengths_m": None, "kitti_lengths_m": None,
                                     "alignment": None})
    return code, _out(console)


def test_score_prints_coverage_checks_frame_timing_and_summary(scorer):
    import os

    code, lines = _score()
    assert code == 0
    assert lines == [
        "[b]orb: 90 of the 100 scans with ground truth scored (90.0 %; 80 matched within 0.005 s, "
        "10 interpolated (--max-gap 0.25 s; the widest gap bridged 0.123 s))",
        "clock check: [i]offset 0.000 s", "convention check: [i]T_world_sensor",
        "poses moved to the sensor frame by T_frame_sensor = [i]identity",
        "timing: [i]CPU time of one thread", "summary of run"]
    cores = min(len(os.sched_getaffinity(0)), 8)
    (store, name, out, scoring, force, threads), = scorer.asked
    assert threads == [cores]  # every core while scoring, then one again
    assert scorer.threads == [cores, 1]
    from bench.runs.evaluate import Scoring

    assert (store, name, out, scoring, force) == (Path("s.h5"), "[b]orb", Path("o"), Scoring(),
                                                  False)


def test_score_passes_the_options_given_and_says_what_it_skipped(scorer):
    scorer.status = "skipped"
    scorer.warnings = ["few [i]scans", "a gap"]
    scorer.coverage.update(max_gap_s=None)
    code, lines = _score({"lengths_m": (8.0,), "kitti_lengths_m": None, "alignment": "sim3"},
                         force=True)
    assert lines[0] == ("[b]orb: 90 of the 100 scans with ground truth scored (90.0 %; 80 "
                        "matched within 0.005 s, no interpolation) (unchanged: not scored "
                        "again; --force to)")
    assert lines[3:5] == ["warning: few [i]scans", "warning: a gap"]
    scoring, force = scorer.asked[0][3:5]
    assert (scoring.lengths_m, scoring.alignment, force) == ((8.0,), "sim3", True)


def test_score_without_a_widest_gap_says_zero_and_resets_threads_on_error(scorer,
                                                                         monkeypatch):
    del scorer.coverage["widest_bridged_s"]
    assert "the widest gap bridged 0 s)" in _score()[1][0]

    def fails(*args):
        raise DataError("no overlap")

    monkeypatch.setattr(external_score, "score_external", fails)
    scorer.threads.clear()
    with pytest.raises(DataError):
        _score()
    assert scorer.threads[-1] == 1


# --- bench synth's dispatch -------------------------------------------------------------------

def test_synth_dispatch_runs_fidelity_realism_or_the_generator(monkeypatch, tmp_path):
    import bench.data.synth as synth
    import bench.studies.realism as realism
    import bench.studies.reproduce as reproduce

    asked = []
    failing = []
    monkeypatch.setattr(reproduce, "reproduce_table",
                        lambda *a: asked.append(("fidelity", *a)) or failing)
    monkeypatch.setattr(realism, "main", lambda argv: asked.append(("realism", argv)) or 7)
    monkeypatch.setattr(synth, "synth_command",
                        lambda console, **kw: asked.append(("synth", console, kw)) or 5)
    console = _console()
    assert synth_dispatch(console, True, tmp_path / "f", False, tmp_path / "d") == 0
    assert asked[-1] == ("fidelity", tmp_path / "f", tmp_path / "d", 2, False, True, console)
    failing.append("a row")
    assert synth_dispatch(console, True, tmp_path / "f", True, tmp_path / "d") == 1
    assert synth_dispatch(console, False, tmp_path / "f", True, tmp_path / "d") == 7
    assert asked[-1] == ("realism", [])
    assert synth_dispatch(console, False, tmp_path / "f", False, tmp_path / "d", scene="loop",
                          frames=3) == 5
    assert asked[-1] == ("synth", console, {"data_dir": tmp_path / "d", "scene": "loop",
                                            "frames": 3})


def test_external_trajectories_are_scored_and_each_said(monkeypatch):
    from bench.commands import external_runs

    asked = []
    done = [("orb", "done", "scored [b]90 %"), ("vins", "failed", "no overlap")]
    monkeypatch.setattr(external_score, "score_experiment_external",
                        lambda exp, force: asked.append((exp.name, force)) or done)
    console = _console()
    assert external_runs(SimpleNamespace(external=[], name="e"), True, console) == []
    assert asked == [] and _out(console) == []
    assert external_runs(SimpleNamespace(external=["x"], name="e"), True, console) == done
    assert asked == [("e", True)]
    assert _out(console) == ["external orb: done: scored [b]90 %",
                             "external vins: failed: no overlap"]


def test_score_uses_at_most_eight_threads(scorer, monkeypatch):
    import os

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(16)))
    _score()
    assert scorer.threads == [8, 1]
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2})
    _score()
    assert scorer.threads[-2:] == [3, 1]


def test_tables_sweeps_and_refusals_are_never_wrapped_on_a_narrow_terminal(runner, tmp_path,
                                                                          monkeypatch):
    long_row = "| " + " | ".join(f"cell {i}" for i in range(20)) + " |"
    monkeypatch.setattr(paper, "write_tables", lambda d: {"md": long_row})
    runner.refused = ["doppler on s.h5: " + "no Doppler values in this store " * 3]
    narrow = Console(file=io.StringIO(), width=30, color_system=None)
    _run(narrow, experiment=Path("e.yaml"))
    lines = _out(narrow)
    assert long_row in lines
    assert "refused " + runner.refused[0] in lines
    monkeypatch.setattr(tables_sweep, "sweep_markdown", lambda d: long_row)
    narrow = Console(file=io.StringIO(), width=30, color_system=None)
    print_sweeps(tmp_path, {"sweeps": []}, narrow)
    assert _out(narrow) == [long_row]


def test_only_failed_external_runs_print_no_table_and_skipped_runs_succeed(runner):
    runner.outcomes = [SimpleNamespace(status="failed", run_dir=None)]
    runner.external = [("x", "failed", "no file")]
    assert _run(_console(), experiment=Path("e.yaml")) == 1
    assert "tables" not in _names(runner)
    runner.outcomes = [SimpleNamespace(status="skipped", run_dir=None)] * 2
    runner.external = []
    assert _run(_console(), experiment=Path("e.yaml")) == 0
    assert "tables" in _names(runner)


def test_check_tables_refuses_a_file_as_the_results_folder(tmp_path):
    mine = tmp_path / "results"
    mine.write_text("mine")
    with pytest.raises(guard.Refused, match="is a file; expected a folder"):
        check_tables(mine)
