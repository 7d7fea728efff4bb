"""The write guard (bench.guard) at unit level, rule by rule: names and paths (one check, one
message naming the option), what the harness wrote (signatures, the ledger, the mark), run
folders, and the writers (new, or replacing only the harness's own file of that kind; atomic:
a failed write leaves the old file and no temporary). Fast: no command runs; the CLI cases are
in tests/test_guard.py and tests/test_write_guard.py."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from bench import guard
from loaders.errors import DataError

# -- names -------------------------------------------------------------------------------------

LIMIT = guard.NAME_MAX_BYTES - 16  # the longest name: 239 bytes (room for a temporary name)


def test_a_name_of_the_longest_length_passes_and_one_byte_more_is_refused():
    assert LIMIT == 239
    assert guard.check_name("n" * LIMIT) == "n" * LIMIT
    for name in ("n" * (LIMIT + 1), "n" * 256):
        with pytest.raises(DataError) as err:
            guard.check_name(name, "--label")
        text = str(err.value)
        assert text.startswith("--label ") and f"{len(name)} bytes long" in text
        assert f"at most {LIMIT} bytes" in text


def test_a_names_length_counts_bytes_not_characters():
    assert guard.check_name("é" * (LIMIT // 2)) == "é" * (LIMIT // 2)  # 238 bytes
    with pytest.raises(DataError, match="240 bytes long"):
        guard.check_name("é" * 120)  # 120 characters, 240 bytes


@pytest.mark.parametrize("name", ["", " ", ".", "..", "a/b", "a\\b", "a\0b"])
def test_check_name_refuses_what_is_not_one_folder_name_naming_the_option(name):
    with pytest.raises(DataError) as err:
        guard.check_name(name, "--run-name")
    text = str(err.value)
    assert text == (f"--run-name {name!r}: expected one path component (a folder name: no "
                    "'/', '\\', '.' or '..', not empty)")
    with pytest.raises(DataError, match=r"^--name "):  # the default option
        guard.check_name(name)


def test_one_component_names_the_option_and_refuses_a_nul():
    with pytest.raises(DataError) as err:
        guard.one_component("a\0b", "--tag")
    assert str(err.value) == ("--tag 'a\\x00b': expected one folder name (no '/', '\\', '.' or "
                              "'..', not empty); it names a folder inside the results root")
    with pytest.raises(DataError, match=r"^--name '': expected one folder name"):
        guard.one_component("")
    assert guard.one_component("a b.c") == "a b.c"


def test_one_component_refuses_the_systems_separators(monkeypatch):
    """Whatever the system's separators (os.sep, os.altsep: Windows' '\\' and '/')."""
    monkeypatch.setattr(os, "sep", ":")
    for name in ("a:b", "a/b", "a\\b"):  # '/' and '\\' are refused on every system
        with pytest.raises(DataError, match="expected one folder name"):
            guard.one_component(name)
    monkeypatch.setattr(os, "altsep", "|")
    with pytest.raises(DataError, match="expected one folder name"):
        guard.one_component("a|b")
    assert guard.one_component("ab") == "ab"


@pytest.mark.parametrize("text", ["", "   "])
def test_check_out_refuses_an_empty_path_naming_the_option(text):
    with pytest.raises(DataError) as err:
        guard.check_out(text, "--plot")
    assert str(err.value) == (f"--plot {text!r}: empty; expected the path of a file or folder "
                              "to write")
    with pytest.raises(DataError, match=r"^--out "):
        guard.check_out(text)


def test_check_out_refuses_a_nul_and_returns_a_path(tmp_path):
    with pytest.raises(DataError, match=r"^--write 'a\\x00b': holds a NUL character"):
        guard.check_out("a\0b", "--write")
    got = guard.check_out(str(tmp_path / "x.h5"))
    assert isinstance(got, Path) and got == tmp_path / "x.h5"


def test_check_out_limits_each_name_in_bytes(tmp_path):
    ok = tmp_path / ("a" * LIMIT) / "f.txt"
    assert guard.check_out(ok) == ok
    for part in ("a" * (LIMIT + 1), "é" * 120):
        with pytest.raises(DataError) as err:
            guard.check_out(tmp_path / part / "f.txt", "--data-dir")
        text = str(err.value)
        assert text.startswith("--data-dir ") and f"is {LIMIT + 1} bytes long" in text
        assert f"at most {LIMIT} bytes (the system's 255 bytes" in text


def test_check_out_limits_the_whole_path(tmp_path):
    """The absolute path is at most 4095 bytes (PATH_MAX less its NUL): exactly that passes,
    one byte more is one message naming the option."""
    assert guard.PATH_MAX_BYTES == 4095
    base = str(tmp_path)

    def path_of(length: int) -> str:
        """``base`` and "/name" parts of 1-200 bytes, exactly ``length`` bytes long (whatever
        the length of pytest's folder, which differs per worker)."""
        room = length - len(base)
        parts = -(-room // 201)  # each part "/" + at most 200 bytes
        names = room - parts  # the bytes of the names, at least one per part
        sizes = [names // parts + (i < names % parts) for i in range(parts)]
        return base + "".join("/" + "p" * size for size in sizes)

    exact = path_of(4095)
    assert len(exact) == 4095
    assert guard.check_out(exact) == Path(exact)
    over = path_of(4096)
    assert len(over) == 4096
    with pytest.raises(DataError, match=r"^--out .*: the path is longer than 4095 bytes"):
        guard.check_out(over)
    with pytest.raises(DataError, match=r"^--store "):
        guard.check_out(over, "--store")


def test_check_out_measures_a_relative_path_from_the_working_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    room = 4095 - len(str(tmp_path)) - 1  # the absolute path: the folder, "/", the relative one
    k = (room - 1) // 201
    rel = ("r" * 200 + "/") * k + "s" * (room - 201 * k)  # names of at most 201 bytes
    assert len(os.path.abspath(rel)) == 4095
    assert guard.check_out(rel) == Path(rel)
    with pytest.raises(DataError, match="longer than 4095 bytes"):
        guard.check_out(rel + "x")  # 4096 bytes from /, far fewer as written


# -- paths -------------------------------------------------------------------------------------

def test_inside_is_by_resolved_path_components(tmp_path):
    root = tmp_path / "r"
    (root / "a").mkdir(parents=True)
    (tmp_path / "rx").mkdir()
    assert guard.inside(root, root) and guard.inside(root / "a" / "f", root)
    assert not guard.inside(tmp_path / "rx" / "f", root)  # a common prefix is not inside
    link = root / "out"
    link.symlink_to(tmp_path / "rx", target_is_directory=True)
    assert not guard.inside(link / "f", root)  # a symlink out of the root is outside
    assert guard.inside(tmp_path / "rx" / ".." / "r" / "a", root)


def test_resolved_is_absolute_and_follows_symlinks(tmp_path, monkeypatch):
    (tmp_path / "real").mkdir()
    (tmp_path / "ln").symlink_to(tmp_path / "real", target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    assert guard.resolved(Path("ln") / "f") == Path(os.path.realpath(tmp_path)) / "real" / "f"


def test_same_file_of_paths_that_do_not_exist_compares_resolved_paths(tmp_path):
    a = tmp_path / "d" / "x.h5"
    assert guard.same_file(a, tmp_path / "d" / ".." / "d" / "x.h5")
    assert not guard.same_file(a, tmp_path / "d" / "y.h5")


def test_an_output_through_a_symlink_onto_an_input_is_refused(tmp_path):
    data = tmp_path / "data"
    data.mkdir()
    store = data / "s.h5"
    store.write_bytes(b"input")
    (tmp_path / "via").symlink_to(data, target_is_directory=True)
    with pytest.raises(guard.Refused) as err:
        guard.not_an_input(tmp_path / "via" / "s.h5", [None, store])
    assert str(err.value) == (f"--out {tmp_path / 'via' / 's.h5'}: is an input of this "
                              f"command ({store}); write to another path, the input is never "
                              "overwritten")
    with pytest.raises(guard.Refused) as err:
        guard.not_an_input(tmp_path / "via", [store], "--into")
    assert str(err.value) == (f"--into {tmp_path / 'via'}: holds an input of this command "
                              f"({store}); write to another path, the input is never "
                              "overwritten")
    with pytest.raises(guard.Refused, match=r"^--out .*: is an input"):
        guard.not_an_input(data, [data])  # a folder that is the input itself
    assert store.read_bytes() == b"input"


def test_an_input_folder_and_a_missing_output_beside_it(tmp_path):
    data = tmp_path / "frames"
    data.mkdir()
    guard.not_an_input(tmp_path / "frames.h5", [data])  # beside it, not in it: fine
    guard.not_an_input(tmp_path / "new" / "s.h5", [data])
    with pytest.raises(guard.Refused, match="holds an input"):
        guard.not_an_input(tmp_path, [tmp_path / "frames" / "missing.txt"])


def test_folders_on_the_way_refuse_a_file_above_the_output(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.folders_on_the_way(notes / "a" / "b.h5", "--plot")
    assert str(err.value) == (f"--plot {notes / 'a' / 'b.h5'}: {notes} is a file; expected a "
                              "folder to write into")
    with pytest.raises(guard.Refused, match=r"^--out "):
        guard.folders_on_the_way(notes / "x")
    guard.folders_on_the_way(tmp_path / "new" / "deeper" / "f")  # folders to make: fine
    assert notes.read_text() == "mine"


# -- signatures: what the harness wrote --------------------------------------------------------

def _store(path: Path, **attrs) -> Path:
    import h5py

    from loaders.store import FORMAT_NAME

    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT_NAME
        for k, v in attrs.items():
            f.attrs[k] = v
    return path


def test_is_store_by_signature_and_format(tmp_path):
    import h5py

    assert guard.is_store(_store(tmp_path / "s.h5"))
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as f:
        f.attrs["format"] = "someone-elses"
    assert not guard.is_store(other)
    broken = tmp_path / "broken.h5"
    broken.write_bytes(guard.HDF5_MAGIC + b"not really hdf5")
    assert not guard.is_store(broken)
    folder = tmp_path / "d.h5"
    folder.mkdir()
    assert not guard.is_store(folder) and not guard.is_store(tmp_path / "absent.h5")
    from loaders.store import FORMAT_NAME

    shifted = tmp_path / "shifted.h5"  # HDF5 behind a user block: no signature at the start
    with h5py.File(shifted, "w", userblock_size=512) as f:
        f.attrs["format"] = FORMAT_NAME
    assert not guard.is_store(shifted)


def test_a_synthetic_store_by_its_provenance(tmp_path):
    assert guard.is_synthetic_store(_store(tmp_path / "a.h5",
                                           provenance=json.dumps({"source": "synthetic"})))
    assert not guard.is_synthetic_store(_store(tmp_path / "b.h5",
                                               provenance=json.dumps({"source": "ros1"})))
    assert not guard.is_synthetic_store(_store(tmp_path / "c.h5"))  # no provenance
    assert not guard.is_synthetic_store(_store(tmp_path / "d.h5", provenance="{not json"))
    assert not guard.is_synthetic_store(_store(tmp_path / "e.h5", provenance="[1, 2]"))
    text = tmp_path / "f.h5"
    text.write_text('{"source": "synthetic"}')
    assert not guard.is_synthetic_store(text)


def test_recordings_and_bags_by_their_first_bytes(tmp_path):
    rrd = tmp_path / "v.rrd"
    rrd.write_bytes(b"RRF2" + b"\0" * 8)
    short = tmp_path / "w.rrd"
    short.write_bytes(b"RR")
    assert guard.is_recording(rrd) and not guard.is_recording(short)
    bag = tmp_path / "b.bag"
    bag.write_bytes(guard.ROS1_MAGIC + b"rest")
    notbag = tmp_path / "n.bag"
    notbag.write_bytes(b"#ROSBAG V1.2\n")
    assert guard.is_ros1_bag(bag) and not guard.is_ros1_bag(notbag)
    folder = tmp_path / "f.bag"
    folder.mkdir()
    assert not guard.is_ros1_bag(folder) and not guard.is_recording(folder)
    assert not guard.is_ros1_bag(tmp_path / "absent.bag")


def test_a_rosbag2_folder_holds_its_metadata_and_storage_files_only(tmp_path):
    bag = tmp_path / "bag"
    bag.mkdir()
    assert not guard.is_rosbag2_folder(bag)  # no metadata.yaml
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert guard.is_rosbag2_folder(bag)
    for name in ("b_0.db3", "b_0.db3-shm", "b_0.db3-wal", "b_1.mcap"):
        (bag / name).write_bytes(b"x")
    assert guard.is_rosbag2_folder(bag)
    (bag / "sub.db3").mkdir()  # a folder of a storage file's name is no storage file
    assert not guard.is_rosbag2_folder(bag)
    other = tmp_path / "other"
    (other / "metadata.yaml").mkdir(parents=True)  # a folder, not the metadata file
    assert not guard.is_rosbag2_folder(other)
    assert not guard.is_rosbag2_folder(bag / "metadata.yaml")  # a file, not a folder


def test_the_mark_counts_near_the_top_only(tmp_path):
    top = tmp_path / "a.html"
    top.write_bytes(b"x" * 100 + guard.MARK.encode())
    assert guard.has_mark(top)
    late = tmp_path / "b.html"
    late.write_bytes(b"x" * 65536 + guard.MARK.encode())
    assert not guard.has_mark(late)
    assert guard.has_mark(late, size=65536 + len(guard.MARK))
    edge = tmp_path / "c.html"
    edge.write_bytes(b"x" * (65536 - len(guard.MARK)) + guard.MARK.encode())
    assert guard.has_mark(edge)
    past = tmp_path / "d.html"  # the mark's last byte one past the first 64 KiB
    past.write_bytes(b"x" * (65537 - len(guard.MARK)) + guard.MARK.encode())
    assert not guard.has_mark(past)
    assert not guard.has_mark(tmp_path)


def _write_run(folder: Path, config: str | None = None, record: str | None = "metrics.json"):
    folder.mkdir(parents=True, exist_ok=True)
    if config is not None:
        (folder / "config.yaml").write_text(config)
    if record is not None:
        (folder / record).write_text("{}")
    return folder


@pytest.mark.parametrize("config, record, kind", [
    (None, "metrics.json", guard.HARNESS),  # a run record alone
    (None, "failed.json", guard.HARNESS),
    ("method: {name: doppler}\n", None, guard.HARNESS),  # a run's config alone
    ("run_key: k\n", None, guard.HARNESS),
    ("other: 1\n", "metrics.json", guard.HARNESS),  # a record makes it a run
    ("other: 1\n", "failed.json", guard.HARNESS),
    ("method: {name: x}\nexternal: {trajectory: t.txt}\n", None, guard.EXTERNAL),
    ("method: {name: x}\nidentity: {kind: external}\n", "metrics.json", guard.EXTERNAL),
    ("method: {name: x}\nidentity: {kind: harness}\n", "metrics.json", guard.HARNESS),
    ("method: {name: x}\nidentity: external\n", None, guard.HARNESS),  # not an identity block
    ("other: 1\n", None, None),  # a user's config.yaml: not a run
    ("- a list\n", None, None),
    ("key: [unclosed\n", None, None),  # not YAML
])
def test_run_kind(tmp_path, config, record, kind):
    assert guard.run_kind(_write_run(tmp_path / "run", config, record)) == kind


def test_run_kind_of_what_is_not_a_run_folder(tmp_path):
    assert guard.run_kind(tmp_path) is None  # an empty folder
    (tmp_path / "notes.txt").write_text("x")
    assert guard.run_kind(tmp_path) is None
    assert guard.run_kind(tmp_path / "notes.txt") is None
    assert guard.run_kind(tmp_path / "absent") is None
    dangling = _write_run(tmp_path / "d", record=None)
    (dangling / "failed.json").symlink_to(tmp_path / "nowhere.json")
    assert guard.run_kind(dangling) == guard.HARNESS  # a record's name, even a broken link


def test_nothing_is_written_into_or_below_a_run_folder(tmp_path, monkeypatch):
    run = _write_run(tmp_path / "seq" / "doppler", "method: {name: doppler}\n")
    ext = _write_run(tmp_path / "seq" / "mine", "method: {name: x}\nexternal: {}\n")
    with pytest.raises(guard.Refused) as err:
        guard.not_in_a_run(run / "deep" / "er" / "f.png", "--plot")
    assert str(err.value) == (f"--plot {run / 'deep' / 'er' / 'f.png'}: lies inside a run "
                              f"folder ({run}, a run made by bench run); its files are the "
                              "run's: choose another folder")
    with pytest.raises(guard.Refused, match=r"^--out .*a run made by bench score"):
        guard.not_in_a_run(ext / "f.png")
    monkeypatch.chdir(run)
    with pytest.raises(guard.Refused, match="lies inside a run folder"):
        guard.not_in_a_run(Path("table.md"))  # a relative path, from inside the run
    guard.not_in_a_run(tmp_path / "seq" / "f.png")  # beside the runs: fine
    assert guard.in_a_run(run / "metrics.json") and not guard.in_a_run(tmp_path / "x")


# -- the checks before the work ----------------------------------------------------------------

def test_replaceable_checks_the_name_input_run_and_folders_first(tmp_path):
    store = _store(tmp_path / "s.h5")
    with pytest.raises(DataError, match=r"^--export '': empty"):
        guard.replaceable("", True, guard.is_store, "a store", "--export")
    with pytest.raises(guard.Refused, match=r"^--export .*: is an input of this command"):
        guard.replaceable(store, True, guard.is_store, "a store", "--export", inputs=[store])
    run = _write_run(tmp_path / "run", "method: {name: x}\n")
    with pytest.raises(guard.Refused, match=r"^--export .*: lies inside a run folder"):
        guard.replaceable(run / "s.h5", True, guard.is_store, "a store", "--export")
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(guard.Refused, match=r"^--export .*notes.txt is a file"):
        guard.replaceable(notes / "s.h5", True, guard.is_store, "a store", "--export")
    assert guard.replaceable(tmp_path / "new.h5", None, guard.is_store, "a store") is False


def test_replaceable_says_what_the_existing_output_is_and_what_force_does(tmp_path):
    folder = tmp_path / "out.bag"
    folder.mkdir()
    with pytest.raises(guard.Refused) as err:
        guard.replaceable(folder, True, guard.is_ros1_bag, "a ROS1 bag", "--bag")
    assert str(err.value) == (f"--bag {folder}: exists and is a folder that is not a ROS1 bag "
                              "this command wrote; it is left as it is (--force replaces only "
                              "that): choose another --bag")
    notes = tmp_path / "n.bag"
    notes.write_text("mine")
    for force in (False, None):
        with pytest.raises(guard.Refused) as err:
            guard.replaceable(notes, force, guard.is_ros1_bag, "a ROS1 bag")
        assert str(err.value) == (f"--out {notes}: exists and is a file that is not a ROS1 bag "
                                  "this command wrote; it is left as it is: choose another "
                                  "--out")
    bag = tmp_path / "b.bag"
    bag.write_bytes(guard.ROS1_MAGIC)
    with pytest.raises(guard.Refused) as err:
        guard.replaceable(bag, False, guard.is_ros1_bag, "a ROS1 bag", "--bag")
    assert str(err.value) == (f"--bag {bag}: exists (a ROS1 bag); give another --bag or "
                              "--force to replace it")
    with pytest.raises(guard.Refused) as err:
        guard.replaceable(bag, None, guard.is_ros1_bag, "a ROS1 bag")
    assert str(err.value) == f"--out {bag}: exists (a ROS1 bag); give another --out (it is not " \
                             "replaced)"
    assert guard.replaceable(bag, True, guard.is_ros1_bag, "a ROS1 bag") is True
    dangling = tmp_path / "gone.bag"
    dangling.symlink_to(tmp_path / "nowhere")
    with pytest.raises(guard.Refused, match="exists and is a file that is not"):
        guard.replaceable(dangling, True, guard.is_ros1_bag, "a ROS1 bag")


def test_run_folder_new_empty_or_of_its_own_kind(tmp_path):
    guard.run_folder(tmp_path / "r" / "seq" / "new", guard.HARNESS, root=tmp_path / "r")
    empty = tmp_path / "empty"
    empty.mkdir()
    guard.run_folder(empty, guard.EXTERNAL, None)
    own = _write_run(tmp_path / "own", "method: {name: x}\nexternal: {}\n")
    guard.run_folder(own, guard.EXTERNAL, None)
    harness = _write_run(tmp_path / "h", "run_key: k\n")
    guard.run_folder(harness, guard.EXTERNAL, True)  # replaced as asked, nobody told
    with pytest.raises(guard.Refused) as err:
        guard.run_folder(harness, guard.EXTERNAL, False)
    assert str(err.value) == (f"{harness}: holds a run made by bench run (harness); bench score "
                              "does not replace it: choose another name, or --force to replace "
                              "that run")
    with pytest.raises(guard.Refused, match="or --force to replace that run"):
        guard.run_folder(harness, guard.EXTERNAL)  # by default: replaced only when asked
    said = []
    guard.run_folder(harness, guard.EXTERNAL, True, say=said.append)
    assert said == [f"replacing the harness run in {harness} (bench run's), as --force asks"]
    other = tmp_path / "other"
    other.mkdir()
    (other / "thesis.tex").write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.run_folder(other, guard.HARNESS, True)
    assert str(err.value) == (f"{other}: holds files that are not a run's; it is left as it "
                              "is: choose another name or folder")


def test_run_folder_refusals_name_the_folder(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.run_folder(notes / "seq" / "run", guard.HARNESS)
    assert str(err.value) == (f"{notes}: is a file, expected a folder of results (to hold "
                              "seq/run); it is left as it is")
    with pytest.raises(guard.Refused) as err:
        guard.run_folder(notes, guard.HARNESS, True)
    assert str(err.value) == f"{notes}: is a file, expected a run folder; it is left as it is"
    with pytest.raises(guard.Refused, match=r"^run folder .*: lies inside a run folder"):
        guard.run_folder(_write_run(tmp_path / "run", "run_key: k\n") / "nested",
                         guard.HARNESS, True)
    store = tmp_path / "d" / "s.h5"
    store.parent.mkdir()
    store.write_bytes(b"x")
    with pytest.raises(guard.Refused, match=r"^run folder .*: holds an input"):
        guard.run_folder(tmp_path / "d", guard.HARNESS, True, inputs=[store])
    with pytest.raises(DataError, match=r"^run folder '': empty"):
        guard.run_folder("", guard.HARNESS)
    with pytest.raises(guard.Refused) as err:
        guard.run_folder(tmp_path / "x", guard.HARNESS, root=tmp_path / "r")
    assert str(err.value) == (f"{tmp_path / 'x'}: outside the results root {tmp_path / 'r'}; "
                              "a run's name is one folder name")
    assert notes.read_text() == "mine"


def test_regenerated_file_and_output_folder_name_the_option(tmp_path):
    page = tmp_path / "p.html"
    page.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.regenerated_file(page, guard.has_mark, "a page", "--page")
    assert str(err.value) == (f"--page {page}: exists and is not a page this command wrote; it "
                              "is left as it is: choose another --page")
    with pytest.raises(guard.Refused) as err:
        guard.regenerated_file(tmp_path, guard.has_mark, "a page")
    assert str(err.value) == f"--out {tmp_path}: is a folder; expected the file name of a page"
    with pytest.raises(guard.Refused, match=r"^--page .*: is an input"):
        guard.regenerated_file(page, guard.has_mark, "a page", "--page", inputs=[page])
    run = _write_run(tmp_path / "run", "run_key: k\n")
    with pytest.raises(guard.Refused, match=r"^--page .*: lies inside a run folder"):
        guard.regenerated_file(run / "p.html", guard.has_mark, "a page", "--page")
    with pytest.raises(guard.Refused, match=r"^--page .*p.html is a file"):
        guard.regenerated_file(page / "q.html", guard.has_mark, "a page", "--page")
    with pytest.raises(DataError, match=r"^--page '': empty"):
        guard.regenerated_file("", guard.has_mark, "a page", "--page")
    guard.regenerated_file(tmp_path / "new.html", guard.has_mark, "a page")
    assert page.read_text() == "mine"


def test_output_folder_refusals(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.output_folder(notes, "--figs")
    assert str(err.value) == f"--figs {notes}: is a file; expected a folder to write into"
    with pytest.raises(guard.Refused, match=r"^--figs .*notes.txt is a file"):
        guard.output_folder(notes / "sub", "--figs")
    ext = _write_run(tmp_path / "ext", "method: {name: x}\nexternal: {}\n")
    with pytest.raises(guard.Refused) as err:
        guard.output_folder(ext, "--figs")
    assert str(err.value) == (f"--figs {ext}: is a run folder (made by bench score); its files "
                              "are the run's: choose another folder")
    with pytest.raises(guard.Refused, match=r"^--figs .*: lies inside a run folder"):
        guard.output_folder(ext / "figs", "--figs")
    data = tmp_path / "data"
    data.mkdir()
    with pytest.raises(guard.Refused, match=r"^--figs .*: is an input"):
        guard.output_folder(data, "--figs", inputs=[data])
    with pytest.raises(DataError, match=r"^--figs '': empty"):
        guard.output_folder("", "--figs")
    dangling = tmp_path / "link"
    dangling.symlink_to(tmp_path / "nowhere")
    with pytest.raises(guard.Refused, match=r"^--out .*link: is a file; expected a folder"):
        guard.output_folder(dangling)
    guard.output_folder(tmp_path / "new" / "figs")


# -- derived files: the ledger and the mark ----------------------------------------------------

def test_a_file_the_harness_wrote_is_listed_and_replaced(tmp_path):
    table = guard.write_text(tmp_path / "t" / "table.md", "| a |\n", guard.derived, "a table")
    ledger = json.loads((tmp_path / "t" / guard.LEDGER).read_text())
    import hashlib

    assert ledger == {"table.md": hashlib.sha256(b"| a |\n").hexdigest()}
    assert guard.derived(table)
    guard.write_text(table, "| b |\n", guard.derived, "a table")
    assert table.read_text() == "| b |\n" and guard.derived(table)
    guard.write_text(tmp_path / "t" / "table.csv", "a\n", guard.derived, "a table")
    assert set(json.loads((tmp_path / "t" / guard.LEDGER).read_text())) == {"table.md",
                                                                            "table.csv"}


def test_a_users_file_of_the_same_name_is_refused(tmp_path):
    mine = tmp_path / "table.md"
    mine.write_text("my table")
    with pytest.raises(guard.Refused) as err:
        guard.write_text(mine, "x", guard.derived, "a table")
    assert str(err.value) == (f"{mine}: exists and is not a table the harness wrote; it is "
                              "left as it is: choose another output")
    assert mine.read_text() == "my table" and not (tmp_path / guard.LEDGER).exists()
    with pytest.raises(guard.Refused, match="is not a file the harness wrote"):
        guard.write_text(mine, "x")  # the default: only a new file


def test_a_ledger_entry_of_another_content_or_file_is_refused(tmp_path):
    table = guard.write_text(tmp_path / "table.md", "ours\n", guard.derived, "a table")
    table.write_text("edited\n")
    assert not guard.derived(table)
    with pytest.raises(guard.Refused, match="is not a table the harness wrote"):
        guard.write_text(table, "again\n", guard.derived, "a table")
    assert table.read_text() == "edited\n"
    other = tmp_path / "other.md"
    other.write_text("ours\n")  # the same bytes under a name the ledger does not list
    assert not guard.derived(other)


def test_a_ledger_that_is_not_the_harnesss_lists_nothing(tmp_path):
    f = tmp_path / "t.md"
    f.write_text("x")
    import hashlib

    digest = hashlib.sha256(b"x").hexdigest()
    for text in ("not json", json.dumps([["t.md", digest]]), json.dumps({"t.md": None})):
        (tmp_path / guard.LEDGER).write_text(text)
        assert not guard.derived(f)
    (tmp_path / guard.LEDGER).write_text(json.dumps({"t.md": digest}))
    assert guard.derived(f)
    link = tmp_path / "l.md"
    link.symlink_to(f)
    (tmp_path / guard.LEDGER).write_text(json.dumps({"t.md": digest, "l.md": digest}))
    assert not guard.derived(link)  # a symlink is never the harness's own file
    assert not guard.derived(tmp_path)


def test_a_broken_ledger_is_replaced_by_a_valid_one(tmp_path):
    (tmp_path / guard.LEDGER).write_text("[1, 2]")
    t = guard.write_text(tmp_path / "t.md", "x", guard.derived, "a table")
    assert guard.derived(t)


def test_the_mark_makes_figures_and_pages_the_harnesss_not_text(tmp_path):
    mark = guard.MARK.encode()
    top = tmp_path / "a.PNG"
    top.write_bytes(b"\x89PNG" + mark)
    assert guard.derived(top)  # the suffix in any case
    tail = tmp_path / "b.pdf"
    tail.write_bytes(b"%PDF" + b"x" * 200_000 + mark + b"%%EOF")  # a PDF's metadata at its end
    assert guard.derived(tail)
    size = 200_000  # a figure's metadata counts in its last 64 KiB: not a byte before
    for start, inside_window in ((size - 65536, True), (size - 65537, False)):
        pdf = tmp_path / f"w{start}.pdf"
        pdf.write_bytes(b"x" * start + mark + b"x" * (size - start - len(mark)))
        assert pdf.stat().st_size == size
        assert guard.derived(pdf) is inside_window
    middle = tmp_path / "c.svg"
    middle.write_bytes(b"x" * 100_000 + mark + b"x" * 100_000)
    assert not guard.derived(middle)
    small = tmp_path / "d.html"
    small.write_bytes(b"<p>" + mark)
    assert guard.derived(small)
    for name in ("notes.md", "table.csv", "t.tex"):
        text = tmp_path / name
        text.write_bytes(mark)
        assert not guard.derived(text)


# -- the writers -------------------------------------------------------------------------------

def _temps(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_write_text_is_atomic_a_failure_leaves_the_old_file_and_no_temp(tmp_path, monkeypatch):
    table = guard.write_text(tmp_path / "table.md", "old\n", guard.derived, "a table")
    real = Path.write_text

    def full_disk(self, *args, **kwargs):
        if self.name.endswith(".tmp"):
            real(self, "half", encoding="utf-8")
            raise OSError(28, "No space left on device")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(Path, "write_text", full_disk)
    with pytest.raises(DataError) as err:
        guard.write_text(table, "new\n", guard.derived, "a table")
    assert str(err.value) == f"{table}: cannot write (No space left on device)"
    monkeypatch.undo()
    assert table.read_text() == "old\n" and guard.derived(table)
    assert _temps(tmp_path) == []


def test_write_text_makes_its_folders_and_refuses_a_folder(tmp_path):
    out = guard.write_text(tmp_path / "a" / "b" / "f.txt", "x")
    assert out == tmp_path / "a" / "b" / "f.txt" and out.read_text() == "x"
    assert not (tmp_path / "a" / "b" / guard.LEDGER).exists()  # not derived: no ledger
    with pytest.raises(guard.Refused) as err:
        guard.write_text(tmp_path / "a", "x", lambda p: True, "a table")
    assert str(err.value) == f"{tmp_path / 'a'}: is a folder; expected the file name of a table"
    with pytest.raises(guard.Refused, match="expected the file name of a file"):
        guard.write_text(tmp_path / "a", "x")


def test_a_symlink_to_a_folder_is_no_folder_to_write_but_an_existing_path(tmp_path):
    (tmp_path / "d").mkdir()
    link = tmp_path / "l"
    link.symlink_to(tmp_path / "d", target_is_directory=True)
    with pytest.raises(guard.Refused, match="exists and is not a file the harness wrote"):
        guard.write_text(link, "x")


def test_write_texts_checks_every_file_before_writing_any(tmp_path):
    mine = tmp_path / "t.tex"
    mine.write_text("% mine")
    with pytest.raises(guard.Refused, match="t.tex: exists and is not a table"):
        guard.write_texts({tmp_path / "t.md": "a", str(mine): "b"}, guard.derived, "a table")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.tex"]
    guard.write_texts({tmp_path / "t.md": "a", tmp_path / "t.csv": "b"}, guard.derived, "a table")
    assert guard.derived(tmp_path / "t.md") and (tmp_path / "t.csv").read_text() == "b"
    guard.write_texts({tmp_path / "t.md": "c"}, guard.derived, "a table")  # its own: again
    assert (tmp_path / "t.md").read_text() == "c"
    with pytest.raises(guard.Refused, match="exists and is not a file the harness wrote"):
        guard.write_texts({tmp_path / "t.csv": "d"})


def test_write_via_writes_through_a_temporary_beside_the_file(tmp_path):
    seen = []

    def writer(tmp: str) -> None:
        seen.append((Path(tmp).parent, os.path.exists(tmp)))
        Path(tmp).write_bytes(b"made")

    out = guard.write_via(tmp_path / "sub" / "f.bin", writer)
    assert out == tmp_path / "sub" / "f.bin" and out.read_bytes() == b"made"
    assert seen == [(tmp_path / "sub", True)]
    assert not (tmp_path / "sub" / guard.LEDGER).exists()
    guard.write_via(tmp_path / "g.bin", writer, fresh=True)
    assert seen[-1] == (tmp_path, False)  # fresh: no temporary file yet
    guard.write_via(tmp_path / "t.csv", writer, guard.derived, "a table")
    assert guard.derived(tmp_path / "t.csv")
    with pytest.raises(guard.Refused, match="g.bin: exists and is not a plot"):
        guard.write_via(tmp_path / "g.bin", writer, None, "a plot")
    with pytest.raises(guard.Refused, match="g.bin: exists and is not a file the harness"):
        guard.write_via(tmp_path / "g.bin", writer)


def test_write_via_failing_leaves_the_old_file_and_no_temp(tmp_path):
    old = guard.write_via(tmp_path / "f.csv", lambda t: Path(t).write_text("old"),
                          guard.derived)

    def broken(tmp: str) -> None:
        Path(tmp).write_text("half")
        raise RuntimeError("the writer failed")

    with pytest.raises(RuntimeError):
        guard.write_via(old, broken, guard.derived)
    assert old.read_text() == "old" and guard.derived(old) and _temps(tmp_path) == []


class _Figure:
    """A figure's savefig: records its arguments, writes the metadata it was given."""

    def __init__(self):
        self.calls = []

    def savefig(self, path, format=None, metadata=None, **options):
        self.calls.append((format, metadata, options))
        Path(path).write_bytes(b"fig " + json.dumps(metadata).encode())


def test_savefig_stamps_the_mark_and_keeps_the_callers_metadata(tmp_path):
    fig = _Figure()
    png = guard.savefig(fig, tmp_path / "a.png", "png", dpi=50)
    assert fig.calls[-1] == ("png", {"Software": guard.MARK}, {"dpi": 50})
    assert guard.derived(png)
    guard.savefig(fig, png, "png")  # its own figure: made again
    for fmt in ("pdf", "svg"):
        guard.savefig(fig, tmp_path / f"a.{fmt}", fmt)
        assert fig.calls[-1][1] == {"Creator": guard.MARK}
    guard.savefig(fig, tmp_path / "b.pdf", "pdf", metadata={"Creator": "me", "Title": "t"})
    assert fig.calls[-1][1] == {"Creator": "me", "Title": "t"}
    guard.savefig(fig, tmp_path / "c.png", "png", metadata={"Title": "t"})
    assert fig.calls[-1][1] == {"Title": "t", "Software": guard.MARK}
    guard.savefig(fig, tmp_path / "d.eps", "eps")
    assert fig.calls[-1][1] is None  # a format without a metadata key: none given
    assert guard.derived(tmp_path / "d.eps")  # listed in the ledger instead
    mine = tmp_path / "mine.png"
    mine.write_bytes(b"\x89PNG my photo")
    with pytest.raises(guard.Refused, match="mine.png: exists and is not a plot"):
        guard.savefig(fig, mine, "png", what="a plot")
    with pytest.raises(guard.Refused, match="is not a figure the harness"):
        guard.savefig(fig, tmp_path / "a.png", "png", own=lambda p: False)
    assert mine.read_bytes() == b"\x89PNG my photo"


def test_remove_only_the_harnesss_own_file(tmp_path):
    assert guard.remove(tmp_path / "absent.md", guard.derived) is False
    ours = guard.write_text(tmp_path / "t.md", "x", guard.derived)
    assert guard.remove(ours, guard.derived) is True and not ours.exists()
    mine = tmp_path / "m.md"
    mine.write_text("mine")
    with pytest.raises(guard.Refused, match="m.md: exists and is not a file the harness"):
        guard.remove(mine, guard.derived)
    with pytest.raises(guard.Refused, match="is a folder"):
        guard.remove(tmp_path, lambda p: True)
    assert mine.read_text() == "mine"
    link = tmp_path / "dangling"
    link.symlink_to(tmp_path / "nowhere")
    assert guard.remove(link, lambda p: True) is True and not os.path.lexists(link)


def test_remove_folder_only_the_harnesss_own(tmp_path):
    assert guard.remove_folder(tmp_path / "absent", lambda p: True) is False
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "f").write_text("x")
    with pytest.raises(guard.Refused) as err:
        guard.remove_folder(mine, guard.is_rosbag2_folder, "a rosbag2 folder")
    assert str(err.value) == f"{mine}: is not a rosbag2 folder the harness made; it is left " \
                             "as it is"
    with pytest.raises(guard.Refused, match=r"mine: is not a folder the harness made"):
        guard.remove_folder(mine, guard.is_rosbag2_folder)
    assert (mine / "f").read_text() == "x"
    bag = tmp_path / "bag"
    (bag / "sub").mkdir(parents=True)
    (bag / "sub" / "x").write_text("x")
    assert guard.remove_folder(bag, lambda p: True) is True and not bag.exists()
    link = tmp_path / "link"
    link.symlink_to(mine, target_is_directory=True)
    assert guard.remove_folder(link, lambda p: True) is True
    assert not os.path.lexists(link) and (mine / "f").read_text() == "x"  # the link only
    f = tmp_path / "file"
    f.write_text("x")
    assert guard.remove_folder(f, lambda p: True) is True and not f.exists()


def test_move_into_place_recognises_the_destination_by_its_owner(tmp_path):
    made = tmp_path / "made.html"
    made.write_text(f"<!-- {guard.MARK} --> new")
    page = tmp_path / "page.html"
    page.write_text("my page")
    with pytest.raises(guard.Refused) as err:
        guard.move_into_place(made, page, guard.has_mark)
    assert str(err.value) == f"{page}: exists and is not an output the harness wrote; it is " \
                             "left as it is"
    assert page.read_text() == "my page" and made.exists()
    page.write_text(f"<!-- {guard.MARK} --> old")
    guard.move_into_place(made, page, guard.has_mark)
    assert page.read_text().endswith("new") and not made.exists()


def test_move_into_place_failing_leaves_the_old_file(tmp_path):
    """The old file is replaced in one step, never removed first: a move that fails (here the
    made file is gone) leaves it as it was."""
    dest = tmp_path / "s.bag"
    dest.write_bytes(guard.ROS1_MAGIC + b"old")
    with pytest.raises(FileNotFoundError):
        guard.move_into_place(tmp_path / "gone.bag", dest, guard.is_ros1_bag)
    assert dest.read_bytes() == guard.ROS1_MAGIC + b"old"


def test_move_into_place(tmp_path):
    made = tmp_path / "made"
    made.write_text("new")
    dest = tmp_path / "dest"
    assert guard.move_into_place(made, dest, lambda p: False) == dest
    assert dest.read_text() == "new" and not made.exists()
    made.write_text("newer")
    with pytest.raises(guard.Refused) as err:
        guard.move_into_place(made, dest, lambda p: False, "a bag")
    assert str(err.value) == f"{dest}: exists and is not a bag the harness wrote; it is left " \
                             "as it is"
    assert dest.read_text() == "new"
    guard.move_into_place(made, dest, lambda p: True)
    assert dest.read_text() == "newer"
    folder = tmp_path / "bag2"
    (folder / "old").mkdir(parents=True)
    (folder / "old" / "x").write_text("x")
    made = tmp_path / "made2"
    made.mkdir()
    (made / "metadata.yaml").write_text("m")
    guard.move_into_place(made, folder, lambda p: True)  # a folder: removed first
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml"]
    target = tmp_path / "target"
    target.mkdir()
    (target / "keep").write_text("k")
    link = tmp_path / "linked"
    link.symlink_to(target, target_is_directory=True)
    made = tmp_path / "made3"
    made.write_text("m")
    guard.move_into_place(made, link, lambda p: True)  # the link replaced, its target kept
    assert link.read_text() == "m" and not link.is_symlink()
    assert (target / "keep").read_text() == "k"


def test_write_store_new_or_a_store_only(tmp_path):
    from conftest import constant_twist_sequence
    from loaders.scan import MemorySequence

    base = constant_twist_sequence(n_frames=3, n_points=50)
    seq = MemorySequence("s", base.sensor, list(base), base.ground_truth)
    frames = []
    out = guard.write_store(seq, tmp_path / "sub" / "s.h5", progress=frames.append)
    assert out == tmp_path / "sub" / "s.h5" and guard.is_store(out)
    assert len(frames) == 3  # the writer's options reach it (a progress call per frame)
    guard.write_store(seq, out)  # a store: the default owner recognises it
    mine = tmp_path / "mine.h5"
    mine.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.write_store(seq, mine)
    assert str(err.value) == f"{mine}: exists and is not a store the harness wrote; it is left " \
                             "as it is: choose another output"
    assert mine.read_text() == "mine"
    with pytest.raises(guard.Refused, match="is not a synthetic store"):
        guard.write_store(seq, out, guard.is_synthetic_store, "a synthetic store")


def test_bag_writer_only_to_a_new_path(tmp_path):
    made = []

    def writer(path, **options):
        made.append((path, options))
        return "the writer"

    assert guard.bag_writer(writer, tmp_path / "b.bag", x=1) == "the writer"
    assert made == [(tmp_path / "b.bag", {"x": 1})]
    (tmp_path / "b.bag").write_bytes(guard.ROS1_MAGIC)
    with pytest.raises(guard.Refused) as err:
        guard.bag_writer(writer, tmp_path / "b.bag")
    assert str(err.value) == f"{tmp_path / 'b.bag'}: exists; a bag is written only to a new path"
    assert len(made) == 1


class _Stream:
    def __init__(self):
        self.saved = []

    def save(self, path):
        self.saved.append(path)
        Path(path).write_bytes(b"RRF2 recording")


def test_saving_names_the_file_when_the_block_ends(tmp_path):
    stream = _Stream()
    out = tmp_path / "rec" / "v.rrd"
    with guard.saving(stream, out, guard.is_recording) as s:
        assert s is stream and not out.exists()
        assert Path(stream.saved[0]).parent == out.parent
    assert out.read_bytes() == b"RRF2 recording" and _temps(out.parent) == []
    with guard.saving(stream, out, guard.is_recording):  # its own recording: made again
        pass
    with guard.saving(stream, tmp_path / "t.rrd", guard.derived):
        pass
    assert guard.derived(tmp_path / "t.rrd")
    mine = tmp_path / "mine.rrd"
    mine.write_text("mine")
    with pytest.raises(guard.Refused, match="mine.rrd: exists and is not a recording"):
        with guard.saving(stream, mine, guard.is_recording, "a recording"):
            pass
    assert mine.read_text() == "mine"


def test_saving_a_failed_block_leaves_the_old_file_and_no_temp(tmp_path):
    out = tmp_path / "v.rrd"
    out.write_bytes(b"RRF old")
    with pytest.raises(RuntimeError):
        with guard.saving(_Stream(), out, guard.is_recording):
            raise RuntimeError("logging failed")
    assert out.read_bytes() == b"RRF old" and _temps(tmp_path) == []


def test_the_writers_make_the_files_folder_and_nothing_else(tmp_path, monkeypatch):
    """Each writer makes the folders of its file, nothing in the working folder."""
    work = tmp_path / "cwd"
    work.mkdir()
    monkeypatch.chdir(work)
    guard.write_text(tmp_path / "a" / "t.md", "x")
    guard.write_via(tmp_path / "b" / "f.png", lambda t: Path(t).write_bytes(b"x"))
    with guard.saving(_Stream(), tmp_path / "c" / "v.rrd"):
        pass
    from conftest import constant_twist_sequence
    from loaders.scan import MemorySequence

    base = constant_twist_sequence(n_frames=2, n_points=20)
    guard.write_store(MemorySequence("s", base.sensor, list(base), base.ground_truth),
                      tmp_path / "d" / "s.h5")
    assert sorted(os.listdir(work)) == []
    assert [p.name for p in sorted(tmp_path.rglob("*")) if p.is_file()] == [
        "t.md", "f.png", "v.rrd", "s.h5"]


def test_a_writer_through_a_file_names_it_as_the_output(tmp_path):
    notes = tmp_path / "notes"
    notes.write_text("mine")
    out = notes / "f.txt"
    expected = f"output {notes}: {notes} is a file, expected a folder; it is left as it is"
    for write in (lambda: guard.write_text(out, "x"),
                  lambda: guard.write_via(out, lambda t: Path(t).write_text("x")),
                  lambda: guard.write_store(None, out)):
        with pytest.raises(guard.Refused) as err:
            write()
        assert str(err.value) == expected
    with pytest.raises(guard.Refused) as err:
        with guard.saving(_Stream(), out):
            pass
    assert str(err.value) == expected
    assert notes.read_text() == "mine"


def test_make_folder(tmp_path):
    assert guard.make_folder(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    assert (tmp_path / "a" / "b").is_dir()
    guard.make_folder(tmp_path / "a" / "b")  # an existing folder is fine
    notes = tmp_path / "a" / "notes"
    notes.write_text("mine")
    with pytest.raises(guard.Refused) as err:
        guard.make_folder(notes / "c" / "d", "--figs")
    assert str(err.value) == (f"--figs {notes / 'c' / 'd'}: {notes} is a file, expected a "
                              "folder; it is left as it is")
    with pytest.raises(guard.Refused, match=r"^--out .*notes is a file"):
        guard.make_folder(notes)
    with pytest.raises(guard.Refused) as err:
        guard.make_folder(tmp_path / ("y" * 300) / "z", "--figs")
    assert str(err.value) == (f"--figs {tmp_path / ('y' * 300) / 'z'}: cannot create this "
                              "folder (File name too long)")
    assert notes.read_text() == "mine"


def test_a_256_byte_name_is_exit_2_with_one_error_line_naming_the_option(
        tmp_path, monkeypatch, capsys):
    from helpers_cli import run_bench

    assert issubclass(guard.Refused, DataError)
    tum = tmp_path / "est.txt"
    tum.write_text("0 0 0 0 0 0 0 1\n")
    code, text = run_bench(["score", tum, "--store", tmp_path / "s.h5", "--name", "x" * 256,
                            "--out", tmp_path / "r"], capsys, monkeypatch)
    lines = [line for line in text.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("error: --name "), text
    assert "256 bytes long" in text and "at most 239 bytes" in text, text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["est.txt"]
