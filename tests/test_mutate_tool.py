"""`make mutate BASE=<commit>` (tools/mutate.py): which modules it mutates (the .py files of
bench, loaders, methods, metrics changed since BASE that still exist), which tests it runs for
each (named after the module or importing it), that it works in a scratch copy and never
writes into the checkout, and how it reads mutmut's results. mutmut itself is not run here
(minutes per module: `make mutate` is the long run)."""

from __future__ import annotations

import importlib.util
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("mutate_tool", ROOT / "tools" / "mutate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


mutate = _tool()


def _git(root, *args):
    subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True)


@pytest.fixture
def repo(tmp_path):
    """A tiny project: metrics/units.py imported by tests/test_units_use.py and by
    bench/runs/score.py (imported by tests/test_score.py), bench/cli.py named by
    tests/test_cli.py; one commit, then changes."""
    files = {
        "metrics/__init__.py": "",
        "metrics/units.py": "def f(x):\n    return x + 1\n",
        "metrics/other.py": "def g():\n    return 2\n",
        "bench/__init__.py": "",
        "bench/runs/__init__.py": "",
        "bench/runs/score.py": "from metrics import units\n",
        "bench/cli.py": "def main():\n    pass\n",
        "tests/test_units_use.py": "def test_f():\n    from metrics.units import f\n",
        "tests/test_score.py": "import bench.runs.score\n",
        "tests/test_cli.py": "def test_cli():\n    pass\n",
        "tests/test_unrelated.py": "import metrics.other\n",
        "docs/notes.md": "notes\n",
        ".gitignore": ".mutate/\n",
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    _git(tmp_path, "init", "-q")
    _git(tmp_path, "-c", "user.email=t@t", "-c", "user.name=t", "add", "-A")
    _git(tmp_path, "-c", "user.email=t@t", "-c", "user.name=t", "commit", "-qm", "base")
    return tmp_path


def test_the_changed_modules_are_the_python_files_of_the_packages_that_still_exist(repo):
    (repo / "metrics/units.py").write_text("def f(x):\n    return x + 2\n")
    (repo / "bench/cli.py").write_text("def main():\n    return 0\n")
    (repo / "docs/notes.md").write_text("changed\n")  # not a package
    (repo / "metrics/other.py").unlink()  # deleted: nothing to mutate
    assert mutate.changed_modules(repo, "HEAD") == ["bench/cli.py", "metrics/units.py"]
    assert mutate.module_name("bench/runs/__init__.py") == "bench.runs"


def test_the_tests_of_a_module_import_it_or_are_named_after_it(repo):
    assert mutate.covering_tests(repo, "metrics.units") == ["tests/test_units_use.py"]
    # one step up the import graph: bench.runs.score imports metrics.units
    assert mutate.covering_tests(repo, "metrics.units", depth=1) == [
        "tests/test_score.py", "tests/test_units_use.py"]
    assert mutate.covering_tests(repo, "bench.cli") == ["tests/test_cli.py"]  # by its name
    assert mutate.covering_tests(repo, "metrics.other") == ["tests/test_unrelated.py"]


def test_the_scratch_copy_holds_the_working_tree_and_the_checkout_is_untouched(repo):
    (repo / "metrics/units.py").write_text("def f(x):\n    return x + 3\n")  # uncommitted
    (repo / "metrics/new.py").write_text("def h():\n    return 4\n")  # untracked
    before = subprocess.run(["git", "-C", str(repo), "status", "--porcelain"],
                            capture_output=True, text=True).stdout
    dest = repo / ".mutate" / "tree"
    mutate.copy_tree(repo, dest)
    assert (dest / "metrics/units.py").read_text() == "def f(x):\n    return x + 3\n"
    assert (dest / "metrics/new.py").exists() and not (dest / ".mutate").exists()
    (repo / "metrics/new.py").unlink()
    mutate.copy_tree(repo, dest)  # a file gone from the tree goes from the copy
    assert not (dest / "metrics/new.py").exists()
    after = subprocess.run(["git", "-C", str(repo), "status", "--porcelain"],
                           capture_output=True, text=True).stdout
    # the copy is ignored; the only change in the checkout is the file removed above
    assert after.replace(" D metrics/new.py\n", "") == before.replace(
        "?? metrics/new.py\n", "")


def test_the_configuration_names_the_modules_and_the_tests():
    text = mutate.mutmut_config(["metrics/units.py"], ["tests/test_a.py", "tests/test_b.py"])
    import configparser

    cfg = configparser.ConfigParser()
    cfg.read_string(text)
    section = cfg["mutmut"]
    assert section["only_mutate"].split() == ["metrics/units.py"]
    assert section["pytest_add_cli_args_test_selection"].split() == ["tests/test_a.py",
                                                                     "tests/test_b.py"]
    assert section["source_paths"].split() == ["bench", "loaders", "methods", "metrics"]


def test_results_are_read_per_module():
    listing = ("    metrics.units.x_f__mutmut_1: killed\n"
               "    metrics.units.x_f__mutmut_2: survived\n"
               "    metrics.units.xǁUnitsǁstatistic__mutmut_3: survived\n"
               "    bench.report.tables.significance.x_worse__mutmut_1: no tests\n"
               "    bench.report.tables.significance.x_worse__mutmut_2: killed\n")
    results = mutate.parse_results(listing)
    assert results["metrics.units.x_f__mutmut_2"] == "survived"
    assert results["bench.report.tables.significance.x_worse__mutmut_1"] == "no tests"
    assert mutate.scores(results) == {"bench.report.tables.significance": (1, 0, 1),
                                      "metrics.units": (1, 2, 0)}


def test_a_second_run_re_tests_the_last_runs_survivors(tmp_path):
    """Only survivors (exit code 0) are marked untested; kills, timeouts and the rest of
    mutmut's state are kept."""
    import json

    meta = tmp_path / "mutants" / "metrics" / "units.py.meta"
    meta.parent.mkdir(parents=True)
    state = {"exit_code_by_key": {"a": 0, "b": 1, "c": None, "d": 0, "e": 36},
             "hash_by_function_name": {"f": "123"}}
    meta.write_text(json.dumps(state), encoding="utf-8")
    (tmp_path / "mutants" / "metrics" / "units.py").write_text("x = 0\n", encoding="utf-8")
    assert mutate.retest_survivors(tmp_path) == 2
    after = json.loads(meta.read_text(encoding="utf-8"))
    assert after["exit_code_by_key"] == {"a": None, "b": 1, "c": None, "d": None, "e": 36}
    assert after["hash_by_function_name"] == {"f": "123"}
    assert mutate.retest_survivors(tmp_path) == 0
