"""Atomic writes: the user's umask, fsync before the rename, stale temporaries of killed writes
removed on the next write, clear errors for unwritable destinations."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import constant_twist_sequence
from loaders import fileio
from loaders.errors import DataError
from loaders.fileio import atomic_path, atomic_write_text, remove_stale_temps, temp_path
from loaders.store import write_store

ROOT = Path(__file__).resolve().parents[1]


def temporaries(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


@pytest.fixture
def umask():
    old = os.umask(0o022)
    yield lambda m: os.umask(m)
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_files_get_the_umask_mode(tmp_path, umask, mask, mode):
    umask(mask)
    atomic_write_text(tmp_path / "a.txt", "x")
    assert (tmp_path / "a.txt").stat().st_mode & 0o777 == mode
    store = write_store(constant_twist_sequence(n_frames=2, n_points=50), tmp_path / "s.h5")
    assert store.stat().st_mode & 0o777 == mode  # h5py recreates the file: mode set after
    assert temporaries(tmp_path) == []


def test_data_fsynced_before_the_rename(tmp_path, monkeypatch):
    events = []
    real_fsync, real_replace = os.fsync, os.replace
    monkeypatch.setattr(fileio.os, "fsync", lambda fd: (events.append("fsync"), real_fsync(fd)))
    monkeypatch.setattr(fileio.os, "replace",
                        lambda a, b: (events.append("replace"), real_replace(a, b)))
    atomic_write_text(tmp_path / "m.json", "{}")
    assert events[:2] == ["fsync", "replace"]  # file data, then rename (then the folder)
    assert (tmp_path / "m.json").read_text() == "{}"


def test_failed_block_leaves_neither_file_nor_temporary(tmp_path):
    (tmp_path / "keep.txt").write_text("old")
    with pytest.raises(RuntimeError), atomic_path(tmp_path / "keep.txt") as tmp:
        tmp.write_text("half")
        raise RuntimeError("writer died")
    assert (tmp_path / "keep.txt").read_text() == "old"
    assert temporaries(tmp_path) == []


def test_stale_temporaries_of_dead_processes_are_removed(tmp_path):
    dest = tmp_path / "s.h5"
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead = temp_path(dest, int(proc.stdout))
    dead.write_text("left by a killed write")
    alive = temp_path(dest, 1)  # pid 1 always runs: a write in progress elsewhere
    alive.write_text("in progress")
    other = tmp_path / f".other.h5.{int(proc.stdout)}.tmp"
    other.write_text("another destination's")
    atomic_write_text(dest, "new")
    assert not dead.exists() and alive.exists() and other.exists()
    assert dest.read_text() == "new"
    assert remove_stale_temps(tmp_path / "other.h5") == [other]


def test_unwritable_destinations_are_data_errors(tmp_path):
    (tmp_path / "folder.h5").mkdir()
    with pytest.raises(DataError, match="folder.h5: is a folder"):
        atomic_write_text(tmp_path / "folder.h5", "x")
    (tmp_path / "file").write_text("")
    with pytest.raises(DataError, match="cannot create its folder"):
        atomic_write_text(tmp_path / "file" / "x.txt", "x")


def test_sigkill_during_synth_then_next_write_cleans_up(tmp_path):
    """SIGKILL of `bench synth` mid-write leaves its temporary; the next write to the same
    store removes it and nothing stays under the final name in between."""
    out = tmp_path / "wall.h5"
    cmd = [sys.executable, "-m", "bench.cli", "synth", "straight-wall", "--sensor",
           "radar-sparse", "--out", str(out)]
    proc = subprocess.Popen([*cmd, "--frames", "2000"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, cwd=ROOT)
    tmp = temp_path(out, proc.pid)
    deadline = time.monotonic() + 60
    while not tmp.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert tmp.exists(), "the write never started"
    time.sleep(0.3)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert tmp.exists() and not out.exists()
    done = subprocess.run([*cmd, "--frames", "3"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    assert out.exists() and temporaries(tmp_path) == []
