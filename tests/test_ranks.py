"""The cross-dataset page's sequences at unit level (bench.report.summary.ranks): sequences under
several names holding one content are counted under the first name and named, group by group,
in the captions. The whole page is in tests/test_report_summary.py."""

from __future__ import annotations

from types import SimpleNamespace

from bench.report.summary.ranks import (
    contender_name,
    counted_as,
    figure_ranks,
    ranked_lengths,
    same_content_note,
)


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


def _rel(rot, trans, n=10, n_independent=10, width=0.1, rot_width=None):
    rw = width if rot_width is None else rot_width
    return SimpleNamespace(n=n, rot_deg_mean=rot, rot_deg_mean_ci=(rot - rw, rot + rw),
                           trans_m_mean=trans, trans_m_mean_ci=(trans - width, trans + width),
                           spread=SimpleNamespace(n_independent=n_independent))


def _run_row(method, rel, sequence="s", label="", failed=False, diverged=False, sha="x",
             lengths=((8.0, 10),)):
    result = SimpleNamespace(relative=lambda length_m: rel,
                             relative_error=[SimpleNamespace(length_m=m, n=n) for m, n in lengths])
    run = SimpleNamespace(config=_cfg(sha), label=label)
    return SimpleNamespace(sequence=sequence, run=run, label=f"{method} {label}", method=method,
                           failed=failed, diverged=diverged, result=result)


def test_figure_ranks_are_the_tables_marks_per_quantity_and_skip_what_is_not_ranked():
    """Marks as numbers, 1 bold, 2 underlined, 3 neither, by the printed intervals: a ranks
    second on rotation (after b's other variant) and last on translation, b the other way;
    d's value lies inside a's interval, so d is marked with a (only because of the
    intervals); rows that failed, diverged, have no segments at the length or too few
    independent ones would each have been bold and are not ranked at all (put first, so that
    one is skipped, not the rest); a second name of one content is counted under the
    first."""
    from metrics.intervals import MIN_INDEPENDENT

    good = _rel(0.1, 0.1)  # the best of every figure, were it ranked
    rows = [_run_row("failed", good, failed=True), _run_row("diverged", good, diverged=True),
            _run_row("none", None), _run_row("empty", _rel(0.1, 0.1, n=0)),
            _run_row("few", _rel(0.1, 0.1, n_independent=MIN_INDEPENDENT - 1)),
            _run_row("a", _rel(1.0, 5.0)), _run_row("b", _rel(2.0, 1.0)),
            _run_row("c", _rel(3.0, 3.0), sequence="t"),  # t holds s's content
            _run_row("d", _rel(1.05, 5.0)),
            _run_row("b", _rel(0.5, 9.0), label="seed")]  # another variant of b
    rot = figure_ranks(rows, 8.0, "rot_deg")
    trans = figure_ranks(rows, 8.0, "trans_m")
    assert rot == {"s": {("a", ""): 2, ("b", ""): 3, ("c", ""): 3, ("d", ""): 2,
                         ("b", "seed"): 1}}
    assert trans == {"s": {("a", ""): 3, ("b", ""): 1, ("c", ""): 2, ("d", ""): 3,
                           ("b", "seed"): 3}}


def test_a_methods_better_row_counts():
    rows = [_run_row("a", _rel(3.0, 1.0)), _run_row("a", _rel(1.0, 1.0)),
            _run_row("b", _rel(2.0, 1.0))]
    assert figure_ranks(rows, 8.0, "rot_deg") == {"s": {("a", ""): 1, ("b", ""): 2}}
    rows = [_run_row("a", _rel(1.0, 1.0)), _run_row("a", _rel(3.0, 1.0)),
            _run_row("b", _rel(2.0, 1.0))]
    assert figure_ranks(rows, 8.0, "rot_deg") == {"s": {("a", ""): 1, ("b", ""): 2}}


def test_the_lengths_ranked_at_are_the_shortest_and_longest_with_segments():
    rows = [_run_row("a", None, lengths=((48.0, 5), (8.0, 3), (100.0, 2), (400.0, 0))),
            _run_row("f", None, failed=True, lengths=((2.0, 9), (800.0, 9)))]
    assert ranked_lengths(rows) == (8.0, 100.0)
    assert ranked_lengths(rows[:1] + [_run_row("b", None, lengths=((8.0, 1),))]) == (8.0, 100.0)
    assert ranked_lengths([_run_row("a", None, lengths=((8.0, 4),))]) == (8.0,)
    assert ranked_lengths([]) == ()


def test_each_quantity_is_marked_by_its_own_interval():
    """Translations 1.00 +- 0.10 and 1.05 +- 0.05: the first's interval reaches the second's
    value, both bold; their rotations, far apart with narrow intervals, are bold and
    underlined - the translation's intervals, not the rotation's, decide its marks."""
    rows = [_run_row("a", _rel(1.0, 1.0, rot_width=0.01)),
            _run_row("b", _rel(5.0, 1.05, width=0.05, rot_width=0.01))]
    assert figure_ranks(rows, 8.0, "trans_m") == {"s": {("a", ""): 1, ("b", ""): 1}}
    assert figure_ranks(rows, 8.0, "rot_deg") == {"s": {("a", ""): 1, ("b", ""): 2}}


def test_a_row_without_a_method_name_is_its_own_contender_by_its_label():
    rows = [_run_row("", _rel(1.0, 1.0)), _run_row("b", _rel(2.0, 1.0))]
    rows[0].label = "external x"
    assert figure_ranks(rows, 8.0, "rot_deg") == {"s": {("external x",): 1, ("b", ""): 2}}
