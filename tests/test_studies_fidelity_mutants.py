"""``bench.studies.fidelity`` on hand-made runs and cells: what is read from a run folder, the
cells' ratios and their bounds, every finding's verdict and measured line, the report's
Markdown and CSV lines (each expected value worked out by hand from the paper's Table III row
or the made-up figures below)."""

from __future__ import annotations

import csv
import io
import math
from types import SimpleNamespace

import pytest

from bench.studies import fidelity as F


def _rec(seq, method, option, label=None, rel=(), ape=None, time_ms=1.0, diverged=False,
         config=None):
    result = SimpleNamespace(
        relative_error=[SimpleNamespace(length_m=x, rot_deg_mean=r, trans_m_mean=t)
                        for x, r, t in rel],
        ape=None if ape is None else SimpleNamespace(trans_rmse_m=ape),
        time_ms=SimpleNamespace(mean=time_ms))
    return SimpleNamespace(label=label, result=result, sequence=seq, method=method,
                           seed=SimpleNamespace(option=option), diverged=diverged,
                           config=config if config is not None else {})


def test_collect_runs_reads_every_field_of_the_unlabelled_runs(monkeypatch, tmp_path):
    records = [
        _rec("Loop1_0", "gicp", True, label="variant", rel=[(8.0, 9.0, 9.0)]),
        _rec("Loop1_0", "doppler", None, rel=[(8.0, 1.5, 0.25), (48.0, None, 2.0)], ape=3.5,
             time_ms=2.5, diverged=0, config={"sequence": {"sensor_class": "Semi-Dense"}}),
        _rec("Loop1_0", "dicp", False, rel=[(16.0, 1.0, 1.0)], time_ms=None, diverged=1,
             config={"sequence": {"sensor_class": None}}),
        _rec("Loop1_1", "dicp", True, config={"sequence": None})]
    seen = []
    monkeypatch.setattr(F, "load_runs", lambda d: seen.append(d) or records)
    runs = F.collect_runs(str(tmp_path))
    assert seen == [tmp_path]
    assert list(runs) == [("Loop1_0", "doppler", None), ("Loop1_0", "dicp", False),
                          ("Loop1_1", "dicp", True)]
    d = runs[("Loop1_0", "doppler", None)]
    assert (d.sequence, d.klass, d.method, d.seed) == ("Loop1_0", "Semi-Dense", "doppler", None)
    assert d.rel["8"] == (1.5, 0.25) and math.isnan(d.rel["48"][0]) and d.rel["48"][1] == 2.0
    assert set(d.rel) == {"8", "48"}
    assert (d.time_ms, d.ape_m, d.diverged) == (2.5, 3.5, False)
    c = runs[("Loop1_0", "dicp", False)]
    assert c.klass == "" and c.ape_m is None and c.diverged is True and math.isnan(c.time_ms)
    assert c.label == "dicp (no seed)" and runs[("Loop1_1", "dicp", True)].klass == ""
    assert runs[("Loop1_1", "dicp", True)].label == "dicp (with seed)" and d.label == "doppler"


@pytest.mark.parametrize(("value", "seed"), [("", None), (None, None), (True, True),
                                             (False, False), ("true", True), ("True", True),
                                             ("false", False), ("x", False)])
def test_seed_option_from_the_csv(value, seed):
    assert F._seed(value) is seed


def test_paper_table3_row_and_seed_options():
    paper = F.paper_table3()
    # paper/table3.csv: Semi-Dense 4D Radar,Loop1_2,dicp,true,0.625,0.620,...,1.859,3.213,4.0
    row = paper[("Loop1_2", "dicp", True)]
    assert row["class"] == "Semi-Dense 4D Radar" and row["time_ms"] == 4.0
    assert row["rel"]["8"] == (0.625, 0.620) and row["rel"]["48"] == (1.859, 3.213)
    assert list(row["rel"]) == list(F.LENGTHS)
    assert paper[("Loop1_2", "dicp", False)]["rel"]["8"] == (0.625, 0.623)
    assert paper[("Loop1_2", "doppler", None)]["time_ms"] == 0.4


def _cell(method, seed, length, quantity, paper, synth, seq="S1"):
    role = "calibration target" if method == F.TARGET else "prediction"
    return F.Cell(seq, "K", method, seed, length, quantity, paper, synth, role)


@pytest.mark.parametrize(("paper", "synth", "ratio", "within"), [
    (1.0, 2.0, 2.0, True), (2.0, 1.0, 0.5, True), (1.0, 2.001, 2.001, False),
    (1.0, 0.499, 0.499, False), (0.0, 1.0, math.nan, False), (-1.0, 1.0, math.nan, False),
    (math.inf, 1.0, math.nan, False), (math.nan, 1.0, math.nan, False),
    (1.0, math.nan, math.nan, False), (1.0, 0.0, 0.0, False)])
def test_cell_ratio_and_within_a_factor_of_two(paper, synth, ratio, within):
    c = _cell("gicp", True, "8", "rot_deg", paper, synth)
    if math.isnan(ratio):
        assert math.isnan(c.ratio)
    else:
        assert c.ratio == pytest.approx(ratio)
    assert c.within is within


def test_table3_cells_of_a_run_missing_a_length():
    paper = F.paper_table3()
    run = F.Run("Loop1_2", "", "dicp", True, {"8": (1.25, 1.24)}, 8.0, None, False)
    cells = F.table3_cells({("Loop1_2", "dicp", True): run}, paper)
    assert len(cells) == 13
    c8 = [c for c in cells if c.length == "8"]
    # paper 0.625 deg / 0.620 m at 8 m: ratios 2.0 both, a prediction of the Semi-Dense class
    assert [(c.quantity, c.paper, c.synth, c.klass, c.role) for c in c8] == [
        ("rot_deg", 0.625, 1.25, "Semi-Dense 4D Radar", "prediction"),
        ("trans_m", 0.620, 1.24, "Semi-Dense 4D Radar", "prediction")]
    assert all(c.sequence == "Loop1_2" and c.seed is True for c in cells)
    c16 = [c for c in cells if c.length == "16"]
    assert [c.paper for c in c16] == [0.928, 1.115] and all(math.isnan(c.synth) for c in c16)
    (t,) = [c for c in cells if c.quantity == "time_ms"]
    assert (t.length, t.paper, t.synth, t.role, t.klass) == ("", 4.0, 8.0, "prediction",
                                                             "Semi-Dense 4D Radar")


def test_target_check_worst_factor_and_a_zero_ratio():
    cells = [_cell("doppler", None, "8", "rot_deg", 1.0, 2.0),
             _cell("doppler", None, "8", "trans_m", 2.0, 0.8),      # 1 / 0.4 = 2.5
             _cell("doppler", None, "16", "rot_deg", 1.0, 9.0),     # not 8 or 48 m
             _cell("doppler", None, "48", "rot_deg", 1.0, 1.5),
             _cell("doppler", None, "", "time_ms", 1.0, 9.0),
             _cell("gicp", True, "8", "rot_deg", 1.0, 9.0),
             _cell("doppler", None, "8", "rot_deg", 1.0, 1.0, seq="S2"),
             _cell("doppler", None, "48", "rot_deg", 1.0, 0.0, seq="S2"),
             _cell("doppler", None, "8", "rot_deg", 1.0, 0.5, seq="S3"),
             _cell("doppler", None, "48", "rot_deg", 1.0, 2.0, seq="S3")]
    (s1, w1, ok1), (s2, w2, ok2), (s3, w3, ok3) = F.target_check(cells)
    assert (s1, s2, s3) == ("S1", "S2", "S3")
    assert w1 == pytest.approx(2.5) and not ok1
    assert w2 == math.inf and not ok2
    assert w3 == pytest.approx(2.0) and ok3


def test_prediction_shares_count_accuracy_cells_of_every_seed_option():
    cells = [_cell("gicp", True, "8", "rot_deg", 1.0, 1.5), _cell("gicp", False, "8",
                                                                   "trans_m", 1.0, 5.0),
             _cell("gicp", True, "", "time_ms", 1.0, 1.0), _cell("doppler", None, "8",
                                                                 "rot_deg", 1.0, 1.0),
             _cell("dicp", True, "48", "rot_deg", 1.0, 0.6)]
    assert F.prediction_shares(cells) == [("gicp", 1, 2), ("dicp", 1, 1)]


# findings -------------------------------------------------------------------------------------

def _run(seq, method, seed, rot=1.0, trans=1.0, time_ms=1.0, ape=1.0, diverged=False):
    return F.Run(seq, "", method, seed, {n: (rot, trans) for n in F.LENGTHS}, time_ms, ape,
                 diverged)


def _put(runs, *items):
    for r in items:
        runs[(r.sequence, r.method, r.seed)] = r
    return runs


def test_ape_prefers_the_seeded_run_and_marks_divergence():
    runs = _put({}, _run("S", "gicp", True, ape=2.0), _run("S", "gicp", None, ape=9.0),
                _run("S", "doppler", None, ape=3.0), _run("S", "dicp", True, diverged=True),
                _run("S", "vgicp", True, ape=None), _run("S", "kiss-icp", False, ape=1.0))
    assert F._ape(runs, "S", "gicp") == 2.0 and F._ape(runs, "S", "doppler") == 3.0
    assert F._ape(runs, "S", "dicp") == math.inf and F._ape(runs, "S", "vgicp") == math.inf
    assert math.isnan(F._ape(runs, "S", "kiss-icp")) and math.isnan(F._ape(runs, "T", "gicp"))
    assert [F._fmt_ape(x) for x in (math.inf, math.nan, 2.345, 10.0)] == ["Div.", "-", "2.35",
                                                                          "10.00"]


def test_finding_doppler_fastest_per_row():
    paper = F.paper_table3()
    runs = _put({}, _run("Loop1_2", "doppler", None, time_ms=0.4),
                _run("Loop1_2", "dicp", True, time_ms=4.0),
                _run("Loop1_2", "dicp", False, time_ms=2.0),
                _run("Loop1_2", "kiss-icp", True, time_ms=0.1),       # not in Table III
                _run("Loop1_3", "doppler", None, time_ms=5.0),        # alone: no row
                _run("Loop1_4", "dicp", True), _run("Loop1_4", "dicp", False))  # no doppler
    f = F.findings(runs, paper)[0]
    assert f.holds and f.source == "Table III"
    assert f.measured == ["Loop1_2: doppler 0.40 ms vs dicp (with seed) 4.00, dicp (no seed) "
                          "2.00"]
    _put(runs, _run("Loop1_3", "dicp", False, time_ms=5.0))  # a tie is not fastest
    f = F.findings(runs, paper)[0]
    assert not f.holds
    assert f.measured[1] == "Loop1_3: doppler 5.00 ms vs dicp (no seed) 5.00 (NOT fastest)"


def test_finding_icp_family_diverges_in_both_tunnels():
    paper = F.paper_table3()
    runs = {}
    for seq in F.TUNNELS:
        _put(runs, *[_run(seq, m, True, ape=None, diverged=True) for m in F.ICP_FAMILY])
    f = F.findings(runs, paper)[1]
    assert f.holds and f.source == "Table V"
    assert f.measured == [f"{seq}: icp-p2p Div., icp-p2plane Div., gicp Div., vgicp Div."
                          for seq in F.TUNNELS]
    # one that did not diverge fails the finding, whatever comes after it
    _put(runs, _run("Tunnel_Vehicles", "gicp", True, ape=5.0))
    del runs[("Tunnel_Empty", "icp-p2p", True)]
    f = F.findings(runs, paper)[1]
    assert not f.holds
    assert f.measured == ["Tunnel_Empty: icp-p2p - m, icp-p2plane Div., gicp Div., vgicp Div.",
                          "Tunnel_Vehicles: icp-p2p Div., icp-p2plane Div., gicp 5.00 m, "
                          "vgicp Div."]


def test_findings_lowest_ape_in_the_tunnels_and_on_the_loops():
    paper = F.paper_table3()
    runs = {}
    for seq in F.TUNNELS[1:]:  # Tunnel_Empty: no run, no line
        _put(runs, _run(seq, "icp-p2p", True, diverged=True), _run(seq, "dicp", True, ape=3.0),
             _run(seq, "doppler-icp", True, ape=2.0), _run(seq, "doppler", None, ape=2.5),
             _run(seq, "kiss-icp", True, ape=0.1))  # not one of the paper's methods
    for seq in ("Loop1_0", "Loop1_1"):
        _put(runs, _run(seq, "vgicp", True, ape=1.0), _run(seq, "doppler", None, ape=2.0))
    # Loop1_3: no run, no line (the next is still checked)
    _put(runs, _run("Loop1_4", "doppler-icp", True, ape=1.0), _run("Loop1_4", "gicp", True,
                                                                   ape=4.0))
    found = F.findings(runs, paper)
    tunnels, loops = found[2], found[3]
    assert tunnels.holds and tunnels.source == "Table V"
    assert tunnels.measured == ["Tunnel_Vehicles: lowest doppler-icp (2.00 m); icp-p2p Div., "
                                "dicp 3.00, doppler 2.50, doppler-icp 2.00"]
    # Loop1_0 reported, not checked; Loop1_1 has vgicp lowest: the finding fails
    assert not loops.holds and loops.source == "Table IV"
    assert loops.measured == [
        "Loop1_0: lowest vgicp (1.00 m) [not checked]; vgicp 1.00, doppler 2.00",
        "Loop1_1: lowest vgicp (1.00 m) (NOT a winner); vgicp 1.00, doppler 2.00",
        "Loop1_4: lowest doppler-icp (1.00 m); gicp 4.00, doppler-icp 1.00"]
    del runs[("Loop1_1", "vgicp", True)]
    assert F.findings(runs, paper)[3].holds  # Loop1_0's vgicp alone does not count


@pytest.mark.parametrize(("rot", "trans", "text", "holds"), [
    (2.1, 0.475, "rotation 2.100 vs 2.000 deg (1.05x), translation 0.475 vs 0.500 m (0.95x)",
     True),
    (2.4, 0.5, "rotation 2.400 vs 2.000 deg (1.20x), translation 0.500 vs 0.500 m (1.00x)",
     False),
    (2.0, 0.425, "rotation 2.000 vs 2.000 deg (1.00x), translation 0.425 vs 0.500 m (0.85x)",
     False)])
def test_finding_loop1_2_doppler_within_ten_percent_of_dicp(rot, trans, text, holds):
    paper = F.paper_table3()
    # DICP at 2 deg / 0.5 m at 8 m: doppler / DICP per error
    runs = _put({}, _run("Loop1_2", "doppler", None, rot=rot, trans=trans),
                _run("Loop1_2", "dicp", True, rot=2.0, trans=0.5))
    f = F.findings(runs, paper)[4]
    assert f.holds is holds and f.source == "Table III"
    assert f.measured == [f"{text}; paper 0.617 / 0.650 vs 0.625 / 0.620"]


def test_finding_loop1_2_without_both_runs_does_not_hold():
    paper = F.paper_table3()
    only = _put({}, _run("Loop1_2", "doppler", None))
    f = F.findings(only, paper)[4]
    assert not f.holds and f.measured == []
    no_8 = _put({}, _run("Loop1_2", "dicp", True),
                F.Run("Loop1_2", "", "doppler", None, {"16": (1.0, 1.0)}, 1.0, 1.0, False))
    assert not F.findings(no_8, paper)[4].holds
    assert len(F.findings({}, paper)) == 5


# the report -----------------------------------------------------------------------------------

CELLS = [_cell("doppler", None, "8", "rot_deg", 1.0, 2.0),
         _cell("doppler", None, "8", "trans_m", 2.0, 1.0),
         _cell("doppler", None, "48", "rot_deg", 1.0, 3.0),
         _cell("doppler", None, "48", "trans_m", 1.0, 1.0),
         _cell("doppler", None, "", "time_ms", 2.0, 4.0),
         _cell("gicp", True, "8", "rot_deg", 1.0, 1.5),
         _cell("gicp", True, "8", "trans_m", 1.0, 5.0),
         _cell("gicp", False, "8", "rot_deg", 1.0, math.nan),
         _cell("gicp", False, "8", "trans_m", 0.0, 1.0)]
FINDS = [F.Finding("claim A", "Table III", True, ["m1", "m2"]),
         F.Finding("claim B", "Table V", False)]


def test_format_markdown_lines():
    text = F.format_markdown(CELLS, FINDS, "CALIBRATION", "HEADER")
    lines = text.splitlines()
    assert lines[:6] == [f"# {F.TITLE}", "", "HEADER", "", "CALIBRATION", ""]
    assert text.endswith("|\n")
    # doppler: worst of 2, 1/0.5, 3, 1 at 8 and 48 m = 3 (OUTSIDE); gicp: 1.5 within, 5, nan
    # and a zero paper value outside: 1 of 4
    checks = lines[6:12]
    assert checks == [
        "## Checks", "",
        "- `doppler` (the calibration target) within 2x of Table III at 8 m and 48 m (rotation "
        "and translation): 0 of 1 sequences",
        "  - S1: worst factor 3.00 (OUTSIDE)",
        "- `gicp` (prediction): 1 of 4 Table III cells within 2x (25%; goal 80%: NOT reached)",
        ""]
    assert lines[12] == "## The paper's findings: 1 of 2 hold on the synthetic suite"
    i = lines.index("1. **holds**: claim A (Table III)")
    assert lines[i + 1:i + 4] == ["   - m1", "   - m2", "2. **does NOT hold**: claim B (Table V)"]
    assert "## Table III, every cell: paper / synthetic (ratio synthetic / paper)" in lines
    assert any("`*` marks a ratio outside 2x. Role: `doppler` = calibration target" in ln
               for ln in lines)
    j = lines.index("| sequence | method | role | length | rotation paper / synth (x) | "
                    "translation paper / synth (x) |")
    assert lines[j + 1:] == [
        "|---|---|---|---|---|---|",
        "| S1 | doppler | calibration target | 8 m | 1.000 / 2.000 (2.00) | 2.000 / 1.000 (0.50) |",
        "| S1 | doppler | calibration target | 48 m | 1.000 / 3.000 (3.00*) | 1.000 / 1.000 "
        "(1.00) |",
        "| S1 | doppler | calibration target | time | 2.00 / 4.00 ms (2.00) | |",
        "| S1 | gicp (with seed) | prediction | 8 m | 1.000 / 1.500 (1.50) | 1.000 / 5.000 "
        "(5.00*) |",
        "| S1 | gicp (no seed) | prediction | 8 m | 1.000 / - (-*) | 0.000 / 1.000 (-*) |"]


def test_format_markdown_without_header_and_a_reached_goal():
    # every length with both errors, as table3_cells makes them
    cells = [_cell("doppler", None, "8", "rot_deg", 1.0, 1.25),
             _cell("doppler", None, "8", "trans_m", 1.0, 0.8),
             *[_cell("gicp", True, n, q, 1.0, 1.0) for n in ("8", "16", "24", "32")
               for q in ("rot_deg", "trans_m")],
             _cell("gicp", True, "40", "rot_deg", 1.0, 3.0),
             _cell("gicp", True, "40", "trans_m", 1.0, 3.0)]
    lines = F.format_markdown(cells, []).splitlines()
    assert lines[:4] == [f"# {F.TITLE}", "", "## Checks", ""]
    assert "  - S1: worst factor 1.25 (within)" in lines
    assert ("- `doppler` (the calibration target) within 2x of Table III at 8 m and 48 m "
            "(rotation and translation): 1 of 1 sequences") in lines
    # 8 of 10 = 80 %, the goal exactly: reached
    assert "- `gicp` (prediction): 8 of 10 Table III cells within 2x (80%; goal 80%: reached)" \
        in lines
    assert "## The paper's findings: 0 of 0 hold on the synthetic suite" in lines


def test_format_csv_rows():
    rows = list(csv.reader(io.StringIO(F.format_csv(CELLS[4:8]))))
    assert rows[0] == ["data", "sequence", "sensor_class", "method", "seed", "length_m",
                       "quantity", "paper", "synthetic", "ratio", "within_2x", "role"]
    assert rows[1:] == [
        ["synthetic", "S1", "K", "doppler", "", "", "time_ms", "2.0000", "4.0000", "2.0000",
         "true", "calibration target"],
        ["synthetic", "S1", "K", "gicp", "true", "8", "rot_deg", "1.0000", "1.5000", "1.5000",
         "true", "prediction"],
        ["synthetic", "S1", "K", "gicp", "true", "8", "trans_m", "1.0000", "5.0000", "5.0000",
         "false", "prediction"],
        ["synthetic", "S1", "K", "gicp", "false", "8", "rot_deg", "1.0000", "nan", "nan",
         "false", "prediction"]]


def test_calibration_text_one_line_per_sensor_class():
    from loaders.synthetic.sensors import CALIBRATION

    lines = F.calibration_text().splitlines()
    assert lines[0] == ("Calibration (one fitted value per sensor class; "
                        "loaders/synthetic/README.md):")
    sensor, name, value, how = CALIBRATION["Sparse 4D Radar"]
    assert f"- Sparse 4D Radar: `{sensor}.{name}` = {value:g} ({how})" in lines
    assert len(lines) == 1 + len(CALIBRATION)


def test_write_report_into_another_folder_with_a_header(monkeypatch, tmp_path):
    runs = _put({}, _run("Loop1_2", "doppler", None, rot=1.234, trans=0.65, time_ms=0.8))
    seen = []
    monkeypatch.setattr(F, "collect_runs", lambda d: seen.append(d) or runs)
    path = F.write_report(str(tmp_path / "results"), str(tmp_path / "out"), header="HEAD")
    assert seen == [tmp_path / "results"] and path == tmp_path / "out" / "fidelity.md"
    text = path.read_text()
    assert text.splitlines()[2] == "HEAD" and "Calibration (one fitted value" in text
    # paper 0.617 deg / 0.650 m at 8 m on Loop1_2
    assert "| Loop1_2 | doppler | calibration target | 8 m | 0.617 / 1.234 (2.00) | 0.650 / " \
           "0.650 (1.00) |" in text
    rows = (tmp_path / "out" / "fidelity.csv").read_text().splitlines()
    assert len(rows) == 1 + 13 and not (tmp_path / "results" / "fidelity.md").exists()


def test_findings_claims_as_the_report_states_them():
    found = F.findings({}, F.paper_table3())
    assert [(f.claim, f.source) for f in found] == [
        ("`doppler` is the fastest method in every Table III row", "Table III"),
        ("the ICP family (point-to-point, point-to-plane, GICP, VGICP) diverges in both tunnels",
         "Table V"),
        ("Doppler 4D-ICP has the lowest APE among the paper's methods in both tunnels",
         "Table V"),
        ("on Loop1_1, Loop1_3 and Loop1_4 one of the paper's two Doppler methods (`doppler`, "
         "`doppler-icp`) has the lowest APE among the paper's methods (Table IV has VGICP "
         "lowest on Loop1_0, reported for information)", "Table IV"),
        ("semi-dense Loop1_2: `doppler` within 10 % of DICP (with seed) at 8 m, rotation and "
         "translation", "Table III")]
    # no run: nothing measured; the ICP finding fails (no divergence), the two APE findings
    # hold vacuously, Loop1_2's needs both runs
    assert [f.holds for f in found] == [True, False, True, True, False]


def test_format_markdown_prose_and_a_method_without_accuracy_cells():
    cells = [_cell("gicp", True, "", "time_ms", 1.0, 1.0),
             _cell("dicp", True, "16", "rot_deg", 1.0, 1.0),
             _cell("dicp", True, "16", "trans_m", 1.0, 1.0)]
    lines = F.format_markdown(cells, [F.Finding("c", "s", False)]).splitlines()
    # no accuracy cell: no share (nan), the goal not reached
    assert "- `gicp` (prediction): 0 of 0 Table III cells within 2x (nan%; goal 80%: NOT " \
           "reached)" in lines
    i = lines.index("## The paper's findings: 0 of 1 hold on the synthetic suite")
    assert lines[i + 1:i + 5] == [
        "", "Checked by value, as the paper states them (fastest, lowest APE, within 10 %), one "
        "drive per sequence: \"holds\" says the values fall that way, not that the 95 % "
        "intervals tell the methods apart (the tables' marks and their intervals say where "
        "they do; APE intervals mostly overlap).", "", "1. **does NOT hold**: c (s)"]
    j = lines.index("## Table III, every cell: paper / synthetic (ratio synthetic / paper)")
    assert lines[j - 1:j + 4] == [
        "", "## Table III, every cell: paper / synthetic (ratio synthetic / paper)", "",
        "Rotation [deg] / translation [m] mean relative error per segment length; time [ms] per "
        "frame (the paper's i7-14700KF against this machine: not a fidelity measure). `*` marks "
        "a ratio outside 2x. Role: `doppler` = calibration target, others = prediction.", ""]
    # a method with a 16 m row only (no 8 m): its row is still there
    assert lines[-2:] == [
        "| S1 | gicp (with seed) | prediction | time | 1.00 / 1.00 ms (1.00) | |",
        "| S1 | dicp (with seed) | prediction | 16 m | 1.000 / 1.000 (1.00) | 1.000 / 1.000 "
        "(1.00) |"]
