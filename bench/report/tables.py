"""Per-run tables from run folders, shaped as the paper's Table III: rows grouped by sensor
class and sequence, one row per method and seed option (``runs``), and one table per metric:

- ``relative_table``: "rotation / translation" mean relative error per segment length and the
  mean time per frame (the paper's Table III);
- ``kitti_table``: KITTI drift, translation [%] and rotation [deg/100 m] over 100-800 m;
- ``velocity_table``: ego-velocity error per axis and as a norm [m/s] (and, for a method that
  measures it, its own Doppler velocity's error).

The APE table (methods x sequences, the paper's Tables IV/V) is ``bench.report.tables_ape``.
Per sequence and column the best value is bold and the second underlined; a diverged run shows
"Div." and is not ranked; a run that did not finish stays as a "failed" row with its reason in
a footnote. Every table is a ``bench.report.table.Table`` (rendered to md / tex / csv).
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
    run_label,
    sequence_key,
    synthetic_note,
)
from bench.report.table import Cell, Part, Row, Table, rank_column, save_table
from bench.runs.folders import RunRecord, load_runs
from bench.runs.result import REPORTED_CLOCK, RunResult, nan
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
    out = []
    for d in dirs:
        for run in load_runs(d, only, failed=True):
            if run.result.finished and not run.result.scored:
                continue  # no ground truth: nothing to tabulate
            label = run_label(run.method, run.seed, run.label, run.doppler_kind)
            out.append(RunRow(run, f"{Path(d).name}: {label}" if len(dirs) > 1 else label))
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
    """A table row of a run; a run that did not finish gets "failed" cells and a footnote."""
    if rr.failed:
        reason = (rr.result.error or rr.result.status).strip().splitlines()
        note = table.note(f"{rr.label} on {rr.sequence}: {rr.result.status}: "
                          f"{reason[0] if reason else ''}")
        cells = [Cell(status="failed", note=note if i == 0 else None)
                 for i in range(len(table.columns))]
    return Row([rr.sensor_class, rr.sequence, rr.label], (rr.sensor_class, rr.sequence), cells,
               {"sequence": rr.run.sequence, "sensor_class": rr.sensor_class,
                "method": rr.method, "seed": rr.seed.value, "label": rr.run.label,
                "status": rr.result.status if rr.failed else
                ("diverged" if rr.diverged else "done")})


def fmt(x: float | None, digits: int = 3) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{x:.{digits}f}"


def fmt_time(x: float | None, threads: int = 1) -> str:
    x = nan(x)
    text = "-" if not math.isfinite(x) else (f"{x:.2f}" if x < 10 else f"{x:.1f}")
    return text if threads == 1 else f"{text} [{threads} thr.]"


def _caption(rows: list[RunRow], text: str) -> str:
    failed = FAILED_NOTE + " " if any(r.failed for r in rows) else ""
    return (synthetic_note(r.sequence for r in rows) + gt_assisted_note(r.label for r in rows)
            + text + " " + hosts_note(r.result.cpu for r in rows
                                      if r.result.finished and r.result.timed_by_harness)
            + "Best per sequence in bold, second underlined; Div. = diverged; " + failed
            + SEED_NOTE)


REPORTED_NOTE = ("A time marked [reported] is the external method's own figure, not measured by "
                 "the harness: not ranked.")


def _time_cell(rr: RunRow) -> Cell:
    t = rr.result.time_ms.mean
    text = fmt_time(t, rr.result.threads)
    if rr.result.clock == REPORTED_CLOCK and text != "-":
        text += " [reported]"
    return Cell([Part(text)], values={"time_ms_mean": t})


def _timed_by_harness(rr: RunRow) -> bool:
    return not rr.diverged and rr.result.clock != REPORTED_CLOCK


def relative_table(rows: list[RunRow], lengths: list[float]) -> Table:
    """The paper's Table III: "rotation / translation" per length and the time per frame."""
    table = Table(["Sensor", "Sequence", "Method"],
                  [f"{L:g} m" for L in lengths] + ["Time (ms)"], [])
    for rr in rows:
        cells = []
        for L in lengths:
            rel = rr.result.relative(L)
            rot, trans = (rel.rot_deg_mean, rel.trans_m_mean) if rel and rel.n else (None, None)
            values = {"rot_deg_mean": rot, "trans_m_mean": trans, "segments":
                      rel.n if rel else 0}
            cells.append(Cell(status="Div.", values=values) if rr.diverged else
                         Cell([Part(fmt(rot)), Part(fmt(trans))], values=values))
        table.rows.append(_row(table, rr, [*cells, _time_cell(rr)]))
    for i in range(len(lengths)):
        for part, q in ((0, "rot_deg_mean"), (1, "trans_m_mean")):
            rank_column(table.rows, i, part, lambda r, i=i, q=q: nan(r.cells[i].values[q]))
    # a diverged run's time is real: shown, not ranked; a time its method reported, too
    ranked = [r for r, rr in zip(table.rows, rows, strict=True) if _timed_by_harness(rr)]
    rank_column(ranked, len(lengths), 0, lambda r: nan(r.cells[-1].values["time_ms_mean"]))
    reported = any(r.result.clock == REPORTED_CLOCK for r in rows)
    table.caption = _caption(rows, "Each cell: mean rotation [deg] / translation [m] relative "
                             "error over the segments of each length (evo_rpe's definition). "
                             + TIME_NOTE + (" " + REPORTED_NOTE if reported else ""))
    return table


def kitti_table(rows: list[RunRow]) -> Table:
    """KITTI drift: translation [%] and rotation [deg/100 m] per run."""
    table = Table(["Sensor", "Sequence", "Method"],
                  ["Trans. drift (%)", "Rot. drift (deg/100 m)", "Segments"], [])
    lengths: set[tuple] = set()
    for rr in rows:
        k = rr.result.kitti
        if k is not None:
            lengths.add(tuple(k.lengths_m))
        t, r, n = (k.trans_pct, k.rot_deg_per_100m, k.n) if k else (None, None, 0)
        values = {"trans_pct": t, "rot_deg_per_100m": r}
        if rr.diverged:
            cells = [Cell(status="Div.", values=values), Cell(status="Div."),
                     Cell([Part(str(n))], values={"segments": n})]
        else:
            cells = [Cell([Part(fmt(t))], values={"trans_pct": t}),
                     Cell([Part(fmt(r))], values={"rot_deg_per_100m": r}),
                     Cell([Part(str(n))], values={"segments": n})]
        table.rows.append(_row(table, rr, cells))
    for col, q in ((0, "trans_pct"), (1, "rot_deg_per_100m")):
        rank_column(table.rows, col, 0, lambda r, col=col, q=q: nan(r.cells[col].values.get(q)))
    over = ", ".join("-".join(f"{x:g}" for x in (ls[0], ls[-1])) + " m" for ls in
                     sorted(lengths)) or "100-800 m"
    table.caption = _caption(rows, f"KITTI drift over segments of {over} (the KITTI odometry "
                             "devkit's definition: a segment starts every 10 frames and ends at "
                             "the first frame beyond its length; translation error in % of the "
                             "length, rotation error in deg per 100 m, averaged over every "
                             "segment); - = the path is shorter than the shortest length.")
    return table


def _velocity_cells(v, diverged: bool) -> list[Cell]:
    if v is None or diverged:
        status = "Div." if diverged else "-"
        return [Cell(status=status) for _ in range(5)]
    values = [*v.axis_mean_mps, v.norm_mean_mps, v.norm_rmse_mps]
    names = ["x_mean_mps", "y_mean_mps", "z_mean_mps", "norm_mean_mps", "norm_rmse_mps"]
    return [Cell([Part(fmt(x))], values={q: x}) for q, x in zip(names, values, strict=True)]


def velocity_table(rows: list[RunRow]) -> Table:
    """Ego-velocity error per run (and a "Doppler ego velocity" row for a method that
    measures its own)."""
    table = Table(["Sensor", "Sequence", "Method"],
                  ["x (m/s)", "y (m/s)", "z (m/s)", "Norm mean (m/s)", "Norm RMSE (m/s)"], [])
    windows = set()
    for rr in rows:
        v = rr.result.velocity
        if v is not None:
            windows.add(v.window_s)
        table.rows.append(_row(table, rr, _velocity_cells(v, rr.diverged)))
        own = rr.result.velocity_own
        if own is not None and not rr.failed:
            row = _row(table, rr, _velocity_cells(own, False))
            row.keys[-1] = f"{rr.label} [Doppler ego velocity]"
            row.meta["status"] = "doppler"
            table.rows.append(row)
    for col in range(5):
        rank_column(table.rows, col, 0,
                    lambda r, col=col: nan(next(iter(r.cells[col].values.values()), None)))
    w = ", ".join(f"{x:g}" for x in sorted(windows)) or f"{DEFAULT_WINDOW_S:g}"
    table.caption = _caption(rows, (
        "Ego-velocity error [m/s] in the sensor frame: mean absolute error per axis (x, y, z) "
        "and the mean and RMS of the error vector's norm. A frame's velocity is its relative "
        f"translation to the first frame at least {w} s later over the time between (the same "
        "frames for the estimate and the ground truth). The reference is the GT over that "
        f"window, not frame to frame: a GT nearest-matched to the scans (NTU4DRadLM: 10 Hz "
        "poses at 12 Hz scans) makes frame-to-frame GT velocities mostly artefact. [Doppler ego "
        f"velocity] rows: the method's own instantaneous Doppler estimate against the GT "
        f"velocity over a {w} s window centred on the frame."))
    return table


TABLES = {"relative": relative_table, "kitti": kitti_table, "velocity": velocity_table}


def build(metric: str, rows: list[RunRow], lengths: list[float] | None = None) -> Table:
    """The table of ``metric`` (one of ``TABLES``) for ``rows``."""
    if metric == "relative":
        return relative_table(rows, lengths if lengths is not None else scored_lengths(rows))
    return TABLES[metric](rows)


def write_tables(results_dir: Path | list[Path], out_dir: Path | None = None,
                 only: set[Path] | None = None, stem: str = "table",
                 lengths_m: list[float] | None = None,
                 keep: Callable[[RunRow], bool] | None = None,
                 metric: str = "relative") -> dict[str, str]:
    """Write <stem>.md, .tex and .csv of ``metric``'s table of the selected rows; return the
    texts by format."""
    rows, lengths = select(results_dir, only, lengths_m, keep)
    first = results_dir[0] if isinstance(results_dir, list) else results_dir
    return save_table(build(metric, rows, lengths), Path(out_dir or first), stem)
