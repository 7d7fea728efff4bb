"""bench.runs.provenance: what the mutation run (``tools/mutate.py``) found untested.

The expected values are worked out by hand from /proc/cpuinfo's documented layout (blocks of
``key : value`` lines, one per processor, separated by a blank line), from git run
independently in a repository made here, and from the standard library."""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from importlib import metadata
from pathlib import Path

import pytest

from bench.runs import provenance
from bench.runs.provenance import (
    _cpuinfo,
    _git_state,
    cpu_flags_digest,
    cpu_model,
    installed_version,
    installed_versions,
    run_meta,
)
from bench.threads import thread_settings
from methods.timing import TIMING_LOCK_ENV

# ---- /proc/cpuinfo ------------------------------------------------------------------------

_TWO_PROCESSORS = """

processor\t: 0
vendor_id\t: GenuineIntel
a line without a separator
model name\t: Intel: Xeon
model name\t: a second value of the same key
flags\t\t: sse2 avx

processor\t: 1
model name\t: another processor
extra\t: only in the second block
"""


def test_cpuinfo_keeps_the_first_processors_block_and_the_first_value_of_each_key():
    assert _cpuinfo(_TWO_PROCESSORS) == {
        "processor": "0", "vendor_id": "GenuineIntel", "model name": "Intel: Xeon",
        "flags": "sse2 avx"}
    assert _cpuinfo("") == {}


def test_cpuinfo_without_text_reads_proc_cpuinfo(monkeypatch):
    """Read independently: the lines of /proc/cpuinfo up to the first blank line."""
    lines = Path("/proc/cpuinfo").read_text().splitlines()
    first = lines[:lines.index("")] if "" in lines else lines
    expected = {}
    for line in first:
        if ":" in line:
            key, value = line.split(":", 1)
            expected.setdefault(key.strip(), value.strip())
    assert _cpuinfo() == expected


def test_cpuinfo_of_an_unreadable_file_is_empty(monkeypatch):
    class Unreadable:
        def __init__(self, *args):
            pass

        def read_text(self):
            raise PermissionError("no")

    monkeypatch.setattr(provenance, "Path", Unreadable)
    assert _cpuinfo() == {}


# ---- cpu_model ------------------------------------------------------------------------------

_ARM = """processor\t: 0
BogoMIPS\t: 50.00
Features\t: fp asimd evtstrm aes
CPU implementer\t: 0x41
CPU architecture: 8
CPU variant\t: 0x3
CPU part\t: 0xd0c
CPU revision\t: 1
"""


def test_an_arm_cpu_is_named_by_its_implementer_part_variant_and_revision():
    assert cpu_model(_ARM) == "unknown CPU (implementer 0x41 part 0xd0c variant 0x3 revision 1)"
    assert cpu_model("Model Name\t: Neoverse-N1\n" + _ARM) == (
        "Neoverse-N1 (implementer 0x41 part 0xd0c variant 0x3 revision 1)")
    assert cpu_model("Hardware\t: BCM2835\n") == "BCM2835"


def test_the_numbers_alone_or_the_vendor_alone_still_describe_the_cpu():
    assert cpu_model("cpu family\t: 6\nmodel\t\t: 85\nstepping\t: 7\n") == (
        "unknown CPU (family 6 model 85 stepping 7)")
    assert cpu_model("vendor_id\t: AuthenticAMD\n") == "unknown CPU (AuthenticAMD)"
    assert cpu_model("model name\t: X\nvendor_id\t: V\n") == "X (V)"


def _no_cpuinfo(monkeypatch, system: str, processor: str = "", machine: str = "x86_64"):
    monkeypatch.setattr(platform, "system", lambda: system)
    monkeypatch.setattr(platform, "processor", lambda: processor)
    monkeypatch.setattr(platform, "machine", lambda: machine)


def test_without_cpuinfo_platform_names_the_cpu(monkeypatch):
    _no_cpuinfo(monkeypatch, "Windows", processor="Intel64 Family 6 Model 85 Stepping 7")
    assert cpu_model("") == "Intel64 Family 6 Model 85 Stepping 7"
    _no_cpuinfo(monkeypatch, "Linux", processor="", machine="aarch64")
    assert cpu_model("") == "aarch64"


def _sysctl(stdout, calls=None):
    """``subprocess.run`` as it behaves: stdout captured only when asked, text only when
    asked; a call without a timeout could hang a run, so none is accepted."""
    def run(args, capture_output=False, text=False, timeout=None, **kwargs):
        if calls is not None:
            calls.append(args)
        assert timeout is not None and timeout > 0
        if isinstance(stdout, Exception):
            raise stdout
        out = (stdout if text else stdout.encode()) if capture_output else None
        return subprocess.CompletedProcess(args, 0, stdout=out, stderr=None)

    return run


def test_macos_names_the_cpu_by_its_brand_string(monkeypatch):
    calls = []
    _no_cpuinfo(monkeypatch, "Darwin", processor="arm")
    monkeypatch.setattr(provenance.subprocess, "run", _sysctl("  Apple M2 Pro \n", calls))
    assert cpu_model("") == "Apple M2 Pro"
    assert calls == [["sysctl", "-n", "machdep.cpu.brand_string"]]


def test_only_macos_is_asked_for_a_brand_string(monkeypatch):
    _no_cpuinfo(monkeypatch, "Linux", processor="x86_64")
    monkeypatch.setattr(provenance.subprocess, "run", _sysctl("Apple M2 Pro"))
    assert cpu_model("") == "x86_64"


@pytest.mark.parametrize("outcome", ["", OSError("no sysctl"),
                                     subprocess.TimeoutExpired("sysctl", 5)])
def test_macos_without_a_brand_string_falls_back_to_platform(monkeypatch, outcome):
    _no_cpuinfo(monkeypatch, "Darwin", processor="i386")
    monkeypatch.setattr(provenance.subprocess, "run", _sysctl(outcome))
    assert cpu_model("") == "i386"


# ---- cpu_flags_digest ----------------------------------------------------------------------

def test_the_flags_digest_is_the_sha256_of_the_sorted_flags():
    expected = hashlib.sha256(b"avx2 fpu sse2").hexdigest()[:12]
    assert cpu_flags_digest("flags\t: sse2 fpu  avx2\n") == expected
    assert cpu_flags_digest("flags\t: avx2 sse2 fpu\n") == expected
    arm = hashlib.sha256(b"aes asimd evtstrm fp").hexdigest()[:12]
    assert cpu_flags_digest(_ARM) == arm
    assert cpu_flags_digest("flags\t:\n") is None


# ---- installed versions -------------------------------------------------------------------

def test_installed_versions_are_the_distributions_metadata():
    assert installed_version("numpy") == metadata.version("numpy")
    assert installed_version("no-such-dist-xyz") is None
    assert installed_versions(["pyyaml", "no-such-dist-xyz"]) == {
        "pyyaml": metadata.version("pyyaml"), "no-such-dist-xyz": None}


# ---- git state ------------------------------------------------------------------------------

def _git(cwd: Path, *args: str) -> str:
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@example.org",
           "GIT_COMMITTER_NAME": "t", "GIT_COMMITTER_EMAIL": "t@example.org"}
    return subprocess.run(["git", *args], cwd=cwd, env=env, check=True, capture_output=True,
                          text=True).stdout.strip()


def test_the_git_state_is_the_commit_and_whether_a_tracked_file_changed(tmp_path, monkeypatch):
    repo = tmp_path / "repo"
    repo.mkdir()
    _git(repo, "init", "-q")
    (repo / "a.txt").write_text("one\n")
    _git(repo, "add", "a.txt")
    _git(repo, "commit", "-q", "-m", "first")
    monkeypatch.setattr(provenance, "ROOT", repo)
    head = _git(repo, "rev-parse", "HEAD")
    assert _git_state() == {"commit": head, "dirty": False}
    (repo / "untracked.txt").write_text("not tracked: not dirty\n")
    assert _git_state() == {"commit": head, "dirty": False}
    (repo / "a.txt").write_text("two\n")
    assert _git_state() == {"commit": head, "dirty": True}


def test_outside_a_repository_the_commit_is_unknown(tmp_path, monkeypatch):
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path))
    folder = tmp_path / "plain"
    folder.mkdir()
    monkeypatch.setattr(provenance, "ROOT", folder)
    assert _git_state() == {"commit": None, "dirty": False}


@pytest.mark.parametrize("error", [FileNotFoundError("no git"),
                                   subprocess.TimeoutExpired("git", 10)])
def test_without_git_the_state_is_unknown(monkeypatch, error):
    def fail(*args, **kwargs):
        raise error

    monkeypatch.setattr(provenance.subprocess, "run", fail)
    assert _git_state() == {"commit": None, "dirty": None}


def test_every_git_call_has_a_timeout(monkeypatch):
    """A hanging git (a locked index, a network file system) must not hang a run."""
    def git(args, cwd=None, capture_output=False, text=False, timeout=None):
        assert timeout is not None and timeout > 0 and capture_output and text
        out = "0123abcd\n" if args[1] == "rev-parse" else " M file\n"
        return subprocess.CompletedProcess(args, 0, stdout=out, stderr="")

    monkeypatch.setattr(provenance.subprocess, "run", git)
    assert _git_state() == {"commit": "0123abcd", "dirty": True}


# ---- run_meta -------------------------------------------------------------------------------

def test_run_meta_records_where_and_when_the_run_was_made(monkeypatch):
    monkeypatch.setenv(TIMING_LOCK_ENV, "/tmp/some.lock")
    before = datetime.now(UTC).replace(microsecond=0)
    meta = run_meta()
    after = datetime.now(UTC)
    assert meta["python"] == platform.python_version()
    assert meta["packages"]["numpy"] == metadata.version("numpy")
    assert set(meta["packages"]) >= {"numpy", "scipy", "h5py", "numba"}
    assert meta["cpu"] == cpu_model()
    assert meta["cpu_count"] == os.cpu_count()
    assert meta["threads"] == thread_settings()
    assert meta["timing_lock"] == "/tmp/some.lock"
    assert meta["host"] == platform.node()
    assert meta["git"] == _git_state()
    date = datetime.fromisoformat(meta["date"])
    assert date.utcoffset() == timedelta(0) and date.microsecond == 0
    assert before <= date <= after
    assert meta["date"].endswith("+00:00") and len(meta["date"]) == 25


def test_run_meta_names_numbas_threads_only_when_numba_is_loaded(monkeypatch):
    import numba

    assert run_meta()["numba_threads"] == numba.config.NUMBA_NUM_THREADS
    monkeypatch.delitem(sys.modules, "numba")
    monkeypatch.delenv(TIMING_LOCK_ENV, raising=False)
    meta = run_meta()
    assert meta["numba_threads"] is None and meta["timing_lock"] is None
