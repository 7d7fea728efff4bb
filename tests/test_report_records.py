"""The report's and the tables' reading of run records (issue 34): a broken metrics.json
(truncated, or a field of the wrong type) is a failed row naming the file while every good
run keeps its table; `bench report` on a folder without runs is exit 2, with broken records
exit 1; runs that differ only in --alignment get one row each, saying so; names from data are
escaped in markdown (checked with markdown-it-py, an independent renderer) and on the page."""

import json
import shutil

import numpy as np
import pytest
from markdown_it import MarkdownIt

from bench.cli import main
from bench.report.html.markdown import inline
from bench.report.html.page import render_page
from bench.report.tables.model import md_escape
from bench.report.tables.paper import write_tables
from bench.report.tables.row_keys import differences
from bench.runs.folders import BROKEN, read_run
from bench.runs.job import Job
from bench.runs.plan import plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import write_store

EVIL = "<img src=x onerror=alert(1)> **b** [bold]x[/bold]"


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Two runs of one method on one store that differ only in their APE alignment."""
    root = tmp_path_factory.mktemp("records")
    seq = constant_twist_sequence(n_frames=30, n_points=1200, noise_m=0.02, max_range_m=60)
    seq.name = "twist"
    store = write_store(seq, root / "twist.h5")
    out = root / "results"
    jobs = [Job(store=store, method="doppler", seed=None, out_root=out, alignment=a,
                run_dir_override=out / "twist" / f"doppler_{a}") for a in ("se3", "sim3")]
    assert all(o.status == "done" for o in run_jobs(plan(jobs), executor="local"))
    return out


def _copy(results, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(results, copy)
    return copy


def _bench(args, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["bench", *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    captured = capsys.readouterr()
    return exit_.value.code, captured.out, captured.err


def test_runs_differing_only_in_alignment_get_one_row_each(results, tmp_path, capsys,
                                                           monkeypatch):
    for metric in ("ape", "relative", "kitti"):
        code, out, err = _bench(["table", str(results), "--metric", metric, "--out",
                                 str(tmp_path)], capsys, monkeypatch)
        assert code == 0, err
        rows = [line for line in out.splitlines() if line.startswith("|") and "Doppler" in line]
        assert len(rows) == 2, out
        assert "[alignment=se3]" in rows[0] and "[alignment=sim3]" in rows[1]


def test_what_differs_names_the_items_known_answer():
    a = {"identity": {"params": {"k": 1.0, "m": 2}, "scoring": {"alignment": "se3"},
                      "store_sha256": "ab" * 32, "code_sha256": "c1"},
         "sequence": {"store": "data/x.h5"}}
    b = json.loads(json.dumps(a))
    b["identity"]["params"]["k"] = 0.5
    b["identity"]["scoring"]["alignment"] = "first-50"
    assert differences([a, b]) == ["k=1, alignment=se3", "k=0.5, alignment=first-50"]
    assert differences([a, a]) == ["", ""]
    c = json.loads(json.dumps(a))
    c["sequence"]["store"], c["identity"]["store_sha256"] = "data/y.h5", "cd" * 32
    assert differences([a, c]) == ["store=x.h5", "store=y.h5"]  # the names, not the hashes


def test_a_truncated_record_is_a_failed_row_and_the_good_run_keeps_its_table(
        results, tmp_path, capsys, monkeypatch):
    """The page and the table with a broken record. The page is written without drawing the
    figures (``--no-figures``: about 5 s a drawing); the figures beside a broken record are
    test_figures_leave_out_a_broken_record_naming_it_and_tell_runs_apart's, and the report's
    drawing step with one is test_a_schema_invalid_record_names_the_field's."""
    copy = _copy(results, tmp_path)
    bad = copy / "twist" / "doppler_sim3" / "metrics.json"
    bad.write_text(bad.read_text()[:100])
    good = read_run(copy / "twist" / "doppler_se3")
    with pytest.raises(DataError, match="doppler_sim3/metrics.json: not valid JSON"):
        read_run(bad.parent)
    assert read_run(bad.parent, failed=True).result.status == BROKEN

    code, out, err = _bench(["report", str(copy), "--no-figures"], capsys, monkeypatch)
    assert code == 1 and "1 run record(s) broken" in out and "Traceback" not in out + err
    page = (copy / "report.html").read_text()
    assert f"{bad}: not valid JSON" in page and "Every run finished" not in page
    assert f"{good.result.ape.trans_rmse_m:.2f}" in page  # the good run's APE cell
    assert "No table" not in page

    code, out, err = _bench(["table", str(copy), "--metric", "ape"], capsys, monkeypatch)
    assert code == 1 and f"broken run record: {bad}: not valid JSON" in err
    assert "failed" in out and f"{good.result.ape.trans_rmse_m:.2f}" in out


def test_a_schema_invalid_record_names_the_field(results, tmp_path, capsys, monkeypatch):
    copy = _copy(results, tmp_path)
    bad = copy / "twist" / "doppler_se3" / "metrics.json"
    bad.write_text(json.dumps({**json.loads(bad.read_text()), "frames": "x"}))
    code, out, err = _bench(["report", str(copy)], capsys, monkeypatch)
    assert code == 1
    page = (copy / "report.html").read_text()
    assert "Every run finished" not in page
    assert f"{bad}: not a valid run record: field frames" in page
    code, out, err = _bench(["table", str(copy)], capsys, monkeypatch)
    assert code == 1 and "field frames" in out and "failed" in out  # its footnote and row


def test_a_folder_without_runs_is_exit_2(tmp_path, capsys, monkeypatch):
    (tmp_path / "empty").mkdir()
    code, out, err = _bench(["report", str(tmp_path / "empty")], capsys, monkeypatch)
    assert code == 2 and "no run records" in err and "Traceback" not in out + err
    assert not (tmp_path / "empty" / "report.html").exists()


def test_names_from_data_render_as_text_in_any_markdown_renderer(results, tmp_path):
    copy = _copy(results, tmp_path)
    for path in copy.rglob("metrics.json"):
        path.write_text(json.dumps({**json.loads(path.read_text()), "display_name": EVIL}))
    md = write_tables(copy)["md"]
    html = MarkdownIt("commonmark").enable("table").render(md)
    assert "<img" not in html and "<strong>b</strong>" not in html
    assert "&lt;img src=x onerror=alert(1)&gt; **b** [bold]x[/bold]" in html
    assert "<strong>" in html  # the table's own marks still render
    page, _ = render_page(copy)
    assert "<img src=x" not in page and "&lt;img src=x onerror=alert(1)&gt;" in page


def test_md_escape_keeps_plain_names_and_the_page_reads_it_back():
    assert md_escape("loop_radar-semidense_s0 (synthetic)") == \
        "loop_radar-semidense_s0 (synthetic)"
    assert md_escape("_a | `b`") == r"\_a \| \`b\`"
    for text in (EVIL, "a_ b | c & d [x](javascript:y) \\"):
        assert inline(md_escape(text)) == inline.__globals__["esc"](text)


def test_paper_coverage_notes_are_escaped_on_the_page(results, tmp_path):
    copy = _copy(results, tmp_path)
    (copy / "reproduction.json").write_text(json.dumps(
        {"data": "real", "found": [], "missing": ["Campus1"],
         "notes": ["<img src=x onerror=alert(1)> note"]}))
    page, _ = render_page(copy)
    assert "<img src=x" not in page
    assert "&lt;img src=x onerror=alert(1)&gt; note" in page


def test_a_metric_without_figures_and_nested_tables_are_not_dropped_silently(results,
                                                                           tmp_path):
    copy = _copy(results, tmp_path)
    for path in copy.rglob("metrics.json"):
        path.write_text(json.dumps({**json.loads(path.read_text()), "ape": None}))
    (copy / "sub").mkdir()
    (copy / "sub" / "table_kitti.md").write_text("| a | b |\n|---|---|\n| 1 | 2 |\n")
    for stem in ("table3_kitti", "table3_velocity"):  # bench reproduce's, as written
        write_tables(copy, copy, stem=stem, metric=stem.split("_")[1])
    page, counts = render_page(copy)
    ape = page.split("Absolute pose error (Tables IV / V)</h3>")[1].split("<h3>")[0]
    assert "Not made: no run of this folder has this metric" in ape
    assert "sub/table_kitti.md" in page
    assert ">table3_kitti.md</h3>" in page and ">table3_velocity.md</h3>" in page
    assert counts["tables"] == 3 + 1 + 2  # 3 made, the nested one, the two of the folder


def test_no_alignment_on_gt_in_world_coordinates_says_why_the_ape_is_large(
        tmp_path, capsys, monkeypatch):
    import numpy as np

    from loaders.trajectory import Trajectory

    seq = constant_twist_sequence(n_frames=25, n_points=1000, noise_m=0.02, max_range_m=60)
    T_world_origin = np.eye(4)
    T_world_origin[:3, 3] = (100.0, -40.0, 2.0)  # GT in world coordinates, far from the origin
    seq.ground_truth = Trajectory(seq.ground_truth.stamps, T_world_origin @ seq.ground_truth.poses)
    store = write_store(seq, tmp_path / "world.h5")
    res = tmp_path / "res"
    for alignment in ("none", "first-10"):
        code, out, err = _bench(["run", "--method", "doppler", "--data", str(store), "--out",
                                 str(res / "world" / f"doppler_{alignment}"), "--alignment",
                                 alignment, "--executor", "local"], capsys, monkeypatch)
        assert code == 0, out + err
        assert ("note: APE with no alignment, and the estimate starts 107.7 m" in out) == \
            (alignment == "none")
    code, out, err = _bench(["table", str(res), "--metric", "ape"], capsys, monkeypatch)
    assert code == 0, err
    assert "[alignment=none] on twist: no alignment, and the estimate starts 107.7 m" in out
    assert out.count("the estimate starts") == 1  # the first-10 run needs no such note
    assert "se3-first-10" in out and "[alignment=se3-first-10]" in out


def test_unreadable_files_of_a_run_folder_are_listed_and_exit_1(results, tmp_path, capsys,
                                                               monkeypatch):
    copy = _copy(results, tmp_path)
    gt = copy / "twist" / "doppler_se3" / "gt_tum.txt"
    gt.write_text("garbage\n")
    failed = copy / "twist" / "dicp_seed" / "failed.json"
    failed.parent.mkdir()
    failed.write_text("{trunc")
    (copy / "reproduction.json").write_text("[1, 2")
    code, out, err = _bench(["report", str(copy)], capsys, monkeypatch)
    assert code == 1 and "1 run folder(s) with unreadable files" in out, out + err
    page = (copy / "report.html").read_text()
    assert f"{gt}: no TUM pose rows found" in page and "Runs with unreadable files (1)" in page
    assert f"{failed}: not a readable failure record" in page
    assert "reproduction.json is not readable" in page


def test_figures_leave_out_a_broken_record_naming_it_and_tell_runs_apart(
        results, tmp_path, capsys, monkeypatch):
    from bench.report.figures.draw import _runs_with_gt
    from bench.report.figures.style import run_name

    assert sorted(run_name(r) for r in _runs_with_gt(results)) == [
        "Doppler Correspondence (Ours) [alignment=se3]",
        "Doppler Correspondence (Ours) [alignment=sim3]"]
    copy = _copy(results, tmp_path)
    bad = copy / "twist" / "doppler_sim3" / "metrics.json"
    bad.write_text("")
    code, out, err = _bench(["figures", str(copy)], capsys, monkeypatch)
    assert code == 1 and f"left out of the figures: {bad}: not valid JSON" in err
    assert "Traceback" not in out + err
    assert list((copy / "figures" / "trajectories").glob("*.png"))  # the good run's figure


def test_a_run_without_ground_truth_is_named_when_left_out_of_a_table(
        results, tmp_path, capsys, monkeypatch):
    copy = _copy(results, tmp_path)
    run = copy / "twist" / "doppler_sim3"
    raw = json.loads((run / "metrics.json").read_text())
    (run / "metrics.json").write_text(json.dumps({**raw, "relative_error": [], "ape": None,
                                                  "diverged": None, "kitti": None,
                                                  "velocity": None}))
    code, out, err = _bench(["table", str(copy)], capsys, monkeypatch)
    assert code == 0 and "[alignment=" not in out  # one row left: nothing to tell apart
    assert f"not in the table: {run} (no ground truth: nothing to score)" in err


@pytest.mark.parametrize("text,expected", [
    ("", "not valid JSON"), ("null", "expected a JSON object"),
    ('{"schema": "2"}', "field schema: should be an integer"),
    ('{"schema": 1, "sequence": "s", "method": "doppler", "diverged": "maybe"}',
     "field diverged"),  # an older record, re-scored, still invalid
])
def test_every_kind_of_broken_record_is_one_line_naming_the_file(results, tmp_path, text,
                                                                 expected):
    copy = _copy(results, tmp_path)
    bad = copy / "twist" / "doppler_sim3" / "metrics.json"
    bad.write_text(text)
    with pytest.raises(DataError, match=expected) as err:
        read_run(bad.parent)
    assert str(err.value).startswith(f"{bad}: ")
    rec = read_run(bad.parent, failed=True)
    assert rec.result.status == BROKEN and expected in rec.result.error
    page, counts = render_page(copy)
    assert counts["broken"] == 1 and expected in page


def test_a_failure_record_saying_done_is_no_finished_run(results, tmp_path):
    copy = _copy(results, tmp_path)
    run = copy / "twist" / "doppler_sim3"
    (run / "metrics.json").unlink()
    (run / "failed.json").write_text(json.dumps({"status": "done", "error": "odd"}))
    assert read_run(run, failed=True).result.status == "failed"


def test_a_run_file_is_parsed_once_per_version_and_handed_out_as_a_copy(tmp_path):
    """bench.runs.folders.read_run_tum: the same parsed trajectory while the file is
    unchanged (a caller changing its copy changes nothing for the next), the new content as
    soon as the file changes."""
    from bench.runs.folders import read_run_tum
    from loaders.posefile import write_tum
    from loaders.trajectory import Trajectory

    poses = np.repeat(np.eye(4)[None], 5, axis=0)
    poses[:, 0, 3] = np.arange(5.0)
    path = tmp_path / "est_tum.txt"
    write_tum(Trajectory(np.arange(5) * 0.1, poses), path)
    first = read_run_tum(path)
    first.poses[:, 0, 3] = -1.0  # the caller's copy
    np.testing.assert_array_equal(read_run_tum(path).poses[:, 0, 3], np.arange(5.0))
    poses[:, 0, 3] *= 2.0
    write_tum(Trajectory(np.arange(6)[:5] * 0.1, poses), path)
    path.write_text(path.read_text() + "0.5 9 0 0 0 0 0 1\n")  # one more row: a new version
    again = read_run_tum(path)
    assert len(again) == 6 and again.poses[1, 0, 3] == 2.0
