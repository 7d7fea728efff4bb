"""bench.runs.identity: what the mutation run (``tools/mutate.py``) found untested.

The code identity is checked on a small repository made here, whose files, imports and
third-party names are known by construction; hashes against ``hashlib`` and ``json`` run
independently."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from bench.runs import identity
from bench.runs.identity import (
    RESULT_CODE,
    _hash_cache_file,
    _imports,
    _is_hash_cache,
    _module_file,
    code_identity,
    file_imports,
    host_identity,
    result_imports,
    result_modules,
    run_key,
    store_identity,
)
from bench.runs.provenance import cpu_flags_digest, cpu_model
from bench.threads import thread_settings
from loaders.errors import DataError

# ---- the store hash cache -----------------------------------------------------------------

def test_the_hash_cache_lives_under_xdg_cache_home_else_home_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert _hash_cache_file() == tmp_path / "xdg" / "doppler-bench" / "store-sha256.json"
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    for unset in (lambda: monkeypatch.setenv("XDG_CACHE_HOME", ""),
                  lambda: monkeypatch.delenv("XDG_CACHE_HOME")):
        unset()
        assert _hash_cache_file() == (tmp_path / "home" / ".cache" / "doppler-bench"
                                      / "store-sha256.json")


@pytest.mark.parametrize("text, expected", [
    ('{"/a|1|2|3": "x"}', True),
    ("{}", True),
    ('{"/a|1|2|3": "x", "no separator": "y"}', False),
    ('["/a|1|2|3"]', False),
    ("{not json", False),
])
def test_only_a_json_object_of_keyed_hashes_is_the_hash_cache(tmp_path, text, expected):
    path = tmp_path / "cache.json"
    path.write_text(text)
    assert _is_hash_cache(path) is expected
    assert _is_hash_cache(tmp_path / "missing.json") is False


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache file location and an empty memory cache."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(identity, "_store_hashes", {})
    return tmp_path / "cache" / "doppler-bench" / "store-sha256.json"


def _store(tmp_path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


def _key(path: Path) -> str:
    st = path.stat()
    return f"{path.resolve()}|{st.st_size}|{st.st_mtime_ns}|{st.st_ino}"


def test_a_store_larger_than_one_read_is_hashed_whole(tmp_path, cache):
    data = os.urandom(3 * (1 << 20) + 12345)
    path = _store(tmp_path, "big.h5", data)
    assert store_identity(path) == hashlib.sha256(data).hexdigest()


def test_the_cache_file_keeps_live_entries_and_drops_those_of_deleted_stores(tmp_path, cache):
    live = _store(tmp_path, "live.h5", b"live")
    gone = tmp_path / "gone.h5"
    cache.parent.mkdir(parents=True)
    cache.write_text(json.dumps({_key(live): "planted-live", f"{gone}|1|2|3": "old"}))
    new = _store(tmp_path, "new.h5", b"new store")
    digest = store_identity(new)
    assert digest == hashlib.sha256(b"new store").hexdigest()
    assert json.loads(cache.read_text()) == {_key(live): "planted-live", _key(new): digest}
    assert store_identity(live) == "planted-live"  # read from the file, not hashed


@pytest.mark.parametrize("content", ["{broken", '["a list"]'])
def test_a_file_that_is_no_cache_is_ignored_and_left_alone(tmp_path, cache, content):
    """Not JSON, or not an object: the store is hashed, and the file (perhaps not ours: the
    guard refuses to overwrite it) keeps its content."""
    path = _store(tmp_path, "s.h5", b"store bytes")
    cache.parent.mkdir(parents=True)
    cache.write_text(content)
    assert store_identity(path) == hashlib.sha256(b"store bytes").hexdigest()
    assert cache.read_text() == content


def test_a_cached_value_that_is_no_digest_is_hashed_again_and_replaced(tmp_path, cache):
    path = _store(tmp_path, "s.h5", b"store bytes")
    cache.parent.mkdir(parents=True)
    cache.write_text(json.dumps({_key(path): 42}))
    digest = store_identity(path)
    assert digest == hashlib.sha256(b"store bytes").hexdigest()
    assert json.loads(cache.read_text()) == {_key(path): digest}


@pytest.mark.parametrize("error", [OSError("read-only home"), DataError("not a cache")])
def test_a_cache_that_cannot_be_written_only_costs_a_new_hash(tmp_path, cache, monkeypatch,
                                                               error):
    def refuse(*args, **kwargs):
        raise error

    monkeypatch.setattr(identity.guard, "write_text", refuse)
    path = _store(tmp_path, "s.h5", b"abc")
    assert store_identity(path) == hashlib.sha256(b"abc").hexdigest()
    assert not cache.exists()


def test_the_memory_cache_answers_without_reading_the_file_again(tmp_path, cache, monkeypatch):
    path = _store(tmp_path, "s.h5", b"abc")
    first = store_identity(path)
    cache.unlink()
    monkeypatch.setattr(identity, "open", lambda *a, **k: pytest.fail("hashed again"),
                        raising=False)
    assert store_identity(path) == first


def test_the_cache_file_written_is_the_one_the_guard_accepts_as_the_cache(tmp_path, cache,
                                                                           monkeypatch):
    seen = []
    real = identity.guard.write_text

    def spy(path, text, check, what):
        seen.append((Path(path), check, what))
        return real(path, text, check, what)

    monkeypatch.setattr(identity.guard, "write_text", spy)
    store_identity(_store(tmp_path, "s.h5", b"abc"))
    assert [(p, c) for p, c, _ in seen] == [(cache, identity._is_hash_cache)]


# ---- imports --------------------------------------------------------------------------------

_SOURCE = """\
import os, sys as system
import a.b.c
from x.y import (p,
    q as r)
from z import *
from u import (Xa, bX)
from m import (a, \\
    b)
import c, \\
    d
from e import f, \\
    g
from . import rel
from .mod import thing
def f():
    import indented  # a comment
from w import v  # from hidden import nothing
# import commented
text = "import in_a_string_not_at_line_start"
"""


def test_imports_are_read_from_the_import_lines(tmp_path):
    path = tmp_path / "m.py"
    path.write_text(_SOURCE)
    assert _imports(path) == {"os", "sys", "a.b.c", "x.y", "x.y.p", "x.y.q", "z", "m", "m.a",
                              "m.b", "u", "u.Xa", "u.bX", "c", "d", "e", "e.f", "e.g",
                              "indented", "w", "w.v"}
    assert file_imports(path) == {"os", "sys", "a", "x", "z", "m", "u", "c", "d", "e", "indented",
                                  "w"}


def test_a_module_is_its_file_or_its_packages_init(tmp_path):
    (tmp_path / "pkg" / "sub").mkdir(parents=True)
    (tmp_path / "pkg" / "__init__.py").write_text("")
    (tmp_path / "pkg" / "mod.py").write_text("")
    (tmp_path / "pkg" / "sub" / "__init__.py").write_text("")
    assert _module_file("pkg", tmp_path) == tmp_path / "pkg" / "__init__.py"
    assert _module_file("pkg.mod", tmp_path) == tmp_path / "pkg" / "mod.py"
    assert _module_file("pkg.sub", tmp_path) == tmp_path / "pkg" / "sub" / "__init__.py"
    assert _module_file("pkg.missing", tmp_path) is None
    assert _module_file("numpy", tmp_path) is None


def _repo(root: Path) -> set[Path]:
    """A repository with every file of RESULT_CODE (empty), where loaders/ imports a helper
    package that imports a third-party module; returns the files that determine a result."""
    for entry in RESULT_CODE:
        path = root / entry
        if path.suffix == ".py":
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("")
        else:
            path.mkdir(parents=True, exist_ok=True)
            (path / "__init__.py").write_text("")
    (root / "__init__.py").write_text("")  # a checkout root is no package: never followed
    (root / "toplevel.py").write_text("import yaml\n")
    (root / "loaders" / "reader.py").write_text(
        "import json\nimport numpy as np\nfrom helpers.util import tool\nimport toplevel\n")
    (root / "helpers").mkdir()
    (root / "helpers" / "__init__.py").write_text("")
    (root / "helpers" / "util.py").write_text("import scipy.linalg\n\ndef tool():\n"
                                              "    import h5py\n")
    (root / "helpers" / "unused.py").write_text("import pandas\n")
    (root / "metrics" / "deep").mkdir()
    (root / "metrics" / "deep" / "inner.py").write_text("import bench.runs.job\n")
    return ({root / e for e in RESULT_CODE if e.endswith(".py")}
            | {root / e / "__init__.py" for e in RESULT_CODE if not e.endswith(".py")}
            | {root / "loaders" / "reader.py", root / "helpers" / "__init__.py",
               root / "helpers" / "util.py", root / "metrics" / "deep" / "inner.py",
               root / "toplevel.py"})


def test_the_result_code_is_followed_through_its_imports(tmp_path):
    expected = _repo(tmp_path)
    assert result_modules(tmp_path) == sorted(expected)
    assert result_imports(tmp_path) == {"numpy", "scipy", "h5py", "yaml"}


def test_the_repositorys_own_scan_is_read_once_per_process(monkeypatch):
    monkeypatch.setattr(identity, "_scanned", [])
    first = result_modules()
    assert Path(identity.__file__).resolve().parents[2] / "bench" / "runs" / "job.py" in first
    assert result_modules() is first and len(identity._scanned) == 1
    assert result_imports() == set(identity._scanned[0][1]) and "numpy" in result_imports()


# ---- the code identity ----------------------------------------------------------------------

def _by_definition(root: Path, files, python: str) -> str:
    h = hashlib.sha256()
    for path in sorted(files):
        h.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    h.update(f"python {python}".encode())
    return h.hexdigest()[:16]


def test_the_code_identity_is_the_hash_of_each_files_path_and_content(tmp_path):
    import platform

    files = _repo(tmp_path / "a")
    code_identity()  # the repository's own, kept apart from any other root's
    key = code_identity(tmp_path / "a")
    assert key == _by_definition(tmp_path / "a", files, platform.python_version())
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    assert code_identity(tmp_path / "b") == key  # where the checkout lies does not count
    (tmp_path / "b" / "helpers" / "unused.py").write_text("import pandas  # edited\n")
    assert code_identity(tmp_path / "b") == key  # a file no result depends on
    (tmp_path / "b" / "helpers" / "util.py").write_text("import scipy.linalg  # edited\n")
    assert code_identity(tmp_path / "b") != key


def test_the_repositorys_code_identity_is_computed_once_per_process(monkeypatch):
    monkeypatch.setattr(identity, "_code_hash", [])
    first = code_identity()
    assert len(first) == 16 and int(first, 16) >= 0
    monkeypatch.setattr(identity.platform, "python_version", lambda: "3.99.0")
    assert code_identity() == first and identity._code_hash == [first]


def test_the_host_identity_is_the_cpu_its_flags_and_the_thread_settings():
    assert host_identity() == {"cpu": cpu_model(), "cpu_flags": cpu_flags_digest(),
                               "threads": thread_settings()}


# ---- the run key ----------------------------------------------------------------------------

def test_the_run_key_is_16_hex_digits_of_the_sorted_identity():
    one = {"method": "doppler", "params": {"b": 1, "a": 2}, "store": Path("/data/s.h5")}
    reordered = {"store": Path("/data/s.h5"), "params": {"a": 2, "b": 1}, "method": "doppler"}
    text = '{"method": "doppler", "params": {"a": 2, "b": 1}, "store": "/data/s.h5"}'
    assert run_key(one) == run_key(reordered) == hashlib.sha256(text.encode()).hexdigest()[:16]
    assert run_key({**one, "seed": True}) != run_key(one)
