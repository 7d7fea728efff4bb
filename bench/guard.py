"""The output guard, and the only way any command writes: nothing lost to a flag, nothing
written where it should not be (the one write rule; tests/test_write_rule.py walks the sources
and fails on a write call anywhere else).

Every file and folder a command writes goes through the writing helpers below
(``write_text`` / ``write_texts``, ``write_via``, ``savefig``, ``saving``, ``write_store``,
``bag_writer``, ``make_folder``, ``remove``, ``remove_folder``, ``move_into_place``): each
writes a new file, or replaces one only when its ``own`` predicate recognises it as the kind
the command makes that the harness wrote (``derived``: listed with its SHA-256 in the folder's
``LEDGER``, or a figure's / page's ``MARK``; ``is_store``; ``in_a_run``; ...). The checks
below run first, before any long work: ``check_out`` / ``check_name`` (empty, too long,
separators), ``replaceable``, ``regenerated_file``, ``output_folder``, ``run_folder``.

Rules (each a ``Refused``, a ``DataError``: exit 2, one message naming the path):

- never onto an input of the same command: the output is not the same file as an input
  (resolved paths, ``os.path.samefile``) and not a folder that holds one (``not_an_input``);
- an existing output is replaced only with ``force`` and only when it is what that command
  makes, recognised by its signature (``is_store``, ``is_ros1_bag``, ``is_rosbag2_folder``,
  ``run_kind``, ``has_mark``): a folder's other files are never deleted (``replaceable``);
- a name that becomes a folder is one path component: no separator, not ``.`` or ``..``, not
  empty (``one_component``); the path it makes stays inside its root (``inside``);
- a run folder is written only over a run of the same kind (a harness run by ``bench run``,
  an external one by ``bench score``); another kind is replaced only when asked, and said
  (``run_folder``); whose run it holds is ``bench.runs.ownership``'s question;
- nothing is written into or below a run folder by anything but its run (``not_in_a_run``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from loaders.errors import DataError

#: the first bytes of an HDF5 file (a store) and of a ROS1 bag
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
ROS1_MAGIC = b"#ROSBAG V2.0\n"
#: the text every figure and page the harness writes carries (PNG metadata, an HTML comment)
MARK = "doppler-bench"
#: the kinds of run folder and the command that makes each
HARNESS, EXTERNAL = "harness", "external"
RUN_MAKERS = {HARNESS: "bench run", EXTERNAL: "bench score"}


class Refused(DataError):
    """An output the guard refuses (a user's file, a folder of another kind, a run folder):
    a DataError (exit 2, one message) that no command turns into a warning and goes on."""


def one_component(name: str, option: str = "--name") -> str:
    """``name`` when it is one path component (a folder name); else a DataError."""
    bad = (not name or not name.strip() or name in (".", "..") or "/" in name
           or "\\" in name or os.sep in name or (os.altsep and os.altsep in name)
           or "\0" in name)
    if bad:
        raise DataError(f"{option} {name!r}: expected one folder name (no '/', '\\', '.' or "
                        "'..', not empty); it names a folder inside the results root")
    return name


def resolved(path: Path) -> Path:
    """``path`` absolute, every symlink followed."""
    return Path(os.path.realpath(os.path.abspath(path)))


_resolved = resolved


def inside(path: Path, root: Path) -> bool:
    """``path`` (resolved) is ``root`` or lies under it."""
    return _resolved(path).is_relative_to(_resolved(root))


def same_file(a: Path, b: Path) -> bool:
    """``a`` and ``b`` are one file or folder (hard links and symlinks included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return _resolved(a) == _resolved(b)


def not_an_input(out: Path, inputs: Iterable[Path | None], option: str = "--out") -> None:
    """Refuse ``out`` when it is an input of the command or a folder holding one."""
    for given in inputs:
        if given is None:
            continue
        if same_file(out, given):
            raise Refused(f"{option} {out}: is an input of this command ({given}); write "
                          "to another path, the input is never overwritten")
        if inside(given, out) and _resolved(out) != _resolved(given):
            raise Refused(f"{option} {out}: holds an input of this command ({given}); "
                          "write to another path, the input is never overwritten")


def _head(path: Path, n: int) -> bytes:
    try:
        with open(path, "rb") as f:
            return f.read(n)
    except OSError:
        return b""


def is_store(path: Path) -> bool:
    """A store (what ``bench convert`` / ``calibrate --write`` write): an HDF5 file by its
    signature whose ``format`` attribute names this harness's store format (another HDF5
    file, a dataset's own or a user's, is not one)."""
    if not (Path(path).is_file() and _head(path, 8) == HDF5_MAGIC):
        return False
    import h5py

    from loaders.store import FORMAT_NAME

    try:
        with h5py.File(path, "r") as f:
            return f.attrs.get("format") == FORMAT_NAME
    except (OSError, ValueError):
        return False


#: the first bytes of a rerun recording (.rrd: "RRF" and the format's version digit)
RRD_MAGIC = b"RRF"


def is_recording(path: Path) -> bool:
    """A rerun recording (what ``bench view`` writes) by its signature."""
    return Path(path).is_file() and _head(path, len(RRD_MAGIC)) == RRD_MAGIC


def is_synthetic_store(path: Path) -> bool:
    """A store ``bench synth`` made (its provenance's source is "synthetic"): what synth may
    make again; a converted store (real data) is never replaced by a synthetic one."""
    if not is_store(path):
        return False
    import json

    import h5py

    try:
        with h5py.File(path, "r") as f:
            source = json.loads(f.attrs.get("provenance", "{}")).get("source")
    except (OSError, ValueError, AttributeError):
        return False
    return source == "synthetic"


def is_ros1_bag(path: Path) -> bool:
    return Path(path).is_file() and _head(path, len(ROS1_MAGIC)) == ROS1_MAGIC


def is_rosbag2_folder(path: Path) -> bool:
    """A rosbag2 folder: metadata.yaml and storage files (.db3 / .mcap) and nothing else."""
    path = Path(path)
    if not path.is_dir() or not (path / "metadata.yaml").is_file():
        return False
    storage = (".db3", ".mcap", ".db3-shm", ".db3-wal")
    return all(p.name == "metadata.yaml" or (p.is_file() and p.name.endswith(storage))
               for p in path.iterdir())


def has_mark(path: Path, size: int = 65536) -> bool:
    """A file the harness wrote with its ``MARK`` near the top (a page, a figure's metadata)."""
    return Path(path).is_file() and MARK.encode() in _head(path, size)


def run_kind(folder: Path) -> str | None:
    """``HARNESS`` or ``EXTERNAL`` for a run folder (a config.yaml of a run, or a run record:
    metrics.json / failed.json), None for anything else."""
    import yaml

    from loaders.yamlio import read_yaml

    folder = Path(folder)
    if not folder.is_dir():
        return None
    # three look-ups, not a listing: this runs on every folder above an output (/tmp too)
    names = {n for n in ("config.yaml", "metrics.json", "failed.json")
             if os.path.lexists(folder / n)}
    if not names:
        return None
    config = {}
    if "config.yaml" in names:
        try:
            config = read_yaml(folder / "config.yaml") or {}
        except (OSError, yaml.YAMLError):
            config = None
        if not isinstance(config, dict) or not (config.keys() & {"method", "run_key"}
                                                or names & {"metrics.json", "failed.json"}):
            return None
    identity = config.get("identity") if isinstance(config.get("identity"), dict) else {}
    return EXTERNAL if "external" in config or identity.get("kind") == EXTERNAL else HARNESS


def folders_on_the_way(out: Path, option: str = "--out") -> None:
    """Refuse ``out`` when the first existing folder above it is a file (one message, not a
    FileExistsError or NotADirectoryError after the work)."""
    for parent in Path(out).parents:
        if os.path.lexists(parent):
            if not parent.is_dir():
                raise Refused(f"{option} {out}: {parent} is a file; expected a folder to "
                              "write into")
            return


def not_in_a_run(out: Path, option: str = "--out") -> None:
    """Refuse ``out`` inside a run folder (its files are that run's; only a run writes there)."""
    for parent in Path(os.path.abspath(out)).parents:
        if run_kind(parent) is not None:
            raise Refused(f"{option} {out}: lies inside a run folder ({parent}, a run "
                          f"made by {RUN_MAKERS[run_kind(parent)]}); its files are the "
                          "run's: choose another folder")


def replaceable(out: Path, force: bool | None, own: Callable[[Path], bool], what: str,
                option: str = "--out", inputs: Iterable[Path | None] = ()) -> bool:
    """Check ``out`` before writing: not an input, not inside a run folder; when it exists,
    ``force`` given and ``own`` recognising it as ``what`` (e.g. "a ROS1 bag") this command
    wrote (``force`` None: the command has no --force, an existing ``out`` is never replaced).
    True when it exists (and may be replaced), False when it is new."""
    out = check_out(out, option)
    not_an_input(out, inputs, option)
    not_in_a_run(out, option)
    folders_on_the_way(out, option)
    if not os.path.lexists(out):
        return False
    if not own(out):
        kind = "a folder" if out.is_dir() else "a file"
        only = " (--force replaces only that)" if force else ""
        raise Refused(f"{option} {out}: exists and is {kind} that is not {what} this command "
                      f"wrote; it is left as it is{only}: choose another {option}")
    if not force:
        raise Refused(f"{option} {out}: exists ({what}); give another {option}"
                      + (" or --force to replace it" if force is False else
                           " (it is not replaced)"))
    return True


def run_folder(run_dir: Path, kind: str, force: bool | None = False,
               inputs: Iterable[Path | None] = (), say: Callable[[str], None] | None = None,
               root: Path | None = None, ask: str = "--force") -> None:
    """Check a run folder before ``RUN_MAKERS[kind]`` writes into it: inside ``root``, holding
    no input; new, empty or a run of the same ``kind``; a run of another kind only with
    ``force`` (the option ``ask``; ``say`` tells it is replaced; None: the command has no such
    option); never a folder of other files (a run writes its own files' names only)."""
    run_dir = check_out(run_dir, "run folder")
    if root is not None and not inside(run_dir, root):
        raise Refused(f"{run_dir}: outside the results root {root}; a run's name is one "
                      "folder name")
    not_an_input(run_dir, inputs, "run folder")
    not_in_a_run(run_dir, "run folder")  # no run nests inside another run's folder
    for parent in run_dir.parents:  # e.g. --out naming a file: one message, not an OSError
        if parent.exists():
            if not parent.is_dir():
                raise Refused(f"{parent}: is a file, expected a folder of results (to hold "
                              f"{run_dir.relative_to(parent)}); it is left as it is")
            break
    if not run_dir.exists():
        return
    if not run_dir.is_dir():
        raise Refused(f"{run_dir}: is a file, expected a run folder; it is left as it is")
    found = run_kind(run_dir)
    if found is None:
        if any(run_dir.iterdir()):
            raise Refused(f"{run_dir}: holds files that are not a run's; it is left as it "
                          "is: choose another name or folder")
        return
    if found != kind:
        if not force:
            raise Refused(f"{run_dir}: holds a run made by {RUN_MAKERS[found]} ({found}); "
                          f"{RUN_MAKERS[kind]} does not replace it: choose another name"
                          + (f", or {ask} to replace that run" if force is False else ""))
        if say is not None:
            say(f"replacing the {found} run in {run_dir} ({RUN_MAKERS[found]}'s), as {ask} "
                "asks")


def regenerated_file(out: Path, own: Callable[[Path], bool], what: str,
                     option: str = "--out", inputs: Iterable[Path | None] = ()) -> None:
    """Check a derived file (a page, a plot: made again from the same inputs on every call)
    before writing it: not an input; an existing file only when ``own`` recognises it as
    ``what`` this command wrote (replaced without ``--force``), never a folder."""
    out = check_out(out, option)
    not_an_input(out, inputs, option)
    not_in_a_run(out, option)
    folders_on_the_way(out, option)
    if out.is_dir():
        raise Refused(f"{option} {out}: is a folder; expected the file name of {what}")
    if os.path.lexists(out) and not own(out):
        raise Refused(f"{option} {out}: exists and is not {what} this command wrote; it is "
                      f"left as it is: choose another {option}")


def output_folder(out: Path, option: str = "--out", inputs: Iterable[Path | None] = ()) -> None:
    """Check a folder that derived files (tables, figures) go into: not an input's folder, not
    a file (nor a path through one), not a run folder (whose files are a run's own, whichever
    command made it) nor inside one."""
    out = check_out(out, option)
    not_an_input(out, inputs, option)
    if os.path.lexists(out) and not out.is_dir():
        raise Refused(f"{option} {out}: is a file; expected a folder to write into")
    folders_on_the_way(out, option)
    if run_kind(out) is not None:
        raise Refused(f"{option} {out}: is a run folder (made by "
                      f"{RUN_MAKERS[run_kind(out)]}); its files are the run's: choose "
                      "another folder")
    not_in_a_run(out, option)


# -- names -------------------------------------------------------------------------------------

#: the longest file or folder name most file systems take [bytes] (NAME_MAX)
NAME_MAX_BYTES = 255
#: the longest path the system takes [bytes] (PATH_MAX, its terminating NUL aside)
PATH_MAX_BYTES = 4095


def check_out(path: Path | str, option: str = "--out") -> Path:
    """``path`` as a Path when it can name a file or folder to write: not empty, no NUL, no
    name longer than ``NAME_MAX_BYTES``, the whole path within ``PATH_MAX_BYTES``; else a
    DataError naming ``option`` (not an OSError "File name too long" deep in a writer)."""
    text = str(path)
    if not text.strip():
        raise DataError(f"{option} {text!r}: empty; expected the path of a file or folder "
                        "to write")
    if "\0" in text:
        raise DataError(f"{option} {text!r}: holds a NUL character; expected a path")
    for part in Path(text).parts:  # room for the temporary name of an atomic write
        if len(os.fsencode(part)) > NAME_MAX_BYTES - 16:
            raise DataError(f"{option} {text[:60]}...: the name {part[:40]}... is "
                            f"{len(os.fsencode(part))} bytes long; a file or folder name is at "
                            f"most {NAME_MAX_BYTES - 16} bytes (the system's {NAME_MAX_BYTES} "
                            "bytes, less room for a temporary name)")
    if len(os.fsencode(os.path.abspath(text))) > PATH_MAX_BYTES:
        raise DataError(f"{option} {text[:60]}...: the path is longer than {PATH_MAX_BYTES} "
                        "bytes")
    return Path(text)


def check_name(name: str, option: str = "--name") -> str:
    """``name`` when it can be one folder name (``one_component``) within ``NAME_MAX_BYTES``."""
    try:
        one_component(name, option)
    except DataError:
        raise DataError(f"{option} {name!r}: expected one path component (a folder name: no "
                        "'/', '\\', '.' or '..', not empty)") from None
    if len(os.fsencode(name)) > NAME_MAX_BYTES - 16:  # room for a suffix (_noseed, .h5)
        raise DataError(f"{option} {name[:40]}...: {len(os.fsencode(name))} bytes long; a "
                        f"name is at most {NAME_MAX_BYTES - 16} bytes (it names a folder)")
    return name


# -- what the harness wrote --------------------------------------------------------------------

#: the kinds of file whose metadata or text carries ``MARK`` when the harness writes them
MARKED = (".png", ".pdf", ".svg", ".html")
#: the file in an output folder that lists the derived files the harness wrote there, each
#: with its SHA-256: such a file, unchanged, is the harness's own and is made again
LEDGER = ".doppler-bench-files.json"


def _sha256(path: Path) -> str | None:
    import hashlib

    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    except OSError:
        return None
    return h.hexdigest()


def _ledger(folder: Path) -> dict:
    import json

    try:
        data = json.loads((Path(folder) / LEDGER).read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _tail(path: Path, n: int) -> bytes:
    try:
        with open(path, "rb") as f:
            f.seek(max(0, os.path.getsize(path) - n))
            return f.read(n)
    except OSError:
        return b""


def derived(path: Path) -> bool:
    """A derived file (a table, a figure, a page, a report) the harness wrote and nobody
    changed since: listed in its folder's ``LEDGER`` with its current SHA-256, or carrying
    ``MARK`` (a page's text, a PNG's or PDF's metadata)."""
    path = Path(path)
    if not path.is_file() or path.is_symlink():
        return False
    # the mark counts in a figure's metadata or a page only: a user's text that names the
    # project (notes.md saying "doppler-bench") is not the harness's table
    if path.suffix.lower() in MARKED and (has_mark(path) or MARK.encode() in _tail(path, 65536)):
        return True
    listed = _ledger(path.parent).get(path.name)
    return listed is not None and listed == _sha256(path)


def in_a_run(path: Path) -> bool:
    """A file of a run folder (its parent is one: ``run_kind``), which only a run writes; the
    folder's kind and identity were checked before the run began (``run_folder``,
    ``foreign_run``)."""
    return run_kind(Path(path).parent) is not None


def _record(path: Path) -> None:
    """List ``path`` (just written) in its folder's ledger."""
    import json

    from loaders.fileio import atomic_write_text

    entries = _ledger(path.parent)
    entries[path.name] = _sha256(path)
    atomic_write_text(path.parent / LEDGER, json.dumps(entries, indent=1, sort_keys=True))


# -- writing: every file and folder a command writes goes through these ----------------------

def _may_write(path: Path, own: Callable[[Path], bool] | None, what: str) -> None:
    """The last word before a write: ``path`` is new, or ``own`` recognises it as ``what`` the
    harness wrote; never a folder."""
    if os.path.isdir(path) and not os.path.islink(path):
        raise Refused(f"{path}: is a folder; expected the file name of {what}")
    if os.path.lexists(path) and (own is None or not own(path)):
        raise Refused(f"{path}: exists and is not {what} the harness wrote; it is left as it "
                      "is: choose another output")


def make_folder(path: Path, option: str = "--out") -> Path:
    """Create ``path`` and its parents (an existing folder is fine); a part that is a file,
    a name too long or a folder that cannot be written: one DataError naming it."""
    path = Path(path)
    for parent in [path, *path.parents]:
        if os.path.lexists(parent):
            if not parent.is_dir():
                raise Refused(f"{option} {path}: {parent} is a file, expected a folder; it is "
                              "left as it is")
            break
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise Refused(f"{option} {path}: cannot create this folder "
                      f"({err.strerror or err})") from None
    return path


def _written(path: Path, own: Callable[[Path], bool] | None) -> None:
    if own is derived:
        _record(path)


def write_text(path: Path, text: str, own: Callable[[Path], bool] | None = None,
               what: str = "a file") -> Path:
    """Write ``text`` to ``path`` atomically: new, or replacing what ``own`` recognises."""
    from loaders.fileio import atomic_write_text

    path = Path(path)
    _may_write(path, own, what)
    make_folder(path.parent, "output")
    try:
        atomic_write_text(path, text)
    except OSError as err:
        raise DataError(f"{path}: cannot write ({err.strerror or err})") from None
    _written(path, own)
    return path


def write_texts(texts: dict[Path, str], own: Callable[[Path], bool] | None = None,
                what: str = "a file") -> None:
    """Write several files (a table's .md/.tex/.csv): every one checked before any is
    written, so a refusal leaves none half done."""
    for path in texts:
        _may_write(Path(path), own, what)
    for path, text in texts.items():
        write_text(Path(path), text, own, what)


def write_via(path: Path, writer: Callable[[str], object],
              own: Callable[[Path], bool] | None = None, what: str = "a file",
              fresh: bool = False) -> Path:
    """Write ``path`` atomically by ``writer(temporary path)`` (a figure's savefig, a bag
    writer): new, or replacing what ``own`` recognises. ``fresh``: the temporary does not
    exist yet when ``writer`` starts (rosbags' ROS1 writer refuses an existing file)."""
    from loaders.fileio import atomic_path

    path = Path(path)
    _may_write(path, own, what)
    make_folder(path.parent, "output")
    with atomic_path(path) as tmp:
        if fresh:
            tmp.unlink()
        writer(str(tmp))
    _written(path, own)
    return path


def savefig(fig, path: Path, fmt: str, own: Callable[[Path], bool] | None = None,
            what: str = "a figure", **options) -> Path:
    """``fig.savefig`` to ``path`` atomically, its metadata carrying ``MARK`` (so the harness
    knows its own figure again); ``own`` default ``derived``."""
    stamp = {"png": "Software", "pdf": "Creator", "svg": "Creator"}.get(fmt)
    meta = dict(options.pop("metadata", None) or {})
    if stamp and stamp not in meta:
        meta[stamp] = MARK
    return write_via(path, lambda tmp: fig.savefig(tmp, format=fmt, metadata=meta or None,
                                                   **options),
                     derived if own is None else own, what)


def remove(path: Path, own: Callable[[Path], bool], what: str = "a file") -> bool:
    """Remove a file the harness wrote (``own``); True when one was removed."""
    path = Path(path)
    if not os.path.lexists(path):
        return False
    _may_write(path, own, what)
    path.unlink()
    return True


def remove_folder(path: Path, own: Callable[[Path], bool], what: str = "a folder") -> bool:
    """Remove a folder the harness made (``own``: e.g. a rosbag2 folder it wrote, or its own
    work folder); True when one was removed."""
    import shutil

    path = Path(path)
    if not os.path.lexists(path):
        return False
    if not own(path):
        raise Refused(f"{path}: is not {what} the harness made; it is left as it is")
    if path.is_symlink() or not path.is_dir():
        path.unlink()
    else:
        shutil.rmtree(path)
    return True


def move_into_place(made: Path, dest: Path, own: Callable[[Path], bool],
                    what: str = "an output") -> Path:
    """Move ``made`` (a file or folder the command finished beside ``dest``) to ``dest``: new,
    or replacing what ``own`` recognises (a folder is removed first)."""
    dest = Path(dest)
    if os.path.lexists(dest):
        if not own(dest):
            raise Refused(f"{dest}: exists and is not {what} the harness wrote; it is left "
                          "as it is")
        if dest.is_dir() and not dest.is_symlink():
            remove_folder(dest, own, what)
    os.replace(made, dest)
    return dest


def write_store(sequence, path: Path, own: Callable[[Path], bool] | None = is_store,
                what: str = "a store", **options) -> Path:
    """``loaders.store.write_store`` after the last check (new, or ``own``'s)."""
    from loaders.store import write_store as _write_store

    path = Path(path)
    _may_write(path, own, what)
    make_folder(path.parent, "output")
    return _write_store(sequence, path, **options)


def bag_writer(cls, path: Path, **options):
    """A rosbags writer (``cls``: ``rosbags.rosbag1.Writer`` / ``rosbags.rosbag2.Writer``) of
    a new bag at ``path`` (the command's own work path: checked before, ``replaceable``)."""
    if os.path.lexists(path):
        raise Refused(f"{path}: exists; a bag is written only to a new path")
    return cls(path, **options)


@contextlib.contextmanager
def saving(stream, path: Path, own: Callable[[Path], bool] | None = None,
           what: str = "a file") -> Iterator:
    """``stream.save(temporary path)`` (a rerun recording stream: it writes as it is logged
    to); the file takes its name ``path`` when the block ends (new, or ``own``'s)."""
    from loaders.fileio import atomic_path

    path = Path(path)
    _may_write(path, own, what)
    make_folder(path.parent, "output")
    with atomic_path(path) as tmp:
        stream.save(str(tmp))
        yield stream
    _written(path, own)
