"""The paper's Tables IV and V from run folders (``bench table --metric ape`` for any results
folder): absolute pose error per method and sequence.

One row per method (and seed option, when a results folder holds both), one column per
sequence; each cell is the translation APE [m] (``metrics.json``'s ``ape.trans_rmse_m``, as
evo_ape computes it) after the alignment the runs were scored with (``ape.requested``, stated
in the caption; a cell whose alignment fell back to the orientations, or differs from the
others, carries a footnote), with its confidence interval (``ci``) and marks by ``marks``
(``bench.report.tables.model.MARK_RULES``: by default read from the printed intervals); a diverged
run
shows "Div." and is not ranked, as in the paper's Table V; a run that did not finish shows
"failed" with its reason in a footnote.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bench.report.names import (
    SEED_NOTE,
    gt_assisted_note,
    order_key,
    overrides_note,
    run_label,
    sequence_key,
    synthetic_note,
)
from bench.report.tables.model import (
    Cell,
    Row,
    Table,
    mark_column,
    rule_text,
    save_table,
)
from bench.report.tables.paper import stat_part
from bench.report.tables.row_keys import distinct_labels
from bench.runs.folders import RunRecord, load_runs
from metrics.ape import Alignment


@dataclass
class ApeTable:
    """The table model and what it was made of."""

    table: Table
    sequences: list[str]  # column titles (display names), in order

    @property
    def rows(self) -> list[tuple[str, Row]]:
        return [(r.keys[0], r) for r in self.table.rows]


def _runs(results_dir: Path, only: set[Path] | None) -> list[RunRecord]:
    return [r for r in load_runs(results_dir, only, failed=True)
            if not r.result.finished or (r.diverged is not None and r.result.ape is not None)]


def _first_n_words(spec: str) -> str:
    """What ``--alignment first-N`` is recorded as, in the caption: "se3-first-N" (evo's
    ``-a --n_to_align N``: SE(3) is the group when none is named)."""
    a = Alignment.parse(spec)
    if a.kind != "se3" or a.first_n is None:
        return ""
    return (f" (recorded as {a.name}: --alignment first-{a.first_n} asks for this same "
            "SE(3) alignment, evo's group when none is named)")


def collect_ape(results_dir: Path, sequences: list[str] | None = None,
                only: set[Path] | None = None, caption: str = "",
                marks: str = "intervals", ci: bool = False) -> ApeTable:
    """The APE table of every finished run with ground truth (and every run that did not
    finish) under ``results_dir``.

    ``sequences``: the columns (display names or sequence names) in order; default: every
    sequence found, in the paper's order (``names.sequence_key``)."""
    runs = _runs(results_dir, only)
    names = {r.sequence: r.display_name for r in runs}
    columns = (sorted(set(names.values()), key=sequence_key) if sequences is None
               else [names.get(s, s) for s in sequences])
    table = Table(["Method"], columns, [])
    by_row: dict[tuple, dict[str, RunRecord]] = {}
    # runs of one sequence under one label (e.g. differing only in --alignment) are told apart
    # by what differs in their configuration: one row each, none dropped
    labels = distinct_labels(runs, lambda r: run_label(r.method, r.seed, r.label,
                                                       r.doppler_kind)
                             + overrides_note(r.config),  # -p max_iterations=3 is no default
                             lambda r: r.display_name, lambda r: r.config, lambda r: r.dir)
    for r, label in zip(runs, labels, strict=True):
        key = (order_key(r.method), r.method, r.label or "", r.seed.rank, r.seed.value, label)
        by_row.setdefault(key, {})[r.display_name] = r
    requested = {r.result.ape.requested for r in runs if r.result.finished}
    # the alignment most runs asked for (ties: by name, so the caption never depends on the
    # order of a set)
    common = max(sorted(requested), key=lambda a: sum(
        r.result.finished and r.result.ape.requested == a for r in runs)) if requested else "se3"
    for key in sorted(by_row):
        cells = []
        for col in columns:
            r = by_row[key].get(col)
            if r is None:
                cells.append(Cell(status="-"))
            elif not r.result.finished:
                reason = (r.result.error or r.result.status).strip().splitlines()
                cells.append(Cell(status="failed", note=table.note(
                    f"{key[-1]} on {col}: {r.result.status}: {reason[0] if reason else ''}")))
            elif r.diverged:
                cells.append(Cell(status="Div.", values={"ape_trans_rmse_m":
                                                         r.result.ape.trans_rmse_m}))
            else:
                a = r.result.ape
                low, high = a.trans_rmse_m_ci or (None, None)
                cell = Cell([stat_part(a.trans_rmse_m, a.trans_rmse_m_ci,
                                       a.spread.n_independent, digits=2, show_ci=ci)],
                            values={"ape_trans_rmse_m": a.trans_rmse_m,
                                    "ape_trans_rmse_m_ci_low": low,
                                    "ape_trans_rmse_m_ci_high": high})
                # one footnote per cell, saying everything that applies to it
                said = []
                if a.alignment and a.alignment != common:
                    said.append(f"aligned by {a.alignment} (the others: {common})")
                offset = start_offset_note(r)
                if offset:
                    said.append(offset)
                if r.result.fallback_text():
                    flag = "[fell back] " if r.result.fell_back else ""
                    said.append(flag + r.result.fallback_text())
                if said:
                    cell.note = table.note(f"{key[-1]} on {col}: " + "; ".join(said))
                cells.append(cell)
        table.rows.append(Row([key[-1]], (), cells, {"method": key[1], "label": key[2] or None,
                                                     "seed": key[4], "status": "done"}))
    for i in range(len(columns)):
        mark_column(table.rows, i, 0, marks)
    failed = any(not r.result.finished for r in runs)
    table.caption = (synthetic_note(columns) + gt_assisted_note(row.keys[0] for row in table.rows)
                     + (caption or "Absolute pose error [m]: "
                     "translation RMSE") + f" after {Alignment.parse(common).description}, as "
                     f"evo_ape {Alignment.parse(common).evo_options} computes it"
                     + _first_n_words(common)
                     + (" ([low, high]: its 95 % confidence interval, from blocks of the "
                        "estimate's frame-to-frame errors resampled, chained along the ground "
                        "truth and aligned as the figure; docs/metrics.md)" if ci else "") + ". "
                     + rule_text(marks, ci) + " Div. = diverged; - = not run"
                     + ("; failed = the run did not finish (reason in its footnote)" if failed
                        else "") + ". " + SEED_NOTE)
    return ApeTable(table, columns)


#: an unaligned estimate whose first pose lies farther than this from the ground truth's
#: first pose gets a note (its APE is mostly that offset)
START_OFFSET_M, START_OFFSET_DEG = 0.5, 2.0


def start_offset_note(run: RunRecord) -> str | None:
    """A note for a run scored without alignment (``none``) whose estimate starts at its own
    origin far from the ground truth's first pose (GT in world coordinates): its APE includes
    that offset. None otherwise (or without trajectory files)."""
    a = run.result.ape
    if a is None or Alignment.parse(a.requested).kind != "none" or not run.has_gt:
        return None
    try:
        gt0, est0 = run.gt[0], run.est[0]
    except (OSError, ValueError, IndexError):
        return None
    offset_m = float(np.linalg.norm(gt0[:3, 3] - est0[:3, 3]))
    cos = (np.trace(gt0[:3, :3].T @ est0[:3, :3]) - 1) / 2
    angle_deg = float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
    if offset_m <= START_OFFSET_M and angle_deg <= START_OFFSET_DEG:
        return None
    return (f"no alignment, and the estimate starts {offset_m:.1f} m / {angle_deg:.1f} deg "
            "from the ground truth's first pose (it begins at the identity, the ground "
            "truth is in world coordinates): this APE includes that offset; "
            "--alignment origin puts the first poses together")


def write_ape_tables(results_dir: Path, out_dir: Path | None = None,
                     sequences: list[str] | None = None, stem: str = "table_ape",
                     caption: str = "", only: set[Path] | None = None,
                     marks: str = "intervals", ci: bool = False) -> dict[str, str]:
    """Write ``<stem>.{md,tex,csv}`` and return the texts by format."""
    ape = collect_ape(results_dir, sequences, only, caption, marks, ci)
    if not ape.table.rows:
        raise FileNotFoundError(f"{results_dir}: no finished runs with ground truth "
                                "(no metrics.json with an APE found)")
    return save_table(ape.table, Path(out_dir or results_dir), stem)
