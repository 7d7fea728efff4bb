"""The import graph keeps its layers: loaders < methods, metrics < bench (methods and metrics
do not import each other, nothing in loaders/, methods/, metrics/ imports bench/), and inside
bench/ no module imports a layer above its own and no modules import each other in
a circle (data < runs < report < studies < commands / cli / api; paths, threads and console
below them all). Every import counts: module level, inside a function, under TYPE_CHECKING."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("loaders", "methods", "metrics", "bench")
#: the top-level packages' layers: each imports only lower layers (and itself)
TOP_LAYERS = {"loaders": 0, "methods": 1, "metrics": 1, "bench": 2}

#: inside bench/: a module's layer is that of its folder, or of the top-level module
BENCH_LAYERS = {"bench": 0, "bench.paths": 0, "bench.guard": 0, "bench.threads": 0,
                "bench.options": 0,
                "bench.console": 0,
                "bench.data": 1, "bench.runs": 2,
                # the report's rooms, each importing only those below it: names and dataframe <
                # tables < figures < summary < html < the report's single jobs (compare, view,
                # commands, ...)
                "bench.report.names": 3.0, "bench.report.dataframe": 3.0,
                "bench.report.tables": 3.1, "bench.report.figures": 3.2,
                "bench.report.summary": 3.3, "bench.report.html": 3.4, "bench.report": 3.5,
                "bench.studies": 4,
                "bench.commands": 5, "bench.cli": 5, "bench.api": 5, "bench.docs_cli": 5}
#: the folders every bench module lives in: each is a package whose face (its __init__.py
#: docstring) says what the room is for and what it may import
BENCH_ROOMS = {"bench.data", "bench.data.calibration", "bench.runs", "bench.runs.external",
               "bench.report", "bench.report.tables", "bench.report.figures",
               "bench.report.summary", "bench.report.html", "bench.studies"}
#: the longest a module may grow [lines] (the command table bench/cli.py aside)
MAX_MODULE_LINES = 600


def modules(root: Path, packages=PACKAGES) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of ``packages`` under ``root``."""
    out = {}
    for package in packages:
        for path in (root / package).rglob("*.py"):
            parts = list(path.relative_to(root).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts.pop()
            out[".".join(parts)] = path
    return out


def import_graph(mods: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules of ``mods`` it imports (``from a import b`` counts as ``a.b``
    when that is a module, else ``a``; relative imports resolved)."""

    def known(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph = {}
    for name, path in mods.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            targets = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    parts = parts[:len(parts) - node.level + 1]
                    base = ".".join([*parts, *([node.module] if node.module else [])])
                targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base
                           for a in node.names]
            for target in targets:
                resolved = known(target)
                if resolved is not None and resolved != name:
                    found.add(resolved)
        graph[name] = found
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def bench_layer(module: str) -> int:
    """A bench module's layer: that of its longest prefix in ``BENCH_LAYERS`` (an unlisted
    top-level module of bench/ falls to the bottom layer, and the test that lists them
    fails)."""
    name = module
    while name not in BENCH_LAYERS:
        name = name.rpartition(".")[0]
    return BENCH_LAYERS[name]


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    """Each import of the same or a higher layer in another package (``TOP_LAYERS``), and
    each bench module importing a bench layer above its own."""
    bad = []
    for a, targets in graph.items():
        for b in sorted(targets):
            top_a, top_b = a.split(".")[0], b.split(".")[0]
            if top_a != top_b and TOP_LAYERS[top_b] >= TOP_LAYERS[top_a]:
                bad.append(f"{a} -> {b}")
            elif top_a == top_b == "bench" and bench_layer(b) > bench_layer(a):
                bad.append(f"{a} -> {b}")
    return bad


def test_every_room_is_a_package_with_a_face():
    """Each folder of bench/ is a listed room whose __init__.py docstring says what it is for
    and what it may import."""
    folders = {".".join(p.relative_to(ROOT).parts) for p in (ROOT / "bench").rglob("*")
               if p.is_dir() and any(p.glob("*.py"))}
    assert folders == BENCH_ROOMS
    for room in sorted(BENCH_ROOMS):
        face = ast.get_docstring(ast.parse((ROOT / room.replace(".", "/") / "__init__.py")
                                           .read_text())) or ""
        assert "May import" in face, f"{room}/__init__.py: say what the room is for and what " \
            "it may import"


def test_no_module_is_overgrown():
    long = {name: n for name, path in modules(ROOT).items()
            if name != "bench.cli" and (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long == {}, f"split these modules (over {MAX_MODULE_LINES} lines): {long}"


def test_the_report_rooms_have_layers():
    assert bench_layer("bench.report.tables.paper") < bench_layer("bench.report.figures.draw") \
        < bench_layer("bench.report.summary.overview") < bench_layer("bench.report.html.page") \
        < bench_layer("bench.report.compare") < bench_layer("bench.studies.reproduce")
    assert bench_layer("bench.report.names") < bench_layer("bench.report.tables.model")


def test_every_top_level_module_of_bench_has_a_layer():
    top = {m for m in modules(ROOT, ("bench",)) if m.count(".") == 1}
    unlisted = sorted(m for m in top if m not in BENCH_LAYERS)
    assert unlisted == [], f"give these a layer in BENCH_LAYERS: {unlisted}"


def test_no_import_circle_anywhere():
    found = cycles(import_graph(modules(ROOT)))
    assert found == [], "modules importing each other in a circle: move what they share " \
        "into a module below both:\n" + "\n".join(" <-> ".join(c) for c in found)


def test_no_upward_import():
    bad = upward_imports(import_graph(modules(ROOT)))
    assert bad == [], "imports of a higher layer:\n" + "\n".join(bad)


def test_the_checks_see_a_circle_and_an_upward_import(tmp_path):
    """The checker on a small tree of its own: a function-level circle in bench/runs, a
    relative-import circle in bench/data, a studies module importing bench.commands, a loader
    importing bench and a metric importing a method are all found; a method importing a
    loader is not an error."""
    files = {
        "bench/__init__.py": "",
        "bench/commands.py": "",
        "bench/runs/__init__.py": "",
        "bench/runs/a.py": "from bench.runs.b import f\n",
        "bench/runs/b.py": "def f():\n    from bench.runs import a\n",
        "bench/data/__init__.py": "",
        "bench/data/x.py": "from .y import g\n",
        "bench/data/y.py": "from . import x\n",
        "bench/studies/__init__.py": "",
        "bench/studies/s.py": "def main():\n    from bench.commands import run\n",
        "loaders/__init__.py": "",
        "loaders/l.py": "import bench.runs.a\n",
        "methods/__init__.py": "", "metrics/__init__.py": "",
        "metrics/m.py": "from methods import x\n", "methods/x.py": "import loaders.l\n",
    }
    for rel, text in files.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    graph = import_graph(modules(tmp_path))
    assert sorted(cycles(graph)) == [["bench.data.x", "bench.data.y"],
                                     ["bench.runs.a", "bench.runs.b"]]
    assert sorted(upward_imports(graph)) == ["bench.studies.s -> bench.commands",
                                             "loaders.l -> bench.runs.a",
                                             "metrics.m -> methods.x"]
    # and the downward direction is allowed
    (tmp_path / "bench/runs/b.py").write_text("from bench.data.x import g\n")
    graph = import_graph(modules(tmp_path))
    assert cycles(graph) == [["bench.data.x", "bench.data.y"]]
    assert "bench.runs.b -> bench.data.x" not in upward_imports(graph)
