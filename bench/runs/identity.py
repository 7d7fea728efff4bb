"""What determines a run's result, as one short key (``config.yaml``'s ``run_key``).

A run is reused only when its folder holds a finished run with the same key, so the key covers
everything that can change the numbers:
- the store's content (``store_identity``: SHA-256 of its bytes, cached by path, size, mtime
  and inode);
- the method, its resolved parameters, the seed option, the frame range and the evaluation
  lengths (given by the job);
- the code (``code_identity``): the content of every module that can change a result, i.e. all
  of ``loaders/`` (the scan types, SE(3) helpers and ground-truth handling that methods and
  scoring use), ``methods/``, ``metrics/`` and the scoring (``bench/runs/evaluate.py``), and the
  versions of the numerical libraries the methods call.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from bench.paths import ROOT
from bench.runs.provenance import installed_versions
from loaders.errors import DataError
from loaders.fileio import atomic_write_text

#: code whose content determines a result (folders searched recursively for *.py)
RESULT_CODE = ("loaders", "methods", "metrics", "bench/runs/evaluate.py")
#: numerical libraries whose version can change a result
RESULT_LIBRARIES = ("numpy", "scipy", "numba", "small_gicp", "kiss-icp", "open3d-cpu", "open3d",
                    "evo", "h5py")
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


def library_versions() -> dict[str, str | None]:
    """Installed versions of ``RESULT_LIBRARIES`` (None when absent)."""
    return installed_versions(RESULT_LIBRARIES)


def code_identity(root: Path = ROOT) -> str:
    """SHA-256 (16 hex digits) of the code that determines a result: the path and content of
    every Python file under ``RESULT_CODE`` and the library versions. A change there re-runs
    every run, so no result of older code is shown as current."""
    if root != ROOT or not _code_hash:
        h = hashlib.sha256()
        files = []
        for entry in RESULT_CODE:
            path = root / entry
            files += sorted(path.rglob("*.py")) if path.is_dir() else [path]
        for path in files:
            h.update(str(path.relative_to(root)).encode())
            h.update(b"\0")
            h.update(path.read_bytes())
        h.update(json.dumps(library_versions(), sort_keys=True).encode())
        digest = h.hexdigest()[:16]
        if root != ROOT:
            return digest
        _code_hash.append(digest)
    return _code_hash[0]


def run_key(identity: dict) -> str:
    """A short key of everything that determines a run's result (``identity``: store content,
    method, resolved parameters, seed option, frame range, evaluation settings, code)."""
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]
