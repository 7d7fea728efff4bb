"""Methods against sequences (bench/report/tables/pivot.py): one table per segment length and
one of the times, each cell the main table's own cell (so its mark is the one decided per
sequence there), rows in the paper's order, an empty cell for a run that is not there."""

from __future__ import annotations

from pathlib import Path

from bench.report.tables.model import BEST, SECOND, to_markdown
from bench.report.tables.paper import TIME_NOTE, RunRow, relative_table
from bench.report.tables.pivot import pivot_markdown, pivot_tables
from bench.runs.folders import RunRecord
from bench.runs.result import REPORTED_CLOCK, RelativeError, RunResult, Spread, TimingStats


def _row(label, seq, seed, rot, trans, time, cpu="X", ci=None) -> RunRow:
    result = RunResult(sequence=seq, method="icp", seed=seed, diverged=False,
                       sensor_class="Radar", cpu=cpu, time_ms=TimingStats(mean=time),
                       relative_error=[RelativeError(length_m=8.0, rot_deg_mean=rot,
                                                     trans_m_mean=trans, n=9, rot_deg_mean_ci=ci,
                                                     spread=Spread(n_independent=4))])
    return RunRow(RunRecord(Path("/r") / seq / label, result, {}), label)


def _rows(cpu_b="X", ci=None):
    # "A" runs without seed, "Z" with: with seed comes first whatever the labels say
    return [_row("Z", "s2", True, 1.0, 0.1, 5.0, ci=ci),
            _row("A", "s2", False, 2.0, 0.2, 4.0, ci=ci),
            _row("Z", "s1", True, 3.0, 0.3, 7.0, cpu=cpu_b, ci=ci)]


def test_one_table_per_length_and_one_of_the_times_each_cell_the_main_tables():
    rows = _rows()
    main = relative_table(rows, [8.0])
    tables = pivot_tables(rows, [8.0])
    assert [t.keys for t in tables] == [["8 m"], ["Time (ms)"]]
    for col, t in enumerate(tables):
        assert t.columns == ["s2", "s1"]  # the sequences in the rows' order
        assert [r.keys for r in t.rows] == [["Z"], ["A"]]
        assert t.rows[0].cells[0] == main.rows[0].cells[col]
        assert t.rows[0].cells[1] == main.rows[2].cells[col]
        assert t.rows[1].cells[0] == main.rows[1].cells[col]
        assert t.rows[1].cells[1].status == "" and not t.rows[1].cells[1].parts
        assert t.footnotes == main.footnotes
        assert t.csv_file == ("of the same table without --pivot (bench table --format csv "
                              "prints it)")
    # marked per sequence: on s2 Z's 1.0 bold, A's 2.0 underlined; alone on s1: bold
    assert [p.rank for p in tables[0].rows[0].cells[0].parts] == [BEST, BEST]
    assert [p.rank for p in tables[0].rows[1].cells[0].parts] == [SECOND, SECOND]
    assert [p.rank for p in tables[0].rows[0].cells[1].parts] == [BEST, BEST]
    assert tables[1].rows[1].cells[0].parts[0].rank == BEST  # 4.0 ms before 5.0 ms


def test_the_captions_say_what_a_cell_holds_and_how_it_is_marked():
    length, time = pivot_tables(_rows(), [8.0], marks="value")
    assert length.caption == ("Each cell: mean rotation [deg] / translation [m] relative "
                              "error over 8 m segments. Best value per sequence in bold, "
                              "second underlined (by value alone, the paper's style: "
                              "differences may lie within the noise). Div. = diverged; "
                              "empty = not run.")
    assert time.caption == (TIME_NOTE + " Per sequence the fastest is bold, the second "
                            "underlined (by value: times have no interval); empty = not run.")
    _, mixed = pivot_tables(_rows(cpu_b="Y"), [8.0])
    assert mixed.caption.startswith(TIME_NOTE + " MIXED HOSTS: these times come from runs on "
                                    "different CPUs (X; Y)")


def test_the_intervals_are_printed_with_ci_and_the_markdown_is_every_table():
    rows = _rows(ci=[0.5, 3.5])
    length, _ = pivot_tables(rows, [8.0], ci=True)
    assert length.rows[0].cells[0].parts[0].text == "1.000 [0.500, 3.500]"
    assert "printed 95 % intervals" in length.caption
    plain = pivot_tables(rows, [8.0])
    assert plain[0].rows[0].cells[0].parts[0].text == "1.000"
    assert pivot_markdown(rows, [8.0]) == "\n".join(to_markdown(t) for t in plain)
    assert pivot_markdown(rows, [8.0], ci=True).count("[0.500, 3.500]") == 3


def test_a_failed_run_keeps_its_footnote_in_every_table():
    failed = RunRow(RunRecord(Path("/r/s1/F"), RunResult(
        sequence="s1", method="icp", seed=True, status="failed", error="no points",
        sensor_class="Radar"), {}), "F")
    for t in pivot_tables([*_rows(), failed], [8.0]):
        assert t.footnotes == ["F on s1: failed: no points"]
        cell = t.rows[[r.keys[0] for r in t.rows].index("F")].cells[1]
        assert cell.status == "failed"


def test_rows_in_the_papers_method_order_and_reported_times_left_out_of_the_hosts():
    def run(method, seq, label, cpu="X", clock=None):
        result = RunResult(sequence=seq, method=method, seed=True, diverged=False,
                           sensor_class="Radar", cpu=cpu, clock=clock,
                           time_ms=TimingStats(mean=1.0))
        return RunRow(RunRecord(Path("/r") / seq / label, result, {}), label)

    # ICP point-to-point (a baseline of the paper) before DICP, though "a" < "b"
    rows = [run("dicp", "s1", "a"), run("icp-p2p", "s1", "b"),
            run("vgicp", "s2", "c", cpu="Z", clock=REPORTED_CLOCK)]
    (time,) = pivot_tables(rows, [])
    assert [r.keys[0] for r in time.rows] == ["b", "c", "a"]
    assert "MIXED HOSTS" not in time.caption  # c's time is its method's own, not measured
