"""The manual (docs/, mkdocs.yml) and the README: the manual builds with `mkdocs build --strict`
(a broken link or anchor fails it), the generated command reference is not stale, the README's
links resolve, and every `bench COMMAND ... --option` either names is one the command line has.
MkDocs is a dev dependency: the build test fails without it, never skips."""

import re
import shlex
import subprocess
import sys
import unicodedata
from pathlib import Path

from bench.docs_cli import PAGE, command_tree, option_names, render_reference
from conftest import dev_dependency

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"

#: the manual's pages and the README: every text a reader takes commands from
TEXTS = [README, *sorted(DOCS.rglob("*.md"))]

#: tokens that end a command on a line
ENDS = {"|", ">", ">>", "&&", ";", "2>&1", "||"}


def slug(text: str) -> str:
    """A heading's anchor as MkDocs (Python-Markdown's toc) makes it."""
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def split_code(text: str) -> tuple[list[str], str]:
    """(the lines of every fenced code block, the text outside them)."""
    code, prose, fence = [], [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fence = not fence
            continue
        (code if fence else prose).append(line)
    return code, "\n".join(prose)


def headings(path: Path) -> set[str]:
    _, prose = split_code(path.read_text())
    return {slug(m.group(1)) for m in re.finditer(r"^#{1,6} (.*)$", prose, re.M)}


def bench_commands(text: str) -> list[str]:
    """Every ``bench ...`` command line of a markdown text: in code blocks (a line continued
    with a backslash joined, a ``#`` comment cut) and in inline code spans."""
    code, prose = split_code(text)
    found = []
    joined = "\n".join(code).replace("\\\n", " ")
    for line in joined.splitlines():
        line = re.split(r"\s#", line, maxsplit=1)[0]
        for m in re.finditer(r"(?:^|[\s;&|(])bench\s+(.*)", line):
            found.append("bench " + m.group(1))
    for m in re.finditer(r"`([^`]+)`", prose):
        span = " ".join(m.group(1).split())
        if span.startswith("bench ") or span == "bench":
            found.append(span)
    return found


def _placeholder(token: str) -> bool:
    return bool(re.fullmatch(r"[A-Z][A-Z0-9_]*(\.\.\.)?|<[^>]+>|\.\.\.", token))


def check_command(line: str, tree: dict) -> list[str]:
    """What in one ``bench ...`` line the command line does not have (empty when all is there):
    a subcommand name, or an option of the command it reaches. A placeholder in a command's
    place (``bench COMMAND --help``, ``bench convert LOADER``) checks the options against every
    command it stands for."""
    text = line.replace("\\|", "|")
    try:
        tokens = shlex.split(text, comments=False)
    except ValueError:
        tokens = text.split()
    tokens = tokens[1:]  # "bench"
    candidates = [()]  # command paths the line may mean
    positional = False
    problems = []
    for raw in tokens:
        if raw in ENDS:
            break
        token = raw.strip("[](){},;:")
        if not token:
            continue
        if token.startswith("-") and len(token) > 1 and not token[1].isdigit():
            option = token.split("=", 1)[0].rstrip(".:")
            if not any(option in option_names(tree[p]) for p in candidates):
                where = " / ".join(" ".join(("bench", *p)) for p in candidates)
                problems.append(f"{line!r}: {where} has no option {option}")
            continue
        groups = [p for p in candidates if hasattr(tree[p], "list_commands")]
        if positional or not groups or len(candidates) > 1:
            positional = True
            continue
        path = groups[0]
        subs = [p for p in tree if len(p) == len(path) + 1 and p[:len(path)] == path]
        if (*path, token) in tree:
            candidates = [(*path, token)]
        elif _placeholder(token):
            candidates = subs
        else:
            problems.append(f"{line!r}: {' '.join(('bench', *path))} has no command {token!r}")
            break
    return problems


def test_command_reference_is_generated_from_the_cli():
    assert PAGE.exists(), f"{PAGE} missing: run python -m bench.docs_cli (make docs)"
    assert PAGE.read_text() == render_reference(), \
        "docs/reference/commands.md is stale: run python -m bench.docs_cli (make docs)"
    text = PAGE.read_text()
    for path in command_tree():
        assert f"`{' '.join(('bench', *path))}`" in text, path
    assert "`--alignment <str>`" in text and "`bench convert vod`" in text


def test_the_manual_builds_strict(tmp_path):
    """`mkdocs build --strict`: a link to a missing page or anchor, a page left out of the
    navigation, any warning fails it."""
    dev_dependency("mkdocs")
    site = tmp_path / "site"
    out = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f",
                          str(ROOT / "mkdocs.yml"), "-d", str(site)],
                         capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    for page in ("index.html", "datasets/index.html", "metrics/index.html",
                 "reference/commands/index.html", "doppler-ego/index.html"):
        assert (site / page).is_file(), page


def test_the_readme_links_resolve():
    """The README is not built by MkDocs: its links to the manual's pages, their anchors and
    the repository's files are checked here."""
    _, prose = split_code(README.read_text())
    links = re.findall(r"\[[^\]]+\]\(([^)\s]+)\)", prose)
    assert len(links) > 10
    for link in links:
        if link.startswith(("http://", "https://", "mailto:")):
            continue
        path, _, anchor = link.partition("#")
        target = (README.parent / path) if path else README
        assert target.exists(), f"README links to {link}: no such file"
        if anchor:
            assert anchor in headings(target), f"README links to {link}: no such heading"


def test_every_command_and_option_named_exists():
    tree = command_tree()
    problems, seen = [], 0
    for path in TEXTS:
        for line in bench_commands(path.read_text()):
            seen += 1
            problems += [f"{path.relative_to(ROOT)}: {p}" for p in check_command(line, tree)]
    assert seen > 100, seen  # the scan finds the commands at all
    assert problems == [], "\n".join(problems)


def test_the_check_sees_a_wrong_command_or_option():
    tree = command_tree()
    text = ("Run `bench run --method doppler --no-such-flag 3` or\n\n```bash\n"
            "bench tabel results/x   # a typo\nbench convert vod data \\\n    --perio 0.1 "
            "--out x.h5\nbench convert LOADER --help\nbench table results/x -f csv > t.csv\n"
            "```\n")
    lines = bench_commands(text)
    assert len(lines) == 5, lines
    problems = [p for line in lines for p in check_command(line, tree)]
    assert len(problems) == 3, problems
    assert "no option --no-such-flag" in problems[2]
    assert "no command 'tabel'" in problems[0] and "no option --perio" in problems[1]
    # what the command line has passes: flags, their negations, short options, placeholders
    for good in ("bench run --method M --no-seed -p key=value --data X.h5",
                 "bench synth --suite synthetic-clean", "bench COMMAND --help",
                 "bench convert dataset 'NTU4DRadLM_*' --jobs 2",
                 "bench table RESULTS_DIR --format md\\|tex\\|csv [--metric kitti]"):
        assert check_command(good, tree) == [], good


def test_the_manual_has_a_place_for_each_section_to_come():
    """Sections other work fills in: each on the page a reader looks for it."""
    assert "intervals-and-significance-marks" in headings(DOCS / "metrics.md")
    assert "tuning-protocol" in headings(DOCS / "methods.md")
    assert any(h.startswith("scoring-an-external-trajectory") for h in
               headings(DOCS / "results.md"))
    assert "adding-a-table-format" in headings(DOCS / "extending.md")
