"""The APE table (bench/report/tables/ape.py, the paper's Tables IV/V) from run folders: one
row per method and seed option, one column per sequence, each cell's text, values, mark and
footnote, the alignment the caption states (the one most runs asked for), and the note on an
unaligned estimate that starts far from the ground truth."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.report.names import SEED_NOTE, order_key, run_label
from bench.report.tables.ape import collect_ape, start_offset_note, write_ape_tables
from bench.report.tables.model import BEST, OTHER, RULE, RULE_UNPRINTED, SECOND
from bench.runs.folders import RunRecord
from bench.runs.result import ApeResult, RunResult, Spread

ICP, DICP = run_label("icp", True), run_label("dicp", True)


def ape(rmse, ci=None, n_ind=5, requested="se3", alignment=None):
    return ApeResult(requested=requested, alignment=alignment or requested, trans_rmse_m=rmse,
                     trans_rmse_m_ci=ci, spread=Spread(n_independent=n_ind))


def write_run(folder: Path, config: dict | None = None, **fields) -> Path:
    folder.mkdir(parents=True)
    fields.setdefault("diverged", False)
    fields.setdefault("sequence", folder.parent.name)
    fields.setdefault("method", folder.name.removesuffix("_seed"))
    fields.setdefault("seed", True)
    (folder / "metrics.json").write_text(RunResult(**fields).dump())
    if config is not None:
        (folder / "config.yaml").write_text(json.dumps(config))
    return folder


def write_failed(folder: Path, status="failed", error="boom\nsecond line") -> None:
    folder.mkdir(parents=True)
    (folder / "failed.json").write_text(json.dumps({"status": status, "error": error}))


@pytest.fixture
def results(tmp_path):
    root = tmp_path / "res"
    write_run(root / "s1" / "icp_seed", ape=ape(0.50, [0.40, 0.60]))
    write_run(root / "s1" / "dicp_seed", frames=101, frames_replaced=10,
              ape=ape(0.30, [0.25, 0.45], alignment="se3-orientation"))
    write_run(root / "s2" / "icp_seed", ape=ape(1.234, None, n_ind=1))
    write_run(root / "s2" / "dicp_seed", diverged=True, ape=ape(9.0))
    write_run(root / "s2" / "gicp_seed")  # no APE: not in the table
    write_failed(root / "s3" / "icp_seed")
    return root


def _cells(made):
    return {(label, col): row.cells[i] for label, row in made.rows
            for i, col in enumerate(made.sequences)}


def test_cells_marks_values_and_footnotes(results):
    made = collect_ape(results)
    assert made.sequences == ["s1", "s2", "s3"] == made.table.columns
    assert made.table.keys == ["Method"]
    order = sorted([("icp", ICP), ("dicp", DICP)], key=lambda m: (order_key(m[0]), m[0]))
    assert [label for label, _ in made.rows] == [label for _, label in order]
    cells = _cells(made)
    icp1, dicp1 = cells[(ICP, "s1")], cells[(DICP, "s1")]
    assert icp1.parts[0].text == "0.50" and dicp1.parts[0].text == "0.30"
    # U = 0.45 (DICP's upper end): DICP bold; then ICP underlined
    assert (dicp1.parts[0].rank, icp1.parts[0].rank) == (BEST, SECOND)
    assert icp1.values == {"ape_trans_rmse_m": 0.5, "ape_trans_rmse_m_ci_low": 0.4,
                           "ape_trans_rmse_m_ci_high": 0.6}
    icp2 = cells[(ICP, "s2")]
    assert icp2.parts[0].text == "1.23 (1 segment)" and icp2.parts[0].rank == OTHER
    assert icp2.values == {"ape_trans_rmse_m": 1.234, "ape_trans_rmse_m_ci_low": None,
                           "ape_trans_rmse_m_ci_high": None}
    assert cells[(DICP, "s2")].status == "Div."
    assert cells[(DICP, "s2")].values == {"ape_trans_rmse_m": 9.0}
    assert cells[(DICP, "s3")].status == "-"
    notes = made.table.footnotes
    assert sorted(notes) == sorted([
        f"{ICP} on s3: failed: boom",
        f"{DICP} on s1: aligned by se3-orientation (the others: se3); [fell back] 10 of 100 "
        "frames replaced by the motion prior (no usable registration)"])
    assert cells[(ICP, "s3")].status == "failed"
    assert notes[cells[(ICP, "s3")].note - 1] == f"{ICP} on s3: failed: boom"
    assert notes[dicp1.note - 1].startswith(f"{DICP} on s1: aligned by")
    assert icp1.note is None and icp2.note is None
    metas = {label: row.meta for label, row in made.rows}
    assert metas[ICP] == {"method": "icp", "label": None, "seed": "with", "status": "done"}


def test_the_caption_states_the_alignment_the_rule_and_what_the_marks_mean(results):
    made = collect_ape(results)
    assert made.table.caption == (
        "Absolute pose error [m]: translation RMSE after SE(3) alignment (Umeyama, all poses), "
        "as evo_ape -a computes it. " + RULE_UNPRINTED + " Div. = diverged; - = not run; "
        "failed = the run did not finish (reason in its footnote). " + SEED_NOTE)
    shown = collect_ape(results, ci=True, caption="APE")
    assert shown.table.caption.startswith(
        "APE after SE(3) alignment (Umeyama, all poses), as evo_ape -a computes it ([low, "
        "high]: its 95 % confidence interval, from blocks of the estimate's frame-to-frame "
        "errors resampled, chained along the ground truth and aligned as the figure; "
        "docs/metrics.md). " + RULE + " Div. = diverged; - = not run; failed")
    assert shown.table.rows[0].cells[0].parts[0].text.count("[") == 1
    by_value = collect_ape(results, marks="value")
    assert "by value alone" in by_value.table.caption


def test_a_table_without_failed_runs_does_not_explain_failed(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", ape=ape(0.5, [0.4, 0.6]))
    caption = collect_ape(tmp_path).table.caption
    assert caption.endswith("Div. = diverged; - = not run. " + SEED_NOTE)


def test_the_caption_states_the_alignment_most_runs_asked_for(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", ape=ape(0.5, requested="sim3"))
    write_run(tmp_path / "s2" / "icp_seed", ape=ape(0.5, requested="sim3"))
    write_run(tmp_path / "s3" / "icp_seed", ape=ape(0.5, requested="se3"))
    made = collect_ape(tmp_path)
    assert "after Sim(3) alignment (Umeyama, all poses), as evo_ape -as computes it. " in \
        made.table.caption
    notes = made.table.footnotes
    assert notes == [f"{ICP} on s3: aligned by se3 (the others: sim3)"]


def test_a_tie_of_alignments_is_broken_by_name(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", ape=ape(0.5, requested="sim3"))
    write_run(tmp_path / "s2" / "icp_seed", ape=ape(0.5, requested="origin"))
    caption = collect_ape(tmp_path).table.caption
    assert "after origin alignment (first estimated pose on the first GT pose), as evo_ape " \
           "--align_origin computes it. " in caption


def test_an_alignment_on_the_first_poses_says_how_it_is_recorded(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", ape=ape(0.5, requested="se3-first-5"))
    caption = collect_ape(tmp_path).table.caption
    assert ("after SE(3) alignment (Umeyama, first 5 poses), as evo_ape -a --n_to_align 5 "
            "computes it (recorded as se3-first-5: --alignment first-5 asks for this same "
            "SE(3) alignment, evo's group when none is named). ") in caption
    write_run(tmp_path / "s2" / "icp_seed", ape=ape(0.5, requested="sim3-first-5"))
    write_run(tmp_path / "s3" / "icp_seed", ape=ape(0.5, requested="sim3-first-5"))
    caption = collect_ape(tmp_path).table.caption
    assert "as evo_ape -as --n_to_align 5 computes it. " in caption
    assert "recorded as" not in caption


def test_only_failed_runs_give_the_default_alignment(tmp_path):
    write_failed(tmp_path / "s1" / "icp_seed", status="timeout", error="")
    made = collect_ape(tmp_path)
    assert made.table.footnotes == [f"{ICP} on s1: timeout: timeout"]
    assert "after SE(3) alignment (Umeyama, all poses)" in made.table.caption


def test_columns_in_the_order_asked_by_sequence_or_display_name(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", display_name="Seq One", ape=ape(0.5))
    write_run(tmp_path / "s2" / "icp_seed", display_name="Seq Two", ape=ape(0.7))
    assert collect_ape(tmp_path).sequences == ["Seq One", "Seq Two"]
    made = collect_ape(tmp_path, sequences=["s2", "Seq One", "zz"])
    assert made.sequences == ["Seq Two", "Seq One", "zz"]
    assert [c.parts[0].text if c.parts else c.status for c in made.table.rows[0].cells] == \
        ["0.70", "0.50", "-"]
    only = collect_ape(tmp_path, only={tmp_path / "s2" / "icp_seed"})
    assert only.sequences == ["Seq Two"]


def test_runs_under_one_label_get_a_row_each(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", {"alignment": "se3"}, ape=ape(0.5, [0.4, 0.6]))
    write_run(tmp_path / "s1" / "icp_seed_b", {"alignment": "sim3"}, method="icp",
              ape=ape(0.2, [0.1, 0.3], requested="sim3"))
    labels = [label for label, _ in collect_ape(tmp_path).rows]
    assert labels == [f"{ICP} [alignment=se3]", f"{ICP} [alignment=sim3]"]


def test_write_ape_tables_writes_beside_the_results_or_refuses_an_empty_folder(results,
                                                                               tmp_path):
    texts = write_ape_tables(results)
    for fmt in ("md", "tex", "csv"):
        assert (results / f"table_ape.{fmt}").read_text() == texts[fmt]
    lines = list(csv.DictReader(io.StringIO(texts["csv"])))
    assert {x["column"] for x in lines} == {"s1", "s2", "s3"}
    out = write_ape_tables(results, tmp_path / "o", sequences=["s2"], stem="x", caption="C",
                           marks="value", ci=True)
    assert (tmp_path / "o" / "x.md").read_text() == out["md"]
    assert "C after SE(3)" in out["md"] and "1.23 (1 segment)" in out["md"]
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError) as err:
        write_ape_tables(empty)
    assert str(err.value) == (f"{empty}: no finished runs with ground truth (no metrics.json "
                              "with an APE found)")


# ---- an unaligned estimate far from the ground truth's start -----------------------------

def _tum(path: Path, xyz, yaw_deg=0.0) -> None:
    half = math.radians(yaw_deg) / 2
    lines = [f"{t:.1f} {xyz[0] + t} {xyz[1]} {xyz[2]} 0 0 {math.sin(half)} {math.cos(half)}"
             for t in (0.0, 1.0)]
    path.write_text("\n".join(lines) + "\n")


def _offset_run(tmp_path, requested="none", gt=(0, 0, 0), est=(0, 0, 0), yaw=0.0,
                files=True) -> RunRecord:
    d = tmp_path / "run"
    d.mkdir()
    if files:
        _tum(d / "gt_tum.txt", gt)
        _tum(d / "est_tum.txt", est, yaw)
    result = RunResult(sequence="s", method="icp", diverged=False,
                       ape=ape(1.0, requested=requested))
    return RunRecord(d, result, {})


def test_an_unaligned_run_far_from_the_start_gets_a_note(tmp_path):
    note = start_offset_note(_offset_run(tmp_path, gt=(3, 4, 0)))
    assert note == ("no alignment, and the estimate starts 5.0 m / 0.0 deg from the ground "
                    "truth's first pose (it begins at the identity, the ground truth is in "
                    "world coordinates): this APE includes that offset; --alignment origin "
                    "puts the first poses together")


def test_a_turned_start_gets_the_note_too(tmp_path):
    note = start_offset_note(_offset_run(tmp_path, yaw=3.0))
    assert note is not None and "starts 0.0 m / 3.0 deg from" in note
    np.testing.assert_allclose(float(note.split(" m / ")[1].split()[0]), 3.0, atol=0.05)


@pytest.mark.parametrize("kwargs", [
    {"gt": (0.5, 0, 0)},  # at the limit: no note
    {"gt": (0.3, 0.3, 0), "yaw": 1.9},
    {"gt": (10, 0, 0), "requested": "se3"},  # aligned: the offset is fitted away
    {"gt": (10, 0, 0), "requested": "origin"},
    {"gt": (10, 0, 0), "files": False},  # no trajectory files
])
def test_no_note_near_the_start_or_when_aligned(tmp_path, kwargs):
    assert start_offset_note(_offset_run(tmp_path, **kwargs)) is None


def test_no_note_without_an_ape_or_with_empty_files(tmp_path):
    run = RunRecord(tmp_path, RunResult(sequence="s", method="icp", diverged=False), {})
    assert start_offset_note(run) is None
    run = _offset_run(tmp_path, gt=(10, 0, 0), files=False)
    (run.dir / "gt_tum.txt").write_text("")
    (run.dir / "est_tum.txt").write_text("")
    assert start_offset_note(run) is None


def test_the_note_reaches_the_tables_footnote(tmp_path):
    d = write_run(tmp_path / "s1" / "icp_seed", ape=ape(1.0, [0.9, 1.1], requested="none"))
    _tum(d / "gt_tum.txt", (0, 0, 2))
    _tum(d / "est_tum.txt", (0, 0, 0))
    notes = collect_ape(tmp_path).table.footnotes
    assert notes == [f"{ICP} on s1: no alignment, and the estimate starts 2.0 m / 0.0 deg "
                     "from the ground truth's first pose (it begins at the identity, the "
                     "ground truth is in world coordinates): this APE includes that offset; "
                     "--alignment origin puts the first poses together"]


# ---- survivors of make mutate ---------------------------------------------------------------

def test_sequences_in_natural_order_rows_in_the_papers_order(tmp_path):
    for seq in ("run10", "run2"):
        write_run(tmp_path / seq / "dicp_seed", ape=ape(0.5, [0.4, 0.6]))
        write_run(tmp_path / seq / "icp-p2p_seed", ape=ape(0.6, [0.5, 0.7]))
    made = collect_ape(tmp_path)
    assert made.sequences == ["run2", "run10"]
    # ICP point-to-point is a baseline of the paper: before DICP, whatever the names' order
    assert [label for label, _ in made.rows] == [run_label("icp-p2p", True), DICP]


def test_a_labelled_gt_assisted_run_and_the_value_rule(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", {"label": "v1"}, label="v1",
              ape=ape(0.30, [0.25, 0.45]))
    write_run(tmp_path / "s1" / "dicp_noseed",
              {"sequence": {"name": "s1", "doppler_kind": "gt-reconstructed"}},
              method="dicp", seed=False, ape=ape(0.40, [0.35, 0.50]))
    made = collect_ape(tmp_path)
    labelled, assisted = run_label("icp", True, "v1"), run_label("dicp", False) + \
        " [GT-assisted]"
    assert sorted(label for label, _ in made.rows) == sorted([labelled, assisted])
    metas = {label: row.meta for label, row in made.rows}
    assert metas[labelled] == {"method": "icp", "label": "v1", "seed": "with", "status": "done"}
    assert metas[assisted] == {"method": "dicp", "label": None, "seed": "without",
                               "status": "done"}
    assert made.table.caption.startswith("GT-ASSISTED: ")
    cells = _cells(made)
    # U = 0.45: both bold by the intervals; by value 0.30 bold, 0.40 underlined
    assert (cells[(labelled, "s1")].parts[0].rank, cells[(assisted, "s1")].parts[0].rank) == \
        (BEST, BEST)
    by_value = _cells(collect_ape(tmp_path, marks="value"))
    assert (by_value[(labelled, "s1")].parts[0].rank,
            by_value[(assisted, "s1")].parts[0].rank) == (BEST, SECOND)


def test_runs_alike_in_everything_but_their_folder_are_told_apart_by_it(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", ape=ape(0.5))
    write_run(tmp_path / "s1" / "icp_seed_again", method="icp", ape=ape(0.6))
    labels = [label for label, _ in collect_ape(tmp_path).rows]
    assert labels == [f"{ICP} [run folder icp_seed]", f"{ICP} [run folder icp_seed_again]"]


def test_a_few_frames_fallen_back_are_noted_without_the_flag(tmp_path):
    write_run(tmp_path / "s1" / "icp_seed", frames=101, frames_replaced=1, ape=ape(0.5))
    assert collect_ape(tmp_path).table.footnotes == [
        f"{ICP} on s1: 1 of 100 frames replaced by the motion prior (no usable registration)"]


def test_a_failure_without_a_reason_says_only_its_status(tmp_path):
    write_failed(tmp_path / "s1" / "icp_seed", status=" ", error="")
    assert collect_ape(tmp_path).table.footnotes == [f"{ICP} on s1:  : "]


def test_the_offset_is_between_the_two_starts(tmp_path):
    note = start_offset_note(_offset_run(tmp_path, gt=(3, 4, 0), est=(1, 1, 0)))
    assert "starts 3.6 m / 0.0 deg from" in note  # |(2, 3, 0)| = 3.61


def _tum_q(path: Path, q) -> None:
    text = " ".join(repr(float(v)) for v in q)
    path.write_text("".join(f"{t} 0 0 0 {text}\n" for t in (0.0, 1.0)))


def _turned_run(tmp_path, k, q_gt, q_est) -> RunRecord:
    d = tmp_path / f"run{k}"
    d.mkdir()
    _tum_q(d / "gt_tum.txt", q_gt)
    _tum_q(d / "est_tum.txt", q_est)
    return RunRecord(d, RunResult(sequence="s", method="icp", diverged=False,
                                  ape=ape(1.0, requested="none")), {})


def test_the_angle_between_the_starts_stays_defined_at_zero_and_half_a_turn(tmp_path):
    # the cosine of the angle, from rotation matrices, may fall a rounding error outside
    # [-1, 1]: the same orientation is 0 deg apart, one turned by 180 deg is 180 deg apart
    rng = np.random.default_rng(7)
    for k, q in enumerate(rng.normal(size=(12, 4))):
        q = q / np.linalg.norm(q)
        same = _turned_run(tmp_path, 2 * k, q, q)
        assert len(same.gt) == 2  # read back
        assert start_offset_note(same) is None
        x, y, z, w = q  # turned by 180 deg about its own x axis: q * (1, 0, 0, 0)
        half = np.array([w, z, -y, -x])
        note = start_offset_note(_turned_run(tmp_path, 2 * k + 1, q, half))
        assert note is not None and "0.0 m / 180.0 deg from" in note, note


def test_write_ape_tables_passes_every_choice_on(results, tmp_path):
    default = write_ape_tables(results, tmp_path / "d")["md"]
    assert "Absolute pose error [m]: translation RMSE after" in default
    assert "0.50" in default and "[0.40, 0.60]" not in default
    chosen = write_ape_tables(results, tmp_path / "c", sequences=["s1"], ci=True,
                              only={results / "s1" / "icp_seed"})["md"]
    assert chosen.splitlines()[0] == "| Method | s1 |"
    assert "0.50 [0.40, 0.60]" in chosen and "0.30" not in chosen
    reordered = write_ape_tables(results, tmp_path / "r", sequences=["s3", "s1"])["md"]
    assert reordered.splitlines()[0] == "| Method | s3 | s1 |"
