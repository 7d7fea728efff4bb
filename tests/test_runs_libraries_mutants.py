"""bench/runs/libraries.py: which third-party libraries a run recorded, at which versions, and
when a recorded run is no longer current; checked against importlib.metadata and the
``packaging`` parser directly (the mutation run of tools/mutate.py over
bench/runs/libraries.py)."""

from __future__ import annotations

import platform
import sys
from importlib import metadata

import hypothesis  # noqa: F401 - loaded, but no module of a run imports it
import numpy  # noqa: F401
import pydantic  # noqa: F401
import yaml  # noqa: F401
from packaging.requirements import Requirement

from bench.runs import libraries as lib

NUMPY = metadata.version("numpy")


def test_the_repositorys_own_packages_are_not_third_party():
    assert {"bench", "loaders", "methods", "metrics"} <= lib.REPO_PACKAGES
    assert "tests" not in lib.REPO_PACKAGES and "numpy" not in lib.REPO_PACKAGES
    assert lib.IGNORED == {"_distutils_hack"}


def test_the_import_roots():
    roots, stdlib = lib._import_roots()
    assert [len(r) for r in roots] == sorted((len(r) for r in roots), reverse=True)
    assert stdlib <= set(roots)

    def holder(file):  # the longest root above ``file``
        return next(r for r in roots if file.startswith(r + "/"))

    assert holder(sys.modules["json"].__file__) in stdlib
    assert holder(numpy.__file__) not in stdlib
    dynload = [r for r in roots if r.endswith("lib-dynload")]
    assert all(r in stdlib for r in dynload)
    assert not any(r.endswith(("site-packages", "dist-packages")) for r in stdlib)


def test_the_loaded_third_party_modules():
    names = lib._third_party_modules()
    assert names == sorted(names)
    assert {"numpy", "pydantic", "yaml", "hypothesis"} <= set(names)
    # the standard library's, the repository's and the interpreter's own are left out
    assert not {"json", "os", "bench", "loaders", "methods", "metrics"} & set(names)
    assert not {"_distutils_hack"} & set(names)
    assert not any(n.startswith("__") for n in names)
    assert all("." not in n and "/" not in n for n in names)


def test_the_distribution_of_a_module():
    assert lib.distribution_of("numpy") == "numpy"
    assert lib.distribution_of("yaml") == "PyYAML"
    assert lib.distribution_of("PIL") == "pillow"
    assert lib.distribution_of("attr") == "attrs"  # found in the installed file lists
    assert lib.distribution_of("no_such_module_anywhere") is None
    assert lib.MODULE_DISTRIBUTIONS["dateutil"] == "python-dateutil"


def test_normal_names():
    assert lib._normal("Typing_Extensions") == "typing-extensions"
    assert lib._normal("ruamel.yaml") == "ruamel-yaml"
    assert lib._normal("a-_.b") == "a-b"


def test_requirements_leave_out_the_extras():
    want = []
    for text in metadata.requires("pydantic"):
        req = Requirement(text)
        if req.marker is None or "extra" not in str(req.marker):
            want.append(req.name)
    assert lib._requirements("pydantic") == want
    assert "pydantic-core" in want and "email-validator" not in want
    assert lib._requirements("no-such-distribution-anywhere") == []


def test_a_run_records_what_its_code_imported_with_their_requirements():
    got = lib.imported_libraries()
    assert list(got)[0] == "python" and got["python"] == platform.python_version()
    assert got["numpy"] == NUMPY
    assert got["pydantic"] == metadata.version("pydantic")
    # required by pydantic, imported by no module of the run itself
    core = {lib._normal(k): v for k, v in got.items()}["pydantic-core"]
    assert core == metadata.version("pydantic-core")
    assert got["PyYAML"] == metadata.version("PyYAML")
    names = list(got)[1:]
    assert names == sorted(names, key=str.lower)
    # loaded by the test runner, not by the run: left out
    assert "hypothesis" not in got


def test_a_plugins_imports_count_too(tmp_path):
    plugin = tmp_path / "my_plugin.py"
    plugin.write_text("import hypothesis\n")
    got = lib.imported_libraries([plugin])
    assert got["hypothesis"] == metadata.version("hypothesis")
    assert got["numpy"] == NUMPY


def test_changed_libraries_and_current():
    recorded = {"python": platform.python_version(), "numpy": NUMPY}
    assert lib.changed_libraries(recorded) == {}
    assert lib.libraries_current(recorded)
    assert lib.libraries_current(None) and lib.libraries_current({})
    older = {"python": "2.7.18", "numpy": "0.0.1", "no-such-distribution-anywhere": "1.0"}
    assert lib.changed_libraries(older) == {
        "python": ("2.7.18", platform.python_version()), "numpy": ("0.0.1", NUMPY),
        "no-such-distribution-anywhere": ("1.0", None)}
    assert not lib.libraries_current({"numpy": "0.0.1"})
    # a library recorded as not installed is current while it is still absent
    assert lib.libraries_current({"no-such-distribution-anywhere": None})
