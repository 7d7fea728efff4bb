"""The third-party libraries a run actually imported, with their versions (config.yaml's
``libraries``), and whether they are still installed at those versions.

A run is reused only while every library it imported is installed at the version it ran with
(``libraries_current``, checked by ``bench.runs.folders.is_finished`` beside the run key). The
list is taken from what the worker loaded, after the run (``imported_libraries``): the loaded
libraries that the run path's code imports, with the loaded libraries they require; not a
fixed list, nor every library any line of the repository names: a ``doppler`` run records
NumPy, SciPy, numba and llvmlite, h5py, pydantic and its parts, PyYAML, small_gicp (every
method module is loaded by the registry), never Open3D, kiss-icp, dask or the command line's
rich, so installing an extra that only another method or backend imports (``.[open3d]``,
``.[dev]``) re-runs nothing, while a new version of a library the run used re-runs it. The
repository's own packages are covered by the code hash (``bench.runs.identity.code_identity``)
instead.
"""

from __future__ import annotations

import functools
import os
import re
import sys
import sysconfig
from importlib import metadata
from pathlib import Path

from bench.paths import ROOT
from bench.runs.provenance import installed_version

#: the repository's own top-level packages (their content is in the code hash)
REPO_PACKAGES = frozenset(p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file())
#: importable modules whose distribution is named otherwise (saves scanning every installed
#: distribution's file list, about 0.5 s, for the common ones)
MODULE_DISTRIBUTIONS = {"yaml": "PyYAML", "_yaml": "PyYAML", "open3d": "open3d-cpu",
                        "dateutil": "python-dateutil", "PIL": "pillow",
                        "mpl_toolkits": "matplotlib", "pkg_resources": "setuptools",
                        "_distutils_hack": "setuptools"}
#: loaded by the interpreter itself in every process (setuptools' distutils shim, from a .pth
#: file), never by a run
IGNORED = frozenset({"_distutils_hack"})
_provided: list[dict[str, list[str]]] = []  # metadata.packages_distributions(), read once


def _import_roots() -> tuple[list[str], set[str]]:
    """(the folders of ``sys.path``, longest first; those of the standard library)."""
    roots = {os.path.abspath(p) for p in sys.path if p and os.path.isdir(p)}
    paths = sysconfig.get_paths()
    stdlib = {os.path.abspath(paths[k]) for k in ("stdlib", "platstdlib")}
    # the standard library's extension folder (lib-dynload) too, not the site-packages in it
    stdlib |= {r for r in roots if any(r.startswith(s + os.sep) for s in stdlib)
               and os.path.basename(r) not in ("site-packages", "dist-packages")}
    return sorted(roots | stdlib, key=len, reverse=True), stdlib


def _third_party_modules() -> list[str]:
    """The top-level import names of every loaded module that is neither the standard
    library's nor the repository's, found from its file: a module's top-level name is the
    first folder (or file) of its path below the ``sys.path`` entry that holds it (an
    extension that registers itself under another name still counts for its package)."""
    roots, stdlib = _import_roots()
    repo = str(ROOT)
    names = set()
    for module in list(sys.modules.values()):
        file = getattr(module, "__file__", None)
        if not isinstance(file, str):
            continue  # built in, or a namespace without a file
        file = os.path.abspath(file)
        root = next((r for r in roots if file.startswith(r + os.sep)), None)
        # the repository's own modules sit directly below its root (a virtual environment
        # inside the checkout, .venv, is a longer sys.path entry and matched first)
        if root is None or root in stdlib or root == repo:
            continue
        top = file[len(root) + 1:].split(os.sep, 1)[0].split(".", 1)[0]
        if (top and top not in REPO_PACKAGES and top not in IGNORED
                and top not in sys.stdlib_module_names and not top.startswith("__")):
            names.add(top)
    return sorted(names)


@functools.cache
def distribution_of(module: str) -> str | None:
    """The installed distribution that provides top-level module ``module`` (None: none, e.g.
    a plugin module on PYTHONPATH); looked up once per process, like ``installed_version``
    (each lookup parses the distribution's metadata: about 1 ms, for every loaded library
    after every run)."""
    try:
        return metadata.distribution(module).metadata["Name"]
    except metadata.PackageNotFoundError:
        pass
    if module in MODULE_DISTRIBUTIONS:
        return MODULE_DISTRIBUTIONS[module]
    if not _provided:
        _provided.append(metadata.packages_distributions())
    found = _provided[0].get(module)
    return sorted(found)[0] if found else None


def _normal(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


@functools.cache
def _requirements(dist: str) -> list[str]:
    """The distributions ``dist`` requires, other than for an extra of its own; read once per
    process (the caller only reads the list)."""
    try:
        requires = metadata.requires(dist) or []
    except metadata.PackageNotFoundError:
        return []
    found = []
    for req in requires:
        name, _, marker = req.partition(";")
        if "extra" not in marker:
            match = re.match(r"\s*([A-Za-z0-9][A-Za-z0-9._-]*)", name)
            if match:
                found.append(match.group(1))
    return found


def imported_libraries(code_files=()) -> dict[str, str | None]:
    """The distributions (name -> installed version) of the third-party libraries the run
    loaded, and ``python``: those whose modules the code of the run path imports
    (``bench.runs.identity.result_imports``, at module level or lazily inside a function, and
    ``code_files``: a plugin method's module) and that are loaded in this process, with the
    loaded distributions these require (numba's llvmlite, pydantic's pydantic-core). Called by
    the job runner after the run. What the process loaded for other reasons (the command
    line's rich and typer, a notebook's imports, another method's Open3D) is left out; a
    library loaded only after the run's code asked for it (an Open3D backend) is in."""
    import platform

    from bench.runs.identity import file_imports, result_imports

    loaded: dict[str, str] = {}  # normalized name -> distribution name
    by_module: dict[str, str] = {}
    for module in _third_party_modules():
        dist = distribution_of(module)
        if dist is not None:
            loaded[_normal(dist)] = dist
            by_module[module] = dist
    wanted = set(result_imports())
    for path in code_files:
        wanted |= file_imports(Path(path))
    todo = [by_module[m] for m in sorted(wanted) if m in by_module]
    used: set[str] = set()
    while todo:
        dist = todo.pop()
        if _normal(dist) in used:
            continue
        used.add(_normal(dist))
        todo += [loaded[_normal(r)] for r in _requirements(dist) if _normal(r) in loaded]
    names = sorted((loaded[n] for n in used), key=str.lower)
    return {"python": platform.python_version(),
            **{name: installed_version(name) for name in names}}


def changed_libraries(recorded: dict[str, str | None]) -> dict[str, tuple]:
    """The libraries of ``recorded`` (``imported_libraries`` of a run) whose installed
    version differs now: name -> (recorded, installed)."""
    import platform

    changed = {}
    for name, version in recorded.items():
        now = platform.python_version() if name == "python" else installed_version(name)
        if now != version:
            changed[name] = (version, now)
    return changed


def libraries_current(recorded: dict[str, str | None] | None) -> bool:
    """Every library a run imported is installed at the version it ran with (a run recorded
    before libraries were recorded has none to check: its code hash differs anyway)."""
    return not changed_libraries(recorded or {})
