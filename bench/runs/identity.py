"""What determines a run's result, as one short key (``config.yaml``'s ``run_key``).

A run is reused only when its folder holds a finished run with the same key, so the key covers
everything that can change the numbers:
- the store's content (``store_identity``: SHA-256 of its bytes, cached by path, size, mtime
  and inode);
- the method, its resolved parameters, the seed option, the frame range and the evaluation
  lengths (given by the job);
- the code (``code_identity``): the content of every module that can change a result, i.e. all
  of ``loaders/`` (the scan types, SE(3) helpers and ground-truth handling that methods and
  scoring use), ``methods/``, ``metrics/``, the scoring (``bench/runs/evaluate.py``), how a run
  is timed (``bench/runs/timed.py``, ``bench/threads.py``), every module of the repository these
  import (followed transitively, ``result_modules``), and the source of the functions of other
  modules that decide what is scored (``RESULT_FUNCTIONS``: the choice of scored frames in
  ``bench/runs/job.py``); and the versions of Python, of ``RESULT_LIBRARIES`` and of every
  third-party distribution that code imports (``result_libraries``);
- the machine (``host_identity``): the CPU model and the library thread settings, so a
  ``time_ms`` measured on another computer or with other threads is never reused as this
  one's.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import os
import platform
import re
import sys
from importlib import metadata
from pathlib import Path

from bench.paths import ROOT
from bench.runs.provenance import cpu_model, installed_versions
from bench.threads import thread_settings
from loaders.errors import DataError
from loaders.fileio import atomic_write_text

#: code whose content determines a result (folders searched recursively for *.py), with every
#: repository module it imports (``result_modules``)
RESULT_CODE = ("loaders", "methods", "metrics", "bench/runs/evaluate.py", "bench/runs/result.py",
               "bench/runs/timed.py",
               "bench/threads.py")
#: functions of other modules that determine a result: (file, function name)
RESULT_FUNCTIONS = (("bench/runs/job.py", "calibration_frames"),)
#: libraries whose version can change a result (beside those the result code imports)
#: importable modules whose distribution is named otherwise (no scan of every installed file)
MODULE_DISTRIBUTIONS = {"open3d": ("open3d", "open3d-cpu"), "yaml": ("PyYAML",)}
RESULT_LIBRARIES = ("numpy", "scipy", "numba", "small_gicp", "kiss-icp", "open3d-cpu", "open3d",
                    "evo", "h5py", "pydantic")
_store_hashes: dict[str, str] = {}
_code_hash: list[str] = []


def _hash_cache_file() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "doppler-bench" / "store-sha256.json"


def store_identity(path: Path) -> str:
    """SHA-256 of a store's bytes (its content identity). Cached in memory and in
    ~/.cache/doppler-bench/store-sha256.json by resolved path, size, mtime and inode (a store
    rewritten by an atomic rename has a new inode), so an unchanged store is hashed once."""
    st = Path(path).stat()
    cache_key = f"{Path(path).resolve()}|{st.st_size}|{st.st_mtime_ns}|{st.st_ino}"
    if cache_key in _store_hashes:
        return _store_hashes[cache_key]
    cache_file = _hash_cache_file()
    try:
        cached = json.loads(cache_file.read_text())
    except (OSError, ValueError):
        cached = {}
    digest = cached.get(cache_key) if isinstance(cached, dict) else None
    if not isinstance(digest, str):
        h = hashlib.sha256()
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
        digest = h.hexdigest()
        cached = cached if isinstance(cached, dict) else {}
        live = {k: v for k, v in cached.items() if Path(k.split("|")[0]).exists()}
        try:  # best effort: a read-only home only costs re-hashing next time
            cache_file.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_text(cache_file, json.dumps({**live, cache_key: digest}))
        except (OSError, DataError):
            pass
    _store_hashes[cache_key] = digest
    return digest


_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+([\w.]+)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)"
                     r"|import[ \t]+([^\n#]+))", re.MULTILINE)


def _imports(path: Path) -> set[str]:
    """Absolute module names ``path`` imports (``import a.b``, ``from a.b import c`` as a.b and
    a.b.c), read from its import lines (a regular expression: parsing every file is slow)."""
    names = set()
    for module, what, plain in _IMPORT.findall(path.read_text()):
        items = [x.strip().split(" as ")[0].strip() for x in (what or plain).strip("()")
                 .replace("\\\n", " ").split(",")]
        if plain:
            names.update(x for x in items if x)
        elif not module.startswith("."):
            names.add(module)
            names.update(f"{module}.{x}" for x in items if x.isidentifier())
    return names


def _module_file(name: str, root: Path) -> Path | None:
    base = root.joinpath(*name.split("."))
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def result_modules(root: Path = ROOT) -> tuple[list[Path], set[str]]:
    """(every repository file that determines a result, the top-level names of the
    third-party modules they import): ``RESULT_CODE`` and, transitively, every repository
    module those import (with its packages' ``__init__.py``)."""
    todo = []
    for entry in RESULT_CODE:
        path = root / entry
        todo += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    files, external = set(), set()
    while todo:
        path = todo.pop()
        if path in files:
            continue
        files.add(path)
        for name in _imports(path):
            parts = name.split(".")
            found = [_module_file(".".join(parts[:k]), root) for k in range(1, len(parts) + 1)]
            if not any(found):
                if parts[0] not in sys.stdlib_module_names:
                    external.add(parts[0])
                continue
            todo += [f for f in found if f is not None and f not in files]
    return sorted(files), external


def function_source(path: Path, name: str) -> str:
    """The source of the top-level function ``name`` of ``path`` (ValueError when absent: a
    renamed function must be renamed in ``RESULT_FUNCTIONS`` too)."""
    text = path.read_text()
    for node in ast.parse(text, str(path)).body:
        if isinstance(node, ast.FunctionDef) and node.name == name:
            return ast.get_source_segment(text, node) or ""
    raise ValueError(f"{path}: no function {name!r} (RESULT_FUNCTIONS in {__file__})")


def result_libraries(external: set[str]) -> list[str]:
    """``RESULT_LIBRARIES`` and the distributions that provide the modules in ``external``
    (a module named like its distribution directly, the others through the installed
    distributions' file lists)."""
    names, unknown = set(RESULT_LIBRARIES), []
    for module in sorted(external):
        try:
            names.add(metadata.distribution(module).metadata["Name"])
        except metadata.PackageNotFoundError:
            if module in MODULE_DISTRIBUTIONS:
                names.update(MODULE_DISTRIBUTIONS[module])
            elif importlib.util.find_spec(module) is None:
                names.add(module)  # not installed: listed without a version
            else:
                unknown.append(module)
    if unknown:  # scanning every installed distribution's file list costs about 0.5 s
        provided = metadata.packages_distributions()
        for module in unknown:
            names.update(provided.get(module, [module]))
    return sorted(names)


def library_versions(external: set[str] | None = None) -> dict[str, str | None]:
    """Installed versions of the result libraries (None when absent) and of Python."""
    if external is None:
        external = result_modules()[1]
    return {"python": platform.python_version(),
            **installed_versions(result_libraries(external))}


def host_identity() -> dict:
    """The machine a run's times depend on: CPU model and library thread settings."""
    return {"cpu": cpu_model(), "threads": thread_settings()}


def code_identity(root: Path = ROOT) -> str:
    """SHA-256 (16 hex digits) of the code that determines a result: the path and content of
    every file of ``result_modules``, the source of ``RESULT_FUNCTIONS`` and the library
    versions. A change there re-runs every run, so no result of older code is shown as
    current."""
    if root != ROOT or not _code_hash:
        h = hashlib.sha256()
        files, external = result_modules(root)
        for path in files:
            h.update(str(path.relative_to(root)).encode())
            h.update(b"\0")
            h.update(path.read_bytes())
        for file, name in RESULT_FUNCTIONS:
            h.update(f"{file}:{name}\0{function_source(root / file, name)}".encode())
        h.update(json.dumps(library_versions(external), sort_keys=True).encode())
        digest = h.hexdigest()[:16]
        if root != ROOT:
            return digest
        _code_hash.append(digest)
    return _code_hash[0]


def run_key(identity: dict) -> str:
    """A short key of everything that determines a run's result (``identity``: store content,
    method, resolved parameters, seed option, frame range, evaluation settings, code, host)."""
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
