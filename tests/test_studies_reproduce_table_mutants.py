"""bench/studies/reproduce.py's ``reproduce_table`` in process, within seconds: the three table
experiments replaced by tiny ones (Doppler Correspondence only, on 8-frame stores), the
synthetic suite by those stores, ``run_jobs`` wrapped to record how it is asked (the real runs
still happen, in process) and the figures (bench/report/figures, tested on their own, and nine
tenths of the time) by a stand-in that records the folder it is given. What it pins: each
table written as ``bench table`` writes it from that table's runs only, the record
``reproduction.json``, the page, the fidelity report on the synthetic suite only, the scoring
options reaching the runs, the failed runs' messages returned, a table without finished runs
or without sequences not written (and an earlier one of ours removed), a re-run skipping the
finished runs, and real stores switching the default output folder (the mutation run of
tools/mutate.py over ``reproduce_table``, which only a >10 min real-data test reached)."""

from __future__ import annotations

import functools
import io
import json
import re
import warnings
from pathlib import Path

import pytest
from rich.console import Console

import bench.studies.reproduce as rep
from bench import guard
from bench.data.datasets import dataset_configs
from bench.report.tables.ape import write_ape_tables
from bench.report.tables.paper import write_tables
from bench.runs.experiment import SequenceEntry
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store

#: the tiny stores' paths are shorter than KITTI's lengths: plan says so, as expected here
pytestmark = pytest.mark.filterwarnings("ignore:.*no KITTI drift:UserWarning")

#: the paper's sequences (configs/datasets/*.yaml with paper: true)
PAPER_SEQUENCES = {"Campus1", "Campus2", "CurvedWall", "StraightWall", "Tunnel_Empty",
                   "Tunnel_Vehicles", "Loop1_0", "Loop1_1", "Loop1_2", "Loop1_3", "Loop1_4"}

#: tiny stand-ins for configs/experiments/table{3,4,5}.yaml (the same shape: Table III on two
#: sequences, Table IV on the same two in the other order, Table V on a tunnel)
TINY = {
    "table3": "methods:\n  - {name: doppler, sequences: [Campus1, Loop1_0]}\n",
    "table4": "methods:\n  - {name: doppler, sequences: [Loop1_0, Campus1]}\n",
    "table5": "methods:\n  - {name: doppler, sequences: [Tunnel_Empty]}\n",
}


@pytest.fixture(scope="module")
def stores(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("stores")
    paths = {}
    for k, name in enumerate(("Campus1", "Loop1_0", "Tunnel_Empty")):
        seq = constant_twist_sequence(n_frames=8, n_points=200, max_range_m=60, seed=k)
        paths[name] = write_store(seq, root / f"{name}.h5")
    return paths


#: the dataset configs, read once (reproduce reads them several times per call)
_CONFIGS = functools.cache(dataset_configs)


def _write_tables(folder: Path, lengths: str = "[4]", extra: str = "") -> None:
    for name, methods in TINY.items():
        (folder / f"{name}.yaml").write_text(
            f"name: {name}\nsuite: synthetic-paper\ndata_dir: data\n{methods}"
            f"lengths_m: {lengths}\nout: results\n{extra}")


@pytest.fixture()
def tiny_tables(monkeypatch, tmp_path):
    folder = tmp_path / "experiments"
    folder.mkdir()
    _write_tables(folder)
    monkeypatch.setattr(rep, "EXPERIMENTS", folder)
    monkeypatch.setattr(rep, "dataset_configs", _CONFIGS)
    plan_tables = rep.plan_tables

    def planning(experiments, console):
        figures.plan_consoles.append(console)
        return plan_tables(experiments, console)

    monkeypatch.setattr(rep, "plan_tables", planning)
    figures = Figures()
    monkeypatch.setattr(rep, "make_figures", figures)
    return figures


class Figures:
    """Stands in for ``make_figures``: records the results folder, returns ``files`` (and
    keeps the consoles ``plan_tables`` was given)."""

    def __init__(self):
        self.asked, self.files, self.plan_consoles = [], [Path("a.png"), Path("b.pdf")], []

    def __call__(self, results_dir):
        self.asked.append(results_dir)
        return self.files


class Runs:
    """Wraps ``run_jobs``: records its arguments, runs the jobs for real (in process: the
    "local" executor, whichever was asked), except those of ``fail`` (sequence names), which
    fail without running, recorded as a crashed worker's job is, and those of ``vanish``,
    which fail leaving no record."""

    def __init__(self, fail=(), vanish=()):
        self.fail, self.vanish, self.asked, self.consoles = set(fail), set(vanish), [], []

    def __call__(self, jobs, console, workers, force, executor, job_timeout_s, scheduler):
        from bench.runs.job import JobOutcome, record_unfinished
        from bench.runs.progress import run_jobs

        self.asked.append((len(jobs), workers, force, executor, job_timeout_s, scheduler))
        self.consoles.append(console)
        failing = self.fail | self.vanish
        ran = [j for j in jobs if j.name not in failing]
        for j in jobs:
            if j.name in self.fail:
                record_unfinished(j, f"boom: {j.name}", "crashed")
        outcomes = iter(run_jobs(ran, console, workers, force, "local", job_timeout_s,
                                 scheduler))
        return [JobOutcome(j, "failed", f"boom: {j.name}") if j.name in failing
                else next(outcomes) for j in jobs]


def _console() -> tuple[Console, io.StringIO]:
    buf = io.StringIO()
    return Console(file=buf, width=400), buf


def _said(buf: io.StringIO) -> str:
    return " ".join(buf.getvalue().split())


def _run_dirs(out: Path, sequences) -> set[Path]:
    return {p.parent for p in out.rglob("metrics.json") if p.parent.parent.name in sequences}


def _synthetic_suite(monkeypatch, stores, asked):
    """The tiny stores stand in for the suite, wherever it is asked for (reproduce resolves
    it once; an experiment left with its suite would have the plan resolve it again)."""
    import bench.runs.plan

    def suite(name, data_dir, console):
        asked.append((name, data_dir, console))
        return [SequenceEntry(path=p, name=n) for n, p in stores.items()]

    monkeypatch.setattr(rep, "suite_sequences", suite)
    monkeypatch.setattr(bench.runs.plan, "suite_sequences", suite)


def test_a_synthetic_reproduction_writes_each_table_from_its_own_runs(
        monkeypatch, tmp_path, stores, tiny_tables):
    asked = []
    _synthetic_suite(monkeypatch, stores, asked)
    runs = Runs()
    monkeypatch.setattr(rep, "run_jobs", runs)
    # a folder name with brackets: every line naming it is printed as it is (no markup)
    out, data = tmp_path / "paper [b]", tmp_path / "data"
    console, buf = _console()
    failed = rep.reproduce_table(out, data, 1, False, False, console, executor="local",
                                 scoring={"lengths_m": (2.0, 3.0), "alignment": "sim3",
                                          "kitti_lengths_m": None}, marks="value", ci=True)
    said = _said(buf)
    assert failed == []
    assert asked == [("synthetic-paper", data, console)]
    # the union of the tables' runs, once each (Loop1_0's run is Table III's and IV's)
    assert runs.asked == [(3, 1, False, "local", None, None)]
    assert runs.consoles == [console] and tiny_tables.plan_consoles == [console]
    # the scoring option reached the runs: their relative errors are over 2 and 3 m
    runs_made = _run_dirs(out, stores)
    assert len(runs_made) == 3
    for run in runs_made:
        metrics = json.loads((run / "metrics.json").read_text())
        assert [r["length_m"] for r in metrics["relative_error"]] == [2.0, 3.0], run
        assert metrics["ape"]["requested"] == "sim3"
        assert metrics["kitti"]["lengths_m"][0] == 100.0  # not given: the default
    three = _run_dirs(out, ("Campus1", "Loop1_0"))
    assert len(three) == 2
    # each table as `bench table` writes it from that table's runs, with the marks and ci
    ref = tmp_path / "ref"
    expected = {"table3": write_tables(out, ref, only=three, stem="t3", marks="value",
                                       ci=True)["md"]}
    for metric in ("kitti", "velocity"):
        expected[f"table3_{metric}"] = write_tables(out, ref, only=three, stem=f"t3{metric}",
                                                    metric=metric, marks="value", ci=True)["md"]
    # Table IV's columns in its YAML's order
    expected["table4"] = write_ape_tables(
        out, ref, ["Loop1_0", "Campus1"], "t4", rep.TABLES["table4"][2],
        only=three, marks="value", ci=True)["md"]
    expected["table5"] = write_ape_tables(
        out, ref, ["Tunnel_Empty"], "t5", rep.TABLES["table5"][2],
        only=_run_dirs(out, ("Tunnel_Empty",)), marks="value", ci=True)["md"]
    for stem, text in expected.items():
        assert (out / f"{stem}.md").read_text() == text, stem
        assert (out / f"{stem}.tex").exists() and (out / f"{stem}.csv").exists()
    assert "Tunnel" not in expected["table3"] and "Tunnel" not in expected["table4"]
    assert expected["table4"].index("Loop1_0") < expected["table4"].index("Campus1")
    assert "Tunnel_Empty" in expected["table5"]
    lines = buf.getvalue().splitlines()
    for stem in ("table3", "table4", "table5"):  # each table printed under its name, unwrapped
        assert stem in lines
        assert all(line in lines for line in expected[stem].splitlines()), stem
    record = json.loads((out / "reproduction.json").read_text())
    assert record == {
        "data": "the synthetic suite 'synthetic-paper' (synthetic data, not the paper's)",
        "found": ["Campus1", "Loop1_0", "Tunnel_Empty"], "missing": [],
        "tables_written": record["tables_written"], "tables_not_written": {}, "notes": []}
    assert sorted(record["tables_written"]) == ["table3", "table3_kitti", "table3_velocity",
                                                "table4", "table5"]
    assert guard.derived(out / "reproduction.json")
    assert '{\n  "data": "the synthetic suite' in (out / "reproduction.json").read_text()
    # the summary, the fidelity report (synthetic suite), the figures and the page
    seconds = re.search(r"3 done, 0 failed in (\d+) s; wrote ", said)
    assert seconds and int(seconds.group(1)) < 600
    # every table written named in the summary, one after the other
    assert "; wrote " + ", ".join(f"{out}/{stem}.{{md,tex,csv}}"
                                  for stem in record["tables_written"]) in said
    assert "not written" not in said
    assert (out / "fidelity.md").exists()
    assert f"fidelity report (synthetic suite vs the paper): {out / 'fidelity.md'}" in said
    assert tiny_tables.asked == [out] and f"figures: {out / 'figures'}/ (2 files)" in said
    assert (out / "report.html").exists() and f"results page: {out / 'report.html'}" in said

    # again, the same lengths from the YAML (a list): every run is finished, so it is
    # skipped, and nothing failed
    _write_tables(rep.EXPERIMENTS, "[2.0, 3.0]", "alignment: sim3\n")
    console, buf = _console()
    assert rep.reproduce_table(out, data, 2, False, False, console, executor="local") == []
    assert runs.asked[-1] == (3, 2, False, "local", None, None)
    assert "3 skipped, 0 failed in" in _said(buf) and " done," not in _said(buf)


def test_a_table_without_finished_runs_is_not_written_and_the_failures_are_returned(
        monkeypatch, tmp_path, stores, tiny_tables):
    _synthetic_suite(monkeypatch, stores, [])
    # the runs of Tables III and IV leave nothing: only Table V has a run
    runs = Runs(vanish={"Loop1_0", "Campus1"})
    monkeypatch.setattr(rep, "run_jobs", runs)
    tiny_tables.files = []
    out = tmp_path / "out"
    out.mkdir()
    guard.write_text(out / "table4.md", "an old table4\n", guard.derived, "a table")
    # a terminal's console (colours): the styles of what it says are seen
    buf = io.StringIO()
    console = Console(file=buf, width=400, force_terminal=True, color_system="standard")
    failed = rep.reproduce_table(out, tmp_path / "data", 1, True, False, console,
                                 executor="local", job_timeout_s=30.0,
                                 scheduler="tcp://nowhere:1")
    raw = buf.getvalue()
    said = " ".join(re.sub(r"\x1b\[[0-9;]*m", "", raw).split())
    assert "\x1b[31mtable4: no finished runs\x1b[0m" in raw  # in red
    assert "\x1b[1mtable5\x1b[0m" in raw  # a written table's name in bold
    rows = [line for line in raw.splitlines() if line.startswith("|")]
    assert rows and not [r for r in rows if "\x1b" in r]  # the tables printed plain
    assert sorted(failed) == ["boom: Campus1", "boom: Loop1_0"]
    assert runs.asked == [(3, 1, True, "local", 30.0, "tcp://nowhere:1")]
    assert not (out / "table4.md").exists()  # the earlier one removed
    assert not (out / "table3.md").exists() and (out / "table5.md").exists()
    for stem in ("table3", "table4"):
        assert f"not written: {stem} (no finished run)" in said
    record = json.loads((out / "reproduction.json").read_text())
    assert record["tables_not_written"] == {"table3": "no finished run",
                                            "table4": "no finished run"}
    assert record["notes"] == ["table3 not written: no finished run",
                               "table4 not written: no finished run"]
    assert record["tables_written"] == ["table5"]
    assert "1 done, 2 failed" in said  # the summary of the runs
    assert "figures:" not in said  # no figure made: none said


def test_real_stores_are_used_and_move_the_default_output_folder(monkeypatch, tmp_path, stores,
                                                                  tiny_tables):
    data = tmp_path / "data"
    (data / "real").mkdir(parents=True)
    (data / "real" / "Loop1_0.h5").write_bytes(stores["Loop1_0"].read_bytes())

    def no_suite(*a):
        raise AssertionError("no synthetic suite with real stores")

    monkeypatch.setattr(rep, "suite_sequences", no_suite)
    runs = Runs()
    monkeypatch.setattr(rep, "run_jobs", runs)
    monkeypatch.chdir(tmp_path)
    out = Path("results/paper-real")
    out.mkdir(parents=True)
    guard.write_text(out / "table5.md", "an old table5\n", guard.derived, "a table")
    console, buf = _console()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        failed = rep.reproduce_table(Path("results/paper-synthetic"), data, 1, False, False,
                                     console)
    said = _said(buf)
    assert failed == []
    # the defaults: the process executor, no timeout, no scheduler
    assert runs.asked == [(1, 1, False, "process", None, None)]  # one run, two tables
    # the default synthetic folder is replaced by the real one
    assert not Path("results/paper-synthetic").exists()
    assert (out / "table3.md").exists() and (out / "table4.md").exists()
    assert not (out / "table5.md").exists()  # no tunnel: the earlier one removed
    # the default marks and no intervals in the cells, as `bench table` writes it
    ref = tmp_path / "ref"
    expected = write_ape_tables(out, ref, ["Loop1_0"], "t4", rep.TABLES["table4"][2],
                                only=_run_dirs(out, ("Loop1_0",)))["md"]
    # (its caption names the CSV beside it)
    assert (out / "table4.md").read_text() == expected.replace(f"{ref}/t4.csv",
                                                               f"{out}/table4.csv")
    record = json.loads((out / "reproduction.json").read_text())
    missing = sorted(PAPER_SEQUENCES - {"Loop1_0"})
    assert record["data"] == f"real stores under {data / 'real'}"
    assert record["found"] == ["Loop1_0"] and sorted(record["missing"]) == missing
    assert sorted(record["tables_written"]) == ["table3", "table3_kitti", "table3_velocity",
                                                "table4"]
    assert record["tables_not_written"] == {"table5": "none of its sequences found "
                                                      "(Tunnel_Empty)"}
    # the notes: the missing sequences, the store's warnings (a LiDAR store for a radar
    # sequence, a far too short path), the table not written
    notes = record["notes"]
    assert notes[0].startswith("missing (10 of 11): ")
    assert notes[-1] == "table5 not written: none of its sequences found (Tunnel_Empty)"
    store_warnings = [str(w.message) for w in caught if "Loop1_0.h5" in str(w.message)]
    assert store_warnings and notes[1:-1] == store_warnings
    assert not (out / "fidelity.md").exists() and "fidelity report" not in said
    assert "not written: table5 (none of its sequences found (Tunnel_Empty))" in said
    assert f"results page: {out / 'report.html'}" in said


def _nothing(*a):
    raise AssertionError("nothing may run")


def test_a_users_file_where_a_table_goes_stops_it_before_anything_runs(
        monkeypatch, tmp_path, tiny_tables):
    monkeypatch.setattr(rep, "suite_sequences", _nothing)
    monkeypatch.setattr(rep, "run_jobs", _nothing)
    out = tmp_path / "out"
    out.mkdir()
    (out / "table4.md").write_text("my notes\n")
    with pytest.raises(DataError):
        rep.reproduce_table(out, tmp_path / "data", 1, False, False, _console()[0])
    assert (out / "table4.md").read_text() == "my notes\n"


def test_real_stores_with_a_users_file_in_the_real_folder_stop_it(monkeypatch, tmp_path,
                                                                  stores, tiny_tables):
    data = tmp_path / "data"
    (data / "real").mkdir(parents=True)
    (data / "real" / "Loop1_0.h5").write_bytes(stores["Loop1_0"].read_bytes())
    monkeypatch.setattr(rep, "run_jobs", _nothing)
    monkeypatch.chdir(tmp_path)
    Path("results/paper-real").mkdir(parents=True)
    Path("results/paper-real/table3.md").write_text("my notes\n")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(DataError):
            rep.reproduce_table(Path("results/paper-synthetic"), data, 1, False, False,
                                _console()[0])
    assert Path("results/paper-real/table3.md").read_text() == "my notes\n"


def test_synthetic_only_ignores_real_stores_and_keeps_the_default_folder(monkeypatch, tmp_path,
                                                                         stores, tiny_tables):
    data = tmp_path / "data"
    (data / "real").mkdir(parents=True)
    (data / "real" / "Loop1_0.h5").write_bytes(stores["Loop1_0"].read_bytes())
    asked = []
    _synthetic_suite(monkeypatch, stores, asked)
    monkeypatch.setattr(rep, "run_jobs", Runs(fail=set(stores)))  # nothing runs: quick
    monkeypatch.chdir(tmp_path)
    console, buf = _console()
    failed = rep.reproduce_table(Path("results/paper-synthetic"), data, 1, False, True,
                                 console, executor="local")
    assert sorted(failed) == [f"boom: {n}" for n in sorted(stores)]
    assert len(asked) == 1  # the synthetic suite, though a real store is there
    out = Path("results/paper-synthetic")  # kept: no real store used
    assert not Path("results/paper-real").exists()
    record = json.loads((out / "reproduction.json").read_text())
    assert record["data"] == ("the synthetic suite 'synthetic-paper' (synthetic data, not "
                              "the paper's)")
    assert record["found"] == sorted(stores) and record["missing"] == []
    assert "synthetic only (as asked)" in _said(buf)


def test_a_table_without_sequences_before_one_with_does_not_stop_the_tables(
        monkeypatch, tmp_path, stores, tiny_tables):
    """Only a tunnel among the real stores: Tables III and IV have no sequence, Table V is
    still written (its run fails here, recorded: a row all the same)."""
    data = tmp_path / "data"
    (data / "real").mkdir(parents=True)
    (data / "real" / "Tunnel_Empty.h5").write_bytes(stores["Tunnel_Empty"].read_bytes())
    monkeypatch.setattr(rep, "run_jobs", Runs(fail={"Tunnel_Empty"}))
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        failed = rep.reproduce_table(out, data, 1, False, False, _console()[0])
    assert failed == ["boom: Tunnel_Empty"]
    record = json.loads((out / "reproduction.json").read_text())
    assert record["tables_written"] == ["table5"]
    assert record["tables_not_written"] == {
        "table3": "none of its sequences found (Campus1, Loop1_0)",
        "table4": "none of its sequences found (Loop1_0, Campus1)"}


def test_stores_without_ground_truth_give_no_table_and_say_so(monkeypatch, tmp_path,
                                                             tiny_tables):
    """Runs on stores without ground truth finish, but no table has a row: none is written,
    and the summary says so."""
    from loaders.scan import MemorySequence

    stores = {}
    for name in ("Campus1", "Loop1_0", "Tunnel_Empty"):
        seq = constant_twist_sequence(n_frames=6, n_points=150, max_range_m=60)
        bare = MemorySequence(name, seq.sensor, [seq[i] for i in range(len(seq))])
        stores[name] = write_store(bare, tmp_path / f"{name}.h5")
    _synthetic_suite(monkeypatch, stores, [])
    monkeypatch.setattr(rep, "run_jobs", Runs())
    console, buf = _console()
    out = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        failed = rep.reproduce_table(out, tmp_path / "data", 1, False, False, console,
                                     executor="local")
    assert failed == []
    record = json.loads((out / "reproduction.json").read_text())
    assert record["tables_written"] == []
    assert "; wrote no table" in _said(buf)
