"""Fidelity of ``synthetic-paper`` to the paper: Table III next to the synthetic suite.

For every sequence of the suite, every method the paper reports on it (sparse radar:
point-to-point ICP with and without seed, and ``doppler``; semi-dense radar and dense LiDAR:
DICP with and without seed, and ``doppler``; on the tunnels also point-to-point ICP, which
Table V reports as diverged) is run on the suite's store (``bench.runs.plan.
run_single``: the same runs as ``bench run``, reused when already finished), and its mean
relative error at 8 m and 48 m (rotation [deg], translation [m]) is put next to the paper's
Table III value with the ratio synthetic / paper. Then the paper's orderings are checked on the
synthetic numbers (``orderings``).

Command line (also ``bench synth --fidelity``)::

    python -m bench.studies.fidelity [--data-dir data] [--out results/fidelity]
        [--csv FILE] [--doppler-only]
"""

from __future__ import annotations

import argparse
import csv
import io
from dataclasses import dataclass
from pathlib import Path

from bench.paths import PAPER_TABLE3
from loaders.sensor_classes import DENSE_LIDAR, SEMI_DENSE_RADAR, SPARSE_RADAR

SUITE = "synthetic-paper"
LENGTHS = ("8", "48")
#: within this factor of the paper counts as faithful (issue 11; goal 1.5)
FACTOR = 2.0
#: (method, seed) the paper reports per sensor class (Table III)
PAPER_METHODS = {
    SPARSE_RADAR: [("icp-p2p", True), ("icp-p2p", False), ("doppler", None)],
    SEMI_DENSE_RADAR: [("dicp", True), ("dicp", False), ("doppler", None)],
    DENSE_LIDAR: [("dicp", True), ("dicp", False), ("doppler", None)],
}
#: runs beyond Table III for the paper's other orderings: Table V reports point-to-point ICP
#: as diverged ("Div.") on both tunnels
EXTRA_METHODS = {"Tunnel_Empty": [("icp-p2p", True)], "Tunnel_Vehicles": [("icp-p2p", True)]}


@dataclass
class Row:
    sequence: str
    klass: str
    method: str
    seed: bool | None
    paper: dict[str, float]  # rot_8, trans_8, rot_48, trans_48
    synth: dict[str, float]
    diverged: bool

    @property
    def label(self) -> str:
        if self.seed is None:
            return self.method
        return f"{self.method}-{'seed' if self.seed else 'noseed'}"

    def ratio(self, key: str) -> float:
        p = self.paper.get(key, float("nan"))
        return self.synth.get(key, float("nan")) / p if p else float("nan")


def paper_table(path: Path = PAPER_TABLE3) -> dict[tuple[str, str, bool | None], dict]:
    """(sequence, method, seed) -> {rot_8, trans_8, rot_48, trans_48} from Table III."""
    out = {}
    with open(path, newline="") as fh:
        for r in csv.DictReader(fh):
            seed = None if r["seed"] == "" else r["seed"] == "true"
            out[(r["sequence"], r["method"], seed)] = {
                f"{q}_{n}": float(r[f"{col}_{n}"])
                for n in LENGTHS for q, col in (("rot", "rot_deg"), ("trans", "trans_m"))}
    return out


def _synth_values(metrics: dict) -> dict[str, float]:
    rel = metrics.get("relative_error") or {}
    out = {}
    for n in LENGTHS:
        r = rel.get(n) or rel.get(f"{float(n)}") or {}
        out[f"rot_{n}"] = float(r.get("rot_deg_mean", float("nan")))
        out[f"trans_{n}"] = float(r.get("trans_m_mean", float("nan")))
    return out


def fidelity_rows(data_dir: Path, out_dir: Path, doppler_only: bool = False,
                  progress=None) -> list[Row]:
    """Run (or reuse) every reported method on every store of the suite; one Row each."""
    from bench.runs.plan import run_single
    from loaders.synthetic.suite import ensure_suite, suite_entries

    paper = paper_table()
    paths = ensure_suite(SUITE, data_dir)
    rows = []
    for entry, path in zip(suite_entries(SUITE), paths, strict=True):
        for method, seed in PAPER_METHODS[entry.klass] + EXTRA_METHODS.get(entry.name, []):
            if doppler_only and method != "doppler":
                continue
            tag = method if seed is None else f"{method}_{'seed' if seed else 'noseed'}"
            if progress:
                progress(f"{entry.name}: {tag}")
            metrics = run_single(method, path, seed=bool(seed) if seed is not None else True,
                                 out=out_dir / entry.name / tag).metrics
            rows.append(Row(entry.name, entry.klass, method, seed,
                            paper.get((entry.name, method, seed), {}), _synth_values(metrics),
                            bool(metrics.get("diverged"))))
    return rows


def orderings(rows: list[Row]) -> list[tuple[str, str, bool]]:
    """The paper's orderings checked on the synthetic values: (check, measured, holds)."""
    by = {(r.sequence, r.label): r for r in rows}
    checks = []

    def get(seq, label, key):
        r = by.get((seq, label))
        return None if r is None else r.synth[key]

    for seq in ("Campus1", "Campus2"):
        d, icp = get(seq, "doppler", "rot_8"), get(seq, "icp-p2p-seed", "rot_8")
        if d is not None and icp is not None:
            checks.append((f"{seq}: doppler beats icp-p2p (seed) in rotation at 8 m",
                           f"{d:.3f} vs {icp:.3f} deg", d < icp))
    for seq in ("Loop1_0", "Loop1_2", "Loop1_3"):
        d, dicp = get(seq, "doppler", "rot_48"), get(seq, "dicp-seed", "rot_48")
        if d is not None and dicp is not None:
            checks.append((f"{seq}: dicp (seed) beats doppler in rotation at 48 m",
                           f"{dicp:.3f} vs {d:.3f} deg", dicp < d))
    gentle = [get(s, "doppler", "rot_48") for s in ("Loop1_0", "Loop1_1", "Loop1_2", "Loop1_3")]
    gentle = [g for g in gentle if g is not None]
    uturn = get("Loop1_4", "doppler", "rot_48")
    if gentle and uturn is not None:
        mean = sum(gentle) / len(gentle)
        checks.append(("Loop1_4 (U-turn): doppler 48 m rotation >= 3x the gentle loops' mean",
                       f"{uturn:.3f} vs {mean:.3f} deg ({uturn / mean:.1f}x)", uturn >= 3 * mean))
    for seq in ("StraightWall", "CurvedWall", "Tunnel_Empty", "Tunnel_Vehicles"):
        d, dicp = get(seq, "doppler", "rot_8"), get(seq, "dicp-seed", "rot_8")
        if d is not None and dicp is not None:
            checks.append((f"{seq}: dicp (seed) best in rotation at 8 m",
                           f"{dicp:.3f} vs doppler {d:.3f} deg", dicp < d))
    for seq in ("Tunnel_Empty", "Tunnel_Vehicles"):
        r = by.get((seq, "icp-p2p-seed"))
        if r is not None:
            checks.append((f"{seq}: icp-p2p (seed) diverges (paper Table V: Div.)",
                           f"8 m {r.synth['trans_8']:.3f} m, 48 m {r.synth['trans_48']:.3f} m, "
                           f"diverged {r.diverged}", r.diverged))
    return checks


def format_table(rows: list[Row]) -> str:
    """Plain text: paper / synthetic / ratio for rot and trans at 8 and 48 m."""
    head = f"{'sequence':<16}{'method':<17}"
    for n in LENGTHS:
        for q, unit in (("rot", "deg"), ("trans", "m")):
            head += f"{q + '_' + n + ' ' + unit + ' paper/synth (x)':>32}"
    lines = [head]
    for r in rows:
        line = f"{r.sequence:<16}{r.label:<17}"
        for n in LENGTHS:
            for q in ("rot", "trans"):
                key = f"{q}_{n}"
                line += (f"{r.paper.get(key, float('nan')):>11.3f} /{r.synth[key]:>8.3f}"
                         f" ({r.ratio(key):>5.2f})     ")
        if r.diverged:
            line += "  DIVERGED"
        lines.append(line)
    return "\n".join(lines)


def format_csv(rows: list[Row]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf)
    keys = [f"{q}_{n}" for n in LENGTHS for q in ("rot", "trans")]
    w.writerow(["sequence", "class", "method", "seed", "diverged"]
               + [f"{k}_{s}" for k in keys for s in ("paper", "synth", "ratio")])
    for r in rows:
        w.writerow([r.sequence, r.klass, r.method, "" if r.seed is None else str(r.seed).lower(),
                    str(r.diverged).lower()]
                   + [f"{v:.4f}" for k in keys
                      for v in (r.paper.get(k, float("nan")), r.synth[k], r.ratio(k))])
    return buf.getvalue()


def summary(rows: list[Row]) -> str:
    """The doppler-within-FACTOR check and the orderings, one line each."""
    lines = []
    for r in rows:
        if r.method != "doppler":
            continue
        if not r.paper:
            lines.append(f"doppler on {r.sequence}: not in the paper's Table III")
            continue
        ratios = [r.ratio(f"{q}_{n}") for n in LENGTHS for q in ("rot", "trans")]
        far = max(max(x, 1 / x) for x in ratios)
        lines.append(f"doppler on {r.sequence}: worst factor {far:.2f} "
                     f"({'within' if far <= FACTOR else 'OUTSIDE'} {FACTOR:g}x)")
    for check, value, ok in orderings(rows):
        lines.append(f"{'holds' if ok else 'FAILS'}: {check}: {value}")
    return "\n".join(lines)


def fidelity_table(data_dir: str | Path, console=None, out_dir: str | Path | None = None,
                   doppler_only: bool = False) -> str:
    """Generate (if stale) the suite under ``data_dir``, run the paper's methods on it (runs
    under ``out_dir``, default ``results/fidelity``), print the table and the checks on
    ``console`` (a rich Console, or None for no printing), write ``fidelity.csv`` and
    ``fidelity.txt`` into ``out_dir`` and return the text."""
    out = Path(out_dir) if out_dir is not None else Path("results/fidelity")
    say = (lambda m: console.print(m, markup=False, highlight=False)) if console else None
    rows = fidelity_rows(Path(data_dir), out, doppler_only,
                         progress=(lambda m: say(f"running {m}")) if say else None)
    text = format_table(rows) + "\n\n" + summary(rows) + "\n"
    out.mkdir(parents=True, exist_ok=True)
    (out / "fidelity.csv").write_text(format_csv(rows))
    (out / "fidelity.txt").write_text(text)
    if say:
        say(text)
    return text


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="synthetic-paper vs the paper's Table III")
    ap.add_argument("--data-dir", type=Path, default=Path("data"), help="data folder")
    ap.add_argument("--out", type=Path, default=Path("results/fidelity"), help="run folder")
    ap.add_argument("--doppler-only", action="store_true", help="only the doppler rows")
    args = ap.parse_args(argv)
    from bench.console import make_console

    fidelity_table(args.data_dir, make_console(), args.out, args.doppler_only)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
