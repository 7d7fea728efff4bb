"""The paper's Tables IV and V from run folders: absolute pose error per method and sequence.

One row per method (and seed option, when a results folder holds both), one column per
sequence; each cell is the translation APE [m] after SE(3) alignment (``metrics.json``'s
``ape.trans_rmse_m``, as evo computes it). Per column the best value is bold and the second
underlined; a diverged run shows "Div." and is not ranked, as in the paper's Table V.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

from bench.report.cells import md_mark, save_formats, tex_escape, tex_mark
from bench.report.names import (
    SEED_NOTE,
    gt_assisted_note,
    order_key,
    run_label,
    sequence_key,
    synthetic_note,
)
from bench.runs.folders import load_runs


@dataclass(frozen=True)
class ApeCell:
    ape_m: float
    diverged: bool


@dataclass
class ApeTable:
    sequences: list[str]                       # column titles (display names), in order
    rows: list[tuple[str, dict[str, ApeCell]]]  # (row label, sequence -> cell)


def collect_ape(results_dir: Path, sequences: list[str] | None = None,
                only: set[Path] | None = None) -> ApeTable:
    """The APE table of every finished run with ground truth under ``results_dir``.

    ``sequences``: the columns (display names or sequence names) in order; default: every
    sequence found, in the paper's order (``names.sequence_key``)."""
    runs = [r for r in load_runs(results_dir, only) if r.diverged is not None and r.ape]
    cells: dict[tuple, dict[str, ApeCell]] = {}
    names: dict[str, str] = {}
    for r in runs:
        title = r.display_name
        names[r.sequence] = title
        key = (order_key(r.method), r.method, r.label or "", r.seed is False,
               run_label(r.method, r.seed, r.label, r.doppler_kind))
        ape_m = r.ape.get("trans_rmse_m")
        cells.setdefault(key, {})[title] = ApeCell(
            math.nan if ape_m is None else float(ape_m), bool(r.diverged))
    if sequences is None:
        columns = sorted(set(names.values()), key=sequence_key)
    else:
        columns = [names.get(s, s) for s in sequences]
    rows = [(key[-1], cells[key]) for key in sorted(cells)]
    return ApeTable(columns, rows)


def _ranks(table: ApeTable) -> dict[tuple[int, str], int]:
    """(row index, column) -> 0 best, 1 second, 2 otherwise; diverged and missing unranked."""
    ranks = {}
    for col in table.sequences:
        values = sorted({c.ape_m for _, row in table.rows if (c := row.get(col))
                         and not c.diverged and math.isfinite(c.ape_m)})
        for i, (_, row) in enumerate(table.rows):
            c = row.get(col)
            if c and not c.diverged and math.isfinite(c.ape_m):
                ranks[(i, col)] = min(values.index(c.ape_m), 2)
    return ranks


def _cell_text(table: ApeTable, ranks, i: int, col: str, mark) -> str:
    c = table.rows[i][1].get(col)
    if c is None:
        return "-"
    if c.diverged:
        return "Div."
    if not math.isfinite(c.ape_m):
        return "-"
    return mark(f"{c.ape_m:.2f}", ranks.get((i, col), 2))


def to_markdown(table: ApeTable, caption: str = "") -> str:
    mark = md_mark
    ranks = _ranks(table)
    lines = ["| Method | " + " | ".join(table.sequences) + " |",
             "|---|" + "---|" * len(table.sequences)]
    for i, (label, _) in enumerate(table.rows):
        lines.append(f"| {label} | " + " | ".join(
            _cell_text(table, ranks, i, col, mark) for col in table.sequences) + " |")
    caption = (caption or "Absolute pose error [m] (translation RMSE after SE(3) alignment, as "
               "evo). Best per sequence in bold, second underlined; Div. = diverged.")
    caption = (synthetic_note(table.sequences) + gt_assisted_note(label for label, _ in table.rows)
               + caption + " " + SEED_NOTE)
    return "\n".join(lines) + "\n\n" + caption + "\n"


def to_latex(table: ApeTable, caption: str = "") -> str:
    mark = tex_mark
    ranks = _ranks(table)
    out = [r"\begin{tabular}{c|" + "c" * len(table.sequences) + "}", r"\hline",
           r"\textbf{Method} & "
           + " & ".join(rf"\textit{{{tex_escape(s)}}}" for s in table.sequences) + r" \\ \hline"]
    for i, (label, _) in enumerate(table.rows):
        out.append(tex_escape(label) + " & " + " & ".join(
            _cell_text(table, ranks, i, col, mark) for col in table.sequences) + r" \\")
    out += [r"\hline", r"\end{tabular}"]
    return "\n".join(out) + "\n"


def to_csv(table: ApeTable, caption: str = "") -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["method", "sequence", "ape_m", "diverged"])
    for label, row in table.rows:
        for col in table.sequences:
            c = row.get(col)
            if c is not None:
                w.writerow([label, col, "" if not math.isfinite(c.ape_m) else f"{c.ape_m:.6f}",
                            c.diverged])
    return buf.getvalue()


FORMATS = {"md": to_markdown, "tex": to_latex, "csv": to_csv}


def write_ape_tables(results_dir: Path, out_dir: Path | None = None,
                     sequences: list[str] | None = None, stem: str = "table_ape",
                     caption: str = "", only: set[Path] | None = None) -> dict[str, str]:
    """Write ``<stem>.{md,tex,csv}`` and return the texts by format."""
    table = collect_ape(results_dir, sequences, only)
    if not table.rows:
        raise FileNotFoundError(f"{results_dir}: no finished runs with ground truth "
                                "(no metrics.json with an APE found)")
    return save_formats(Path(out_dir or results_dir), stem,
                        {fmt: fn(table, caption) for fmt, fn in FORMATS.items()})
