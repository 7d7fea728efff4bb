"""One write rule, enforced by the code: every file and folder a command writes goes through
``bench/guard.py``'s writing helpers (new, or replaced only when the harness wrote it and it is
the kind the command makes). This test walks the sources of bench/, loaders/, methods/ and
metrics/ (AST) and fails on any write call outside the guard's helper modules, so a new writer
cannot bypass it; the end-to-end cases through the command line are in test_write_guard.py."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("bench", "loaders", "methods", "metrics")
#: the only modules that may call a write primitive: the guard (bench's commands) and the
#: atomic-file mechanics below it (loaders/ may not import bench: its store writer uses these)
HELPERS = {"bench/guard.py", "loaders/fileio.py"}
#: the loaders' path writers and atomic helpers: bench calls them only through the guard
GUARDED_IN_BENCH = {"atomic_write_text", "atomic_path", "write_store", "write_tum",
                    "write_kitti", "write_pcd", "create_hdf5"}
#: (module, function) that write outside any output tree, each with its reason
EXEMPT = {
    # the timing lock every executor shares in the temporary folder: no output, no input
    ("methods/timing.py", "_lock_fd"),
}

#: the project's own writer classes, which open their file through the guard
#: (bench/data/bag_messages.py: ``guard.bag_writer``)
PROJECT_WRITERS = {"BagWriter"}
ATTR_WRITERS = {"write_text", "write_bytes", "savefig", "to_csv", "to_parquet", "to_hdf",
                "to_excel", "to_pickle", "to_feather", "touch", "unlink", "rmdir", "mkdir",
                "symlink_to", "hardlink_to", "rename", "save", "tofile", "makedirs"}
MODULE_WRITERS = {
    "os": {"replace", "rename", "renames", "remove", "unlink", "rmdir", "removedirs", "mkdir",
           "makedirs", "symlink", "link", "truncate"},
    "shutil": {"move", "rmtree", "copy", "copy2", "copyfile", "copytree", "copymode",
               "copystat", "make_archive"},
    "np": {"save", "savez", "savez_compressed", "savetxt"},
    "numpy": {"save", "savez", "savez_compressed", "savetxt"},
    "json": {"dump"}, "pickle": {"dump"}, "yaml": {"dump", "safe_dump"},
}
WRITE_FLAGS = {"O_WRONLY", "O_RDWR", "O_CREAT", "O_TRUNC", "O_APPEND"}


def _name(node: ast.AST) -> str:
    if isinstance(node, ast.Name):
        return node.id
    if isinstance(node, ast.Attribute):
        return node.attr
    return ""


def _mode(call: ast.Call, position: int) -> ast.AST | None:
    for kw in call.keywords:
        if kw.arg == "mode":
            return kw.value
    return call.args[position] if len(call.args) > position else None


def _writes_mode(mode: ast.AST | None, letters: str) -> bool:
    """A mode that writes (or one not written out: it cannot be shown to read only)."""
    if mode is None:
        return False
    if isinstance(mode, ast.Constant) and isinstance(mode.value, str):
        return any(c in mode.value for c in letters)
    return True


def _open_method_writes(call: ast.Call) -> bool:
    """``x.open("w")`` / ``x.open(mode=m)``: a path opened for writing (a loader's
    ``Loader.open(paths, options)`` passes no mode string)."""
    mode = _mode(call, 0)
    if any(kw.arg == "mode" for kw in call.keywords):
        return _writes_mode(mode, "wax+")
    return (isinstance(mode, ast.Constant) and isinstance(mode.value, str)
            and _writes_mode(mode, "wax+"))


#: modules whose ``open(path, mode)`` takes the mode second, as the builtin's does
OPENERS = {"io", "gzip", "bz2", "lzma", "tarfile", "codecs"}


def _imported(tree: ast.AST) -> dict[str, tuple[str, str]]:
    """Local name -> (module, name) of every ``from MODULE import NAME [as LOCAL]``."""
    found = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            for a in node.names:
                found[a.asname or a.name] = (node.module.split(".")[0], a.name)
    return found


def write_calls(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, what) of every write call in a module's syntax tree."""
    found = []
    imported = _imported(tree)
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func, name = node.func, _name(node.func)
        owner = _name(func.value) if isinstance(func, ast.Attribute) else ""
        if isinstance(func, ast.Name) and func.id in imported:  # from shutil import rmtree
            owner, name = imported[func.id]
            owner = "np" if owner == "numpy" else owner
        if owner == "guard":
            continue  # the guard's own helpers: the way every command writes
        what = None
        if isinstance(func, ast.Name) and name == "open" and _writes_mode(_mode(node, 1),
                                                                          "wax+"):
            what = "open for writing"
        elif name == "open" and owner in OPENERS and _writes_mode(_mode(node, 1), "wax+"):
            what = f"{owner}.open for writing"
        elif name == "ZipFile" and _writes_mode(_mode(node, 1), "wax+"):
            what = "ZipFile for writing"
        elif isinstance(func, ast.Attribute) and name == "open" and owner != "os" and \
                _open_method_writes(node):
            what = "open for writing"
        elif owner == "os" and name == "open" and any(
                _name(n) in WRITE_FLAGS for n in ast.walk(node)):
            what = "os.open for writing"
        elif name == "File" and _writes_mode(_mode(node, 1), "wax+-"):
            what = "h5py.File in a writing mode"
        elif name.endswith("Writer") and name[:1].isupper() and name not in PROJECT_WRITERS:
            what = f"{name} (a file writer)"
        elif owner in MODULE_WRITERS and name in MODULE_WRITERS[owner]:
            if owner == "yaml" and len(node.args) < 2 and not any(
                    kw.arg == "stream" for kw in node.keywords):
                continue  # yaml.safe_dump(data): a string, no file
            what = f"{owner}.{name}"
        elif owner == "tempfile" and any(kw.arg == "dir" for kw in node.keywords):
            what = "tempfile in a given folder"
        elif isinstance(func, ast.Attribute) and name in ATTR_WRITERS and owner not in (
                "os", "shutil"):
            what = f".{name}()"
        elif isinstance(func, ast.Attribute) and name == "replace" and len(node.args) == 1 \
                and not node.keywords and owner not in ("dataclasses",):
            what = "Path.replace (a move)"  # str.replace takes two arguments
        if what:
            found.append((node.lineno, what))
    return found


def _functions(tree: ast.AST) -> dict[int, str]:
    """Line -> the innermost function defined around it."""
    where = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for line in range(node.lineno, (node.end_lineno or node.lineno) + 1):
                if line not in where or where[line][0] < node.lineno:
                    where[line] = (node.lineno, node.name)
    return {line: name for line, (_, name) in where.items()}


def guarded_in_bench(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, name) of every use of a loaders path writer in a bench module: bench writes
    through the guard's helpers only."""
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(
                "loaders"):
            found += [(node.lineno, f"imports {a.name}") for a in node.names
                      if a.name in GUARDED_IN_BENCH]
        elif isinstance(node, ast.Attribute) and node.attr in GUARDED_IN_BENCH and \
                _name(node.value) != "guard":
            found.append((node.lineno, f"uses {node.attr}"))
    return found


def violations(root: Path = ROOT) -> list[str]:
    out = []
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            rel = path.relative_to(root).as_posix()
            if rel in HELPERS:
                continue
            tree = ast.parse(path.read_text(), filename=rel)
            where = _functions(tree)
            calls = write_calls(tree)
            if package == "bench":
                calls += guarded_in_bench(tree)
            out += [f"{rel}:{line}: {what}" for line, what in calls
                    if (rel, where.get(line)) not in EXEMPT]
    return out


def test_no_write_call_outside_the_guard():
    found = violations()
    assert not found, ("write calls outside bench/guard.py's helpers (route them through "
                       "guard.write_text / guard.atomic_path / guard.savefig / guard.remove / "
                       "guard.make_folder ...):\n" + "\n".join(found))


RAW_WRITES = [
    'Path("x").write_text("y")',
    'open(path, "w").write("y")',
    'open(path, mode="ab")',
    'path.open("w")',
    'fig.savefig(out / "plot.png")',
    'frame.to_csv(out)',
    'h5py.File(out, "a")',
    'h5py.File(out, mode="r+")',
    'shutil.rmtree(out)',
    'shutil.move(a, b)',
    'os.replace(a, b)',
    'os.remove(a)',
    'out.unlink()',
    'out.mkdir(parents=True)',
    'np.savetxt(out, values)',
    'json.dump(data, f)',
    'Writer(out)',
    'rec.save(str(out))',
    'os.open(out, os.O_WRONLY | os.O_CREAT)',
    'yaml.safe_dump(data, f)',
    'tarfile.open(out, "w:gz")',
    'gzip.open(out, "wt")',
    'zipfile.ZipFile(out, "w")',
    'np.save(out, a)',
    'pickle.dump(a, f)',
    'frame.to_parquet(out)',
    'os.makedirs(out)',
    'shutil.copyfile(a, b)',
    'tempfile.mkstemp(dir=out)',
    'tmp.replace(out)',
]


@pytest.mark.parametrize("imports, call", [
    ("from shutil import rmtree", "rmtree(out)"),
    ("from os import remove as rm", "rm(out)"),
    ("from numpy import savetxt", "savetxt(out, a)"),
])
def test_a_writer_imported_by_name_is_found(tmp_path, imports, call):
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "commands.py").write_text(f"{imports}\n\n\ndef command(out, a):\n    {call}\n")
    found = violations(tmp_path)
    assert len(found) == 1 and found[0].startswith("bench/commands.py:5:"), found


@pytest.mark.parametrize("source", RAW_WRITES)
def test_a_raw_write_added_to_a_command_is_found(tmp_path, source):
    """The walk finds each kind of write in a command module of a copy of the tree (and only
    there: the copy without it is clean of that line)."""
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "commands.py").write_text(f"def command(path, out, a, b, fig, frame, rec, tmp):\n"
                                       f"    {source}\n")
    found = violations(tmp_path)
    assert len(found) == 1 and found[0].startswith("bench/commands.py:2:"), found


@pytest.mark.parametrize("source", ['open(path)', 'open(path, "rb")', 'h5py.File(p, "r")',
                                    'yaml.safe_dump(data)', 'json.dumps(data)',
                                    'text.replace("a", "b")', 'csv.writer(buf)',
                                    'dataclasses.replace(p, name="x")',
                                    'Loader.open(paths, options)',
                                    'guard.write_text(path, text, guard.derived)'])
def test_reads_are_not_writes(tmp_path, source):
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "commands.py").write_text(f"def command(path, p, data, text, buf, paths, "
                                       "options):\n"
                                       f"    {source}\n")
    assert violations(tmp_path) == []


def test_bench_writes_through_the_guard_not_the_loaders_helpers(tmp_path):
    bench = tmp_path / "bench"
    bench.mkdir()
    (bench / "table.py").write_text("from loaders.fileio import atomic_write_text\n"
                                    "def f(p):\n    atomic_write_text(p, 'x')\n")
    assert [v.split(": ", 1)[1] for v in violations(tmp_path)] == [
        "imports atomic_write_text"]
    (bench / "guard.py").write_text("from loaders.fileio import atomic_write_text\n")
    assert len(violations(tmp_path)) == 1  # the guard itself may
