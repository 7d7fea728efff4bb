"""``bench compare`` (bench.report.compare) on hand-made result frames.

Both sides are small frames given by hand (``_pair`` patched), so every verdict follows from
the module's definition: a cell is a regression when its error grew by more than the threshold
(relative) or the run newly diverged; "worse" / "better" only where A's and B's printed
intervals do not meet; a regression within them "cannot tell it from noise"; a run under other
parameters is a difference, not a regression; a length without segments on either side is no
cell."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from bench.report import compare as cmp
from bench.report.compare import (
    _change,
    _finite,
    _fmt_ci,
    _length,
    _params,
    _run_name,
    _seed,
    _true,
    markdown_table,
    params_differ,
    summary,
)

NAN = math.nan


def _cell(seq, length, rot, trans, ci=0.1, method="gicp", params="tau=1", diverged=False,
          run=None, seed="With Seed"):
    """One frame row: rotation and translation with intervals +-ci (NaN: no interval)."""
    r = {"sequence": seq, "sequence_name": seq, "method": method, "label": "", "seed": seed,
         "overrides": "", "length_m": length, "run": run or f"({seed}) {method}",
         "params": params, "diverged": diverged}
    for q, v in (("rot_deg_mean", rot), ("trans_m_mean", trans)):
        r[q] = v
        r[f"{q}_ci_low"] = v - ci if _finite(v) else NAN
        r[f"{q}_ci_high"] = v + ci if _finite(v) else NAN
    return r


def _run_compare(monkeypatch, a_rows, b_rows, threshold=0.10, keys=cmp.RUN_KEYS):
    da, db = pd.DataFrame(a_rows), pd.DataFrame(b_rows)
    monkeypatch.setattr(cmp, "_pair", lambda a, b: (da, db, list(keys)) if (a, b) == ("A", "B")
                        else None)
    return cmp.compare("A", "B", threshold)


def _note(df, seq, length, method="gicp"):
    row = df[(df["sequence"] == seq) & (df["method"] == method)
             & ((df["length_m"] == length) | (df["length_m"].isna() & math.isnan(length)))]
    assert len(row) == 1
    return row.iloc[0]


def test_regressions_and_what_the_intervals_can_tell(monkeypatch):
    a = [_cell("s1", 8.0, 1.0, 1.0, ci=0.05),      # rotation grows 50 %, intervals apart
         _cell("s1", 48.0, 1.0, 1.0, ci=0.5),      # both grow 20 %, intervals meet
         _cell("s2", 8.0, 1.0, 1.0, ci=NAN),       # grows 20 %, no intervals
         _cell("s3", 8.0, 1.0, 1.0, ci=0.05),      # better beyond the intervals
         _cell("s4", 8.0, 2.0, 2.0, ci=0.5),       # 5 %: no regression at 10 %
         _cell("s5", 8.0, 1.0, 1.0)]               # only in A
    b = [_cell("s1", 8.0, 1.5, 1.0, ci=0.05),
         _cell("s1", 48.0, 1.2, 1.2, ci=0.5),
         _cell("s2", 8.0, 1.2, 1.0, ci=NAN),
         _cell("s3", 8.0, 0.5, 1.0, ci=0.05),
         _cell("s4", 8.0, 2.1, 2.1, ci=0.5),
         _cell("s6", 8.0, 1.0, 1.0)]               # only in B
    df = _run_compare(monkeypatch, a, b)
    r = _note(df, "s1", 8.0)
    assert r["regression"] and r["rot_deg_mean_delta"] == pytest.approx(0.5)
    assert r["trans_m_mean_delta"] == pytest.approx(0.0)
    assert r["note"] == "! regression; rotation worse beyond the intervals"
    r = _note(df, "s1", 48.0)
    assert r["regression"]
    assert r["note"].startswith("! regression by value only")
    assert "cannot tell it from noise" in r["note"] and "beyond" not in r["note"]
    r = _note(df, "s2", 8.0)
    assert r["regression"] and r["note"] == "! regression (by value: no intervals)"
    r = _note(df, "s3", 8.0)
    assert not r["regression"] and r["note"] == "rotation better beyond the intervals"
    assert r["rot_deg_mean_delta"] == pytest.approx(-0.5)
    r = _note(df, "s4", 8.0)
    assert not r["regression"] and r["note"] == ""
    assert r["only_in"] == ""
    r = _note(df, "s5", 8.0)
    assert r["only_in"] == "A" and r["note"] == "only in A" and not r["regression"]
    assert math.isnan(r["rot_deg_mean_delta"])
    r = _note(df, "s6", 8.0)
    assert r["only_in"] == "B" and r["note"] == "only in B"
    # a lower threshold makes the 5 % growth a regression (it is above 4 %, below 6 %)
    assert _note(_run_compare(monkeypatch, a, b, 0.04), "s4", 8.0)["regression"]
    assert not _note(_run_compare(monkeypatch, a, b, 0.06), "s4", 8.0)["regression"]
    # rows in the table's order: sequences, then lengths
    # growth by exactly the threshold is not more than it; from zero, no relative growth
    e = _run_compare(monkeypatch, [_cell("s", 8.0, 1.0, 0.0)], [_cell("s", 8.0, 1.25, 0.5)],
                     0.25)
    assert not e.iloc[0]["regression"] and "regression" not in e.iloc[0]["note"]
    assert set(df.columns) == {
        *cmp.RUN_KEYS, "length_m", "run", "only_in", "regression", "note",
        *(f"{q}_{x}" for q in cmp.QUANTITIES for x in ("a", "b", "delta")),
        *(f"{q}_ci_{end}_{side}" for q in cmp.QUANTITIES for end in ("low", "high")
          for side in "ab")}
    assert list(zip(df["sequence"], df["length_m"], strict=True)) == [
        ("s1", 8.0), ("s1", 48.0), ("s2", 8.0), ("s3", 8.0), ("s4", 8.0), ("s5", 8.0),
        ("s6", 8.0)]
    assert not {"has_data", "_first", "_params"} & set(df.columns)
    text = summary(df, 0.10)
    assert text.startswith("7 cells (1 only in A, 1 only in B), 3 regressions (> 10% growth")
    assert "1 of them by value only" in text and "cannot tell it from noise" in text


def test_divergence_parameters_and_empty_lengths(monkeypatch):
    a = [_cell("s1", 8.0, 1.0, 1.0),
         _cell("s2", 8.0, 1.0, 1.0, params="tau=1;k=2"),
         _cell("s3", 8.0, 1.0, 1.0, diverged=True),
         _cell("s4", 8.0, 1.0, 1.0, diverged=True),
         _cell("s5", 8.0, 1.0, 1.0), _cell("s5", 48.0, NAN, NAN),
         _cell("s7", 8.0, NAN, 1.0)]
    b = [_cell("s1", 8.0, NAN, NAN, diverged=True),   # newly diverged, no segments in B
         _cell("s2", 8.0, 2.0, 2.0, params="tau=3;k=2"),  # other parameters: not a regression
         _cell("s3", 8.0, 1.0, 1.0, diverged=True),
         _cell("s4", 8.0, 1.0, 1.0),
         _cell("s5", 8.0, 1.0, 1.0), _cell("s5", 48.0, NAN, NAN),  # 48 m: no cell
         _cell("s7", 8.0, 1.0, NAN)]
    df = _run_compare(monkeypatch, a, b)
    r = _note(df, "s1", 8.0)
    assert r["regression"] and r["note"] == "! newly diverged; no segments in B"
    r = _note(df, "s2", 8.0)
    assert not r["regression"]
    assert r["note"] == "parameters differ: tau A 1, B 3; rotation worse beyond the intervals" \
        "; translation worse beyond the intervals"
    assert _note(df, "s3", 8.0)["note"] == "diverged in A and B"
    assert _note(df, "s4", 8.0)["note"] == "diverged in A only"
    assert not _note(df, "s4", 8.0)["regression"]
    assert list(df[df["sequence"] == "s5"]["length_m"]) == [8.0]
    # one quantity on each side: a cell, no regression, no side without segments
    r = _note(df, "s7", 8.0)
    assert r["note"] == "" and not r["regression"] and math.isnan(r["rot_deg_mean_delta"])


def test_a_newly_diverged_run_without_any_segments_keeps_one_row(monkeypatch):
    a = [_cell("s1", L, NAN, NAN) for L in (8.0, 48.0, 100.0)]
    b = [_cell("s1", L, NAN, NAN, diverged=True) for L in (8.0, 48.0, 100.0)]
    df = _run_compare(monkeypatch, a, b)
    assert len(df) == 1 and df.iloc[0]["regression"] and math.isnan(df.iloc[0]["length_m"])
    assert "! newly diverged" in df.iloc[0]["note"]
    # not diverged: no cell at all
    df = _run_compare(monkeypatch, a, a)
    assert df.empty or len(df) == 0
    # nothing on either side: an empty frame
    none = pd.DataFrame(columns=list(pd.DataFrame(a).columns))
    assert _run_compare(monkeypatch, none, none).empty


def test_a_run_under_other_parameters_on_each_side_is_named(monkeypatch):
    a = [{**_cell("s1", 8.0, 1.0, 1.0, params="tau=1"), "overrides": " -p tau=1"}]
    b = [{**_cell("s1", 8.0, 1.0, 1.0, params="tau=3"), "overrides": " -p tau=3"}]
    df = _run_compare(monkeypatch, a, b)
    assert sorted(df["only_in"]) == ["A", "B"]
    na = df[df["only_in"] == "A"].iloc[0]["note"]
    nb = df[df["only_in"] == "B"].iloc[0]["note"]
    assert na == "only in A (B has this run with other parameters: tau A 1, B 3)"
    assert nb == "only in B (A has this run with other parameters: tau A 1, B 3)"
    # parameters unknown: the overrides are named, "defaults" for none
    a = [{**_cell("s1", 8.0, 1.0, 1.0, params=""), "overrides": " -p tau=1"}]
    b = [{**_cell("s1", 8.0, 1.0, 1.0, params=""), "overrides": ""}]
    df = _run_compare(monkeypatch, a, b)
    assert df[df["only_in"] == "A"].iloc[0]["note"].endswith(
        "(B has this run with other parameters: A -p tau=1, B defaults)")


def test_another_content_under_one_name_is_said(monkeypatch):
    a = [{**_cell("data1 [a.h5]", 8.0, 1.0, 1.0), "sequence_name": "data1"}]
    b = [{**_cell("data1 [b.h5]", 8.0, 1.0, 1.0), "sequence_name": "data1"}]
    df = _run_compare(monkeypatch, a, b)
    na = df[df["only_in"] == "A"].iloc[0]["note"]
    assert na == ("only in A; B holds data1 [b.h5]: another content of data1 (other store or "
                  "frames), not compared")
    assert "A holds data1 [a.h5]" in df[df["only_in"] == "B"].iloc[0]["note"]


def test_single_run_folders_pair_by_sequence_and_order_by_method(monkeypatch):
    a = [_cell("s1", 8.0, 1.0, 1.0, method="gicp", run="G")]
    b = [_cell("s1", 8.0, 1.0, 1.0, method="vgicp", run="V")]
    df = _run_compare(monkeypatch, a, b, keys=["sequence"])
    assert len(df) == 1 and df.iloc[0]["run"] == "G -> V" and df.iloc[0]["only_in"] == ""
    # several runs: the paper's methods order, with seed before without
    a = [_cell("s1", 8.0, 1.0, 1.0, method=m, seed=s) for m in ("vgicp", "icp-p2p")
         for s in ("No Seed", "With Seed")]
    df = _run_compare(monkeypatch, a, a)
    assert list(zip(df["method"], df["seed"], strict=True)) == [
        ("icp-p2p", "With Seed"), ("icp-p2p", "No Seed"), ("vgicp", "With Seed"),
        ("vgicp", "No Seed")]


def test_small_helpers():
    assert _seed(None) is None and _seed(NAN) is None
    assert _seed(1.0) is True and _seed(False) is False and _seed(0.0) is False
    assert _params({"method": {"params": {"b": 2, "a": 1.5}}}) == "a=1.5;b=2"
    assert _params({"method": "gicp"}) == "" and _params({"method": {"params": 3}}) == ""
    assert params_differ("a=1;b=2", "a=1;b=3;c=x") == "b A 2, B 3; c A -, B x"
    assert params_differ("a=1", "a=1") == ""
    assert params_differ("", "a=1") == "" and params_differ(NAN, "a=1") == ""
    assert params_differ("a=1", None) == ""
    assert params_differ("a=x=y", "a=x") == "a A x=y, B x"
    assert _finite(1.0) and _finite(np.float32(2)) and _finite(3)
    assert not _finite(True) and not _finite(NAN) and not _finite(math.inf)
    assert not _finite("1") and not _finite(None)
    assert _true(True) and _true(np.bool_(True))
    assert not _true(1) and not _true(NAN) and not _true(False) and not _true(None)
    assert _run_name({"run_a": "x", "run_b": "x"}) == "x"
    assert _run_name({"run_a": NAN, "run_b": "y"}) == "y"
    assert _run_name({"run_a": "x", "run_b": "y"}) == "x -> y"
    assert _change(1.0, 1.1) == "+0.100 (+10.0%)"
    assert _change(2.0, 1.0, 2) == "-1.00 (-50.0%)"
    assert _change(0.0, 0.5) == "+0.500"
    assert _change(NAN, 1.0) == "-" and _change(1.0, None) == "-"
    assert _length(8.0) == "8" and _length(12.5) == "12.5" and _length(NAN) == "-"
    r = {"q_a": 0.5, "q_ci_low_a": 0.4, "q_ci_high_a": 0.6, "q_b": 0.25,
         "q_ci_low_b": NAN, "q_ci_high_b": 0.3, "q_c": NAN}
    assert _fmt_ci(r, "q", "a") == "0.500 [0.400, 0.600]"
    assert _fmt_ci(r, "q", "a", 1) == "0.5 [0.4, 0.6]"
    assert _fmt_ci(r, "q", "b") == "0.250"
    assert _fmt_ci(r, "q", "c") == "-"
    r.update({"q_ci_low_c": 0.1, "q_ci_high_c": 0.2})
    assert _fmt_ci(r, "q", "c") == "-"  # no value: no interval printed either


def test_markdown_table_pads_and_aligns():
    lines = markdown_table(["Name", "N"], [["a|b", "1"], ["long name", "12345"]], right={1})
    assert len({len(x) for x in lines}) == 1  # every line as wide
    assert lines[0] == "| Name      |     N |"
    assert lines[1] == "| --------- | ----: |"
    assert lines[2] == r"| a\|b      |     1 |"
    assert lines[3] == "| long name | 12345 |"
    # a narrow column is three wide; an escaped pipe is not escaped twice
    assert markdown_table(["x"], [[r"a\|"]], set()) == ["| x   |", "| --- |", r"| a\| |"]
    assert markdown_table(["x"], [["a"]], {0}) == ["|   x |", "| --: |", "|   a |"]
    with pytest.raises(ValueError):  # a row with more cells than the header
        markdown_table(["x"], [["a", "b"]], set())


def test_summary_counts():
    one = pd.DataFrame([{"only_in": "", "regression": True, "note": "! regression"}])
    assert summary(one, 0.1) == ("1 cell (0 only in A, 0 only in B), 1 regression (> 10% "
                                 "growth or newly diverged)")
    assert summary(pd.DataFrame(), 0.25) == ("0 cells (0 only in A, 0 only in B), 0 "
                                             "regressions (> 25% growth or newly diverged)")


def _timed(seq, length, t, method="gicp", ape=0.1, align="se3"):
    return {**_cell(seq, length, 1.0, 1.0, method=method), "time_ms_mean": t,
            "ape_trans_m": ape, "ape_alignment": align, "kitti_trans_pct": 1.5,
            "kitti_rot_deg_per_100m": 0.25, "velocity_err_mps": NAN}


def test_times_per_run_metrics_and_the_markdown(monkeypatch):
    # "run10" sorts before "run2" by its letters, after it in the tables' (natural) order
    a = [_timed("s1", 8.0, 10.0), _timed("s1", 48.0, 10.0), _timed("run10", 8.0, 4.0)]
    b = [_timed("s1", 8.0, 12.5, ape=0.2, align="sim3"), _timed("s1", 48.0, 12.5, ape=0.2),
         _timed("run2", 8.0, 5.0)]
    da, db = pd.DataFrame(a), pd.DataFrame(b)
    monkeypatch.setattr(cmp, "_pair", lambda x, y: (da, db, list(cmp.RUN_KEYS))
                        if (x, y) == ("A", "B") else None)
    times = cmp.compare_times("A", "B")
    # one row per run (two lengths of s1 are one run), in the table's order
    assert list(times["sequence"]) == ["run2", "run10", "s1"]
    assert list(times["only_in"]) == ["B", "A", ""]
    assert times.iloc[2]["time_ms_delta"] == pytest.approx(2.5)
    assert times.iloc[2]["run"] == "(With Seed) gicp"
    assert math.isnan(times.iloc[1]["time_ms_delta"]) and times.iloc[1]["time_ms_a"] == 4.0
    per_run = cmp.compare_run_metrics("A", "B")
    assert list(per_run["sequence"]) == ["run2", "run10", "s1"]
    r = per_run.iloc[2]
    assert (r["ape_trans_m_a"], r["ape_trans_m_b"]) == (0.1, 0.2)
    assert (r["ape_alignment_a"], r["ape_alignment_b"]) == ("se3", "sim3")
    assert r["kitti_trans_pct_b"] == 1.5 and list(per_run["only_in"]) == ["B", "A", ""]
    cells = cmp.compare("A", "B")
    md = cmp.to_markdown(cells, times, "A", "B", 0.10, per_run)
    lines = md.splitlines()
    assert lines[0] == "A = `A`, B = `B`" and md.endswith("\n")
    assert "| Sequence | Run" in md and "Rot. change" in md and "Trans. change" in md
    row = next(x for x in lines if x.startswith("| s1") and "10.00" in x)
    assert [c.strip() for c in row.strip("|").split("|")] == [
        "s1", "(With Seed) gicp", "10.00", "12.50", "+2.50 (+25.0%)", ""]
    assert any(x.startswith("| run10") and "only in A" in x and "4.00" in x for x in lines)
    assert "Per run: APE (alignment: se3, sim3)" in md
    row = next(x for x in lines if x.startswith("| s1") and "->" in x)
    assert [c.strip() for c in row.strip("|").split("|")] == [
        "s1", "(With Seed) gicp", "0.100 -> 0.200", "1.50 -> 1.50", "0.25 -> 0.25",
        "- -> -", ""]
    cell = next(x for x in lines if x.startswith("| s1") and "[0.900, 1.100]" in x)
    assert [c.strip() for c in cell.strip("|").split("|")][2:6] == [
        "8", "1.000 [0.900, 1.100]", "1.000 [0.900, 1.100]", "+0.000 (+0.0%)"]
    assert lines[-1] == summary(cells, 0.10)

    def split(line):
        return [c.strip() for c in line.strip().strip("|").split("|")]

    # the three tables: their headers, right-aligned number columns, a blank line and a
    # sentence saying what they hold before each
    heads = [i for i, x in enumerate(lines) if x.startswith("| Sequence")]
    assert [split(lines[i]) for i in heads] == [
        ["Sequence", "Run", "Length [m]", "Rot. A", "Rot. B", "Rot. change", "Trans. A",
         "Trans. B", "Trans. change", "Note"],
        ["Sequence", "Run", "Time A", "Time B", "Change", "Note"],
        ["Sequence", "Run", "APE [m]", "KITTI trans. [%]", "KITTI rot. [deg/100 m]",
         "Velocity err. [m/s]", "Note"]]
    right = [[j for j, c in enumerate(split(lines[i + 1])) if c.endswith(":")] for i in heads]
    assert right == [list(range(2, 9)), [2, 3, 4], [2, 3, 4, 5]]
    for i in heads:
        assert lines[i - 1] == "" and lines[i - 3] == "" and lines[i - 2].endswith(":")
    assert lines[1] == "" and lines[heads[0] - 2].startswith(
        "Mean relative error over the segments of each length: rotation [deg], translation "
        "[m], each with its 95 % confidence interval [low, high]")
    assert "change = B - A" in md and "A's and B's printed intervals do not meet:" in md
    assert lines[heads[1] - 2] == "Mean time per frame [ms] (all per-frame work, `time_ms`):"
    assert lines[heads[2] - 2].endswith("ego-velocity error (mean norm); A -> B:")
    assert lines[-2] == ""
    # a cell row in full: run, note
    row = next(split(x) for x in lines if x.startswith("| run2") and "only in B" in x
               and "[" in x)
    assert row[1] == "(With Seed) gicp" and row[-1] == "only in B"
    # alignments not recorded: "-"
    unaligned = per_run.assign(ape_alignment_a=NAN, ape_alignment_b=NAN)
    assert "Per run: APE (alignment: -), KITTI" in cmp.to_markdown(cells, times, "A", "B",
                                                                  0.10, unaligned)
    # no per-run table when none is given
    assert "Per run:" not in cmp.to_markdown(cells, times, "A", "B", 0.10)
