"""The cross-dataset page's sequences at unit level (bench.report.summary.ranks): sequences under
several names holding one content are counted under the first name and named, group by group,
in the captions. The whole page is in tests/test_report_summary.py."""

from __future__ import annotations

from types import SimpleNamespace

from bench.report.summary.ranks import contender_name, counted_as, same_content_note


def _rows(pairs):
    return [SimpleNamespace(sequence=label, run=SimpleNamespace(config=config))
            for label, config in pairs]


def _cfg(sha):
    return {"identity": {"store_sha256": sha}, "sequence": {"content_sha256": sha}}


def test_names_of_one_content_are_counted_once_and_said_group_by_group():
    rows = _rows([("e", _cfg("y")), ("d", _cfg("y")), ("b", _cfg("x")), ("c", _cfg("y")),
                  ("a", _cfg("x")), ("f", _cfg("z")), ("g", {"sequence": {}})])
    assert counted_as(rows) == {"a": "a", "b": "a", "c": "c", "d": "c", "e": "c", "f": "f",
                                "g": "g"}
    assert same_content_note(rows) == (
        " Sequences holding one content under different names, counted once (as the first): "
        "a = b; c = d = e.")


def test_no_note_when_every_name_holds_its_own_content():
    rows = _rows([("a", _cfg("x")), ("b", _cfg("y")), ("a", _cfg("x"))])
    assert same_content_note(rows) == ""
    assert same_content_note([]) == ""


def test_a_contenders_name_is_its_method_and_label_or_an_external_label_alone():
    from bench.runs.result import EXTERNAL_MARK

    assert contender_name("icp", "") == "icp"
    assert contender_name("icp", "k=3") == "icp [k=3]"
    assert contender_name("kiss", f"kiss-ext{EXTERNAL_MARK}") == f"kiss-ext{EXTERNAL_MARK}"
