"""Atomic file writes (the mechanics below ``bench/guard.py``, which decides what a command may
write; loaders/ may not import bench, so the store writer uses these directly): write to a
temporary file beside the destination, fsync it, rename it.

A crash never leaves a half-written file under the final name, so "the file exists" always
means "the file is complete" (runs are resumed on that basis).

- The temporary file is ``.<name>.<pid>.tmp`` in the destination's folder (same file system, so
  the rename is atomic). A write killed with SIGKILL cannot remove it; the next write to the same
  destination removes every ``.<name>.<pid>.tmp`` whose process no longer runs.
- Files get the user's umask (``0o666 & ~umask``, like ``open()``), not ``mkstemp``'s 0600, so
  collaborators can read stores and results when the umask allows it.
- The data are fsynced before the rename and the folder after it, so a power loss leaves either
  the old file or the complete new one.
- A destination that is a folder, or a folder that cannot be written, raises ``DataError``
  naming the path (a user error, reported without a traceback).
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from pathlib import Path

from loaders.errors import DataError


def temp_path(path: Path, pid: int | None = None) -> Path:
    """The temporary file a process ``pid`` (default: this one) writes ``path`` through."""
    return path.with_name(f".{path.name}.{os.getpid() if pid is None else pid}.tmp")


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's live process
        return True
    return True


def remove_stale_temps(path: str | Path) -> list[Path]:
    """Remove the temporaries of writes to ``path`` whose process is gone; returns them."""
    path = Path(path)
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.(\d+)\.tmp$")
    removed = []
    try:
        siblings = list(path.parent.iterdir())
    except OSError:
        return removed
    for p in siblings:
        m = pattern.match(p.name)
        if m and int(m.group(1)) != os.getpid() and not _pid_alive(int(m.group(1))):
            with contextlib.suppress(FileNotFoundError):
                p.unlink()
                removed.append(p)
    return removed


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _fsync_path(path: Path, directory: bool = False) -> None:
    fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
    try:
        os.fsync(fd)
    except OSError:  # some file systems cannot fsync a folder; the data fsync is what matters
        if not directory:
            raise
    finally:
        os.close(fd)


def _prepare(path: Path) -> Path:
    if path.is_dir():
        raise DataError(f"{path}: is a folder; expected a file name to write")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise DataError(f"{path}: cannot create its folder ({err.strerror or err})") from None
    if not path.parent.is_dir():
        raise DataError(f"{path}: {path.parent} is not a folder")
    remove_stale_temps(path)
    tmp = temp_path(path)
    try:
        # a leftover of this very process (an earlier attempt) is overwritten
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    except OSError as err:
        raise DataError(f"{path}: cannot write here ({err.strerror or err})") from None
    os.close(fd)
    return tmp


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block succeeds, fsync it, give it the
    umask's permissions and rename it to ``path``. On failure the temporary is removed."""
    path = Path(path)
    tmp = _prepare(path)
    try:
        yield tmp
        # writers such as h5py may recreate the file: set the mode the umask asks for
        os.chmod(tmp, 0o666 & ~_umask())
        _fsync_path(tmp)
        try:
            os.replace(tmp, path)
        except IsADirectoryError:
            raise DataError(f"{path}: is a folder; expected a file name to write") from None
        _fsync_path(path.parent, directory=True)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def create_hdf5(path: str | Path, **options):
    """A new HDF5 file open for writing at ``path`` (the temporary of an ``atomic_path``):
    the store writer's only way to create one (tests/test_write_rule.py)."""
    import h5py

    return h5py.File(path, "w", **options)
