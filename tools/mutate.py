"""Mutation testing of what changed: ``make mutate BASE=<commit>``.

The modules changed since ``BASE`` (``git diff --name-only BASE -- bench loaders methods
metrics``, the .py files that still exist) are mutated with mutmut 3, each mutant is run against
the test files that cover its module, and the survivors are listed (each with its diff), then a
score per module: killed / (killed + survived).

Which tests cover a module: the test files under tests/ named after it (``test_scale.py`` for
``bench/studies/scale.py``, which it runs through the CLI) and those that import it (``import
metrics.units``, ``from metrics.units import ...``, ``from metrics import units``), and with
``--depth N`` also
those that import a module importing it, up to N steps up the project's import graph (depth 0,
the default, keeps a run to minutes; the CLI tests, which import everything through
``bench.cli``, are not counted as covering every module). ``--tests`` names them instead.

Nothing is written into the checkout's tracked files: the working tree (tracked and untracked
files that git does not ignore, as they are now) is copied into a scratch folder, ``.mutate/``
at the checkout's root (git-ignored; ``--scratch`` moves it), where mutmut keeps its
``mutants/`` and its configuration (a ``setup.cfg`` of the copy). A second run over the same
scratch folder re-tests the mutants of functions that changed (mutmut's own cache) and every
survivor of the last run (``retest_survivors``: mutmut keeps a verdict while only the tests
change, so without this a test written to kill a survivor would never be tried on it). The
scratch folder must be one git ignores (``.mutate*/``), else the next copy would hold it. One
worker (``--workers``), so that a run never takes more than its share of a shared machine.

Numba-compiled functions (any decorated function) are not mutated by mutmut; their Python
callers are.
"""

from __future__ import annotations

import argparse
import ast
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

#: the packages whose changes are mutated
PACKAGES = ("bench", "loaders", "methods", "metrics")
#: what the tests read besides the packages and tests/ (copied into mutmut's mutants/)
ALSO_COPY = ("configs", "samples", "examples", "docs", "mkdocs.yml", "README.md", "Makefile",
             "paper")
SCRATCH = ".mutate"


def git(root: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], check=True, capture_output=True,
                          text=True).stdout


def changed_modules(root: Path, base: str) -> list[str]:
    """The .py files of ``PACKAGES`` changed since ``base`` that still exist (relative
    paths, sorted)."""
    names = git(root, "diff", "--name-only", base, "--", *PACKAGES).split()
    return sorted(n for n in names if n.endswith(".py") and (root / n).is_file())


def module_name(path: str) -> str:
    """"metrics/units.py" -> "metrics.units"; "bench/runs/__init__.py" -> "bench.runs"."""
    parts = list(Path(path).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imported(source: str, known: set[str], package: str = "") -> set[str]:
    """The modules of ``known`` that ``source`` imports anywhere (module level or inside a
    function): ``from a import b`` counts as ``a.b`` when that is a module, else ``a``;
    ``package``: the importing module's package, for relative imports."""
    found = set()
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return found
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.add(alias.name)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                up = parts[:len(parts) - node.level + 1] if node.level > 1 else parts
                base = ".".join([*up, base] if base else up)
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
    out = set()
    for name in found:
        while name and name not in known:
            name = name.rpartition(".")[0]
        if name:
            out.add(name)
    return out


def project_modules(root: Path) -> dict[str, Path]:
    out = {}
    for package in PACKAGES:
        for path in (root / package).rglob("*.py"):
            out[module_name(str(path.relative_to(root)))] = path
    return out


def covering_tests(root: Path, module: str, depth: int = 0) -> list[str]:
    """The test files (paths relative to ``root``) named after ``module``'s file
    (``test_<name>.py``) or that import ``module``, or with ``depth`` a module that imports it
    up to ``depth`` steps away."""
    mods = project_modules(root)
    known = set(mods)
    targets = {module}
    if depth:
        graph = {name: imported(path.read_text(encoding="utf-8"), known,
                                name if path.name == "__init__.py" else name.rpartition(".")[0])
                 for name, path in mods.items()}
        for _ in range(depth):
            targets |= {name for name, deps in graph.items() if deps & targets}
    stem = module.rpartition(".")[2]
    tests = []
    for path in sorted((root / "tests").glob("test_*.py")):
        named = stem != "__init__" and path.stem in (f"test_{stem}", f"test_{stem}s")
        if named or imported(path.read_text(encoding="utf-8"), known) & targets:
            tests.append(str(path.relative_to(root)))
    return tests


def copy_tree(root: Path, dest: Path) -> int:
    """Copy the working tree (tracked and untracked, not ignored files, as they are now) into
    ``dest``; files no longer in the tree are removed from ``dest`` (its mutmut state
    ``mutants/`` and ``setup.cfg`` aside). Returns the number of files."""
    files = git(root, "ls-files", "-z", "--cached", "--others", "--exclude-standard").split("\0")
    files = [f for f in files if f and (root / f).is_file()]
    wanted = set(files)
    if dest.exists():
        for path in dest.rglob("*"):
            rel = path.relative_to(dest).as_posix()
            if path.is_file() and not rel.startswith("mutants/") and rel != "setup.cfg" \
                    and rel not in wanted:
                path.unlink()
    for f in files:
        target = dest / f
        target.parent.mkdir(parents=True, exist_ok=True)
        if not target.exists() or (root / f).read_bytes() != target.read_bytes():
            shutil.copy2(root / f, target)
    return len(files)


def retest_survivors(tree: Path) -> int:
    """Mark every survivor recorded in the scratch copy's mutmut state (``mutants/**/*.meta``,
    exit code 0) as not yet tested, so that the next run tries it on the tests as they are
    now; returns how many."""
    count = 0
    for meta in sorted((tree / "mutants").rglob("*.py.meta")):
        data = json.loads(meta.read_text(encoding="utf-8"))
        codes = data.get("exit_code_by_key", {})
        survivors = [k for k, code in codes.items() if code == 0]
        if survivors:
            codes.update(dict.fromkeys(survivors))
            meta.write_text(json.dumps(data), encoding="utf-8")
            count += len(survivors)
    return count


def mutmut_config(modules: list[str], tests: list[str]) -> str:
    """The ``[mutmut]`` section of the scratch copy's setup.cfg (mutmut reads it from its
    working directory; the copy's pyproject.toml has no ``[tool.mutmut]``)."""
    def block(items) -> str:
        return "\n" + "\n".join(f"    {x}" for x in items)

    return ("[mutmut]\n"
            f"source_paths ={block(PACKAGES)}\n"
            f"only_mutate ={block(modules)}\n"
            f"pytest_add_cli_args_test_selection ={block(tests)}\n"
            f"pytest_add_cli_args ={block(['-p', 'no:cacheprovider', '-q'])}\n"
            f"also_copy ={block(ALSO_COPY)}\n"
            "use_git_change_detection = false\n"
            "use_setproctitle = false\n")


_RESULT = re.compile(r"^\s*(\S+): (\w[\w ]*)$")


def parse_results(text: str) -> dict[str, str]:
    """``mutmut results --all true`` lines "    name: status" -> {name: status}."""
    out = {}
    for line in text.splitlines():
        m = _RESULT.match(line)
        if m:
            out[m.group(1)] = m.group(2).strip()
    return out


def mutant_module(name: str) -> str:
    """"metrics.units.x_drift_units__mutmut_3" -> "metrics.units"."""
    head = name.split("__mutmut_")[0]
    parts = head.split(".")
    # the last part is the mangled function ("x_f" or "xǁClassǁmethod")
    return ".".join(parts[:-1])


def scores(results: dict[str, str]) -> dict[str, tuple[int, int, int]]:
    """module -> (killed, survived, other) from ``parse_results``."""
    out: dict[str, list[int]] = {}
    for name, status in results.items():
        k = out.setdefault(mutant_module(name), [0, 0, 0])
        k[0 if status == "killed" else 1 if status == "survived" else 2] += 1
    return {m: tuple(v) for m, v in sorted(out.items())}


#: the frames of mutmut's spinner, which it redraws many times a second
_SPINNER = tuple("⠋⠙⠹⠸⠼⠴⠦⠧⠇⠏")


def _run_quietly(cmd: list[str], cwd: Path, env: dict) -> subprocess.CompletedProcess:
    """Run mutmut, printing its lines but not its spinner's redraws (only the progress line
    every 50 mutants and the last one)."""
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True, bufsize=1)
    last, shown = "", 0
    buffer = ""
    assert proc.stdout is not None
    while chunk := proc.stdout.read(256):
        buffer += chunk
        *lines, buffer = re.split(r"[\r\n]", buffer)
        for line in lines:
            text = line.strip()
            if not text:
                continue
            if text.startswith(_SPINNER):
                last = text
                done = re.match(r"\S+ (\d+)/\d+", text)
                if done and int(done.group(1)) >= shown + 50:
                    shown = int(done.group(1))
                    print(text, flush=True)
            else:
                print(text, flush=True)
    if last:
        print(last, flush=True)
    return subprocess.CompletedProcess(cmd, proc.wait())


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="make mutate", description=__doc__.split("\n\n")[0])
    p.add_argument("--base", required=True, help="the commit to diff against (BASE=...)")
    p.add_argument("--only", nargs="*", default=None,
                   help="mutate only these of the changed modules (paths, e.g. metrics/units.py)")
    p.add_argument("--tests", nargs="*", default=None,
                   help="run these test files instead of the ones that import the modules")
    p.add_argument("--depth", type=int, default=0,
                   help="also tests importing a module that imports a changed one, N steps up")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--scratch", type=Path, default=None,
                   help=f"the scratch folder (default: {SCRATCH}/ at the checkout's root)")
    p.add_argument("--list", action="store_true",
                   help="only list the modules and their tests, mutate nothing")
    args = p.parse_args(argv)
    root = Path(git(Path.cwd(), "rev-parse", "--show-toplevel").strip())
    modules = changed_modules(root, args.base)
    if args.only is not None:
        unknown = sorted(set(args.only) - set(modules))
        if unknown:
            print(f"error: not changed since {args.base}: {', '.join(unknown)}", file=sys.stderr)
            return 2
        modules = [m for m in modules if m in set(args.only)]
    if not modules:
        print(f"no module of {', '.join(PACKAGES)} changed since {args.base}")
        return 0
    per_module = {m: covering_tests(root, module_name(m), args.depth) for m in modules}
    for m, tests in per_module.items():
        print(f"{m}: {len(tests)} test file(s): {' '.join(Path(t).name for t in tests) or '-'}")
    tests = sorted(set(args.tests) if args.tests is not None
                   else {t for ts in per_module.values() for t in ts})
    print(f"running {len(tests)} test file(s) on each mutant (those that reach it): "
          f"{' '.join(tests)}")
    untested = [m for m, ts in per_module.items() if not ts]
    if untested and args.tests is None:
        print(f"note: no test file imports {', '.join(untested)}: their mutants all survive "
              "(--depth 1 or --tests to widen)")
    if args.list:
        return 0
    if not tests:
        print("error: no test file to run", file=sys.stderr)
        return 2
    scratch = (args.scratch or root / SCRATCH).resolve()
    tree = scratch / "tree"
    print(f"copying the working tree into {tree} ...", flush=True)
    copy_tree(root, tree)
    (tree / "setup.cfg").write_text(mutmut_config(modules, tests), encoding="utf-8")
    again = retest_survivors(tree)
    if again:
        print(f"re-testing the last run's {again} survivor(s) on the tests as they are now")
    mutmut = Path(sys.executable).parent / "mutmut"
    env = {**os.environ, "PYTHONPATH": "", "PYTHONDONTWRITEBYTECODE": "1"}
    run = _run_quietly([str(mutmut), "run", "--max-children", str(args.workers)], tree, env)
    listing = subprocess.run([str(mutmut), "results", "--all", "true"], cwd=tree, env=env,
                             capture_output=True, text=True).stdout
    results = parse_results(listing)
    wanted = {module_name(m) for m in modules}
    results = {k: v for k, v in results.items() if mutant_module(k) in wanted}
    survivors = sorted(k for k, v in results.items() if v == "survived")
    print(f"\n{len(survivors)} survivor(s):")
    for name in survivors:
        shown = subprocess.run([str(mutmut), "show", name], cwd=tree, env=env,
                               capture_output=True, text=True).stdout
        print(f"\n--- {name}\n{shown.strip()}")
    print("\nmutation score per module (killed / (killed + survived); other: timeout, "
          "no tests, ...):")
    summary = scores(results)
    for module, (killed, survived, other) in summary.items():
        total = killed + survived
        pct = f"{killed / total:.0%}" if total else "-"
        print(f"  {module}: {killed}/{total} killed ({pct}), {survived} survived, {other} other")
    (scratch / "summary.json").write_text(json.dumps(
        {"base": args.base, "modules": modules, "tests": tests, "survivors": survivors,
         "scores": summary}, indent=2), encoding="utf-8")
    return 0 if run.returncode == 0 else run.returncode


if __name__ == "__main__":
    sys.exit(main())
