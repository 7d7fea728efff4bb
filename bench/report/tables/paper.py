"""Per-run tables from run folders, shaped as the paper's Table III: rows grouped by sensor
class and sequence, one row per method and seed option (``runs``), and one table per metric:

- ``relative_table``: "rotation / translation" mean relative error per segment length and the
  mean time per frame (the paper's Table III);
- ``kitti_table``: KITTI drift, translation [%] and rotation [deg/100 m] over 100-800 m;
- ``velocity_table``: ego-velocity error per axis and as a norm [m/s] (and, for a method that
  measures it, its own Doppler velocity's error).

The APE table (methods x sequences, the paper's Tables IV/V) is ``bench.report.tables.ape``.
Every figure carries its confidence interval and independent-segment count (``metrics.json``,
``bench.runs.uncertainty``), shown with ``ci=True`` and always in the CSV; marks follow
``marks`` (``bench.report.tables.model.MARK_RULES``: by default read from the printed intervals
alone,
``bench.report.tables.significance``); a diverged run
shows "Div." and is not ranked; a run that did not finish stays as a "failed" row with its
reason in a footnote; a run whose frames fell back (replaced by the motion prior, or not
converged) carries a footnote saying how many, and is flagged when more than
``FALLBACK_LIMIT`` of them did. Every table is a ``bench.report.tables.model.Table`` (rendered to
md /
tex / csv).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bench.report.names import (
    SEED_NOTE,
    gt_assisted_note,
    hosts_note,
    order_key,
    overrides_note,
    run_label,
    sequence_key,
    synthetic_note,
)
from bench.report.tables.model import (
    Cell,
    Part,
    Row,
    Stat,
    Table,
    mark_column,
    rule_text,
    save_table,
    stat_text,
)
from bench.report.tables.row_keys import distinct_labels
from bench.runs.folders import RunRecord, load_runs, with_sequence_tags
from bench.runs.result import FALLBACK_LIMIT, REPORTED_CLOCK, RunResult, nan
from loaders.sensor_classes import class_rank
from methods.registry import Seed
from metrics.velocity import DEFAULT_WINDOW_S

#: the metrics ``bench table --metric`` shows
METRICS = ("relative", "kitti", "ape", "velocity")

#: what the Time column holds (methods/base.py, methods/timing.py)
TIME_NOTE = ("Time: mean per-frame time [ms] of all per-frame work from a scan in memory to its "
             "pose (downsampling, normals, kd-trees, maps, registration, map update; not file "
             "I/O), after the same untimed warm-up for every method; the CPU time of a "
             "one-thread run, which other jobs running beside it do not inflate (a run marked "
             "[N thr.] used N threads and is timed by the wall clock).")
FAILED_NOTE = "failed = the run did not finish (the reason in its footnote)."


@dataclass
class RunRow:
    """One run as a table row: its record and its row label (with its folder's name when
    several results folders are merged)."""

    run: RunRecord
    label: str

    @property
    def result(self) -> RunResult:
        return self.run.result

    @property
    def sensor_class(self) -> str:
        return self.run.sensor_class

    @property
    def sequence(self) -> str:
        return self.run.display_name

    @property
    def method(self) -> str:
        return self.run.method

    @property
    def seed(self) -> Seed:
        return self.run.seed

    @property
    def failed(self) -> bool:
        return not self.result.finished

    @property
    def diverged(self) -> bool:
        return bool(self.result.diverged)

    @property
    def is_variant(self) -> bool:
        """A labelled variant of a method (an experiment entry with its own ``label:``)."""
        return bool(self.run.label)

    def order(self) -> tuple:
        # Table III's order: sensor classes, the paper's sequences, the baselines before the
        # paper's own methods, and with seed before without
        return (class_rank(self.sensor_class), self.sensor_class, sequence_key(self.sequence),
                order_key(self.method), self.method, self.seed.rank, self.label)


def runs(results_dir: Path | list[Path], only: set[Path] | None = None) -> list[RunRow]:
    """Every finished run with ground truth and every run that did not finish (or only the run
    folders in ``only``), in the paper's order; of several results folders, each row labelled
    with its folder's name."""
    dirs = results_dir if isinstance(results_dir, list) else [results_dir]
    found = [(d, run) for d in dirs for run in load_runs(d, only, failed=True)
             if not (run.result.finished and not run.result.scored)]  # no GT: nothing to show
    # different content under one sequence name, across the folders too: never one sequence
    tagged = with_sequence_tags([run for _, run in found])
    out = []
    for (d, _), run in zip(found, tagged, strict=True):
        label = (run_label(run.method, run.seed, run.label, run.doppler_kind)
                 + overrides_note(run.config))  # -p max_iterations=3 is no default row
        out.append(RunRow(run, f"{Path(d).name}: {label}" if len(dirs) > 1 else label))
    # two runs of one sequence under one label (e.g. differing only in --alignment): each row
    # says what differs (bench.report.tables.row_keys), none is merged or dropped
    labels = distinct_labels(out, lambda r: r.label, lambda r: r.sequence,
                             lambda r: r.run.config, lambda r: r.run.dir)
    for row, label in zip(out, labels, strict=True):
        row.label = label
    return sorted(out, key=RunRow.order)


def scored_lengths(rows: list[RunRow]) -> list[float]:
    return sorted({r.length_m for x in rows for r in x.result.relative_error})


def select(results_dir: Path | list[Path], only: set[Path] | None = None,
           lengths_m: list[float] | None = None,
           keep: Callable[[RunRow], bool] | None = None) -> tuple[list[RunRow], list[float]]:
    """The rows and lengths of a table (of every run, or of the folders in ``only``; only the
    segment lengths in ``lengths_m`` when given; only the rows ``keep`` accepts). Raises when
    nothing is left."""
    first = results_dir[0] if isinstance(results_dir, list) else results_dir
    rows = runs(results_dir, only)
    if keep is not None and rows:
        rows = [r for r in rows if keep(r)]
        if not rows:
            raise ValueError(f"{first}: no run matches the chosen methods / variants")
    if not rows:
        raise FileNotFoundError(f"{first}: no finished runs with ground truth "
                                "(no metrics.json found)")
    lengths = scored_lengths(rows)
    if lengths_m is not None:
        missing = [L for L in lengths_m if L not in lengths]
        if missing:
            raise ValueError(
                f"{first}: no results at {', '.join(f'{L:g}' for L in missing)} m (scored "
                f"lengths: {', '.join(f'{x:g}' for x in lengths)}); score them with `bench run "
                f"--lengths {','.join(f'{x:g}' for x in sorted(set(lengths) | set(missing)))}` "
                "(an experiment's lengths_m); KITTI drift over 100-800 m: `bench table --metric "
                "kitti`")
        lengths = [x for x in lengths if x in lengths_m]
    return rows, lengths


# ---- rows -------------------------------------------------------------------------------------

def _row(table: Table, rr: RunRow, cells: list[Cell]) -> Row:
    """A table row of a run; a run that did not finish gets "failed" cells and a footnote, a
    run whose frames fell back a footnote on its first cell saying how many (and "[fell
    back]" in its label above ``FALLBACK_LIMIT``)."""
    if rr.failed:
        reason = (rr.result.error or rr.result.status).strip().splitlines()
        note = table.note(f"{rr.label} on {rr.sequence}: {rr.result.status}: "
                          f"{reason[0] if reason else ''}")
        cells = [Cell(status="failed", note=note if i == 0 else None)
                 for i in range(len(table.columns))]
    elif rr.result.fallback_text() and cells and cells[0].note is None:
        cells[0].note = table.note(f"{rr.label} on {rr.sequence}: "
                                   f"{rr.result.fallback_text()}")
    label = rr.label
    if not rr.failed and rr.result.fell_back:
        label += " [fell back]"
    return Row([rr.sensor_class, rr.sequence, label], (rr.sensor_class, rr.sequence), cells,
               {"sequence": rr.run.sequence, "sensor_class": rr.sensor_class,
                "method": rr.method, "seed": rr.seed.value, "label": rr.run.label,
                "status": rr.result.status if rr.failed else
                ("diverged" if rr.diverged else "done")})


def fmt_time(x: float | None, threads: int = 1) -> str:
    x = nan(x)
    text = "-" if not math.isfinite(x) else (f"{x:.2f}" if x < 10 else f"{x:.1f}")
    return text if threads == 1 else f"{text} [{threads} thr.]"


def _caption(rows: list[RunRow], text: str, marks: str = "intervals",
             ci: bool = False) -> str:
    failed = FAILED_NOTE + " " if any(r.failed for r in rows) else ""
    fell = (f"[fell back] = more than {100 * FALLBACK_LIMIT:g} % of the run's frames were "
            "replaced by the motion prior or did not converge (counts in the footnotes). "
            if any(not r.failed and r.result.fell_back for r in rows) else "")
    level = next((r.result.ci_level for r in rows if r.result.finished), 0.95)
    shown = (f"[low, high] = the {100 * level:g} % confidence interval (block bootstrap "
             "along the trajectory; docs/metrics.md). " if ci else "")
    return (synthetic_note(r.sequence for r in rows) + gt_assisted_note(r.label for r in rows)
            + text + " " + shown + hosts_note(r.result.cpu for r in rows
                                              if r.result.finished and r.result.timed_by_harness)
            + rule_text(marks, ci) + " Div. = diverged; " + failed + fell + SEED_NOTE)


def _ci(ci) -> tuple[float, float] | None:
    return None if ci is None or None in ci else (float(ci[0]), float(ci[1]))


def stat_part(value: float | None, ci, n_independent: int | None, digits: int = 3,
              show_ci: bool = False) -> Part:
    """A figure as a table part with the ``Stat`` its marks are decided on (the numbers it
    prints: ``bench.report.tables.significance``)."""
    stat = Stat(nan(value), _ci(ci), n_independent, digits)
    return Part(stat_text(value, ci, n_independent, digits, show_ci), stat=stat)


REPORTED_NOTE = ("A time marked [reported] is the external method's own figure, not measured by "
                 "the harness: not ranked.")


def _time_cell(rr: RunRow) -> Cell:
    t = rr.result.time_ms.mean
    text = fmt_time(t, rr.result.threads)
    if rr.result.clock == REPORTED_CLOCK and text != "-":
        text += " [reported]"
    return Cell([Part(text, stat=Stat(nan(t)))], values={"time_ms_mean": t})


def _timed_by_harness(rr: RunRow) -> bool:
    return not rr.diverged and rr.result.clock != REPORTED_CLOCK


def _ci_values(name: str, ci) -> dict:
    ci = _ci(ci)
    return {f"{name}_ci_low": ci[0] if ci else None, f"{name}_ci_high": ci[1] if ci else None}


def relative_table(rows: list[RunRow], lengths: list[float], marks: str = "intervals",
                   ci: bool = False) -> Table:
    """The paper's Table III: "rotation / translation" per length and the time per frame."""
    table = Table(["Sensor", "Sequence", "Method"],
                  [f"{L:g} m" for L in lengths] + ["Time (ms)"], [])
    for rr in rows:
        cells = []
        for L in lengths:
            rel = rr.result.relative(L)
            ok = rel is not None and rel.n > 0
            rot, trans = (rel.rot_deg_mean, rel.trans_m_mean) if ok else (None, None)
            n_ind = rel.spread.n_independent if ok else None
            values = {"rot_deg_mean": rot, "trans_m_mean": trans,
                      "segments": rel.n if rel else 0, "independent_segments": n_ind,
                      **_ci_values("rot_deg_mean", rel.rot_deg_mean_ci if ok else None),
                      **_ci_values("trans_m_mean", rel.trans_m_mean_ci if ok else None)}
            if rr.diverged:
                cells.append(Cell(status="Div.", values=values))
                continue
            cells.append(Cell([
                stat_part(rot, rel.rot_deg_mean_ci if ok else None, n_ind, show_ci=ci),
                stat_part(trans, rel.trans_m_mean_ci if ok else None, n_ind, show_ci=ci)],
                values=values))
        table.rows.append(_row(table, rr, [*cells, _time_cell(rr)]))
    for i in range(len(lengths)):
        for part in (0, 1):
            mark_column(table.rows, i, part, marks)
    # a diverged run's time is real: shown, not ranked; a time its method reported, too
    ranked = [r for r, rr in zip(table.rows, rows, strict=True) if _timed_by_harness(rr)]
    mark_column(ranked, len(lengths), 0, marks)
    reported = any(r.result.clock == REPORTED_CLOCK for r in rows)
    table.caption = _caption(rows, "Each cell: mean rotation [deg] / translation [m] relative "
                             "error over the segments of each length (evo_rpe's definition). "
                             + TIME_NOTE + " Times have no interval: marked by value."
                             + (" " + REPORTED_NOTE if reported else ""), marks, ci)
    return table


def kitti_segments_text(rows: list[RunRow]) -> str:
    """Which KITTI lengths had segments, and how many per sequence: "100 m (4 segments per
    sequence; Campus1: 1)"; the lengths no path reaches are named apart."""
    per_seq: dict[float, dict[str, int]] = {}
    asked: set[float] = set()
    for rr in rows:
        k = rr.result.kitti if rr.result.finished else None
        if k is None:
            continue
        asked.update(k.lengths_m)
        for pl in k.per_length:
            per_seq.setdefault(pl.length_m, {})[rr.sequence] = pl.n
    used = [L for L in sorted(per_seq) if any(per_seq[L].values())]
    if not used:
        return "no KITTI segment: every path is shorter than the shortest length"
    parts = []
    for L in used:
        counts = per_seq[L]
        common = max(set(counts.values()), key=list(counts.values()).count)
        odd = [f"{s}: {n}" for s, n in counts.items() if n != common]
        noun = "segment" if common == 1 else "segments"
        parts.append(f"{L:g} m ({common} {noun} per sequence" +
                     (f"; {', '.join(odd)}" if odd else "") + ")")
    unused = sorted(asked - set(used))
    text = "segments of " + ", ".join(parts)
    if unused:
        text += (f"; none of {unused[0]:g}-{unused[-1]:g} m (the paths are shorter)"
                 if len(unused) > 1 else f"; none of {unused[0]:g} m (the paths are shorter)")
    return text


def kitti_table(rows: list[RunRow], marks: str = "intervals", ci: bool = False) -> Table:
    """KITTI drift: translation [%] and rotation [deg/100 m] per run."""
    table = Table(["Sensor", "Sequence", "Method"],
                  ["Trans. drift (%)", "Rot. drift (deg/100 m)", "Segments (independent)"], [])
    for rr in rows:
        k = rr.result.kitti
        t, r, n = (k.trans_pct, k.rot_deg_per_100m, k.n) if k else (None, None, 0)
        n_ind = k.spread.n_independent if k else None
        values = {"trans_pct": t, "rot_deg_per_100m": r}
        # every segment, and in brackets the independent (non-overlapping) ones the interval
        # and a cell's "(1 segment)" count
        segments = Cell([Part(f"{n} ({n_ind})" if n_ind is not None else str(n))],
                        values={"segments": n, "independent_segments": n_ind})
        if rr.diverged:
            cells = [Cell(status="Div.", values=values), Cell(status="Div."), segments]
        else:
            cells = [Cell([stat_part(t, k.trans_pct_ci if k else None, n_ind, digits=2,
                                     show_ci=ci)],
                          values={"trans_pct": t, **_ci_values("trans_pct",
                                                               k.trans_pct_ci if k else None)}),
                     Cell([stat_part(r, k.rot_deg_per_100m_ci if k else None, n_ind, digits=2,
                                     show_ci=ci)],
                          values={"rot_deg_per_100m": r, **_ci_values(
                              "rot_deg_per_100m", k.rot_deg_per_100m_ci if k else None)}),
                     segments]
        table.rows.append(_row(table, rr, cells))
    for col in (0, 1):
        mark_column(table.rows, col, 0, marks)
    table.caption = _caption(rows, f"KITTI drift over {kitti_segments_text(rows)} (the KITTI "
                             "odometry devkit's definition: a segment starts every 10 frames "
                             "and ends at the first frame beyond its length; translation error "
                             "in % of the length, rotation error in deg per 100 m, averaged "
                             "over every segment); - = the path is shorter than the shortest "
                             "length. Segments: every segment, in brackets the independent "
                             "(non-overlapping) ones behind the interval.", marks, ci)
    return table


VELOCITY_COLUMNS = (("x_mean_mps", "x_abs_mps", False), ("y_mean_mps", "y_abs_mps", False),
                    ("z_mean_mps", "z_abs_mps", False), ("norm_mean_mps", "norm_mps", False),
                    ("norm_rmse_mps", "norm_mps", True))


def _velocity_cells(v, diverged: bool, ci: bool) -> list[Cell]:
    if v is None or diverged:
        status = "Div." if diverged else "-"
        return [Cell(status=status) for _ in range(5)]
    values = [*v.axis_mean_mps, v.norm_mean_mps, v.norm_rmse_mps]
    n_ind = v.spread.n_independent
    cells = []
    for (name, _, _), x in zip(VELOCITY_COLUMNS, values, strict=True):
        interval = v.norm_mean_mps_ci if name == "norm_mean_mps" else None
        cells.append(Cell([stat_part(x, interval, n_ind, show_ci=ci)],
                          values={name: x, **(_ci_values(name, interval) if interval
                                              else {})}))
    return cells


def velocity_table(rows: list[RunRow], marks: str = "intervals", ci: bool = False) -> Table:
    """Ego-velocity error per run (and a "Doppler ego velocity" row for a method that
    measures its own)."""
    table = Table(["Sensor", "Sequence", "Method"],
                  ["x (m/s)", "y (m/s)", "z (m/s)", "Norm mean (m/s)", "Norm RMSE (m/s)"], [])
    windows = set()
    for rr in rows:
        v = rr.result.velocity
        if v is not None:
            windows.add(v.window_s)
        table.rows.append(_row(table, rr, _velocity_cells(v, rr.diverged, ci)))
        own = rr.result.velocity_own
        if own is not None and not rr.failed:
            row = _row(table, rr, _velocity_cells(own, False, ci))
            row.keys[-1] = f"{rr.label} [Doppler ego velocity]"
            row.meta["status"] = "doppler"
            row.meta["label"] = f"{rr.run.label or ''} [Doppler ego velocity]"
            table.rows.append(row)
    for col in range(5):
        mark_column(table.rows, col, 0, marks)
    w = ", ".join(f"{x:g}" for x in sorted(windows)) or f"{DEFAULT_WINDOW_S:g}"
    table.caption = _caption(rows, (
        "Ego-velocity error [m/s] in the sensor frame: mean absolute error per axis (x, y, z) "
        "and the mean and RMS of the error vector's norm. A frame's velocity is its relative "
        f"translation to the first frame at least {w} s later over the time between (the same "
        "frames for the estimate and the ground truth). The reference is the GT over that "
        f"window, not frame to frame: a GT nearest-matched to the scans (NTU4DRadLM: 10 Hz "
        "poses at 12 Hz scans) makes frame-to-frame GT velocities mostly artefact. [Doppler ego "
        f"velocity] rows: the method's own instantaneous Doppler estimate against the GT "
        f"velocity over a {w} s window centred on the frame. Only the norm mean has an "
        "interval: the other columns are marked by value."), marks, ci)
    return table


TABLES = {"relative": relative_table, "kitti": kitti_table, "velocity": velocity_table}


def build(metric: str, rows: list[RunRow], lengths: list[float] | None = None,
          marks: str = "intervals", ci: bool = False) -> Table:
    """The table of ``metric`` (one of ``TABLES``) for ``rows``, marked by ``marks``, with
    the intervals in the cells when ``ci``."""
    if metric == "relative":
        return relative_table(rows, lengths if lengths is not None else scored_lengths(rows),
                              marks, ci)
    return TABLES[metric](rows, marks, ci)


def write_tables(results_dir: Path | list[Path], out_dir: Path | None = None,
                 only: set[Path] | None = None, stem: str = "table",
                 lengths_m: list[float] | None = None,
                 keep: Callable[[RunRow], bool] | None = None,
                 metric: str = "relative", marks: str = "intervals",
                 ci: bool = False) -> dict[str, str]:
    """Write <stem>.md, .tex and .csv of ``metric``'s table of the selected rows; return the
    texts by format."""
    rows, lengths = select(results_dir, only, lengths_m, keep)
    first = results_dir[0] if isinstance(results_dir, list) else results_dir
    return save_table(build(metric, rows, lengths, marks, ci), Path(out_dir or first), stem)
