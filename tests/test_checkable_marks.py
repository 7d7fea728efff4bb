"""Every mark checkable from what its page prints (issue 48): a table printed without its
intervals says so and names the file that holds them, and the marks re-derived from the
printed figures and that file's intervals alone are the marks printed. A table printed with
them says they are printed, and every marked figure shows one."""

from __future__ import annotations

import csv
import io
import re
from pathlib import Path

import numpy as np
import pytest

from bench.report.tables.ape import collect_ape
from bench.report.tables.model import save_table
from bench.report.tables.paper import build, select
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult

BOLD, UNDER, NONE = "bold", "under", "none"


def _write(root, seq, name, method, seed, gt, est):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 24.0, 48.0))
    config = {"method": method, "seed": seed, "label": None,
              "sequence": {"name": seq, "display_name": seq,
                           "sensor_class": "Semi-Dense 4D Radar"}}
    write_run(root / seq / name, result, ev.gt, config,
              {**ev.metrics, "sequence": seq, "method": method, "seed": seed, "frames": n,
               "status": "done"})


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Two sequences; four methods of graded noise, two of them equal in truth."""
    root = tmp_path_factory.mktemp("checkable")
    for seq, n in (("long", 900), ("short", 300)):
        gt = ground_truth(n)
        for k, (name, method, seed, noise) in enumerate((
                ("vgicp_seed", "vgicp", True, NoiseModel()),
                ("gicp_seed", "gicp", True, NoiseModel()),
                ("icp-p2p_seed", "icp-p2p", True, NoiseModel(0.12, 0.025)),
                ("doppler", "doppler", None, NoiseModel(0.3, 0.06)))):
            _write(root, seq, name, method, seed, gt, noisy_estimate(gt, noise, 10 * k + n))
    return root


def _printed_cells(md: str) -> dict[tuple[str, str, str], list[tuple[str, str]]]:
    """(group, row label, column) -> [(mark, printed text)] per part, from a markdown table
    (groups: the Sequence column when there is one, else one group per column)."""
    lines = [x for x in md.splitlines() if x.startswith("| ")]
    header = [c.strip() for c in lines[0].strip("|").split(" | ")]
    out, keys = {}, ["", "", ""]
    n_keys = 3 if header[0] == "Sensor" else 1
    for line in lines[1:]:
        cells = [c.strip() for c in line.strip("|").split(" | ")]
        keys = [c or k for c, k in zip(cells[:n_keys], keys, strict=False)]
        for col, cell in zip(header[n_keys:], cells[n_keys:], strict=True):
            parts = []
            for part in cell.split(" / "):
                part = re.sub(r" \[\d+\]$", "", part.strip())
                mark = BOLD if part.startswith("**") else UNDER if part.startswith("<u>") \
                    else NONE
                parts.append((mark, re.sub(r"\*\*|</?u>", "", part)))
            group = keys[1] if n_keys == 3 else col
            out[(group, keys[-1], col)] = parts
    return out


def _file_figures(path: Path) -> dict[tuple[str, str, str], list[tuple[float, float, float]]]:
    """(group, row, column) -> [(value, low, high)] per figure, from the CSV the caption names:
    every quantity q with q_ci_low / q_ci_high beside it, in the file's order."""
    cells: dict[tuple, dict[str, float]] = {}
    for r in csv.DictReader(io.StringIO(path.read_text())):
        group = r["sequence"] if r["column"].endswith(" m") or r["column"].startswith("Time") \
            else r["column"]
        cells.setdefault((group, r["row"], r["column"]), {})[r["quantity"]] = \
            float(r["value"]) if r["value"] else float("nan")
    out = {}
    for key, values in cells.items():
        out[key] = [(v, values[f"{q}_ci_low"], values[f"{q}_ci_high"])
                    for q, v in values.items() if f"{q}_ci_low" in values]
    return out


def _rule(figs: list[tuple[float, float, float]]) -> list[str]:
    """The tables' rule, written again: U = the smallest upper end, bold at or below it,
    underlined the same among the rest."""
    marks, left = [NONE] * len(figs), dict(enumerate(figs))
    for tier in (BOLD, UNDER):
        if not left:
            break
        u = min(hi for _, _, hi in left.values())
        for i in [i for i, (v, _, _) in left.items() if v <= u]:
            marks[i] = tier
            del left[i]
    return marks


def _check(md: str, csv_path: Path) -> int:
    """Re-derive every interval-marked part of ``md`` from its printed value and the CSV's
    interval (rounded to the printed digits, widened to hold the value); returns the count."""
    printed, filed = _printed_cells(md), _file_figures(csv_path)
    columns: dict[tuple[str, str, int], list] = {}
    for key, parts in printed.items():
        figs = filed.get(key, [])
        for p, (mark, text) in enumerate(parts):
            if p >= len(figs) or "segment)" in text or not re.match(r"-?\d", text):
                continue
            digits = len(text.split()[0].split(".")[1])
            v, lo, hi = figs[p]
            shown = [round(x, digits) for x in (v, min(lo, v), max(hi, v))]
            assert float(text.split()[0]) == shown[0], (key, text, v)
            columns.setdefault((key[0], key[2], p), []).append((mark, shown))
    checked = 0
    for col, members in columns.items():
        expected = _rule([s for _, s in members])
        assert [m for m, _ in members] == expected, (col, members)
        checked += len(members)
    return checked


def test_a_table_without_intervals_names_the_file_and_its_marks_check_out(results, tmp_path):
    rows, lengths = select(results)
    for metric, made in (("relative", build("relative", rows, lengths)),
                         ("ape", collect_ape(results).table)):
        texts = save_table(made, tmp_path, f"t_{metric}")
        md = texts["md"]
        assert "printed 95 % intervals" not in md  # it does not claim what it does not show
        assert "which this table does not print" in md
        named = re.search(r"they are in the CSV (\S+) \(written beside this table\), as the "
                          r"quantities", md).group(1)
        assert Path(named) == tmp_path / f"t_{metric}.csv" and Path(named).is_file()
        assert "--ci" in md
        assert _check(md, Path(named)) >= (12 if metric == "relative" else 4)


def test_a_table_with_intervals_says_so_and_prints_one_beside_every_marked_figure(results):
    rows, lengths = select(results)
    for made in (build("relative", rows, lengths, ci=True),
                 collect_ape(results, ci=True).table):
        md = save_table(made, Path(results), "t_ci")["md"]
        assert "printed 95 % intervals" in md and "does not print" not in md
        for parts in _printed_cells(md).values():
            for mark, text in parts:
                if mark != NONE and re.match(r"-?\d+\.\d+ ", text) and "segment)" not in text:
                    assert re.search(r"\[-?\d+\.\d+, -?\d+\.\d+\]", text), text


def test_the_check_would_see_a_wrong_mark(results, tmp_path):
    rows, lengths = select(results)
    made = build("relative", rows, lengths)
    md = save_table(made, tmp_path, "t")["md"]
    # a row whose 8 m rotation is bold: that mark taken away
    bold = next(line for line in md.splitlines() if line.startswith("| ")
                and line.split(" | ")[3].startswith("**"))
    cells = bold.split(" | ")
    cells[3] = cells[3].replace("**", "", 2)
    spoiled = md.replace(bold, " | ".join(cells), 1)
    with pytest.raises(AssertionError):
        _check(spoiled, tmp_path / "t.csv")
