"""What bench.studies.independent writes and refuses (the guard's arguments), its JSON layout
and the sweep text it prints: tests reaching the survivors the first mutation pass left."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from bench import guard
from bench.studies import independent


def _rows():
    base = independent.Baseline("ours-x", "ref-x", "a test reference")
    errors = {"ours-x": {8.0: (1.0, 2.0)}, "ref-x": {8.0: (2.0, 4.0)}}
    return independent.compare(errors, [base], lengths_m=(8.0,), half="A", tuned_on="B")


# write_outputs --------------------------------------------------------------------------------

def test_write_outputs_default_has_no_decisions(tmp_path):
    rows = _rows()
    assert independent.write_outputs(rows, tmp_path) == independent.table_markdown(rows)


def test_write_outputs_refuses_a_run_folder(tmp_path):
    # a run's folder (it holds a run record) is the run's: nothing is written into it
    (tmp_path / "metrics.json").write_text("{}")
    with pytest.raises(guard.Refused, match="is a run folder"):
        independent.write_outputs(_rows(), tmp_path)
    assert not (tmp_path / "comparison.md").exists()


def test_write_outputs_twice_replaces_its_own_files(tmp_path):
    rows = _rows()
    independent.write_outputs(rows, tmp_path, "FIRST\n")
    text = independent.write_outputs(rows, tmp_path, "SECOND\n")
    assert (tmp_path / "comparison.md").read_text() == text and text.endswith("SECOND\n")
    # both files are recorded as the harness's own (listed in the folder's ledger)
    assert guard.derived(tmp_path / "comparison.md")
    assert guard.derived(tmp_path / "comparison.json")


@pytest.mark.parametrize("name", ["comparison.md", "comparison.json"])
def test_write_outputs_refuses_a_foreign_file(tmp_path, name):
    (tmp_path / name).write_text("a user's notes\n")
    with pytest.raises(guard.Refused) as err:
        independent.write_outputs(_rows(), tmp_path)
    message = str(err.value)
    assert str(tmp_path / name) in message
    assert "exists and is not a comparison the harness wrote" in message
    assert (tmp_path / name).read_text() == "a user's notes\n"


def test_write_outputs_json_indented_by_one_space(tmp_path):
    independent.write_outputs(_rows(), tmp_path)
    lines = (tmp_path / "comparison.json").read_text().splitlines()
    # a list of one object: "[", then the object's brace one space in, its keys two
    assert lines[0] == "[" and lines[1] == " {" and lines[2] == '  "method": "ours-x",'
    assert lines[-1] == "]"


def test_write_outputs_row_without_ours_is_null(tmp_path):
    base = independent.Baseline("ours-z", "ref-z", "no run of ours")
    row = independent.Comparison(base, None, {8.0: (1.0, 1.0)}, (8.0,))
    independent.write_outputs([row], tmp_path)
    (entry,) = json.loads((tmp_path / "comparison.json").read_text())
    assert entry["ours"] is None and entry["reference_errors"] == {"8": [1.0, 1.0]}
    assert entry["ratios"] == {"8": [None, None]}


# run_experiment: the sweep table ----------------------------------------------------------------

SWEEP = "sweep [deg] [bold]x[/bold] " + "z" * 400


def _layers(monkeypatch, tmp_path):
    from bench.report.tables import paper as paper_tables
    from bench.report.tables import sweep as sweep_tables
    from bench.runs import experiment, job, plan, progress
    from bench.runs import sweep as sweep_mod

    seen = []
    exp = SimpleNamespace(out_dir=tmp_path / "exp", jobs=1)
    monkeypatch.setattr(experiment, "load_experiment", lambda p: exp)
    monkeypatch.setattr(plan, "jobs_for_experiment", lambda e, console: ["j"])
    monkeypatch.setattr(plan, "plan", lambda jobs: jobs)
    monkeypatch.setattr(sweep_mod, "sweep_index", lambda e, jobs: {"sweeps": []})
    monkeypatch.setattr(sweep_mod, "write_sweep_index", lambda d, s: None)
    monkeypatch.setattr(progress, "run_jobs",
                        lambda *a: [SimpleNamespace(status="done")])
    monkeypatch.setattr(job, "summarize", lambda outcomes: "done")
    monkeypatch.setattr(paper_tables, "write_tables", lambda d: {"md": "T"})
    monkeypatch.setattr(sweep_tables, "sweep_markdown", lambda d: seen.append(d) or SWEEP)
    return exp, seen


def _console():
    from rich.console import Console

    return Console(record=True, width=120, color_system=None)


def test_run_experiment_sweep_of_its_folder_printed_as_is(monkeypatch, tmp_path):
    exp, seen = _layers(monkeypatch, tmp_path)
    console = _console()
    assert independent.run_experiment(console, Path("x.yaml"), None, False, "local") == 0
    assert seen == [exp.out_dir]
    assert (exp.out_dir / "sweep.md").read_text() == SWEEP
    # the whole text on one line: brackets kept, not wrapped at the console's 120 columns
    assert SWEEP in console.export_text().splitlines()


def test_run_experiment_twice_replaces_its_sweep_table(monkeypatch, tmp_path):
    exp, _ = _layers(monkeypatch, tmp_path)
    for _ in range(2):
        assert independent.run_experiment(_console(), Path("x.yaml"), None, False, "local") == 0
    assert guard.derived(exp.out_dir / "sweep.md")


def test_run_experiment_refuses_a_foreign_sweep_table(monkeypatch, tmp_path):
    exp, _ = _layers(monkeypatch, tmp_path)
    exp.out_dir.mkdir()
    (exp.out_dir / "sweep.md").write_text("mine\n")
    with pytest.raises(guard.Refused) as err:
        independent.run_experiment(_console(), Path("x.yaml"), None, False, "local")
    message = str(err.value)
    assert str(exp.out_dir / "sweep.md") in message
    assert "exists and is not a sweep table the harness wrote" in message
    assert (exp.out_dir / "sweep.md").read_text() == "mine\n"
