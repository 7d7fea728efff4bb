"""The pairwise verdicts across sequences (bench.report.summary.pairwise) on hand-made marks.

The marks per sequence (``figure_ranks``) and which name a sequence is counted under
(``counted_as``) are given by hand, so every count below follows from the module's definition:
on a sequence A is better than B when its mean mark over the figures both are marked on is
lower; over a class, a two-sided exact sign test on the untied sequences, bold when p < 0.05
and A has more wins."""

from __future__ import annotations

import itertools
import math
from types import SimpleNamespace

import pytest

from bench.report.summary import pairwise
from bench.report.summary.pairwise import LEVEL, pairwise_table, sign_test_p, verdicts
from bench.report.tables.model import BEST, OTHER
from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR


def _brute_p(wins: int, losses: int) -> float:
    """Every sequence of n fair coins: the share with a split at least as far from even."""
    n = wins + losses
    if n == 0:
        return 1.0
    far = abs(wins - n / 2)
    hits = sum(abs(sum(c) - n / 2) >= far for c in itertools.product((0, 1), repeat=n))
    return hits / 2 ** n


@pytest.mark.parametrize("wins,losses", [(0, 0), (1, 0), (0, 1), (3, 3), (5, 1), (1, 5),
                                         (6, 0), (0, 6), (4, 2), (7, 1), (2, 9)])
def test_sign_test_is_the_exact_two_sided_binomial(wins, losses):
    p = sign_test_p(wins, losses)
    assert p == pytest.approx(_brute_p(wins, losses), rel=1e-12)
    assert 0.0 < p <= 1.0


def test_six_untied_sequences_all_one_way_is_the_fewest_that_hold():
    # 2 / 2^6 = 0.031 < 0.05; 2 / 2^5 = 0.0625 does not hold, nor does 6 : 1
    assert sign_test_p(6, 0) < LEVEL <= sign_test_p(5, 0)
    assert sign_test_p(6, 1) > LEVEL
    assert LEVEL == pytest.approx(0.05)
    assert sign_test_p(0, 0) == 1.0 and sign_test_p(2, 2) == 1.0


def test_verdicts_compare_mean_marks_on_the_figures_both_are_marked_on():
    a, b, c = ("gicp", None), ("icp-p2p", None), ("vgicp", "v1")
    per_seq = {
        "s1": {a: [1, 1, 1, 1], b: [2, 2, 3, 1]},        # a better (1 < 2)
        "s2": {a: [1, 3, 1, 3], b: [2, 2, 2, 2]},        # means 2 and 2: tie
        "s3": {a: [3, None, 3, None], b: [1, 1, 1, 1]},  # on the first and third: b better
        "s4": {a: [None, 1, None, 1], b: [2, None, 2, None]},  # nothing in common: skipped
        "s5": {a: [1, 1, 1, 1]},                          # b not ranked: skipped
        "s6": {a: [2, 2, 2, 3], b: [2, 2, 2, 2], c: [1, 1, 1, 1]},  # b better by a quarter
    }
    assert verdicts(per_seq, a, b) == (1, 2, 1)
    assert verdicts(per_seq, b, a) == (2, 1, 1)
    assert verdicts(per_seq, c, a) == (1, 0, 0)
    assert verdicts(per_seq, a, a) == (0, 0, 6)  # a with itself: tied on all six
    assert verdicts({}, a, b) == (0, 0, 0)
    # the figures are one list in one order: lists of different lengths are an error
    with pytest.raises(ValueError):
        verdicts({"s": {a: [1, 1], b: [2]}}, a, b)


A, B, V, D = ("gicp", None), ("icp-p2p", None), ("vgicp", "v1"), ("doppler", None)
G = ("gicp", "Abc")  # a labelled variant of gicp: after plain gicp (labels "" first)
LENGTHS = (8.0, 48.0)
FIGS = [(L, q) for L in LENGTHS for q in ("rot_deg", "trans_m")]


def _marks():
    """(length, quantity) -> sequence -> contender -> mark, and each sequence's class."""
    per: dict[str, dict[tuple, list]] = {}
    cls = {}
    # Semi-dense radar: gicp better than icp-p2p on s2..s7 (6 untied), tied on s1 by the mean
    per["s1"] = {A: [1, 3, 1, 3], B: [2, 2, 2, 2]}
    for s in ("s2", "s3", "s4", "s5", "s6", "s7"):
        per[s] = {A: [1, 1, 1, 1], B: [2, 2, 2, 2]}
    # a variant marked on s2's first figure only, there as good as gicp and better than icp-p2p
    per["s2"][V] = [1, None, None, None]
    # the variant alone on a sequence of its own: never ranked together with any other
    per["s8"] = {G: [1, 1, 1, 1]}
    cls.update({s: SEMI_DENSE_RADAR for s in per})
    # Sparse radar (first in the paper's order, though "Semi" sorts before it): two sequences;
    # t1 is not in the last figure at all
    per["t1"] = {B: [1, 1, 1, None], D: [2, 2, 2, None]}
    per["t2"] = {B: [2, 2, 2, 2], D: [1, 1, 1, 1]}
    cls.update({"t1": SPARSE_RADAR, "t2": SPARSE_RADAR})
    # Dense LiDAR: one sequence, no matrix
    per["u1"] = {B: [1, 1, 1, 1], D: [2, 2, 2, 2]}
    cls["u1"] = DENSE_LIDAR
    figures = {}
    for j, fig in enumerate(FIGS):
        figures[fig] = {s: {k: r[j] for k, r in ks.items() if r[j] is not None}
                        for s, ks in per.items()}
        figures[fig] = {s: ks for s, ks in figures[fig].items() if ks}
    return figures, cls


@pytest.fixture
def patched(monkeypatch):
    figures, cls = _marks()
    calls = []

    def figure_ranks(rows_given, length_m, quantity):
        assert rows_given is rows
        calls.append((length_m, quantity))
        return figures.get((length_m, quantity), {})

    # "s7b" is s7 under a second name: one content, counted (and classed) as s7
    rows = [SimpleNamespace(sequence=s, sensor_class=c) for s, c in cls.items()]
    rows.append(SimpleNamespace(sequence="s7b", sensor_class=SEMI_DENSE_RADAR))
    monkeypatch.setattr(pairwise, "figure_ranks", figure_ranks)
    monkeypatch.setattr(pairwise, "counted_as",
                        lambda rows: {r.sequence: ("s7" if r.sequence == "s7b" else r.sequence)
                                      for r in rows})

    def ranked_lengths(rows_given):
        assert rows_given is rows
        return LENGTHS

    def same_content_note(rows_given):
        assert rows_given is rows
        return " Sequences holding one content: s7 = s7b."

    monkeypatch.setattr(pairwise, "ranked_lengths", ranked_lengths)
    monkeypatch.setattr(pairwise, "same_content_note", same_content_note)
    return rows, calls


def test_the_matrix_per_class(patched):
    rows, calls = patched
    table = pairwise_table(rows)
    assert sorted(set(calls)) == sorted(FIGS)
    # classes in the paper's order, one with a single sequence left out
    assert [r.keys[0] for r in table.rows] == [SPARSE_RADAR] * 2 + [SEMI_DENSE_RADAR] * 4
    # by the methods' order, then name, then label (none first)
    assert [r.keys[1] for r in table.rows] == ["icp-p2p", "doppler",
                                              "icp-p2p", "gicp", "gicp [Abc]", "vgicp [v1]"]
    assert all(r.group == (r.keys[0],) for r in table.rows)
    assert [r.meta for r in table.rows][-1] == {"method": "vgicp", "label": "v1"}
    assert table.columns == ["icp-p2p", "doppler", "gicp", "gicp [Abc]", "vgicp [v1]"]
    assert table.keys == ["Sensor class", "Method"]
    col = {name: i for i, name in enumerate(table.columns)}
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}

    def cell(cls, a, b):
        return by[(cls, a)].cells[col[b]]

    # gicp over icp-p2p: better on 6 of 7 (one tie), p = 2/2^6 over the 6 untied: holds
    c = cell(SEMI_DENSE_RADAR, "gicp", "icp-p2p")
    assert (c.values["better"], c.values["worse"], c.values["tied"],
            c.values["sequences"]) == (6, 0, 1, 7)
    assert c.values["p"] == pytest.approx(2 / 64)
    assert c.parts[0].text == "6/7, p 0.031" and c.parts[0].rank == BEST
    # the other way round: the same p, but a loss, never bold
    c = cell(SEMI_DENSE_RADAR, "icp-p2p", "gicp")
    assert (c.values["better"], c.values["worse"], c.values["tied"]) == (0, 6, 1)
    assert c.values["p"] == pytest.approx(2 / 64)
    assert c.parts[0].text == "0/7, p 0.031" and c.parts[0].rank == OTHER
    # the variant, ranked on one sequence and one figure: tied with gicp, better than icp-p2p
    c = cell(SEMI_DENSE_RADAR, "vgicp [v1]", "gicp")
    assert (c.values["better"], c.values["tied"], c.values["sequences"]) == (0, 1, 1)
    assert c.values["p"] == 1.0 and c.parts[0].text == "0/1, p 1"
    c = cell(SEMI_DENSE_RADAR, "vgicp [v1]", "icp-p2p")
    assert (c.values["better"], c.values["worse"], c.values["sequences"]) == (1, 0, 1)
    assert c.parts[0].text == "1/1, p 1" and c.parts[0].rank == OTHER
    # the other way round, after a column it was never ranked with ("gicp [Abc]")
    c = cell(SEMI_DENSE_RADAR, "icp-p2p", "vgicp [v1]")
    assert c.parts[0].text == "0/1, p 1" and c.values["worse"] == 1
    # sparse radar: one each way, t1 ranked on three figures only
    c = cell(SPARSE_RADAR, "doppler", "icp-p2p")
    assert (c.values["better"], c.values["worse"], c.values["sequences"]) == (1, 1, 2)
    assert c.parts[0].text == "1/2, p 1" and c.parts[0].rank == OTHER
    # never ranked together, or a method with itself: "-"
    for cls, a, b in ((SPARSE_RADAR, "doppler", "gicp"), (SPARSE_RADAR, "icp-p2p", "icp-p2p"),
                      (SEMI_DENSE_RADAR, "gicp", "doppler"), (SEMI_DENSE_RADAR, "gicp", "gicp"),
                      (SEMI_DENSE_RADAR, "gicp [Abc]", "icp-p2p"),
                      (SEMI_DENSE_RADAR, "icp-p2p", "gicp [Abc]")):
        assert cell(cls, a, b).status == "-" and not cell(cls, a, b).parts
    assert "at 8 m and 48 m" in table.caption
    # how to read a cell, as the caption says it
    for words in ('the cell of row A and column B reads "k/n, p": A ranks better than B on k '
                  'of the n sequences where both are ranked',
                  "Across sequences, pairwise, per sensor class with two or more sequences",
                  "the lower mean mark, 1 bold, 2 underlined, 3 neither as the tables print it",
                  "equal is a tie), and p is a two-sided exact sign test (binomial, 1/2) over "
                  "the untied sequences, sequences taken as independent.",
                  "sequences taken as independent. Bold: the verdict holds across sequences "
                  "(p < 0.05), which needs at least 6 untied sequences all one way; "
                  '"-": never ranked together.'):
        assert words in table.caption
    assert table.caption.endswith(" Sequences holding one content: s7 = s7b.")


def test_the_lengths_given_replace_the_ranked_ones(patched):
    rows, calls = patched
    table = pairwise_table(rows, (8.0,))
    assert set(calls) == {(8.0, "rot_deg"), (8.0, "trans_m")}
    assert "at 8 m;" in table.caption
    col = {name: i for i, name in enumerate(table.columns)}
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}
    # at 8 m only (the first two figures) s1 is still a tie: gicp (1, 3), icp-p2p (2, 2)
    c = by[(SEMI_DENSE_RADAR, "gicp")].cells[col["icp-p2p"]]
    assert (c.values["better"], c.values["tied"]) == (6, 1)
    empty = pairwise_table(rows, ())
    assert empty.rows == [] and empty.columns == [] and "at no length" in empty.caption


def test_a_class_needs_two_ranked_sequences(patched, monkeypatch):
    rows, _ = patched
    # two semi-dense sequences ranked: a matrix (after a sparse class with one: left out);
    # one: none
    figures, _ = _marks()
    keep = {"t1", "s1", "s2"}
    few = {fig: {s: v for s, v in f.items() if s in keep} for fig, f in figures.items()}
    monkeypatch.setattr(pairwise, "figure_ranks", lambda rows, L, q: few[(L, q)])
    table = pairwise_table(rows)
    assert {r.keys[0] for r in table.rows} == {SEMI_DENSE_RADAR}
    keep = {"s1"}
    few = {fig: {s: v for s, v in f.items() if s in keep} for fig, f in figures.items()}
    assert pairwise_table(rows).rows == []
    assert math.isclose(sign_test_p(1, 0), 1.0)
