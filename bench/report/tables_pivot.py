"""Methods against sequences: one markdown table per segment length, a row per method (and
seed option or label), a column per sequence, "rotation / translation" per cell; per column
the best value is bold and the second underlined (diverged runs show "Div." and are not
ranked). For comparing one method with all others across a suite at a glance
(``bench table DIR --pivot``)."""

from __future__ import annotations

import math

from bench.report.cells import md_mark, ranks
from bench.report.tables import Row


def _fmt(x: float) -> str:
    """Three decimals below 1 (LiDAR translations are millimetres), two above."""
    return "-" if not math.isfinite(x) else (f"{x:.2f}" if abs(x) >= 1 else f"{x:.3f}")


def to_pivot_markdown(rows: list[Row], length: str) -> str:
    """The table at one segment length (a key of ``Row.rot``, e.g. "48")."""
    sequences = list(dict.fromkeys(r.sequence for r in rows))
    labels = list(dict.fromkeys(r.label for r in rows))
    by_key = {(r.label, r.sequence): r for r in rows}
    cells: dict[tuple[str, str], str] = {}
    for seq in sequences:
        ranked = [by_key[(lab, seq)] for lab in labels
                  if (lab, seq) in by_key and not by_key[(lab, seq)].diverged]
        rot = ranks([r.rot.get(length, math.nan) for r in ranked])
        trans = ranks([r.trans.get(length, math.nan) for r in ranked])
        for r, a, b in zip(ranked, rot, trans, strict=True):
            cells[(r.label, seq)] = (f"{md_mark(_fmt(r.rot.get(length, math.nan)), a)} / "
                                     f"{md_mark(_fmt(r.trans.get(length, math.nan)), b)}")
        for lab in labels:
            if (lab, seq) in by_key and by_key[(lab, seq)].diverged:
                cells[(lab, seq)] = "Div."
    lines = [f"| {float(length):g} m | " + " | ".join(sequences) + " |",
             "|---|" + "---|" * len(sequences)]
    for lab in labels:
        lines.append(f"| {lab} | " + " | ".join(cells.get((lab, s), "") for s in sequences)
                     + " |")
    lines.append("")
    lines.append(f"Each cell: mean rotation [deg] / translation [m] relative error over "
                 f"{float(length):g} m segments; per sequence the best is bold, the second "
                 "underlined; Div. = diverged; empty = not run.")
    return "\n".join(lines) + "\n"
