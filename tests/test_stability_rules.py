"""The stability count (bench.report.tables.stability) on hand-made tables.

The whole sequence's table and each half's table are given by hand (``half`` and
``relative_table`` patched), so every count follows from the definition: a mark holds when both
halves give it and neither half is blind there; a half is blind where its figure is unmarked
for want of segments or every ranked figure of the column and sequence is bold; otherwise the
mark differs and its cell is flagged."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import pytest

from bench.report.tables import stability as st
from bench.report.tables.model import Cell, Part, Row, Table
from bench.report.tables.significance import BEST, OTHER, SECOND, Stat
from bench.report.tables.stability import CHANGED, Stability, _blind


def _part(rank, rankable=True):
    if rank is None:
        return Part("-", OTHER, None)
    return Part("1.000", rank, Stat(1.0, (0.9, 1.1), 10 if rankable else 1))


def _table(spec, group_of):
    """spec: one list per row of cells, each cell a list of (rank | None, rankable)."""
    rows = []
    for i, cells in enumerate(spec):
        rows.append(Row([f"r{i}"], (group_of[i],),
                        [Cell([_part(r, ok) for r, ok in cell]) for cell in cells]))
    return Table(["Method"], ["8 m"] * len(spec[0]), rows, caption="Caption.")


def test_blind_where_a_half_cannot_tell():
    t = _table([[[(BEST, True), (BEST, True)]],
                [[(SECOND, True), (BEST, True)]],
                [[(BEST, True)]],                 # one part only
                [[(None, True), (OTHER, False)]]],  # no figure; an unrankable one
               ["d", "d", "d", "e"])
    assert not _blind(t, 0, 0, 0)      # bold and underlined: it tells
    assert not _blind(t, 1, 0, 0)
    assert _blind(t, 0, 0, 1)          # both ranked figures bold: it cannot tell
    assert _blind(t, 1, 0, 1)
    assert _blind(t, 2, 0, 1)          # no such part
    assert _blind(t, 3, 0, 0)          # no figure
    assert _blind(t, 3, 0, 1)          # on too few segments
    # the only ranked figure of its group: cannot tell (another group's do not count)
    t = _table([[[(BEST, True)]], [[(SECOND, True)]], [[(OTHER, False)]]], ["d", "e", "d"])
    assert _blind(t, 0, 0, 0) and _blind(t, 1, 0, 0)
    # peers with fewer parts are left out
    t = _table([[[(BEST, True), (BEST, True)]], [[(SECOND, True)]]], ["d", "d"])
    assert _blind(t, 0, 0, 1) and not _blind(t, 0, 0, 0)


@pytest.fixture
def halves(monkeypatch):
    """Patch ``half`` and ``relative_table``: the halves' tables are ``made[0]``, ``made[1]``."""
    made = {}
    seen = []

    def relative_table(rows, lengths, marks):
        seen.append((lengths, marks))
        whichs = {w for w, _ in rows}
        assert len(whichs) == 1
        return made[whichs.pop()]

    monkeypatch.setattr(st, "half", lambda rr, w, lengths: (w, rr))
    monkeypatch.setattr(st, "relative_table", relative_table)
    return made, seen


def test_hold_differ_and_cannot_tell(halves):
    made, seen = halves
    groups = ["d", "d", "d", "s", "s"]
    rows = [SimpleNamespace(sequence=g) for g in groups]
    # one column, two parts (rotation, translation)
    whole = _table([[[(BEST, True), (BEST, True)]],
                    [[(SECOND, True), (SECOND, True)]],
                    [[(OTHER, True), (BEST, True)]],
                    [[(BEST, True), (OTHER, True)]],
                    [[(SECOND, True), (OTHER, True)]]], groups)
    made[0] = _table([[[(BEST, True), (BEST, True)]],
                      [[(SECOND, True), (BEST, True)]],
                      [[(OTHER, True), (BEST, True)]],
                      [[(BEST, True), (None, True)]],
                      [[(SECOND, True), (None, True)]]], groups)
    made[1] = _table([[[(BEST, True), (BEST, True)]],
                      [[(SECOND, True), (SECOND, True)]],
                      [[(BEST, True), (BEST, True)]],  # an unmarked figure turns bold
                      [[(BEST, True), (None, True)]],
                      [[(SECOND, True), (None, True)]]], groups)
    found = st.stability(rows, [8.0], whole, "value")
    assert seen == [([8.0], "value")] * 2
    # "d": rotation of r0, r1 hold (both halves agree, both tell); translation: half 0 marks
    # every figure bold there (blind), so r0, r1, r2's translation marks cannot be told;
    # r2's rotation (not marked on the whole) differs on half 1 and is flagged
    assert found.held["d"] == (2, 5, 3)
    # "s": both rotation marks hold; the translations are unmarked and stay so
    assert found.held["s"] == (2, 2, 0)
    assert found.changed == {(2, 0, 0)}
    assert found.text().startswith("Stability (")
    assert "d: 2 hold, 0 differ, 3 cannot tell (of 5); s: 2 hold, 0 differ, 0 cannot tell " \
           "(of 2)." in found.text()


def test_a_mark_that_flips_differs(halves):
    made, _ = halves
    groups = ["d", "d"]
    rows = [SimpleNamespace(sequence="d")] * 2
    whole = _table([[[(BEST, True)], [(BEST, True)]], [[(SECOND, True)], [(SECOND, True)]]],
                   groups)
    made[0] = _table([[[(BEST, True)], [(BEST, True)]], [[(SECOND, True)], [(SECOND, True)]]],
                     groups)
    # half 1: the first column flips, the second column's first figure has no part there
    made[1] = _table([[[(SECOND, True)], []], [[(BEST, True)], [(SECOND, True)]]], groups)
    found = st.stability(rows, [8.0, 48.0], whole)
    assert found.changed == {(0, 0, 0), (1, 0, 0)}
    # column 2: r0's part is missing on half 1 (blind), r1's is then the only ranked: blind
    assert found.held == {"d": (0, 4, 2)}
    assert "d: 0 hold, 2 differ, 2 cannot tell (of 4)" in found.text()


def test_text_and_flags():
    assert "of its marks: none." in Stability({}, set()).text()
    assert f"{CHANGED} = a cell whose mark differs" in Stability({}, set()).text()
    assert CHANGED == "\u2020"


def test_with_stability_flags_the_cells_and_says_it(monkeypatch):
    table = _table([[[(BEST, True), (BEST, True)]], [[(SECOND, True), (SECOND, True)]]],
                   ["d", "d"])
    found = Stability({"d": (3, 4, 0)}, {(1, 0, 1)})
    got = []
    monkeypatch.setattr(st, "stability", lambda *a: got.append(a) or found)
    assert st.with_stability(["x"], [8.0], table, "value") is found
    assert got == [(["x"], [8.0], table, "value")]
    texts = [[p.text for p in r.cells[0].parts] for r in table.rows]
    assert texts == [["1.000", "1.000"], ["1.000", f"1.000 {CHANGED}"]]
    assert table.caption == "Caption. " + found.text()
    assert "d: 3 hold, 1 differ, 0 cannot tell (of 4)" in table.caption


def test_half_leaves_runs_without_halves_alone():
    for failed, diverged, has_gt in ((True, False, True), (False, True, True),
                                     (False, False, False)):
        rr = SimpleNamespace(failed=failed, diverged=diverged, run=SimpleNamespace(has_gt=has_gt))
        assert st.half(rr, 0, [8.0]) is rr and st.half(rr, 1, [8.0]) is rr


def test_the_caption_says_the_rule():
    text = Stability({"d": (1, 2, 0)}, set()).text()
    assert "A mark holds when both halves give it and each could have told otherwise" in text
    assert "cannot tell where its figure rests on fewer than 2 independent segments or " \
           "every figure of its column is bold" in text
    assert text.endswith(f"{CHANGED} = a cell whose mark differs on a half.")


def test_rows_and_table_must_match(halves):
    made, _ = halves
    whole = _table([[[(BEST, True)]], [[(SECOND, True)]]], ["d", "d"])
    made[0] = made[1] = whole
    with pytest.raises(ValueError):
        st.stability([SimpleNamespace(sequence="d")], [8.0], whole)


@dataclasses.dataclass
class _Run:
    gt: object
    est: object
    result: object
    has_gt: bool = True


class _Result:
    finished, diverged = True, False

    def model_copy(self, update):
        return SimpleNamespace(**update)


def test_half_scores_each_half_at_the_lengths_asked():
    from bench.report.tables.paper import RunRow
    from bench.runs.evaluate import relative_part
    from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
    from metrics import relative_errors

    gt = ground_truth(301)
    est = noisy_estimate(gt, NoiseModel(), seed=4)
    rr = RunRow(_Run(gt, est, _Result()), "row")
    for which, part in ((0, slice(0, 150)), (1, slice(150, 301))):
        h = st.half(rr, which, [5.0, 20.0])
        assert h.label == "row" and h.run.gt is gt
        figures = h.result.relative_error
        ref = relative_part(gt[part], est[part], relative_errors(gt[part], est[part],
                                                                 [5.0, 20.0]))
        assert [f.length_m for f in figures] == [5.0, 20.0] == [f.length_m for f in ref]
        for f, g in zip(figures, ref, strict=True):
            assert f.n == g.n
            assert f.rot_deg_mean == pytest.approx(g.rot_deg_mean, rel=1e-12)
    # a half too short for any segment: no figure
    short = RunRow(_Run(gt[:6], est[:6], _Result()), "row")
    assert st.half(short, 0, [50.0]).result.relative_error == []
