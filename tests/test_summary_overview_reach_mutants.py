"""bench/report/summary/overview.py: the cross-dataset summary's caption word for word (a
user reads it under the table: the marking rule, the advice for a class outside the paper's
three) and the same-content note made from the table's own rows. Written for a mutation run
of the module; the marks come from stand-ins, as in tests/test_overview_rules.py."""

from pathlib import Path
from types import SimpleNamespace

from bench.report.summary import overview
from loaders.sensor_classes import SEMI_DENSE_RADAR

CUSTOM = "Custom radar"

CAPTION = (
    "Across datasets, per sensor class: the sequences each method was scored on and its mean "
    "mark over them (the mean rotation and the mean translation relative error at 8 m and "
    "48 m, the shortest and the longest length the runs have; on each figure the mark the "
    "relative-error tables on this page print for it, counted 1 = bold, 2 = underlined, "
    "3 = neither, so the summary follows the tables' one rule; the seed and no-seed rows of a "
    "method count as one, its better mark; figures on fewer than 2 independent segments are "
    "not marked and not counted). Bold: on how many of those figures the method is bold. The "
    "lowest mean mark of a class is bold (by value: a summary, not a test). Failed / "
    "Diverged: runs that did not finish / diverged; Fell back: runs with more than 5 % of "
    "their frames replaced by the motion prior or not converged.")
UNKNOWN = (
    " Custom radar: stores whose loader does not know the sensor's density (NumPy frames, a "
    "ROS bag converted without --model); the same drive converted by its own loader lands in "
    "its paper class (the Oculii Eagle: Semi-Dense 4D Radar), so one drive can appear in two "
    "classes here: convert with --model (e.g. radar-semidense) to rank it in one.")


def _run(seq, cls, method="gicp"):
    result = SimpleNamespace(relative=lambda L: SimpleNamespace(n=5), fell_back=False)
    run = SimpleNamespace(label=None, doppler_kind="ego", config={}, dir=Path("."))
    return SimpleNamespace(sequence=seq, sensor_class=cls, method=method, run=run,
                           result=result, failed=False, diverged=False)


def _summary(monkeypatch, rows):
    noted = []

    def same_content_note(given):
        noted.append(given)
        return f" Sequences holding one content: {' = '.join(r.sequence for r in given)}."

    monkeypatch.setattr(overview, "ranked_lengths", lambda rows: (8.0, 48.0))
    monkeypatch.setattr(overview, "figure_ranks",
                        lambda rows, L, q: {"a": {("gicp", None): 1}})
    monkeypatch.setattr(overview, "counted_as", lambda rows: {r.sequence: r.sequence
                                                              for r in rows})
    monkeypatch.setattr(overview, "same_content_note", same_content_note)
    return overview.summary_table(rows), noted


def test_the_caption_word_for_word_with_an_unknown_class(monkeypatch):
    rows = [_run("a", SEMI_DENSE_RADAR), _run("b", CUSTOM)]
    table, noted = _summary(monkeypatch, rows)
    assert noted == [rows]  # the note is made from the table's rows
    assert table.caption == CAPTION + UNKNOWN + " Sequences holding one content: a = b."


def test_the_caption_of_the_paper_s_classes_only(monkeypatch):
    rows = [_run("a", SEMI_DENSE_RADAR), _run("c", SEMI_DENSE_RADAR)]
    table, _ = _summary(monkeypatch, rows)
    assert table.caption == CAPTION + " Sequences holding one content: a = c."


def test_the_unknown_classes_note_word_for_word():
    assert overview._unknown_classes_note([SEMI_DENSE_RADAR, CUSTOM]) == UNKNOWN
