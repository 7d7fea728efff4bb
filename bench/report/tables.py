"""The paper's Table III from run folders: rows grouped by sensor class and sequence, one row
per method and seed option, "rotation / translation" per segment length and the mean time per
frame. Per sequence and column, the best value is bold and the second underlined; a diverged run
shows "Div." and is not ranked.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bench.report.cells import md_mark, ranks, save_formats, tex_escape, tex_mark
from bench.report.names import (
    SEED_NOTE,
    gt_assisted_note,
    hosts_note,
    order_key,
    run_label,
    sequence_key,
    synthetic_note,
)
from bench.runs.folders import load_runs
from loaders.sensor_classes import class_rank


@dataclass
class Row:
    sensor_class: str
    sequence: str
    method: str
    seed: bool | None
    label: str
    rot: dict[str, float]     # length -> mean rotation error [deg]
    trans: dict[str, float]   # length -> mean translation error [m]
    time_ms: float
    diverged: bool
    threads: int = 1  # a run on several threads is timed by the wall clock (methods.timing)
    cpu: str | None = None  # the CPU model the run was timed on (metrics.json)


#: what the Time column holds (methods/base.py, methods/timing.py)
TIME_NOTE = ("Time: mean per-frame time [ms] of all per-frame work from a scan in memory to its "
             "pose (downsampling, normals, kd-trees, maps, registration, map update; not file "
             "I/O), after the same untimed warm-up for every method; the CPU time of a "
             "one-thread run, which other jobs running beside it do not inflate (a run marked "
             "[N thr.] used N threads and is timed by the wall clock).")


def _value(x) -> float:
    return math.nan if x is None else float(x)


def collect_rows(results_dir: Path, only: set[Path] | None = None
                 ) -> tuple[list[Row], list[str]]:
    """Rows of every finished run with ground truth (or of the run folders in ``only``), sorted
    as in the paper, and the lengths."""
    rows, lengths = [], set()
    for run in load_runs(results_dir, only):
        if not run.relative_error or run.diverged is None:
            continue
        rel = run.relative_error
        lengths.update(rel)
        rows.append(Row(
            sensor_class=run.sensor_class, sequence=run.display_name,
            method=run.method, seed=run.seed,
            label=run_label(run.method, run.seed, run.label, run.doppler_kind),
            rot={k: _value(v["rot_deg_mean"]) if v["n"] else math.nan for k, v in rel.items()},
            trans={k: _value(v["trans_m_mean"]) if v["n"] else math.nan for k, v in rel.items()},
            time_ms=_value(run.time_ms.get("mean")),
            diverged=bool(run.diverged),
            threads=int(run.metrics.get("threads") or 1), cpu=run.metrics.get("cpu"),
        ))
    return sorted(rows, key=_row_order), sorted(lengths, key=float)


def _row_order(r: Row):
    # Table III's order: sensor classes, the paper's sequences, the baselines before the
    # paper's own methods, and with seed before without
    return (class_rank(r.sensor_class), r.sensor_class, sequence_key(r.sequence),
            order_key(r.method), r.method, r.seed is False, r.label)


def collect_rows_of(results_dirs: list[Path]) -> tuple[list[Row], list[str]]:
    """Rows of several results folders in one table; with more than one folder, each row's
    label starts with its folder's name (the experiment)."""
    if len(results_dirs) == 1:
        return collect_rows(results_dirs[0])
    rows, lengths = [], set()
    for d in results_dirs:
        these, lens = collect_rows(d)
        lengths.update(lens)
        for r in these:
            r.label = f"{Path(d).name}: {r.label}"
        rows += these
    return sorted(rows, key=_row_order), sorted(lengths, key=float)


def _fmt(x: float, digits: int = 3) -> str:
    return "-" if not math.isfinite(x) else f"{x:.{digits}f}"


def _fmt_time(x: float, threads: int = 1) -> str:
    text = "-" if not math.isfinite(x) else (f"{x:.2f}" if x < 10 else f"{x:.1f}")
    return text if threads == 1 else f"{text} [{threads} thr.]"


def _cells(rows: list[Row], lengths: list[str], mark) -> list[list[str]]:
    """Formatted cells per row; ``mark(text, rank)`` applies bold / underline."""
    out = [[] for _ in rows]
    groups: dict[tuple, list[int]] = {}
    for i, r in enumerate(rows):
        groups.setdefault((r.sensor_class, r.sequence), []).append(i)
    for idx in groups.values():
        ranked = [i for i in idx if not rows[i].diverged]
        for length in lengths:
            rot = ranks([rows[i].rot.get(length, math.nan) for i in ranked])
            trans = ranks([rows[i].trans.get(length, math.nan) for i in ranked])
            rank = {i: (a, b) for i, a, b in zip(ranked, rot, trans, strict=True)}
            for i in idx:
                r = rows[i]
                if r.diverged:
                    out[i].append("Div.")
                    continue
                a, b = rank[i]
                out[i].append(f"{mark(_fmt(r.rot.get(length, math.nan)), a)} / "
                              f"{mark(_fmt(r.trans.get(length, math.nan)), b)}")
        times = ranks([rows[i].time_ms for i in ranked])
        trank = dict(zip(ranked, times, strict=True))
        for i in idx:  # a diverged run's time is still real: shown, not ranked
            text = _fmt_time(rows[i].time_ms, rows[i].threads)
            out[i].append(text if rows[i].diverged else mark(text, trank[i]))
    return out


def to_markdown(rows: list[Row], lengths: list[str]) -> str:
    mark = md_mark
    header = ["Sensor", "Sequence", "Method", *[f"{float(L):g} m" for L in lengths],
              "Time (ms)"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    prev = (None, None)
    for r, cells in zip(rows, _cells(rows, lengths, mark), strict=True):
        klass = r.sensor_class if r.sensor_class != prev[0] else ""
        seq = r.sequence if (r.sensor_class, r.sequence) != prev else ""
        prev = (r.sensor_class, r.sequence)
        lines.append("| " + " | ".join([klass, seq, r.label, *cells]) + " |")
    caption = (synthetic_note(r.sequence for r in rows) + gt_assisted_note(r.label for r in rows) +
               "Each cell: mean rotation [deg] / translation [m] relative error per segment "
               "length. " + TIME_NOTE + " " + hosts_note(r.cpu for r in rows) +
               "Best per sequence in bold, second underlined; Div. = "
               "diverged. " + SEED_NOTE)
    return "\n".join(lines) + "\n\n" + caption + "\n"


def to_latex(rows: list[Row], lengths: list[str]) -> str:
    mark = tex_mark
    ncol = 3 + len(lengths) + 1
    out = [r"\begin{tabular}{@{}" + "c" * ncol + "@{}}", r"\toprule",
           " & ".join(["Sensor", "Dataset", "Method",
                       *[rf"\textbf{{{float(L):g}m}}" for L in lengths], r"\textbf{Time (ms)}"])
           + r" \\", r"\midrule"]
    prev = (None, None)
    for r, cells in zip(rows, _cells(rows, lengths, mark), strict=True):
        if prev[0] is not None and r.sensor_class != prev[0]:
            out.append(r"\midrule")
        elif prev[0] is not None and r.sequence != prev[1]:
            out.append(rf"\cmidrule{{2-{ncol}}}")
        klass = tex_escape(r.sensor_class) if r.sensor_class != prev[0] else ""
        seq = rf"\emph{{{tex_escape(r.sequence)}}}" if (r.sensor_class, r.sequence) != prev \
            else ""
        prev = (r.sensor_class, r.sequence)
        out.append(" & ".join([klass, seq, tex_escape(r.label), *cells]) + r" \\")
    out += [r"\bottomrule", r"\end{tabular}"]
    return "\n".join(out) + "\n"


def to_csv(rows: list[Row], lengths: list[str]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["sensor_class", "sequence", "method", "seed", "row", "diverged",
                *[f"{k}_{float(L):g}m" for L in lengths for k in ("rot_deg", "trans_m")],
                "time_ms_mean"])
    for r in rows:
        vals = []
        for L in lengths:
            vals += [r.rot.get(L, math.nan), r.trans.get(L, math.nan)]
        w.writerow([r.sensor_class, r.sequence, r.method,
                    "" if r.seed is None else r.seed, r.label, r.diverged,
                    *[f"{v:.6f}" for v in vals], f"{r.time_ms:.6f}"])
    return buf.getvalue()


FORMATS = {"md": to_markdown, "tex": to_latex, "csv": to_csv}


def is_variant(row: Row) -> bool:
    """A labelled variant of a method (an experiment entry with its own ``label:``)."""
    return row.label not in (run_label(row.method, row.seed),
                             run_label(row.method, row.seed, doppler_kind="gt-reconstructed"))


def select_rows(results_dir: Path | list[Path], only: set[Path] | None = None,
                lengths_m: list[float] | None = None,
                keep: Callable[[Row], bool] | None = None) -> tuple[list[Row], list[str]]:
    """The rows and lengths of a table (of every run, or of the folders in ``only``; of several
    results folders, each row labelled with its folder; only the segment lengths in
    ``lengths_m`` when given; only the rows ``keep`` accepts). Raises when nothing is left."""
    if isinstance(results_dir, list):
        rows, lengths = collect_rows_of(results_dir)
        results_dir = results_dir[0]
    else:
        rows, lengths = collect_rows(results_dir, only)
    if keep is not None and rows:
        rows = [r for r in rows if keep(r)]
        if not rows:
            raise ValueError(f"{results_dir}: no run matches the chosen methods / variants")
    if not rows:
        raise FileNotFoundError(f"{results_dir}: no finished runs with ground truth "
                                "(no metrics.json found)")
    if lengths_m is not None:
        missing = [L for L in lengths_m if not any(float(x) == L for x in lengths)]
        if missing:
            raise ValueError(f"{results_dir}: no results at {', '.join(f'{L:g}' for L in missing)}"
                             f" m (scored lengths: {', '.join(f'{float(x):g}' for x in lengths)})")
        lengths = [x for x in lengths if float(x) in lengths_m]
    return rows, lengths


def write_tables(results_dir: Path | list[Path], out_dir: Path | None = None,
                 only: set[Path] | None = None, stem: str = "table",
                 lengths_m: list[float] | None = None,
                 keep: Callable[[Row], bool] | None = None,
                 rows_lengths: tuple[list[Row], list[str]] | None = None) -> dict[str, str]:
    """Write <stem>.md, .tex and .csv of ``select_rows``'s rows (or of ``rows_lengths`` when
    already selected); return the texts by format."""
    rows, lengths = rows_lengths or select_rows(results_dir, only, lengths_m, keep)
    first = results_dir[0] if isinstance(results_dir, list) else results_dir
    return save_formats(Path(out_dir or first), stem,
                        {fmt: fn(rows, lengths) for fmt, fn in FORMATS.items()})


