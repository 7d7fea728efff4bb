"""What determines a run's result, as one short key (``config.yaml``'s ``run_key``).

A run is reused only when its folder holds a finished run with the same key, whose timing is
clean and whose libraries are still installed at the versions it ran with
(``bench.runs.folders.is_finished``). The key covers everything that can change the numbers:
- the store's content (``store_identity``: SHA-256 of its bytes, cached by path, size, mtime
  and inode);
- the method, its resolved parameters, the seed option, the frame range and the evaluation
  lengths (given by the job);
- the code (``code_identity``): the content of every module that executes between the store and
  metrics.json (``RESULT_CODE``): all of ``loaders/`` (the store reader, the scan types, SE(3)
  helpers, ground truth), ``methods/``, ``metrics/``, the job runner (``bench/runs/job.py``:
  ``prepare``, ``run_job``, the choice of scored frames), the executors that call it in a
  worker, the scoring (``evaluate.py``, ``result.py``), the writing of the run folder
  (``folders.py``), how a run is timed (``timed.py``, ``bench/threads.py``), and every module of
  the repository these import (followed transitively, ``result_modules``); and the Python
  version;
- the machine (``host_identity``): the full CPU description and the library thread settings,
  so a ``time_ms`` measured on another computer or with other threads is never reused as this
  one's.
The third-party libraries are not guessed here: the job runner records the ones the run
actually imported, with their versions (``bench.runs.libraries``), and a run whose libraries
changed since is run again.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import re
import sys
from pathlib import Path

from bench import guard
from bench.paths import ROOT
from bench.runs.provenance import cpu_flags_digest, cpu_model
from bench.threads import thread_settings
from loaders.errors import DataError

#: code that executes between the store and metrics.json (folders searched recursively for
#: *.py), with every repository module it imports (``result_modules``)
RESULT_CODE = ("loaders", "methods", "metrics", "bench/runs/job.py", "bench/runs/executors.py",
               "bench/runs/executor_dask.py", "bench/runs/evaluate.py", "bench/runs/result.py",
               "bench/runs/folders.py", "bench/runs/timed.py", "bench/threads.py")
_store_hashes: dict[str, str] = {}
_code_hash: list[str] = []
_scanned: list[tuple[list[Path], set[str]]] = []  # ``_scan`` of ROOT, once per process


def _hash_cache_file() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "doppler-bench" / "store-sha256.json"


def _is_hash_cache(path: Path) -> bool:
    """The cache ``store_identity`` writes: a JSON object of "path|size|mtime|inode" keys."""
    try:
        cached = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return False
    return isinstance(cached, dict) and all("|" in str(k) for k in cached)


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
            guard.write_text(cache_file, json.dumps({**live, cache_key: digest}),
                             _is_hash_cache, "the store hash cache")
        except (OSError, DataError):
            pass
    _store_hashes[cache_key] = digest
    return digest


#: an import line: ``from a import ...`` (a parenthesised list, or names up to the line's end
#: or a comment, continued over backslash-newlines) or ``import ...`` (likewise)
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+([\w.]+)[ \t]+import[ \t]+"
                     r"(\([^)]*\)|(?:[^\n#\\]|\\\n)*)"
                     r"|import[ \t]+((?:[^\n#\\]|\\\n)+))", re.MULTILINE)


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


def _scan(root: Path) -> tuple[list[Path], set[str]]:
    if root == ROOT and _scanned:
        return _scanned[0]
    todo = []
    for entry in RESULT_CODE:
        path = root / entry
        todo += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    files, external = set(), set()
    where: dict[str, Path | None] = {}  # module name -> its file (each looked up once)

    def module_file(name: str) -> Path | None:
        if name not in where:
            where[name] = _module_file(name, root)
        return where[name]

    while todo:
        path = todo.pop()
        if path in files:
            continue
        files.add(path)
        for name in _imports(path):
            parts = name.split(".")
            found = [module_file(".".join(parts[:k])) for k in range(1, len(parts) + 1)]
            if not any(found):
                if parts[0] not in sys.stdlib_module_names:
                    external.add(parts[0])
                continue
            todo += [f for f in found if f is not None and f not in files]
    scanned = (sorted(files), external)
    if root == ROOT:
        _scanned.append(scanned)
    return scanned


def result_modules(root: Path = ROOT) -> list[Path]:
    """Every repository file that determines a result: ``RESULT_CODE`` and, transitively, every
    repository module those import (with its packages' ``__init__.py``)."""
    return _scan(root)[0]


def result_imports(root: Path = ROOT) -> set[str]:
    """The top-level names of the third-party modules that the files of ``result_modules``
    import, at module level or inside a function (``bench.runs.libraries`` keeps those a run
    actually loaded)."""
    return set(_scan(root)[1])


def file_imports(path: Path) -> set[str]:
    """The top-level names of the modules ``path`` imports (e.g. a plugin method's module)."""
    return {name.partition(".")[0] for name in _imports(path)}


def host_identity() -> dict:
    """The machine a run's times depend on: the full CPU description (``cpu_model``), a digest
    of its instruction-set flags (numba compiles for them) and the library thread settings."""
    return {"cpu": cpu_model(), "cpu_flags": cpu_flags_digest(), "threads": thread_settings()}


def code_identity(root: Path = ROOT) -> str:
    """SHA-256 (16 hex digits) of the code that determines a result: the path and content of
    every file of ``result_modules`` and the Python version. A change there re-runs every run,
    so no result of older code is shown as current."""
    if root != ROOT or not _code_hash:
        h = hashlib.sha256()
        for path in result_modules(root):
            h.update(str(path.relative_to(root)).encode())
            h.update(b"\0")
            h.update(path.read_bytes())
        h.update(f"python {platform.python_version()}".encode())
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
