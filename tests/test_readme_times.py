"""The README's (and the installing page's) times for `make reproduce-table` and `make test`
state the conditions they were measured under: a date and the machine's load (or that it was
not recorded). "About 7 minutes" alone was 9 min 20 s on a busy machine."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: a duration: "7 minutes", "9 min 20 s", "80 s"
DURATION = re.compile(r"\b\d+(\.\d+)? ?(minutes?|min)\b")
DATE = re.compile(r"\b20\d\d-\d\d-\d\d\b")
LOAD = re.compile(r"load|busy|quiet|other (engineers' )?jobs")


def _clauses(text: str) -> list[str]:
    """The make targets' time statements: the text split at sentences and semicolons outside
    parentheses, the clauses naming `make reproduce-table` or `make test` with a duration."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0 and (text.startswith(". ", i) or ch == ";"):
            out.append(text[start:i])
            start = i + 1
    out.append(text[start:])
    return [c for c in out if DURATION.search(c)
            and ("make reproduce-table" in c or "make test" in c)]


@pytest.mark.parametrize("page", ["README.md", "docs/installing.md"])
def test_every_make_target_time_names_its_date_and_load(page):
    text = " ".join((ROOT / page).read_text().split())
    clauses = _clauses(text)
    assert len(clauses) >= 2, clauses  # reproduce-table and test
    for clause in clauses:
        assert DATE.search(clause) and LOAD.search(clause), clause


def test_the_check_rejects_a_bare_time():
    assert _clauses("`make reproduce-table` takes about 7 minutes.")
    bare = _clauses("`make reproduce-table` takes about 7 minutes.")[0]
    assert not (DATE.search(bare) and LOAD.search(bare))
