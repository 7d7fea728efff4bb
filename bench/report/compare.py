"""``bench compare A B``: two result folders (or two run folders) side by side.

Runs are matched by sequence, method, label, seed option and segment length; each cell shows
A, B and the change B - A of the mean rotation [deg] and translation [m] relative error. A
cell whose error grew by more than ``threshold`` (relative) is marked as a regression, and so
is a run that diverges in B but not in A. Two run folders (each with a metrics.json) are
compared by sequence and length whatever their methods.
"""

from __future__ import annotations

import math
from pathlib import Path

import pandas as pd

from bench.report.dataframe import load_results

KEYS = ["sequence", "method", "label", "seed", "length_m"]


def _frame(path: Path) -> pd.DataFrame:
    df = load_results(path)
    if df.empty:
        raise FileNotFoundError(f"{path}: no finished runs (no metrics.json found)")
    return df


def compare(a: Path, b: Path, threshold: float = 0.10) -> pd.DataFrame:
    """One row per matched cell: A and B values, deltas, ``regression`` flag."""
    da, db = _frame(a), _frame(b)
    single = (Path(a) / "metrics.json").exists() and (Path(b) / "metrics.json").exists()
    keys = ["sequence", "length_m"] if single else KEYS
    for df in (da, db):
        df["label"] = df["label"].fillna("")
        df["seed"] = df["seed"].astype(str)
    merged = da.merge(db, on=keys, suffixes=("_a", "_b"), how="outer", indicator=True)
    rows = []
    for _, r in merged.iterrows():
        row = {k: r[k] for k in keys}
        if single:
            row["method"] = f"{r['method_a']} -> {r['method_b']}"
        row["only_in"] = {"left_only": "A", "right_only": "B"}.get(r["_merge"], "")
        regression = bool(r.get("diverged_b") is True and r.get("diverged_a") is not True)
        for q in ("rot_deg_mean", "trans_m_mean"):
            va, vb = r.get(f"{q}_a"), r.get(f"{q}_b")
            row[f"{q}_a"], row[f"{q}_b"] = va, vb
            delta = vb - va if _finite(va) and _finite(vb) else math.nan
            row[f"{q}_delta"] = delta
            if _finite(delta) and va > 0 and delta / va > threshold:
                regression = True
        row["regression"] = regression
        rows.append(row)
    return pd.DataFrame(rows)


def _finite(x) -> bool:
    return x is not None and isinstance(x, float | int) and math.isfinite(x)


def to_text(df: pd.DataFrame) -> str:
    """A plain table: "A -> B (delta)" per quantity, regressions marked with '!'."""
    lines = ["sequence | method | label | seed | length [m] | rotation [deg] A -> B (delta) | "
             "translation [m] A -> B (delta) | "]
    for _, r in df.iterrows():
        cells = []
        for q in ("rot_deg_mean", "trans_m_mean"):
            a, b, d = r[f"{q}_a"], r[f"{q}_b"], r[f"{q}_delta"]
            cells.append(f"{_fmt(a)} -> {_fmt(b)} ({'+' if _finite(d) and d >= 0 else ''}"
                         f"{_fmt(d)})")
        mark = "! regression" if r["regression"] else (f"only in {r['only_in']}"
                                                        if r.get("only_in") else "")
        lines.append(f"{r['sequence']} | {r.get('method', '')} | {r.get('label', '')} | "
                     f"{r.get('seed', '')} | {r['length_m']:g} | {cells[0]} | {cells[1]} | "
                     f"{mark}")
    return "\n".join(lines) + "\n"


def _fmt(x) -> str:
    return f"{x:.3f}" if _finite(x) else "-"
