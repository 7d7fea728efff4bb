"""What bench.studies.fidelity.write_report writes and refuses (the guard's output folder,
owner and description) and its default header: tests reaching the survivors the first
mutation pass left."""

from __future__ import annotations

import pytest

from bench import guard
from bench.studies import fidelity as F


def _no_runs(monkeypatch):
    monkeypatch.setattr(F, "collect_runs", lambda d: {})


def test_write_report_default_has_no_header(monkeypatch, tmp_path):
    _no_runs(monkeypatch)
    lines = F.write_report(tmp_path).read_text().splitlines()
    # the title, a blank line, then straight to the calibration paragraph
    assert lines[0] == f"# {F.TITLE}" and lines[1] == ""
    assert lines[2].startswith("Calibration (one fitted value per sensor class")


def test_write_report_refuses_a_run_folder(monkeypatch, tmp_path):
    _no_runs(monkeypatch)
    (tmp_path / "metrics.json").write_text("{}")
    with pytest.raises(guard.Refused, match="is a run folder"):
        F.write_report(tmp_path / "results", tmp_path)
    assert not (tmp_path / "fidelity.md").exists()


def test_write_report_twice_replaces_its_own_files(monkeypatch, tmp_path):
    _no_runs(monkeypatch)
    F.write_report(tmp_path, header="FIRST")
    path = F.write_report(tmp_path, header="SECOND")
    assert path.read_text().splitlines()[2] == "SECOND"
    assert guard.derived(tmp_path / "fidelity.md") and guard.derived(tmp_path / "fidelity.csv")


@pytest.mark.parametrize("name", ["fidelity.md", "fidelity.csv"])
def test_write_report_refuses_a_foreign_file(monkeypatch, tmp_path, name):
    _no_runs(monkeypatch)
    (tmp_path / name).write_text("a user's notes\n")
    with pytest.raises(guard.Refused) as err:
        F.write_report(tmp_path)
    message = str(err.value)
    assert str(tmp_path / name) in message
    assert "exists and is not a fidelity report the harness wrote" in message
    # checked before any write: neither file is touched
    assert (tmp_path / name).read_text() == "a user's notes\n"
    other = {"fidelity.md": "fidelity.csv", "fidelity.csv": "fidelity.md"}[name]
    assert not (tmp_path / other).exists()
