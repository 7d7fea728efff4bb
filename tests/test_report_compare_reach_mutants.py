"""bench.report.compare: survivors of its mutation run, killed on hand-made result frames.

Both sides are small frames given by hand (``_pair`` patched, as in test_compare_rules), so each
answer follows from the module's definition: the default threshold is 10 %; a side whose
quantity holds no number at all (an all-None column, as pandas keeps it: a folder of runs
without segments at a length, or of external runs without per-frame times) gives no change and
no error; every pair of runs under other parameters is named, whichever key comes first; the
summary and the per-run table say what they hold in full."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from bench.report import compare as cmp
from bench.report.names import display_name

NAN = math.nan


def _cell(seq, length, rot, trans, ci=0.1, method="gicp", params="tau=1", overrides="",
          time_ms=10.0):
    r = {"sequence": seq, "sequence_name": seq, "method": method, "label": "",
         "seed": "With Seed", "overrides": overrides, "length_m": length,
         "run": f"(With Seed) {method}{overrides}", "params": params, "diverged": False,
         "time_ms_mean": time_ms, "ape_trans_m": 0.5, "ape_alignment": "se3",
         "kitti_trans_pct": 1.0, "kitti_rot_deg_per_100m": 0.5, "velocity_err_mps": 0.1}
    for q, v in (("rot_deg_mean", rot), ("trans_m_mean", trans)):
        r[q] = v
        r[f"{q}_ci_low"] = v - ci if isinstance(v, float) and math.isfinite(v) else None
        r[f"{q}_ci_high"] = v + ci if isinstance(v, float) and math.isfinite(v) else None
    return r


def _patch(monkeypatch, a_rows, b_rows):
    da, db = pd.DataFrame(a_rows), pd.DataFrame(b_rows)
    monkeypatch.setattr(cmp, "_pair", lambda a, b: (da, db, list(cmp.RUN_KEYS))
                        if (a, b) == ("A", "B") else None)


def test_the_default_threshold_is_ten_percent(monkeypatch):
    """(kills compare 1: the default 0.10 -> 1.1)"""
    _patch(monkeypatch, [_cell("s1", 8.0, 1.0, 1.0), _cell("s2", 8.0, 1.0, 1.0)],
           [_cell("s1", 8.0, 1.15, 1.0), _cell("s2", 8.0, 1.05, 1.0)])
    df = cmp.compare("A", "B")
    assert list(df["regression"]) == [True, False]  # 15 % and 5 % growth


def test_a_side_without_any_number_gives_no_change(monkeypatch):
    """(kills compare 96, 98 and compare_times 50, 52: B - A taken with None on one side)"""
    _patch(monkeypatch, [_cell("s1", 8.0, 1.0, 1.0)],
           [_cell("s1", 8.0, None, None, time_ms=None)])
    df = cmp.compare("A", "B")
    assert len(df) == 1
    r = df.iloc[0]
    assert math.isnan(r["rot_deg_mean_delta"]) and math.isnan(r["trans_m_mean_delta"])
    assert not r["regression"] and r["note"] == "no segments in B"
    times = cmp.compare_times("A", "B")
    assert times.iloc[0]["time_ms_a"] == 10.0 and times.iloc[0]["time_ms_b"] is None
    assert math.isnan(times.iloc[0]["time_ms_delta"])
    # and the other way round
    _patch(monkeypatch, [_cell("s1", 8.0, None, None, time_ms=None)],
           [_cell("s1", 8.0, 1.0, 1.0)])
    assert math.isnan(cmp.compare("A", "B").iloc[0]["rot_deg_mean_delta"])
    assert math.isnan(cmp.compare_times("A", "B").iloc[0]["time_ms_delta"])


def test_every_pair_under_other_parameters_is_named(monkeypatch):
    """(kills _name_other_parameters 34: the loop stops at a key without a pair)"""
    a = [_cell("s0", 8.0, 1.0, 1.0, params="tau=2", overrides=" -p tau=2"),  # no pair in B
         _cell("s1", 8.0, 1.0, 1.0, params="tau=1", overrides=" -p tau=1")]
    b = [_cell("s1", 8.0, 1.0, 1.0, params="tau=3", overrides=" -p tau=3")]
    _patch(monkeypatch, a, b)
    df = cmp.compare("A", "B")
    notes = {(s, o): n for s, o, n in zip(df["sequence"], df["only_in"], df["note"],
                                          strict=True)}
    assert notes == {
        ("s0", "A"): "only in A",
        ("s1", "A"): "only in A (B has this run with other parameters: tau A 1, B 3)",
        ("s1", "B"): "only in B (A has this run with other parameters: tau A 1, B 3)"}


def test_the_summary_in_full_when_a_regression_is_by_value_only():
    """(kills summary 61: the wording of the intervals' clause)"""
    cells = pd.DataFrame([
        {"only_in": "", "regression": True,
         "note": "! regression by value only: A's and B's intervals meet, they cannot tell it "
                 "from noise"},
        {"only_in": "A", "regression": False, "note": "only in A"}])
    assert cmp.summary(cells, 0.10) == (
        "2 cells (1 only in A, 0 only in B), 1 regression (> 10% growth or newly diverged; "
        "1 of them by value only: A's and B's intervals meet, so they cannot tell it from "
        "noise)")


def test_the_per_run_table_says_what_it_holds_and_which_side_a_run_is_on(monkeypatch):
    """(kills to_markdown 193: the per-run sentence's wording, 213: its 'only in' note)"""
    _patch(monkeypatch, [_cell("s1", 8.0, 1.0, 1.0), _cell("s2", 8.0, 1.0, 1.0)],
           [_cell("s1", 8.0, 1.0, 1.0)])
    md = cmp.to_markdown(cmp.compare("A", "B"), cmp.compare_times("A", "B"), "A", "B", 0.10,
                         cmp.compare_run_metrics("A", "B"))
    lines = md.splitlines()
    assert ("Per run: APE (alignment: se3), KITTI drift over 100-800 m and ego-velocity error "
            "(mean norm); A -> B:") in lines
    start = lines.index("Per run: APE (alignment: se3), KITTI drift over 100-800 m and "
                        "ego-velocity error (mean norm); A -> B:")
    rows = [[c.strip() for c in x.strip("|").split("|")] for x in lines[start + 4:]
            if x.startswith("| s")]
    assert [r[0] for r in rows] == ["s1", "s2"]
    assert rows[0][-1] == "" and rows[1][-1] == "only in A"
    assert rows[1][2] == "0.500 -> -"


def test_a_kept_empty_row_has_no_length(monkeypatch):
    """A newly diverged run without segments keeps one row whose length is NaN (a float
    column: compare 208's None is the same NaN there)."""
    a = [_cell("s1", 8.0, None, None)]
    b = [{**_cell("s1", 8.0, None, None), "diverged": True}]
    _patch(monkeypatch, a, b)
    df = cmp.compare("A", "B")
    assert len(df) == 1 and df["length_m"].dtype == float and math.isnan(df.iloc[0]["length_m"])


def test_runs_of_one_sequence_in_the_papers_method_order(monkeypatch):
    """(kills _in_table_order 13: methods by name only; gicp sorts before icp-p2p by its
    letters, after it in the paper's order)"""
    rows = [_cell("s1", 8.0, 1.0, 1.0, method=m) for m in ("gicp", "icp-p2p")]
    _patch(monkeypatch, rows, rows)
    assert list(cmp.compare("A", "B")["method"]) == ["icp-p2p", "gicp"]
    assert list(cmp.compare_times("A", "B")["method"]) == ["icp-p2p", "gicp"]


def test_a_run_under_defaults_in_a_is_named_so(monkeypatch):
    """(kills _name_other_parameters 51, 52: the word for A's defaults)"""
    _patch(monkeypatch, [_cell("s1", 8.0, 1.0, 1.0, params="")],
           [_cell("s1", 8.0, 1.0, 1.0, params="", overrides=" -p tau=3")])
    df = cmp.compare("A", "B")
    assert df[df["only_in"] == "B"].iloc[0]["note"] == (
        "only in B (A has this run with other parameters: A defaults, B -p tau=3)")


def test_two_other_contents_under_one_name_are_both_said(monkeypatch):
    """(kills _other_content 33: the separator of the other side's labels)"""
    a = [{**_cell("data1 [a.h5]", 8.0, 1.0, 1.0), "sequence_name": "data1"}]
    b = [{**_cell(f"data1 [{x}.h5]", 8.0, 1.0, 1.0), "sequence_name": "data1"}
         for x in ("b", "c")]
    _patch(monkeypatch, a, b)
    df = cmp.compare("A", "B")
    assert df[df["only_in"] == "A"].iloc[0]["note"] == (
        "only in A; B holds data1 [b.h5], data1 [c.h5]: another content of data1 (other store "
        "or frames), not compared")


def test_params_differ_reads_b_as_a():
    """(kills params_differ 24, 25, 27: B's values split at their first '=' only; 38, 40, 41:
    a parameter B lacks is '-')"""
    assert cmp.params_differ("a=x", "a=x=y") == "a A x, B x=y"
    assert cmp.params_differ("a=1;c=x", "a=1") == "c A x, B -"


def test_a_regression_within_the_intervals_is_said_in_full(monkeypatch):
    """(kills _note 16: the wording a user reads)"""
    _patch(monkeypatch, [_cell("s1", 8.0, 1.0, 1.0, ci=0.5)],
           [_cell("s1", 8.0, 1.2, 1.0, ci=0.5)])
    assert cmp.compare("A", "B").iloc[0]["note"] == (
        "! regression by value only: A's and B's intervals meet, they cannot tell it from noise")


def test_half_an_interval_is_no_interval(monkeypatch):
    """(kills _stat 6: a side whose interval lacks its low end was read as having one)"""
    a = _cell("s1", 8.0, 1.0, 1.0, ci=0.1)
    a["rot_deg_mean_ci_low"] = None
    a["trans_m_mean_ci_low"] = None
    _patch(monkeypatch, [a], [_cell("s1", 8.0, 2.0, 2.0, ci=0.1)])
    assert cmp.compare("A", "B").iloc[0]["note"] == "! regression (by value: no intervals)"


def _run_folder(root, sequence: str, store: str, content: str, rot: float,
                method: str = "icp-p2p", label: str | None = None,
                doppler_kind: str = "radial"):
    """A finished run folder with what compare reads: metrics.json (one length, 8 m) and the
    config's record of the sequence's store, content and Doppler kind."""
    import json

    d = root / sequence / f"{method}_seed{'_' + label if label else ''}"
    d.mkdir(parents=True)
    (d / "metrics.json").write_text(json.dumps({
        "sequence": sequence, "method": method, "seed": True, "frames": 50, "label": label,
        "diverged": False, "time_ms": {"mean": 5.0, "median": 5.0},
        "relative_error": {"8": {"rot_deg_mean": rot, "trans_m_mean": rot / 2, "n": 10}}}))
    (d / "config.yaml").write_text(json.dumps({
        "sequence": {"name": sequence, "store": store, "content_sha256": content,
                     "doppler_kind": doppler_kind}}))
    return d


def test_folders_holding_one_name_with_two_contents_say_so(tmp_path):
    """(kills _frame 7 and 10: the sequence's base name lost, so the other content unsaid)"""
    _run_folder(tmp_path / "A", "seqA", "/data/a.h5", "1" * 64, 1.0)
    _run_folder(tmp_path / "B", "seqA", "/data/b.h5", "2" * 64, 1.0)
    df = cmp.compare(tmp_path / "A", tmp_path / "B")
    notes = dict(zip(df["sequence"], df["note"], strict=True))
    assert notes == {
        "seqA [a.h5]": "only in A; B holds seqA [b.h5]: another content of seqA (other store "
                       "or frames), not compared",
        "seqA [b.h5]": "only in B; A holds seqA [a.h5]: another content of seqA (other store "
                       "or frames), not compared"}


def test_an_empty_folder_is_refused_in_words(tmp_path):
    """(kills _frame 4 and 5: the refusal's wording)"""
    _run_folder(tmp_path / "A", "seqA", "/data/a.h5", "1" * 64, 1.0)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError) as caught:
        cmp.compare(tmp_path / "A", tmp_path / "empty")
    assert str(caught.value) == (f"{tmp_path / 'empty'}: no finished runs with relative errors "
                                 "(no metrics.json of a run with ground truth found)")


def test_folders_keep_labels_gt_assisted_marks_and_own_priors_apart(tmp_path):
    """(kills _frame 16-19: the label not filled with "", 51/57: the label left out of the run's
    name, 52/56: the GT-assisted mark, 82: the seed tag without the method)"""
    for side in ("A", "B"):
        _run_folder(tmp_path / side, "seqA", "/data/a.h5", "1" * 64, 1.0)
        _run_folder(tmp_path / side, "seqA", "/data/a.h5", "1" * 64, 1.0, label="mine")
        _run_folder(tmp_path / side, "seqG", "/data/g.h5", "3" * 64, 1.0,
                    doppler_kind="gt-reconstructed")
        _run_folder(tmp_path / side, "seqA", "/data/a.h5", "1" * 64, 1.0, method="kiss-icp")
    df = cmp.compare(tmp_path / "A", tmp_path / "B")
    got = sorted(zip(df["sequence"], df["method"], df["label"], df["seed"], df["run"],
                     df["only_in"], strict=True))
    icp, kiss = display_name("icp-p2p"), display_name("kiss-icp")  # the tables' names
    assert got == [
        ("seqA", "icp-p2p", "", "With Seed", f"(With Seed) {icp}", ""),
        ("seqA", "icp-p2p", "mine", "With Seed", "(With Seed) mine", ""),
        ("seqA", "kiss-icp", "", "With Seed, own model", f"(With Seed, own model) {kiss}", ""),
        ("seqG", "icp-p2p", "", "With Seed", f"(With Seed) {icp} [GT-assisted]", "")]


def test_a_run_folder_against_a_results_folder_pairs_by_run(tmp_path):
    """(kills _pair 2: one run folder made both sides pair by sequence alone)"""
    run = _run_folder(tmp_path / "A", "seqA", "/data/a.h5", "1" * 64, 1.0)
    _run_folder(tmp_path / "B", "seqA", "/data/a.h5", "1" * 64, 1.0, method="gicp")
    df = cmp.compare(run, tmp_path / "B")
    assert sorted(df["only_in"]) == ["A", "B"]


def test_an_empty_first_folder_is_named(tmp_path):
    """(kills _pair 19: A's path left out of its refusal)"""
    _run_folder(tmp_path / "B", "seqA", "/data/a.h5", "1" * 64, 1.0)
    (tmp_path / "empty").mkdir()
    with pytest.raises(FileNotFoundError, match=f"^{tmp_path / 'empty'}: no finished runs"):
        cmp.compare(tmp_path / "empty", tmp_path / "B")
