"""bench inspect's GT-clock check on the vendored sample's pieces (bench.studies.
inspect_clock_study): no warning on a correct ground truth (as is, jittered, nearest-sampled
from 10 Hz) in any piece; the halves' spread that decided before warned on 5 of 10."""

from bench.studies.inspect_clock_study import study, table


def test_no_false_alarm_on_the_samples_pieces_and_the_table_counts_every_row():
    rows = study()
    correct = [r for r in rows if r["lag"] is None]
    assert len(correct) == 30
    assert not [r for r in correct if r["outcome"] == "warned"], \
        [(r["variant"], r["piece"], r["line"]) for r in correct if r["outcome"] == "warned"]
    # a green "within one scan period" only where the interval says so
    for r in rows:
        if r["outcome"] == "passed":
            assert "95 % block-bootstrap interval" in r["line"], r["line"]
    text = table(rows)
    assert text.count("\n") == 1 + 7 and "| as is | - | 10 |" in text
