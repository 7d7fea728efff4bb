"""One page across datasets (bench.report.summary.overview): the tables' marks summed up per
sensor class (mean mark, bold count), failures counted, a method that cannot run on a class
says why, every sequence's source listed, and the HTML report showing it all with intervals."""

from __future__ import annotations

import numpy as np
import pytest

from bench.report.html.page import render_page
from bench.report.summary.overview import cross_dataset, summary_table
from bench.report.tables.model import to_markdown
from bench.report.tables.paper import select
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult


def _write(root, seq, cls, kind, name, method, seed, gt, est, dataset=None):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 48.0))
    config = {"method": method, "seed": seed,
              "sequence": {"name": seq, "display_name": seq, "sensor_class": cls,
                           "doppler_kind": kind, "dataset": dataset or f"{seq} dataset"}}
    write_run(root / seq / name, result, ev.gt, config,
              {**ev.metrics, "sequence": seq, "method": method, "seed": seed, "frames": n,
               "status": "done"})


@pytest.fixture(scope="module")
def two_datasets(tmp_path_factory):
    root = tmp_path_factory.mktemp("across")
    gt = ground_truth(900)
    good = noisy_estimate(gt, NoiseModel(), 1)
    bad = noisy_estimate(gt, NoiseModel(0.3, 0.06), 2)
    # a radar sequence (radial Doppler): doppler good, icp-p2p bad
    _write(root, "RadarSeq", "Semi-Dense 4D Radar", "radial", "doppler", "doppler", None, gt,
           good)
    _write(root, "RadarSeq", "Semi-Dense 4D Radar", "radial", "icp-p2p-seed", "icp-p2p", True,
           gt, bad)
    # a LiDAR sequence with ego-compensated Doppler: only the geometric method ran
    _write(root, "LidarSeq", "Dense 4D LiDAR", "ego-compensated", "icp-p2p-seed", "icp-p2p",
           True, gt, good)
    return root


def test_mean_rank_ties_and_why_a_method_did_not_run(two_datasets):
    rows, _ = select(two_datasets)
    table = summary_table(rows)
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}
    radar_doppler = by[("Semi-Dense 4D Radar", "doppler")]
    radar_icp = by[("Semi-Dense 4D Radar", "icp-p2p")]
    assert radar_doppler.cells[1].values["mean_mark"] == 1.0
    assert radar_icp.cells[1].values["mean_mark"] == 2.0  # underlined everywhere
    assert radar_doppler.cells[2].parts[0].text == "4 of 4"  # bold on every figure
    assert radar_doppler.cells[1].parts[0].rank == 0
    lidar_doppler = by[("Dense 4D LiDAR", "doppler")]
    assert "needs raw (radial) Doppler" in lidar_doppler.cells[0].status
    assert "ego-compensated" in lidar_doppler.cells[0].status
    assert by[("Dense 4D LiDAR", "icp-p2p")].cells[1].values["mean_mark"] == 1.0


def test_the_page_across_datasets_has_a_table_per_dataset_with_intervals(two_datasets):
    made = dict(cross_dataset(two_datasets))
    assert "Across datasets: mean mark per method" in made
    assert "Sources of the sequences" in made
    per_dataset = [t for title, t in made.items() if title.startswith("Dataset: ")]
    assert len(per_dataset) == 2
    assert all("[" in to_markdown(t) for t in per_dataset)  # intervals shown
    page, counts = render_page(two_datasets)
    assert "Across datasets" in page and "needs raw (radial) Doppler" in page
    assert counts["tables"] >= 4


def _write_failed(root, seq, cls, method, seed):
    from bench.runs.folders import write_failure

    config = {"method": {"name": method}, "seed": seed,
              "sequence": {"name": seq, "display_name": seq, "sensor_class": cls,
                           "doppler_kind": "radial", "dataset": "DsA"}}
    write_failure(root / seq / f"{method}_seed", config, "boom: the method raised")


def _write_short(root, seq, cls, kind, folder, method, seed, gt, est, dataset, label=None,
                 **extra):
    """A run scored at 2 and 4 m only (``extra``: metrics overrides, e.g. diverged)."""
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(2.0, 4.0))
    config = {"method": method, "seed": seed, "label": label,
              "sequence": {"name": seq, "display_name": seq, "sensor_class": cls,
                           "doppler_kind": kind, "dataset": dataset}}
    write_run(root / seq / folder, result, ev.gt, config,
              {**ev.metrics, "sequence": seq, "method": method, "seed": seed, "frames": n,
               "status": "done", **extra})


RADAR, LIDAR = "Semi-Dense 4D Radar", "Dense 4D LiDAR"


@pytest.fixture(scope="module")
def mixed(tmp_path_factory):
    """Two datasets scored at 2 and 4 m only. Radar (DsA): six sequences, doppler good and
    icp-p2p bad with and without seed on each; gicp diverged on S1, vgicp fell back on S2
    (60 of 299 frames replaced), kiss-icp failed on S3. LiDAR (DsB): two sequences, icp-p2p
    good on L1 and bad on L2, and an external trajectory (bench score) good on both, on this
    class only."""
    root = tmp_path_factory.mktemp("mixed")
    gt = ground_truth(300, speed_mps=2.0)
    good = noisy_estimate(gt, NoiseModel(0.02, 0.002), 1)
    bad = noisy_estimate(gt, NoiseModel(0.6, 0.06), 2)
    worse = noisy_estimate(gt, NoiseModel(0.9, 0.09), 3)
    for k in range(1, 7):
        seq = f"S{k}"
        _write_short(root, seq, RADAR, "radial", "doppler", "doppler", None, gt, good, "DsA")
        _write_short(root, seq, RADAR, "radial", "icp-p2p_seed", "icp-p2p", True, gt, bad,
                     "DsA")
        _write_short(root, seq, RADAR, "radial", "icp-p2p_noseed", "icp-p2p", False, gt,
                     worse, "DsA")
    _write_short(root, "S1", RADAR, "radial", "gicp_seed", "gicp", True, gt, bad, "DsA",
                 diverged=True)
    _write_short(root, "S2", RADAR, "radial", "vgicp_seed", "vgicp", True, gt, bad, "DsA",
                 frames_replaced=60)
    _write_failed(root, "S3", RADAR, "kiss-icp", True)
    _write_short(root, "L1", LIDAR, "ego-compensated", "icp-p2p_seed", "icp-p2p", True, gt,
                 good, "DsB")
    _write_short(root, "L2", LIDAR, "ego-compensated", "icp-p2p_seed", "icp-p2p", True, gt,
                 bad, "DsB")
    for seq in ("L1", "L2"):
        _write_short(root, seq, LIDAR, "ego-compensated", "kiss-ext", "kiss-ext", None, gt,
                     good, "DsB", label="kiss-ext (external)")
    return root


def test_summary_columns_count_sequences_failures_divergence_and_fallback(mixed):
    rows, _ = select(mixed)
    table = summary_table(rows)
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}
    col = {name: i for i, name in enumerate(table.columns)}

    def cell(cls, name, column):
        return by[(cls, name)].cells[col[column]]

    # six sequences, not twelve runs (the seed / no-seed pair is one sequence)
    assert cell(RADAR, "icp-p2p", "Sequences").values["sequences"] == 6
    assert cell(RADAR, "doppler", "Sequences").values["sequences"] == 6
    assert cell(RADAR, "gicp", "Diverged").values["diverged"] == 1
    assert cell(RADAR, "gicp", "Failed").values["failed"] == 0
    assert cell(RADAR, "vgicp", "Fell back").values["fell_back"] == 1
    assert cell(RADAR, "vgicp", "Diverged").values["diverged"] == 0
    assert cell(RADAR, "kiss-icp", "Failed").values["failed"] == 1
    assert cell(RADAR, "kiss-icp", "Sequences").values["sequences"] == 0  # never scored
    assert cell(RADAR, "doppler", "Failed").values["failed"] == 0
    assert cell(RADAR, "doppler", "Fell back").values["fell_back"] == 0
    # ranked at the lengths the runs have (2 and 4 m), not "-" for want of 8 / 48 m
    assert cell(RADAR, "doppler", "Mean mark").values["mean_mark"] == 1.0
    assert cell(RADAR, "icp-p2p", "Mean mark").values["mean_mark"] > 1.0
    assert "relative error at 2 m and 4 m" in table.caption
    # an external trajectory scored on one class only: its row on the other says so
    assert "external trajectory" in cell(RADAR, "kiss-ext (external)", "Sequences").status
    assert cell(LIDAR, "kiss-ext (external)", "Sequences").values["sequences"] == 2


def test_pairwise_verdicts_count_sequences_and_test_them(mixed):
    from bench.report.summary.pairwise import pairwise_table, sign_test_p

    assert sign_test_p(6, 0) == pytest.approx(2 / 64)
    assert sign_test_p(5, 1) == pytest.approx(2 * 7 / 64)
    assert sign_test_p(0, 0) == 1.0 and sign_test_p(3, 3) == 1.0
    rows, _ = select(mixed)
    table = pairwise_table(rows)
    col = {name: i for i, name in enumerate(table.columns)}
    by = {(r.keys[0], r.keys[1]): r for r in table.rows}
    a_b = by[(RADAR, "doppler")].cells[col["icp-p2p"]]
    assert a_b.values["better"] == 6 and a_b.values["sequences"] == 6
    assert a_b.parts[0].text == "6/6, p 0.031" and a_b.parts[0].rank == 0  # holds: bold
    b_a = by[(RADAR, "icp-p2p")].cells[col["doppler"]]
    assert b_a.values["better"] == 0 and b_a.parts[0].rank != 0
    # two LiDAR sequences: the external run better on L2, tied on L1: 1 of 2, no verdict
    ext = by[(LIDAR, "kiss-ext (external)")].cells[col["icp-p2p"]]
    assert (ext.values["better"], ext.values["tied"], ext.values["sequences"]) == (1, 1, 2)
    assert ext.values["p"] == 1.0 and ext.parts[0].rank != 0


def test_report_on_two_datasets_with_an_external_run_on_one_class(mixed):
    from typer.testing import CliRunner

    from bench.cli import app

    res = CliRunner().invoke(app, ["report", str(mixed), "--out", str(mixed / "page.html"),
                                   "--no-figures"])  # the figures: a test of their own
    assert res.exit_code == 0, res.output
    page = (mixed / "page.html").read_text()
    assert "Across sequences: pairwise verdicts" in page and "6/6, p 0.031" in page
    assert "relative error at 2 m and 4 m" in page
    # the long shared notes of the captions are shown once on the page, then referred to
    from bench.report.html.markdown import _SENTENCE, inline
    from bench.report.tables.model import md_escape
    from bench.report.tables.paper import build

    rows, lengths = select(mixed)
    caption = build("relative", rows, lengths, ci=True).caption
    shared = [s for s in _SENTENCE.split(md_escape(caption)) if len(s) > 80]
    assert shared and all(page.count(inline(s)) == 1 for s in shared)
    assert page.count("The other notes of this caption are given once, under") >= 3


def test_sources_name_the_vendored_sample_from_its_own_metadata(tmp_path):
    """The sample store was made by the generic NumPy-frame loader; its provenance says it is
    NTU4DRadLM (MIT): the sources table says so, not "NumPy frames ... licence: yours"."""
    from bench.paths import ROOT
    from bench.report.summary.overview import sources

    gt = ground_truth(120)
    _write(tmp_path, "loop1", "Semi-Dense 4D Radar", "radial", "doppler", "doppler", None, gt,
           gt)
    config = tmp_path / "loop1" / "doppler" / "config.yaml"
    import yaml

    data = yaml.safe_load(config.read_text())
    data["sequence"].pop("dataset")
    data["sequence"]["store"] = str(ROOT / "samples" / "ntu4dradlm-loop1.h5")
    config.write_text(yaml.safe_dump(data))
    rows, _ = select(tmp_path)
    (found,) = sources(rows)
    assert found["dataset"] == "NTU4DRadLM loop 1"
    assert found["licence"] == "MIT"
    assert found["loader"] == "npy-frames"


def test_parameter_overrides_are_in_the_row_label(tmp_path):
    """A run with -p max_iterations=3 is no default row: its label names the override; a
    labelled variant's label already says what it changes; and the job records what was
    given."""
    import yaml

    from bench.paths import ROOT
    from bench.runs.job import Job, prepare

    gt = ground_truth(120)
    _write(tmp_path, "seq", "Semi-Dense 4D Radar", "radial", "icp-p2p_seed", "icp-p2p", True,
           gt, gt)
    _write(tmp_path, "seq", "Semi-Dense 4D Radar", "radial", "mine_seed", "icp-p2p", True,
           gt, gt)
    for folder, extra in (("icp-p2p_seed", {}), ("mine_seed", {"label": "mine"})):
        path = tmp_path / "seq" / folder / "config.yaml"
        data = yaml.safe_load(path.read_text())
        data.update({"method": {"name": "icp-p2p", "given": {"max_iterations": 3}}, **extra})
        path.write_text(yaml.safe_dump(data))
    rows, _ = select(tmp_path)
    labels = sorted(r.label for r in rows)
    assert labels[0].endswith("ICP point-to-point [max_iterations=3]"), labels
    assert labels[1].endswith("mine"), labels
    # the APE table (methods x sequences) labels its rows alike
    from bench.report.tables.ape import collect_ape

    ape_rows = sorted(r.keys[0] for r in collect_ape(tmp_path).table.rows)
    assert ape_rows[0].endswith("ICP point-to-point [max_iterations=3]"), ape_rows
    assert ape_rows[1].endswith("mine"), ape_rows
    prep = prepare(Job(store=ROOT / "samples" / "ntu4dradlm-loop1.h5", method="icp-p2p",
                       seed=True, out_root=tmp_path, params={"max_iterations": 3}))
    prep.sequence.close()
    assert prep.config["method"]["given"] == {"max_iterations": 3}
    assert prep.config["method"]["params"]["max_iterations"] == 3


def test_a_fresh_report_draws_the_figures_it_shows(tmp_path):
    """`bench report` on a folder without figures draws them (a fresh report is complete);
    once they are newer than every run record it does not draw them again.

    On one run of 300 poses (30 s at 5 m/s: both segment lengths scored): what is drawn when
    does not depend on how many runs or poses there are, and drawing costs per figure (the
    two-dataset folder above has 16: 20 s of CPU per drawing, this one 8: about 5 s)."""
    import os

    from typer.testing import CliRunner

    from bench.cli import app

    root = tmp_path / "r"
    gt = ground_truth(300)
    _write(root, "RadarSeq", "Semi-Dense 4D Radar", "radial", "doppler", "doppler", None, gt,
           noisy_estimate(gt, NoiseModel(), 1))
    assert not (root / "figures").exists()
    res = CliRunner().invoke(app, ["report", str(root)])
    assert res.exit_code == 0, res.output
    pngs = sorted((root / "figures").rglob("*.png"))
    assert pngs and "drew" in res.output
    assert "<img" in (root / "report.html").read_text()
    stamps = {p: p.stat().st_mtime_ns for p in pngs}
    res = CliRunner().invoke(app, ["report", str(root)])
    assert res.exit_code == 0 and "drew" not in res.output
    assert {p: p.stat().st_mtime_ns for p in pngs} == stamps
    # a run newer than the figures: they are drawn again
    record = next(root.rglob("metrics.json"))
    later = max(stamps.values()) / 1e9 + 10
    os.utime(record, (later, later))
    res = CliRunner().invoke(app, ["report", str(root)])
    assert res.exit_code == 0 and "drew" in res.output
    # a folder without runs: no figure drawn, the report's own refusal (exit 2 from `bench`)
    (tmp_path / "empty").mkdir()
    res = CliRunner().invoke(app, ["report", str(tmp_path / "empty")])
    assert res.exit_code == 2 or type(res.exception).__name__ == "DataError", res.output
    assert not (tmp_path / "empty" / "figures").exists()


def _mark_counts_from_tables(root) -> dict[tuple, list[int]]:
    """(sensor class, method) -> the marks (1 bold, 2 underlined, 3 none) the page's
    per-dataset relative-error tables print at the summary's lengths: per sequence, figure and
    method, its better row's mark."""
    from bench.report.summary.ranks import ranked_lengths

    rows, lengths = select(root)
    ranked = ranked_lengths(rows)
    made = dict(cross_dataset(root))
    best: dict[tuple, int] = {}
    for title, table in made.items():
        if not title.startswith("Dataset: "):
            continue
        for row in table.rows:
            for col, name in enumerate(table.columns):
                if not name.endswith(" m") or float(name[:-2]) not in ranked:
                    continue
                for p, part in enumerate(row.cells[col].parts):
                    if part.stat is None or not part.stat.rankable:
                        continue
                    key = (row.keys[0], row.meta["method"], row.keys[1], col, p)
                    best[key] = min(best.get(key, 3), part.rank + 1)
    out: dict[tuple, list[int]] = {}
    for (cls, method, *_), mark in best.items():
        out.setdefault((cls, method), []).append(mark)
    return out


def test_the_summary_counts_the_marks_the_tables_print(mixed, two_datasets):
    """One rule per page: each method's mean mark and bold count are those of the marks the
    per-dataset tables on the same page print."""
    for root in (mixed, two_datasets):
        rows, _ = select(root)
        table = summary_table(rows)
        col = {name: i for i, name in enumerate(table.columns)}
        expected = _mark_counts_from_tables(root)
        checked = 0
        for r in table.rows:
            got = r.cells[col["Mean mark"]].values.get("mean_mark")
            marks = expected.get((r.keys[0], r.meta["method"]))
            if marks is None or r.meta.get("label"):
                continue
            assert got == pytest.approx(sum(marks) / len(marks)), (r.keys, marks)
            assert r.cells[col["Bold"]].values["bold_figures"] == marks.count(1)
            checked += 1
        assert checked >= 3


def test_an_underlined_method_is_not_ranked_with_the_bold_one(tmp_path):
    """The issue's case: B's interval overlaps A's (no interval wholly below B's), yet B's
    figure lies above A's upper end, so the tables underline it; the summary counts it 2, not
    tied best."""
    gt = ground_truth(900)
    est = noisy_estimate(gt, NoiseModel(), 1)
    for seq, dataset in (("SeqA", "DsA"), ("SeqB", "DsB")):
        for name, method, value, ci in (("doppler", "doppler", 1.0, (0.9, 1.1)),
                                        ("icp-p2p_seed", "icp-p2p", 1.3, (1.05, 1.6))):
            _write(tmp_path, seq, "Sparse 4D Radar", "radial", name, method,
                   None if method == "doppler" else True, gt, est, dataset)
            path = tmp_path / seq / name / "metrics.json"
            import json

            m = json.loads(path.read_text())
            for rel in m["relative_error"]:
                for q in ("rot_deg_mean", "trans_m_mean"):
                    rel[q], rel[f"{q}_ci"] = value, list(ci)
            path.write_text(json.dumps(m))
    rows, _ = select(tmp_path)
    table = summary_table(rows)
    by = {r.keys[1]: r for r in table.rows}
    assert by["doppler"].cells[1].values["mean_mark"] == 1.0
    assert by["icp-p2p"].cells[1].values["mean_mark"] == 2.0
    assert by["icp-p2p"].cells[2].values["bold_figures"] == 0
