"""loaders/fileio.py, what tests/test_fileio.py leaves open (make mutate's survivors): which
processes count as alive (another user's process is), stale temporaries looked for in a folder
that does not exist, a folder that cannot be fsynced (tolerated) against data that cannot be
(an error), a destination that turns into a folder during the write, a folder that cannot be
written, and the options the HDF5 writer is given.

The machine's processes are stood in for by ``os.kill`` replaced in the module, so that the
answers do not depend on the user the tests run as (root may signal every process)."""

import errno
import os

import h5py
import pytest

from loaders import fileio
from loaders.errors import DataError
from loaders.fileio import (
    atomic_path,
    atomic_write_bytes,
    create_hdf5,
    remove_stale_temps,
    temp_path,
)


def kill_raising(error):
    def kill(pid, sig):
        assert sig == 0  # only ever asks whether the process exists
        if error is not None:
            raise error
    return kill


@pytest.mark.parametrize("error, alive", [(None, True), (PermissionError(), True),
                                          (ProcessLookupError(), False)])
def test_a_process_is_alive_unless_it_is_not_found(monkeypatch, error, alive):
    monkeypatch.setattr(fileio.os, "kill", kill_raising(error))
    assert fileio._pid_alive(12345) is alive


def test_another_users_write_in_progress_is_left_alone(tmp_path, monkeypatch):
    dest = tmp_path / "s.h5"
    theirs = temp_path(dest, 4242)
    theirs.write_text("in progress")
    monkeypatch.setattr(fileio.os, "kill", kill_raising(PermissionError()))
    assert remove_stale_temps(dest) == []
    assert theirs.exists()
    monkeypatch.setattr(fileio.os, "kill", kill_raising(ProcessLookupError()))
    assert remove_stale_temps(dest) == [theirs]
    assert not theirs.exists()


def test_this_process_own_temporary_is_never_taken_for_stale(tmp_path, monkeypatch):
    dest = tmp_path / "s.h5"
    mine = temp_path(dest)
    assert mine == tmp_path / f".s.h5.{os.getpid()}.tmp"
    mine.write_text("an earlier attempt")
    monkeypatch.setattr(fileio.os, "kill", kill_raising(ProcessLookupError()))  # "all dead"
    assert remove_stale_temps(dest) == []
    assert mine.exists()


def test_no_folder_no_stale_temporaries(tmp_path):
    assert remove_stale_temps(tmp_path / "absent" / "s.h5") == []


def test_only_exact_temporary_names_are_removed(tmp_path, monkeypatch):
    dest = tmp_path / "s.h5"
    near = [tmp_path / ".s.h5.12.tmp.x", tmp_path / "x.s.h5.12.tmp", tmp_path / ".s.h5..tmp",
            tmp_path / ".sxh5.12.tmp", tmp_path / ".s.h5.12a.tmp"]
    for p in near:
        p.write_text("")
    stale = tmp_path / ".s.h5.12.tmp"
    stale.write_text("")
    monkeypatch.setattr(fileio.os, "kill", kill_raising(ProcessLookupError()))
    assert remove_stale_temps(dest) == [stale]
    assert all(p.exists() for p in near)


def test_a_folder_fsync_may_fail_the_data_fsync_may_not(tmp_path, monkeypatch):
    real_fsync = os.fsync

    def fsync_files_only(fd):
        if os.path.isdir(f"/proc/self/fd/{fd}"):
            raise OSError(errno.EINVAL, "cannot fsync a folder here")
        real_fsync(fd)

    monkeypatch.setattr(fileio.os, "fsync", fsync_files_only)
    atomic_write_bytes(tmp_path / "a.bin", b"data")
    assert (tmp_path / "a.bin").read_bytes() == b"data"

    def fsync_nothing(fd):
        raise OSError(errno.EIO, "disk gone")

    monkeypatch.setattr(fileio.os, "fsync", fsync_nothing)
    with pytest.raises(OSError, match="disk gone"):
        atomic_write_bytes(tmp_path / "b.bin", b"data")
    assert not (tmp_path / "b.bin").exists()
    assert [p.name for p in tmp_path.iterdir()] == ["a.bin"]


def test_the_folder_is_fsynced_as_a_folder(tmp_path, monkeypatch):
    opened = []
    real_open = os.open

    def recording_open(path, flags, *args):
        opened.append((str(path), flags))
        return real_open(path, flags, *args)

    monkeypatch.setattr(fileio.os, "open", recording_open)
    atomic_write_bytes(tmp_path / "a.bin", b"x")
    assert (str(tmp_path), os.O_RDONLY | os.O_DIRECTORY) in opened
    file_opens = [flags for path, flags in opened if path.endswith(".tmp")]
    assert os.O_RDONLY in file_opens  # the data fsync opens the temporary read-only
    assert os.O_WRONLY | os.O_CREAT | os.O_TRUNC in file_opens  # the temporary is created


def test_a_destination_that_became_a_folder_is_a_data_error(tmp_path):
    dest = tmp_path / "out.h5"
    with pytest.raises(DataError, match=rf"^{dest}: is a folder; expected a file name to write$"):
        with atomic_path(dest) as tmp:
            tmp.write_text("x")
            dest.mkdir()
            (dest / "inside").write_text("")  # a folder that is not empty cannot be replaced
    assert not any(p.name.endswith(".tmp") for p in tmp_path.iterdir())


def test_a_folder_that_cannot_be_written_is_a_data_error(tmp_path, monkeypatch):
    def refuse(path, flags, *args):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(fileio.os, "open", refuse)
    dest = tmp_path / "r.txt"
    with pytest.raises(DataError, match=rf"^{dest}: cannot write here \(Permission denied\)$"):
        atomic_write_bytes(dest, b"x")


def test_a_destination_folder_is_named_in_the_error(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(DataError, match=rf"^{tmp_path}/d: is a folder; expected a file name"):
        atomic_write_bytes(tmp_path / "d", b"x")
    (tmp_path / "f").write_text("")
    with pytest.raises(DataError, match=rf"^{tmp_path}/f/x: cannot create its folder \(File "
                                        r"exists\)$"):
        atomic_write_bytes(tmp_path / "f" / "x", b"x")


def test_missing_folders_are_created(tmp_path):
    atomic_write_bytes(tmp_path / "a" / "b" / "c.bin", b"deep")
    assert (tmp_path / "a" / "b" / "c.bin").read_bytes() == b"deep"


def test_the_hdf5_writer_truncates_and_is_given_the_options(tmp_path):
    path = tmp_path / "t.h5"
    path.write_bytes(b"not hdf5 at all")  # the temporary atomic_path created already exists
    with create_hdf5(path, libver="latest") as h5:
        assert h5.mode == "r+"  # open for writing
        assert h5.libver[0] != "earliest"  # the default's low bound; "latest" raises it
        h5.create_dataset("x", data=[1, 2, 3])
    with h5py.File(path, "r") as h5:
        assert list(h5["x"][:]) == [1, 2, 3]


def test_a_temporary_removed_by_someone_else_meanwhile_is_no_error(tmp_path, monkeypatch):
    dest = tmp_path / "s.h5"
    stale = temp_path(dest, 777)
    stale.write_text("")

    def gone_while_asking(pid):
        stale.unlink()  # another process's clean-up got there first
        return False

    monkeypatch.setattr(fileio, "_pid_alive", gone_while_asking)
    assert remove_stale_temps(dest) == []
