"""Residue survivor of bench/report/html/runs.py: every unreadable file the page lists names
the file, also when the reader's own message does not (the trajectory readers' messages do,
so this is the fallback for a lower-level error such as numpy's)."""

from __future__ import annotations

import bench.runs.folders as folders
from bench.report.html.runs import file_problems


def test_a_trajectory_error_without_the_file_is_prefixed_with_it(tmp_path, monkeypatch):
    (tmp_path / "gt_tum.txt").write_text("0 0 0 0 0 0 0 1\n")
    (tmp_path / "est_tum.txt").write_text("0 0 0 0 0 0 0 1\n")

    def unreadable(path):
        if path.name == "est_tum.txt":
            raise ValueError("could not convert string to float: 'x'\nsecond line")
        return None

    monkeypatch.setattr(folders, "read_run_tum", unreadable)
    assert file_problems(tmp_path, True) == [
        f"{tmp_path / 'est_tum.txt'}: could not convert string to float: 'x'"]
    assert file_problems(tmp_path, False) == []  # an unfinished run's trajectory is not read


def test_a_trajectory_error_naming_the_file_is_kept_as_it_is(tmp_path):
    path = tmp_path / "est_tum.txt"
    path.write_text("garbage\n")
    (problem,) = file_problems(tmp_path, True)
    assert problem.startswith(f"{path}: ") and not problem.startswith(f"{path}: {path}")
