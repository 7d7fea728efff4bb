"""The per-run tables (bench/report/tables/paper.py: Table III, KITTI drift, ego velocity) on
runs made in memory: every cell's text and values, its mark against the interval printed
beside it, the rows that are not ranked (diverged, failed, a time the method reported), the
footnotes and the caption's clauses. Expected texts are written out by hand."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import pytest

from bench.report.names import SEED_NOTE, run_label
from bench.report.tables.model import BEST, OTHER, RULE, RULE_UNPRINTED, SECOND, to_markdown
from bench.report.tables.paper import (
    FAILED_NOTE,
    REPORTED_NOTE,
    TIME_NOTE,
    RunRow,
    build,
    fmt_time,
    kitti_segments_text,
    kitti_table,
    relative_table,
    runs,
    scored_lengths,
    select,
    stat_part,
    velocity_table,
    write_tables,
)
from bench.runs.folders import RunRecord
from bench.runs.result import (
    REPORTED_CLOCK,
    KittiLength,
    KittiResult,
    RelativeError,
    RunResult,
    Spread,
    TimingStats,
    VelocityResult,
)


def rel(length, rot, trans, rot_ci=None, trans_ci=None, n=10, n_ind=5):
    return RelativeError(length_m=length, rot_deg_mean=rot, trans_m_mean=trans, n=n,
                         rot_deg_mean_ci=rot_ci, trans_m_mean_ci=trans_ci,
                         spread=Spread(n_independent=n_ind))


def record(method="icp", seq="s1", seed=True, *, sensor="Radar", config=None, folder=None,
           **fields) -> RunRecord:
    fields.setdefault("diverged", False)
    result = RunResult(sequence=seq, method=method, seed=seed, sensor_class=sensor, **fields)
    return RunRecord(Path("/results") / seq / (folder or method), result, config or {})


def row(rec: RunRecord, label: str | None = None) -> RunRow:
    return RunRow(rec, label or rec.method)


def ranks(table, col, part=0):
    return [r.cells[col].parts[part].rank if r.cells[col].parts else None for r in table.rows]


def texts(table, col):
    return [" / ".join(p.text for p in r.cells[col].parts) if r.cells[col].status is None
            else r.cells[col].status for r in table.rows]


# ---- Table III ----------------------------------------------------------------------------

def _relative_rows() -> list[RunRow]:
    return [
        row(record("a", relative_error=[rel(8, 1.0, 0.10, [0.9, 1.1], [0.09, 0.11])],
                   time_ms=TimingStats(mean=5.0), cpu="X")),
        row(record("b", relative_error=[rel(8, 2.0, 0.05, [1.9, 2.1], [0.04, 0.06])],
                   time_ms=TimingStats(mean=3.0), cpu="X")),
        row(record("c", diverged=True, relative_error=[rel(8, 0.5, 0.01, [0.4, 0.6],
                                                           [0.0, 0.02])],
                   time_ms=TimingStats(mean=1.0), cpu="X")),
        row(record("d", relative_error=[rel(8, 3.0, 0.30, [2.9, 3.1], [0.2, 0.4])],
                   time_ms=TimingStats(mean=2.0), clock=REPORTED_CLOCK)),
        row(record("e", seq="s2", relative_error=[rel(8, 9.0, 0.9, [8.0, 10.0], [0.8, 1.0])],
                   time_ms=TimingStats(mean=50.0), cpu="Y")),
    ]


def test_table_three_cells_marks_and_unranked_rows():
    t = relative_table(_relative_rows(), [8.0, 16.0])
    assert t.keys == ["Sensor", "Sequence", "Method"]
    assert t.columns == ["8 m", "16 m", "Time (ms)"]
    assert [r.keys for r in t.rows] == [["Radar", "s1", m] for m in "abcd"] + \
        [["Radar", "s2", "e"]]
    assert [r.group for r in t.rows] == [("Radar", "s1")] * 4 + [("Radar", "s2")]
    assert texts(t, 0) == ["1.000 / 0.100", "2.000 / 0.050", "Div.", "3.000 / 0.300",
                           "9.000 / 0.900"]
    # rotation: U = 1.1 -> a bold; then U = 2.1 -> b underlined (d's 3.0 above it)
    assert ranks(t, 0, 0) == [BEST, SECOND, None, OTHER, BEST]
    # translation: U = 0.06 -> b bold; then U = 0.11 -> a underlined
    assert ranks(t, 0, 1) == [SECOND, BEST, None, OTHER, BEST]
    assert texts(t, 1) == ["- / -", "- / -", "Div.", "- / -", "- / -"]
    assert ranks(t, 1, 0) == [OTHER, OTHER, None, OTHER, OTHER]
    # times: shown for all; the diverged run's and the reported one not ranked
    assert texts(t, 2) == ["5.00", "3.00", "1.00", "2.00 [reported]", "50.0"]
    assert ranks(t, 2) == [SECOND, BEST, OTHER, OTHER, BEST]
    assert t.rows[0].cells[0].values == {
        "rot_deg_mean": 1.0, "trans_m_mean": 0.1, "segments": 10, "independent_segments": 5,
        "rot_deg_mean_ci_low": 0.9, "rot_deg_mean_ci_high": 1.1,
        "trans_m_mean_ci_low": 0.09, "trans_m_mean_ci_high": 0.11}
    assert t.rows[2].cells[0].values["rot_deg_mean"] == 0.5  # a diverged run's values kept
    assert t.rows[0].cells[1].values == {
        "rot_deg_mean": None, "trans_m_mean": None, "segments": 0,
        "independent_segments": None, "rot_deg_mean_ci_low": None,
        "rot_deg_mean_ci_high": None, "trans_m_mean_ci_low": None,
        "trans_m_mean_ci_high": None}
    assert t.rows[0].cells[2].values == {"time_ms_mean": 5.0}
    assert [r.meta["status"] for r in t.rows] == ["done", "done", "diverged", "done", "done"]
    assert t.rows[0].meta == {"sequence": "s1", "sensor_class": "Radar", "method": "a",
                              "seed": "with", "label": None, "status": "done"}


def test_table_three_prints_the_intervals_with_ci_and_its_caption_says_what_is_shown():
    rows = _relative_rows()
    t = relative_table(rows, [8.0], ci=True)
    assert texts(t, 0)[0] == "1.000 [0.900, 1.100] / 0.100 [0.090, 0.110]"
    assert REPORTED_NOTE in t.caption and TIME_NOTE in t.caption
    assert "Times have no interval: marked by value." in t.caption
    assert ("[low, high] = the 95 % confidence interval (block bootstrap along the "
            "trajectory; docs/metrics.md). ") in t.caption
    # e ran on another CPU (d's time, reported by its method, is no harness time)
    assert "MIXED HOSTS: these times come from runs on different CPUs (X; Y)" in t.caption
    assert "printed 95 % intervals" in t.caption
    plain = relative_table(rows[:3], [8.0])
    assert REPORTED_NOTE not in plain.caption and "[low, high]" not in plain.caption
    assert "MIXED HOSTS" not in plain.caption and "does not print" in plain.caption


def test_the_value_rule_marks_by_value_alone():
    rows = _relative_rows()
    t = relative_table(rows, [8.0], marks="value")
    assert ranks(t, 0, 0) == [BEST, SECOND, None, OTHER, BEST]
    assert ranks(t, 0, 1) == [SECOND, BEST, None, OTHER, BEST]
    assert "by value alone" in t.caption


def test_a_figure_on_one_segment_says_so_and_is_not_marked():
    rows = [row(record("a", relative_error=[rel(8, 1.0, 0.1, [0.9, 1.1], [0.0, 0.2],
                                                n_ind=1)])),
            row(record("b", relative_error=[rel(8, 2.0, 0.2, [1.9, 2.1], [0.1, 0.3])]))]
    t = relative_table(rows, [8.0])
    assert texts(t, 0) == ["1.000 (1 segment) / 0.100 (1 segment)", "2.000 / 0.200"]
    assert ranks(t, 0, 0) == [OTHER, BEST]


def test_a_failed_run_is_a_failed_row_with_its_reason_once():
    rows = [row(record("a", relative_error=[rel(8, 1.0, 0.1)], time_ms=TimingStats(mean=4))),
            row(record("b", status="timeout", error="ran out of time\nafter 3 s",
                       diverged=None), "B")]
    t = relative_table(rows, [8.0])
    assert [c.status for c in t.rows[1].cells] == ["failed", "failed"]
    assert [c.note for c in t.rows[1].cells] == [1, None]
    assert t.footnotes == ["B on s1: timeout: ran out of time"]
    assert t.rows[1].meta["status"] == "timeout"
    assert t.rows[0].cells[0].parts[0].rank == BEST and t.rows[0].cells[1].parts[0].rank == BEST
    assert FAILED_NOTE in t.caption
    assert FAILED_NOTE not in relative_table(rows[:1], [8.0]).caption
    no_reason = relative_table([row(record("c", status="killed", diverged=None), "C")], [8.0])
    assert no_reason.footnotes == ["C on s1: killed: killed"]


def test_a_run_that_fell_back_says_how_many_and_is_flagged_above_the_limit():
    few = record("a", frames=101, frames_replaced=5, relative_error=[rel(8, 1.0, 0.1)])
    many = record("b", seed=False, frames=101, frames_replaced=6, frames_unconverged=1,
                  relative_error=[rel(8, 1.0, 0.1)])
    t = relative_table([row(few, "A"), row(many, "B")], [8.0])
    assert [r.keys[-1] for r in t.rows] == ["A", "B [fell back]"]
    assert t.footnotes == [
        "A on s1: 5 of 100 frames replaced by the motion prior (no usable registration)",
        "B on s1: 6 of 100 frames replaced by the identity (no usable registration); "
        "1 of 100 frames not converged (last iterate kept)"]
    assert [c.note for c in t.rows[1].cells] == [2, None]
    assert ("[fell back] = more than 5 % of the run's frames were replaced by the motion "
            "prior or did not converge (counts in the footnotes). ") in t.caption
    assert "[fell back] =" not in relative_table([row(few, "A")], [8.0]).caption


def test_times_are_printed_by_size_and_threads():
    assert fmt_time(None) == "-" and fmt_time(float("nan")) == "-"
    assert fmt_time(9.994) == "9.99" and fmt_time(10.0) == "10.0" and fmt_time(12.34) == "12.3"
    assert fmt_time(1.5, threads=2) == "1.50 [2 thr.]" and fmt_time(None, 4) == "- [4 thr.]"
    t = relative_table([row(record("a", threads=3, time_ms=TimingStats(mean=7.0))),
                        row(record("b", clock=REPORTED_CLOCK))], [])
    assert texts(t, 0) == ["7.00 [3 thr.]", "-"]


def test_stat_part_keeps_the_interval_its_mark_reads():
    p = stat_part(1.23456, [1.0, 2.0], 4, digits=2, show_ci=True)
    assert p.text == "1.23 [1.00, 2.00]" and p.rank == OTHER
    assert (p.stat.value, p.stat.ci, p.stat.n_independent, p.stat.digits) == \
        (1.23456, (1.0, 2.0), 4, 2)
    none = stat_part(None, [None, None], None)
    assert none.text == "-" and none.stat.ci is None and not none.stat.rankable


def test_the_caption_states_a_level_other_than_95():
    t = relative_table([row(record("a", ci_level=0.9, relative_error=[rel(8, 1, 0.1)]))],
                       [8.0], ci=True)
    assert "[low, high] = the 90 % confidence interval" in t.caption
    failed_first = relative_table([row(record("f", status="failed", diverged=None)),
                                   row(record("a", ci_level=0.9))], [], ci=True)
    assert "the 90 % confidence interval" in failed_first.caption


# ---- KITTI --------------------------------------------------------------------------------

def kitti(lengths, per_length, trans=None, rot=None, n=0, n_ind=None, trans_ci=None,
          rot_ci=None):
    return KittiResult(lengths_m=lengths, per_length=[KittiLength(length_m=L, n=k)
                                                      for L, k in per_length],
                       trans_pct=trans, rot_deg_per_100m=rot, n=n, trans_pct_ci=trans_ci,
                       rot_deg_per_100m_ci=rot_ci, spread=Spread(n_independent=n_ind))


def test_kitti_segments_are_counted_per_length_with_the_odd_sequences_named():
    rows = [row(record("a", seq="s1", kitti=kitti([100, 200, 300], [(100, 4), (200, 0)]))),
            row(record("a", seq="s2", kitti=kitti([100, 200, 300], [(100, 4)]))),
            row(record("a", seq="s3", kitti=kitti([100, 200, 300], [(100, 1)]))),
            row(record("f", seq="s4", status="failed", diverged=None))]
    assert kitti_segments_text(rows) == ("segments of 100 m (4 segments per sequence; s3: 1); "
                                         "none of 200-300 m (the paths are shorter)")
    rows = [row(record("a", kitti=kitti([100, 200], [(100, 1), (200, 2)]))),
            row(record("b", seq="s2", kitti=kitti([100, 200, 400], [(100, 1)])))]
    assert kitti_segments_text(rows) == ("segments of 100 m (1 segment per sequence), "
                                         "200 m (2 segments per sequence); none of 400 m "
                                         "(the paths are shorter)")
    assert kitti_segments_text([row(record("a", kitti=kitti([100], [(100, 0)])))]) == \
        "no KITTI segment: every path is shorter than the shortest length"
    assert kitti_segments_text([]) == \
        "no KITTI segment: every path is shorter than the shortest length"


def test_kitti_table_cells_marks_and_segment_counts():
    rows = [row(record("a", kitti=kitti([100], [(100, 6)], 1.234, 0.5, 6, 3, [1.0, 1.5],
                                        [0.4, 0.6]))),
            row(record("b", kitti=kitti([100], [(100, 6)], 0.9, 0.7, 6, 3, [0.8, 1.1],
                                        [0.65, 0.75]))),
            row(record("c", diverged=True, kitti=kitti([100], [(100, 6)], 0.1, 0.1, 6))),
            row(record("d"))]
    t = kitti_table(rows, ci=True)
    assert t.columns == ["Trans. drift (%)", "Rot. drift (deg/100 m)", "Segments (independent)"]
    assert texts(t, 0) == ["1.23 [1.00, 1.50]", "0.90 [0.80, 1.10]", "Div.", "-"]
    assert texts(t, 1) == ["0.50 [0.40, 0.60]", "0.70 [0.65, 0.75]", "Div.", "-"]
    assert texts(t, 2) == ["6 (3)", "6 (3)", "6", "0"]
    # translation: U = 1.10 -> b bold, then a; rotation: U = 0.60 -> a bold, then b
    assert ranks(t, 0) == [SECOND, BEST, None, OTHER]
    assert ranks(t, 1) == [BEST, SECOND, None, OTHER]
    assert ranks(t, 2) == [OTHER] * 4  # the counts are not ranked
    assert t.rows[0].cells[0].values == {"trans_pct": 1.234, "trans_pct_ci_low": 1.0,
                                         "trans_pct_ci_high": 1.5}
    assert t.rows[0].cells[1].values == {"rot_deg_per_100m": 0.5,
                                         "rot_deg_per_100m_ci_low": 0.4,
                                         "rot_deg_per_100m_ci_high": 0.6}
    assert t.rows[2].cells[0].values == {"trans_pct": 0.1, "rot_deg_per_100m": 0.1}
    assert t.rows[0].cells[2].values == {"segments": 6, "independent_segments": 3}
    assert t.rows[3].cells[0].values == {"trans_pct": None, "trans_pct_ci_low": None,
                                         "trans_pct_ci_high": None}
    assert "KITTI drift over segments of 100 m (6 segments per sequence)" in t.caption


# ---- ego velocity -------------------------------------------------------------------------

def velocity(axes, mean, rmse, ci=None, window=0.5, n_ind=4):
    return VelocityResult(window_s=window, axis_mean_mps=axes, norm_mean_mps=mean,
                          norm_rmse_mps=rmse, norm_mean_mps_ci=ci,
                          spread=Spread(n_independent=n_ind))


def test_velocity_table_rows_cells_and_the_doppler_row():
    rows = [row(record("a", label="v1", velocity=velocity([0.1, 0.2, 0.3], 0.4, 0.5,
                                                          [0.3, 0.45]),
                       velocity_own=velocity([0.01, 0.02, 0.03], 0.04, 0.05, [0.03, 0.05],
                                             window=0.25)), "A"),
            row(record("b", velocity=velocity([0.2, 0.1, 0.4], 0.6, 0.4, [0.5, 0.7],
                                              window=1.0))),
            row(record("c", diverged=True, velocity=velocity([0, 0, 0], 0, 0))),
            row(record("d"))]
    t = velocity_table(rows)
    assert t.columns == ["x (m/s)", "y (m/s)", "z (m/s)", "Norm mean (m/s)", "Norm RMSE (m/s)"]
    assert [r.keys[-1] for r in t.rows] == ["A", "A [Doppler ego velocity]", "b", "c", "d"]
    assert t.rows[1].meta["status"] == "doppler"
    assert t.rows[1].meta["label"] == "v1 [Doppler ego velocity]"
    assert t.rows[0].meta["label"] == "v1" and t.rows[0].meta["status"] == "done"
    assert [texts(t, c)[1] for c in range(5)] == ["0.010", "0.020", "0.030", "0.040", "0.050"]
    assert texts(t, 0)[2:] == ["0.200", "Div.", "-"]
    assert [r.cells[4].status for r in t.rows[3:]] == ["Div.", "-"]
    # the Doppler row is ranked with the others (one group: s1)
    assert ranks(t, 0) == [SECOND, BEST, OTHER, None, None]
    assert ranks(t, 3) == [SECOND, BEST, OTHER, None, None]
    assert t.rows[0].cells[3].values == {"norm_mean_mps": 0.4, "norm_mean_mps_ci_low": 0.3,
                                         "norm_mean_mps_ci_high": 0.45}
    assert t.rows[0].cells[0].values == {"x_mean_mps": 0.1}
    assert t.rows[0].cells[4].values == {"norm_rmse_mps": 0.5}
    # the windows of the trajectory rows named (the Doppler row's own is not one of them)
    assert "at least 0.5, 1 s later" in t.caption
    assert "Only the norm mean has an interval" in t.caption


def test_velocity_caption_names_the_default_window_without_any_velocity():
    from metrics.velocity import DEFAULT_WINDOW_S

    t = velocity_table([row(record("a"))])
    assert f"at least {DEFAULT_WINDOW_S:g} s later" in t.caption
    failed = velocity_table([row(record("f", status="failed", diverged=None,
                                        velocity_own=velocity([0, 0, 0], 0, 0)))])
    assert len(failed.rows) == 1 and failed.rows[0].cells[0].status == "failed"


def test_build_picks_the_metrics_table_and_the_scored_lengths():
    rows = [row(record("a", relative_error=[rel(16, 1, 0.1), rel(8, 2, 0.2)])),
            row(record("b", relative_error=[rel(8, 3, 0.3), rel(24, 1, 0.1)]))]
    assert scored_lengths(rows) == [8.0, 16.0, 24.0]
    assert build("relative", rows).columns == ["8 m", "16 m", "24 m", "Time (ms)"]
    assert build("relative", rows, [16.0]).columns == ["16 m", "Time (ms)"]
    assert build("kitti", rows).columns[0] == "Trans. drift (%)"
    assert build("velocity", rows, marks="value").columns[0] == "x (m/s)"
    assert texts(build("relative", rows, [16.0], ci=True), 0)[0] == "1.000 / 0.100"


def test_row_order_is_the_papers():
    rows = [row(record("dicp", seq="Loop1_0", seed=False), "z"),
            row(record("dicp", seq="Loop1_0", seed=True), "z"),
            row(record("icp-p2p", seq="Loop1_0", seed=True), "z"),
            row(record("dicp", seq="Campus1", seed=True), "z")]
    order = sorted(rows, key=RunRow.order)
    assert [(r.sequence, r.method, r.seed.option) for r in order] == [
        ("Campus1", "dicp", True), ("Loop1_0", "icp-p2p", True), ("Loop1_0", "dicp", True),
        ("Loop1_0", "dicp", False)]
    assert rows[0].is_variant is False
    assert RunRow(record("a", label="x"), "x").is_variant is True


# ---- from run folders ---------------------------------------------------------------------

def _write(folder: Path, config: dict | None = None, **fields) -> None:
    folder.mkdir(parents=True)
    fields.setdefault("diverged", False)
    fields.setdefault("sequence", folder.parent.name)
    (folder / "metrics.json").write_text(RunResult(**fields).dump())
    if config is not None:
        (folder / "config.yaml").write_text(json.dumps(config))  # JSON is YAML


@pytest.fixture
def results(tmp_path):
    root = tmp_path / "res"
    _write(root / "s1" / "icp_seed", {"alignment": "se3"}, method="icp", seed=True,
           relative_error=[rel(8, 1.0, 0.1, [0.9, 1.1], [0.09, 0.11])],
           time_ms=TimingStats(mean=3.0))
    _write(root / "s1" / "icp_seed_2", {"alignment": "sim3"}, method="icp", seed=True,
           relative_error=[rel(8, 2.0, 0.2), rel(16, 2.0, 0.2)])
    _write(root / "s1" / "gicp", method="gicp", seed=None)  # no ground truth: left out
    (root / "s2" / "dicp_seed").mkdir(parents=True)
    (root / "s2" / "dicp_seed" / "failed.json").write_text(
        json.dumps({"status": "failed", "error": "no points"}))
    return root


def test_runs_read_from_folders_keep_failed_runs_and_tell_clashing_labels_apart(results):
    got = runs(results)
    assert [r.sequence for r in got] == ["s1", "s1", "s2"]
    assert [r.failed for r in got] == [False, False, True]
    assert [r.label for r in got] == [f"{run_label('icp', True)} [alignment=se3]",
                                      f"{run_label('icp', True)} [alignment=sim3]",
                                      run_label("dicp", True)]
    two = runs([results, results])
    assert len(two) == 6 and all(r.label.startswith("res: ") for r in two)


def test_select_filters_and_refuses_what_is_missing(results):
    rows, lengths = select(results)
    assert lengths == [8.0, 16.0] and len(rows) == 3
    rows, lengths = select(results, lengths_m=[16.0])
    assert lengths == [16.0]
    rows, _ = select([results], keep=lambda r: not r.failed)
    assert len(rows) == 2
    with pytest.raises(ValueError) as err:
        select(results, keep=lambda r: False)
    assert str(err.value) == f"{results}: no run matches the chosen methods / variants"
    with pytest.raises(ValueError) as err:
        select(results, lengths_m=[8.0, 32.0, 64.5])
    assert str(err.value) == (
        f"{results}: no results at 32, 64.5 m (scored lengths: 8, 16); score them with "
        "`bench run --lengths 8,16,32,64.5` (an experiment's lengths_m); KITTI drift over "
        "100-800 m: `bench table --metric kitti`")
    with pytest.raises(FileNotFoundError) as err:
        select(results.parent / "empty")
    assert str(err.value) == (f"{results.parent / 'empty'}: no finished runs with ground "
                              "truth (no metrics.json found)")


def test_write_tables_writes_the_three_formats_beside_the_results(results, tmp_path):
    out = tmp_path / "tables"
    texts_ = write_tables(results, out, stem="t3", lengths_m=[8.0])
    for fmt in ("md", "tex", "csv"):
        assert (out / f"t3.{fmt}").read_text() == texts_[fmt]
    lines = list(csv.DictReader(io.StringIO(texts_["csv"])))
    assert {x["column"] for x in lines} == {"8 m", "Time (ms)"}
    assert to_markdown(build("relative", *select(results, lengths_m=[8.0]))) != ""
    default = write_tables([results], metric="kitti", marks="value", ci=True)
    assert (results / "table.md").read_text() == default["md"]
    assert "Trans. drift (%)" in default["md"] and "by value alone" in default["md"]


# ---- survivors of make mutate: the exact captions and keys, what ``ci`` / ``marks`` reach ----

def test_table_three_caption_written_out():
    t = relative_table([row(record("a", relative_error=[rel(8, 1.0, 0.1)]))], [8.0])
    assert t.caption == (
        "Each cell: mean rotation [deg] / translation [m] relative error over the segments of "
        "each length (evo_rpe's definition). " + TIME_NOTE + " Times have no interval: marked "
        "by value. " + RULE_UNPRINTED + " Div. = diverged; " + SEED_NOTE)
    reported = relative_table([row(record("a", clock=REPORTED_CLOCK))], [])
    assert reported.caption.startswith(
        "Each cell: mean rotation [deg] / translation [m] relative error over the segments of "
        "each length (evo_rpe's definition). " + TIME_NOTE + " Times have no interval: marked "
        "by value. " + REPORTED_NOTE + " " + RULE_UNPRINTED)


def test_a_table_of_failed_runs_states_the_default_level():
    t = relative_table([row(record("f", status="failed", diverged=None))], [], ci=True)
    assert "[low, high] = the 95 % confidence interval (block bootstrap" in t.caption


def test_the_value_rule_reaches_every_column_of_table_three():
    # 1.0 [0.5, 1.5] and 1.2 [1.1, 1.3]: one bold pair by the intervals (U = 1.3), bold and
    # underlined by value; times 1.0001 and 1.0002 ms print alike (1.00): equal marks by the
    # printed figures, ranked apart by value
    rows = [row(record("a", relative_error=[rel(8, 1.0, 0.1, [0.5, 1.5], [0.05, 0.15])],
                       time_ms=TimingStats(mean=1.0001))),
            row(record("b", relative_error=[rel(8, 1.2, 0.12, [1.1, 1.3], [0.11, 0.13])],
                       time_ms=TimingStats(mean=1.0002)))]
    by_interval, by_value = relative_table(rows, [8.0]), relative_table(rows, [8.0], "value")
    for part in (0, 1):
        assert ranks(by_interval, 0, part) == [BEST, BEST]
        assert ranks(by_value, 0, part) == [BEST, SECOND]
    assert texts(by_value, 1) == ["1.00", "1.00"]
    assert ranks(by_interval, 1) == [BEST, BEST] and ranks(by_value, 1) == [BEST, SECOND]


def test_segment_counts_decide_whether_a_length_has_a_figure():
    none = rel(8, None, None, n=0, n_ind=0)
    one = rel(16, 1.0, 0.1, n=1, n_ind=1)
    t = relative_table([row(record("a", relative_error=[none, one]))], [8.0, 16.0])
    assert texts(t, 0) == ["- / -"] and t.rows[0].cells[0].values["independent_segments"] is None
    assert texts(t, 1) == ["1.000 (1 segment) / 0.100 (1 segment)"]
    assert t.rows[0].cells[1].values["segments"] == 1


def test_a_run_that_fell_back_with_only_a_time_column_gets_its_note_there():
    many = record("b", frames=11, frames_replaced=2, time_ms=TimingStats(mean=1.0))
    t = relative_table([row(many, "B")], [])
    assert t.rows[0].cells[0].note == 1 and t.rows[0].keys[-1] == "B [fell back]"


def test_a_failure_without_a_reason_says_only_its_status():
    t = relative_table([row(record("c", status=" ", diverged=None), "C")], [8.0])
    assert t.footnotes == ["C on s1:  : "]


def test_kitti_and_velocity_tables_keys_captions_and_what_ci_and_marks_reach():
    rows = [row(record("a", kitti=kitti([100], [(100, 6)], 1.0, 0.50, 6, 3, [0.5, 1.5],
                                        [0.45, 0.55]),
                       velocity=velocity([0.1, 0.2, 0.3], 0.40, 0.5, [0.3, 0.45]))),
            row(record("b", kitti=kitti([100], [(100, 6)], 1.2, 0.52, 6, 3, [1.1, 1.3],
                                        [0.51, 0.53]),
                       velocity=velocity([0.2, 0.1, 0.4], 0.42, 0.4, [0.41, 0.43]))),
            row(record("c", kitti=kitti([100], [(100, 6)], 0.1, 0.1, 6, 1, [0.0, 0.2],
                                        [0.0, 0.2]),
                       velocity=velocity([0.0, 0.0, 0.0], 0.0, 0.0, [0.0, 0.1], n_ind=1)))]
    k, k_ci, k_value = kitti_table(rows), kitti_table(rows, ci=True), kitti_table(rows, "value")
    assert k.keys == k_ci.keys == ["Sensor", "Sequence", "Method"]
    assert texts(k, 0) == ["1.00", "1.20", "0.10 (1 segment)"]
    assert texts(k_ci, 1) == ["0.50 [0.45, 0.55]", "0.52 [0.51, 0.53]",
                              "0.10 [0.00, 0.20] (1 segment)"]
    assert ranks(k, 0) == [BEST, BEST, OTHER] and ranks(k_value, 0) == [BEST, SECOND, OTHER]
    assert ranks(k, 1) == [BEST, BEST, OTHER] and ranks(k_value, 1) == [BEST, SECOND, OTHER]
    assert k.caption == (
        "KITTI drift over segments of 100 m (6 segments per sequence) (the KITTI odometry "
        "devkit's definition: a segment starts every 10 frames and ends at the first frame "
        "beyond its length; translation error in % of the length, rotation error in deg per "
        "100 m, averaged over every segment); - = the path is shorter than the shortest "
        "length. Segments: every segment, in brackets the independent (non-overlapping) ones "
        "behind the interval. " + RULE_UNPRINTED + " Div. = diverged; " + SEED_NOTE)
    assert RULE in k_ci.caption and RULE_UNPRINTED not in k_ci.caption
    v, v_ci = velocity_table(rows), velocity_table(rows, ci=True)
    assert v.keys == ["Sensor", "Sequence", "Method"]
    assert texts(v, 3) == ["0.400", "0.420", "0.000 (1 segment)"]
    assert texts(v_ci, 3) == ["0.400 [0.300, 0.450]", "0.420 [0.410, 0.430]",
                              "0.000 [0.000, 0.100] (1 segment)"]
    assert texts(v_ci, 0)[0] == "0.100"  # no interval of its own
    assert ranks(v, 3) == [BEST, BEST, OTHER]
    assert v.caption == (
        "Ego-velocity error [m/s] in the sensor frame: mean absolute error per axis (x, y, z) "
        "and the mean and RMS of the error vector's norm. A frame's velocity is its relative "
        "translation to the first frame at least 0.5 s later over the time between (the same "
        "frames for the estimate and the ground truth). The reference is the GT over that "
        "window, not frame to frame: a GT nearest-matched to the scans (NTU4DRadLM: 10 Hz "
        "poses at 12 Hz scans) makes frame-to-frame GT velocities mostly artefact. [Doppler "
        "ego velocity] rows: the method's own instantaneous Doppler estimate against the GT "
        "velocity over a 0.5 s window centred on the frame. Only the norm mean has an "
        "interval: the other columns are marked by value. " + RULE_UNPRINTED
        + " Div. = diverged; " + SEED_NOTE)
    assert RULE in v_ci.caption
    assert [len(r.cells) for r in velocity_table([row(record("d")),
                                                  row(record("e", diverged=True))]).rows] == \
        [5, 5]
    for metric in ("relative", "kitti", "velocity"):
        shown = to_markdown(build(metric, rows, [], ci=True))
        assert "[0.45, 0.55]" in shown or "[0.300, 0.450]" in shown or metric == "relative"
        assert "[0.45, 0.55]" not in to_markdown(build(metric, rows, []))
    assert RULE in build("relative", rows, [], ci=True).caption
    assert RULE in build("kitti", rows, ci=True).caption
    assert RULE_UNPRINTED in build("kitti", rows).caption


def test_kitti_segments_name_the_most_common_count_and_every_odd_one():
    def k(seq, n, lengths=(100, 200, 300, 400)):
        return row(record("a", seq=seq, kitti=kitti(list(lengths), [(100, n)])))

    rows = [row(record("x", seq="s0")), k("s1", 1), k("s2", 1), k("s3", 4), k("s4", 3),
            row(record("f", seq="s5", status="failed", diverged=None,
                       kitti=kitti([100, 800], [(100, 9), (800, 9)])))]
    assert kitti_segments_text(rows) == ("segments of 100 m (1 segment per sequence; s3: 4, "
                                         "s4: 3); none of 200-400 m (the paths are shorter)")


def test_runs_and_select_of_chosen_folders_labels_and_gt_assisted_rows(tmp_path):
    root = tmp_path / "res"
    _write(root / "s1" / "icp_seed", {"label": "v1"}, method="icp", seed=True, label="v1",
           relative_error=[rel(8, 1.0, 0.1)])
    _write(root / "s1" / "dicp_seed",
           {"sequence": {"name": "s1", "doppler_kind": "gt-reconstructed"}},
           method="dicp", seed=True, relative_error=[rel(8, 1.0, 0.1)])
    _write(root / "s2" / "icp_seed", {"label": "v1"}, method="icp", seed=True, label="v1",
           relative_error=[rel(8, 1.0, 0.1)])
    got = runs(root)
    assert sorted(r.label for r in got) == sorted([
        run_label("icp", True, "v1"), run_label("icp", True, "v1"),
        run_label("dicp", True) + " [GT-assisted]"])
    assert run_label("icp", True, "v1") == "(With Seed) v1"
    chosen = {root / "s2" / "icp_seed"}
    assert [r.sequence for r in runs(root, chosen)] == ["s2"]
    rows, lengths = select(root, chosen)
    assert [r.sequence for r in rows] == ["s2"] and lengths == [8.0]
    empty = tmp_path / "empty"
    with pytest.raises(FileNotFoundError) as err:
        select([empty])
    assert str(err.value).startswith(f"{empty}: no finished runs")
    assert stat_part(1.0, [0.5, 1.5], 5).text == "1.000"


def test_sensor_classes_in_the_papers_order_not_by_name():
    from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR

    rows = [row(record("a", sensor=k)) for k in (DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR)]
    assert [r.sensor_class for r in sorted(rows, key=RunRow.order)] == \
        [SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR]


def test_the_caption_with_a_failed_run_written_out():
    t = relative_table([row(record("f", status="failed", diverged=None))], [])
    assert t.caption.endswith(" Div. = diverged; " + FAILED_NOTE + " " + SEED_NOTE)


def test_the_doppler_row_with_intervals_its_fall_back_note_and_the_value_rule():
    own = velocity([0.01, 0.02, 0.03], 0.040, 0.05, [0.035, 0.06])
    rows = [row(record("a", frames=11, frames_replaced=1, velocity_own=own,
                       velocity=velocity([0.1, 0.2, 0.3], 0.045, 0.5, [0.044, 0.046])), "A")]
    t = velocity_table(rows, ci=True)
    assert texts(t, 3) == ["0.045 [0.044, 0.046]", "0.040 [0.035, 0.060]"]
    note = "A on s1: 1 of 10 frames replaced by the motion prior (no usable registration)"
    assert t.footnotes == [note] and [r.cells[0].note for r in t.rows] == [1, 1]
    # unlabelled: the CSV's label of the Doppler row is the mark alone, after a space
    assert t.rows[1].meta["label"] == " [Doppler ego velocity]"
    # norm mean: U = 0.046 holds both by the intervals; by value 0.040 first
    assert ranks(t, 3) == [BEST, BEST]
    assert ranks(velocity_table(rows, "value"), 3) == [SECOND, BEST]


def test_write_tables_passes_every_choice_on(results, tmp_path):
    def body(md):
        return md.split("\n\n")[0].replace("**", "").replace("<u>", "").replace("</u>", "")

    plain = body(write_tables(results, tmp_path / "p", lengths_m=[8.0])["md"])
    assert "1.000 / 0.100" in plain and "[0.900, 1.100]" not in plain
    chosen = body(write_tables(results, tmp_path / "c", only={results / "s1" / "icp_seed"},
                               keep=lambda r: not r.failed, ci=True)["md"])
    assert "1.000 [0.900, 1.100] / 0.100 [0.090, 0.110]" in chosen
    assert "s2" not in chosen and "sim3" not in chosen
    with pytest.raises(ValueError, match="no run matches"):
        write_tables(results, tmp_path / "k", keep=lambda r: False)
