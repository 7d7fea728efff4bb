"""``bench compare A B``: two result folders (or two run folders) side by side.

Runs are matched by sequence, method, label and seed tag (which motion prior a run used: "With
Seed", "No Seed", ...). For every segment length at which A or B has segments, one row (a cell)
shows the mean rotation [deg] and translation [m] relative error of A and B, each with its 95 %
confidence interval "[low, high]", and the change B - A; a length at which neither has
segments is no cell. A cell whose error grew by more than
``threshold`` (relative) is a regression, and so is every cell of a run that diverges in B but
not in A. Whether a change is more than noise is read from the printed intervals alone, as the
tables' marks are (``bench.report.tables.significance``): a note says "worse" / "better" for a
quantity whose A and B intervals, as printed, do not meet, and a regression within them says
that the intervals cannot tell it from noise. Runs are labelled as the tables label them (the
parameters a run was given, ``-p tau_spatial_m=1``, after its name) and matched with them: a run
with other parameters is no regression of the default one; where A and B hold a run of the
same method under different parameters, the note names the parameters that differ. A second
table gives each run's mean time per frame ``time_ms`` (all per-frame work,
``methods.timing``) in A and B and its change, and a third its per-run metrics: APE [m] (with
its alignment), KITTI drift [%, deg/100 m] and ego-velocity error [m/s]. Two run folders (each
with a metrics.json) are compared by sequence and length whatever their methods.

``to_markdown`` writes both tables as one markdown document: pipe tables with a header
separator row, columns padded to equal width so that it also reads in a terminal.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from bench.report.dataframe import results_frame
from bench.report.names import order_key, overrides_note, run_label, seed_tag, sequence_key
from bench.report.tables.model import md_escape
from bench.report.tables.significance import Stat, shown_interval, worse
from bench.runs.folders import RunRecord, load_runs, with_sequence_tags

RUN_KEYS = ["sequence", "method", "label", "seed", "overrides"]
QUANTITIES = ("rot_deg_mean", "trans_m_mean")
_SEED_ORDER = ["With Seed", "With Seed, own model", "No Seed", "No initial guess"]


def _seed(x) -> bool | None:
    """A seed option read back through pandas (None and NaN: the method takes no guess)."""
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else bool(x)


def _frame(path: Path, runs: list[RunRecord]) -> pd.DataFrame:
    df = results_frame(runs)
    if df.empty:
        raise FileNotFoundError(f"{path}: no finished runs with relative errors (no "
                                "metrics.json of a run with ground truth found)")
    base = {r.sequence: r.result.sequence for r in runs}
    df["sequence_name"] = [base.get(s, s) for s in df["sequence"]]
    df["label"] = df["label"].fillna("")
    configs = {str(r.dir): r.config for r in runs}
    df["overrides"] = [overrides_note(configs.get(d) or {}) for d in df["run_dir"]]
    df["params"] = [_params(configs.get(d) or {}) for d in df["run_dir"]]
    seeds = [_seed(s) for s in df["seed"]]
    df["run"] = [run_label(m, s, lab or None, kind) + extra
                 for m, s, lab, kind, extra in zip(df["method"], seeds, df["label"],
                                                   df["doppler_kind"], df["overrides"],
                                                   strict=True)]
    df["seed"] = [seed_tag(m, s) for m, s in zip(df["method"], seeds, strict=True)]
    return df


def _params(config: dict) -> str:
    """A run's resolved method parameters as "name=value" pairs joined by ";" (config.yaml's
    ``method.params``), for naming the ones that differ between A and B."""
    method = config.get("method") if isinstance(config.get("method"), dict) else {}
    params = method.get("params") if isinstance(method.get("params"), dict) else {}
    return ";".join(f"{k}={v}" for k, v in sorted(params.items()))


def params_differ(pa, pb) -> str:
    """The parameters whose values differ between two ``_params`` texts: "tau_spatial_m A 3.0,
    B 1.0"; "" when they agree or one is unknown."""
    if not (isinstance(pa, str) and isinstance(pb, str)) or not pa or not pb:
        return ""
    a = dict(x.split("=", 1) for x in pa.split(";"))
    b = dict(x.split("=", 1) for x in pb.split(";"))
    return "; ".join(f"{k} A {a.get(k, '-')}, B {b.get(k, '-')}"
                     for k in sorted(a.keys() | b.keys()) if a.get(k) != b.get(k))


def _pair(a: Path, b: Path) -> tuple[pd.DataFrame, pd.DataFrame, list[str]]:
    """Both sides and the keys that match a run of A with a run of B. The sequences of both
    sides are told apart together (``bench.runs.sequence_identity``): a sequence name that A
    and B hold with different content (another store of that name, other frames) gets its
    content tag on each side, so the two are never paired as one sequence."""
    single = (Path(a) / "metrics.json").exists() and (Path(b) / "metrics.json").exists()
    runs_a, runs_b = load_runs(Path(a)), load_runs(Path(b))
    both = with_sequence_tags(runs_a + runs_b)
    return (_frame(a, both[:len(runs_a)]), _frame(b, both[len(runs_a):]),
            ["sequence"] if single else RUN_KEYS)


def _finite(x) -> bool:
    return isinstance(x, float | int | np.number) and not isinstance(x, bool) and \
        math.isfinite(x)


def _true(x) -> bool:
    return isinstance(x, bool | np.bool_) and bool(x)


def _run_name(r) -> str:
    """The run's name; two run folders of different runs show "A's -> B's"."""
    names = [x for x in (r.get("run_a"), r.get("run_b")) if isinstance(x, str)]
    return names[0] if len(set(names)) == 1 else " -> ".join(names)


def compare(a: Path, b: Path, threshold: float = 0.10) -> pd.DataFrame:
    """One row per cell (run x segment length where A or B has segments): the run's keys,
    ``run`` (its display label), A and B values, ``*_delta`` = B - A, ``only_in`` ("A", "B" or
    ""), ``regression`` and ``note``."""
    da, db, run_keys = _pair(a, b)
    keys = [*run_keys, "length_m"]
    merged = da.merge(db, on=keys, suffixes=("_a", "_b"), how="outer", indicator=True)
    labels = {side: _labels_by_name(d) for side, d in (("A", da), ("B", db))}
    rows = []
    for _, r in merged.iterrows():
        row = {k: r[k] for k in keys}
        row["run"] = _run_name(r)
        row["_params"] = r.get("params_a") if isinstance(r.get("params_a"), str) \
            else r.get("params_b")
        row["only_in"] = {"left_only": "A", "right_only": "B"}.get(r["_merge"], "")
        newly_diverged = _true(r.get("diverged_b")) and not _true(r.get("diverged_a"))
        grew = False
        for q in QUANTITIES:
            va, vb = r.get(f"{q}_a"), r.get(f"{q}_b")
            row[f"{q}_a"], row[f"{q}_b"] = va, vb
            for side in "ab":
                for end in ("low", "high"):
                    row[f"{q}_ci_{end}_{side}"] = r.get(f"{q}_ci_{end}_{side}")
            delta = vb - va if _finite(va) and _finite(vb) else math.nan
            row[f"{q}_delta"] = delta
            grew |= _finite(delta) and va > 0 and delta / va > threshold
        differ = params_differ(r.get("params_a"), r.get("params_b"))
        grew &= not differ  # another configuration: a difference, not a regression
        row["regression"] = newly_diverged or grew
        row["has_data"] = any(_finite(row[f"{q}_{s}"]) for q in QUANTITIES for s in "ab")
        row["note"] = _note(row, grew, newly_diverged, r, _apart(row))
        if differ:
            row["note"] = "; ".join(x for x in (f"parameters differ: {differ}", row["note"])
                                    if x)
        row["note"] += _other_content(row, r, labels)
        rows.append(row)
    _name_other_parameters(rows, [k for k in keys if k != "overrides"])
    df = pd.DataFrame(rows).drop(columns=["_params"], errors="ignore")
    if df.empty:
        return df
    # a length without segments on either side is no cell; a newly diverged run keeps one row
    # even then, so that its regression is never dropped
    empty = ~df["has_data"]
    df["_first"] = ~df.duplicated(subset=run_keys)
    keep = ~empty | (df["regression"] & df["_first"] & ~_any_data(df, run_keys))
    df.loc[keep & empty, "length_m"] = math.nan
    return _in_table_order(df[keep].drop(columns=["has_data", "_first"]), run_keys)


def _name_other_parameters(rows: list[dict], same: list[str]) -> None:
    """A run only in A and one only in B of the same sequence, method, label, seed option and
    length that differ in their parameters (``-p``): each row's note names them."""
    alone = {"A": {}, "B": {}}
    for row in rows:
        if row["only_in"] and "overrides" in row:
            alone[row["only_in"]].setdefault(tuple(row[k] for k in same), []).append(row)
    for key, in_a in alone["A"].items():
        in_b = alone["B"].get(key, [])
        if len(in_a) != 1 or len(in_b) != 1:
            continue
        differ = params_differ(in_a[0]["_params"], in_b[0]["_params"]) or \
            f"A {in_a[0]['overrides'].strip() or 'defaults'}, " \
            f"B {in_b[0]['overrides'].strip() or 'defaults'}"
        for row, other in ((in_a[0], "B"), (in_b[0], "A")):
            row["note"] += f" ({other} has this run with other parameters: {differ})"


def _labels_by_name(df: pd.DataFrame) -> dict[str, set[str]]:
    """Sequence name -> the sequence labels (name and content tag) a side holds under it."""
    out: dict[str, set[str]] = {}
    for name, label in zip(df["sequence_name"], df["sequence"], strict=True):
        out.setdefault(name, set()).add(label)
    return out


def _other_content(row: dict, r, labels: dict[str, dict[str, set[str]]]) -> str:
    """For a run on one side only: "; B holds data1 [b.h5]: another content of data1, not
    compared" when the other side holds that sequence name with other content."""
    side = row["only_in"]
    if not side:
        return ""
    other = "B" if side == "A" else "A"
    name = r.get(f"sequence_name_{side.lower()}")
    if not isinstance(name, str):
        return ""
    theirs = sorted(labels[other].get(name, set()) - {row["sequence"]})
    if not theirs:
        return ""
    return (f"; {other} holds {', '.join(theirs)}: another content of {name} (other store "
            "or frames), not compared")


def _in_table_order(df: pd.DataFrame, run_keys: list[str]) -> pd.DataFrame:
    """Rows in the main table's order: the paper's sequences, methods and seed options (with
    seed first), then by length."""
    def key(r) -> tuple:
        k = (sequence_key(r["sequence"]),)
        if "method" in run_keys:
            tag = r["seed"]
            k += (order_key(r["method"]), r["method"],
                  _SEED_ORDER.index(tag) if tag in _SEED_ORDER else len(_SEED_ORDER),
                  r["label"])
        length = r.get("length_m", 0.0)
        return (*k, length if _finite(length) else -1.0)

    order = sorted(range(len(df)), key=lambda i: key(df.iloc[i]))
    return df.iloc[order].reset_index(drop=True)


def _any_data(df: pd.DataFrame, run_keys: list[str]) -> pd.Series:
    """Per row: does its run have a cell with data at any length?"""
    return df.groupby(run_keys, dropna=False)["has_data"].transform("any")


def _stat(row: dict, q: str, side: str) -> Stat | None:
    value = row[f"{q}_{side}"]
    low, high = row.get(f"{q}_ci_low_{side}"), row.get(f"{q}_ci_high_{side}")
    if not (_finite(value) and _finite(low) and _finite(high)):
        return None
    return Stat(float(value), (float(low), float(high)))


def _apart(row: dict) -> dict[str, str]:
    """quantity -> "worse" / "better" where B's and A's printed intervals do not meet, "" where
    they meet (quantities without both intervals are left out)."""
    out = {}
    for q in QUANTITIES:
        a, b = _stat(row, q, "a"), _stat(row, q, "b")
        if a is not None and b is not None:
            out[q] = "worse" if worse(b, a) else "better" if worse(a, b) else ""
    return out


_WORDS = {"rot_deg_mean": "rotation", "trans_m_mean": "translation"}


def _note(row: dict, grew: bool, newly_diverged: bool, r, apart: dict[str, str]) -> str:
    notes = []
    if grew:
        within = apart and not any(v == "worse" for v in apart.values())
        notes.append("! regression" + (" by value only: A's and B's intervals meet, they cannot "
                                       "tell it from noise" if within else
                                       "" if apart else " (by value: no intervals)"))
    notes += [f"{_WORDS[q]} {v} beyond the intervals" for q, v in apart.items() if v]
    if newly_diverged:
        notes.append("! newly diverged")
    elif _true(r.get("diverged_a")) and _true(r.get("diverged_b")):
        notes.append("diverged in A and B")
    elif _true(r.get("diverged_a")) and row["only_in"] == "":
        notes.append("diverged in A only")
    if row["only_in"]:
        notes.append(f"only in {row['only_in']}")
    else:
        for side in "ab":
            if not any(_finite(row[f"{q}_{side}"]) for q in QUANTITIES):
                notes.append(f"no segments in {side.upper()}")
    return "; ".join(notes)


def compare_times(a: Path, b: Path) -> pd.DataFrame:
    """One row per run: the mean time per frame [ms] of A and B (``time_ms_a``, ``time_ms_b``),
    ``time_ms_delta`` = B - A and ``only_in``."""
    da, db, run_keys = _pair(a, b)
    cols = [*run_keys, "run", "time_ms_mean"]
    runs_a, runs_b = (d.drop_duplicates(subset=run_keys)[cols] for d in (da, db))
    merged = runs_a.merge(runs_b, on=run_keys, suffixes=("_a", "_b"), how="outer",
                          indicator=True)
    rows = []
    for _, r in merged.iterrows():
        ta, tb = r.get("time_ms_mean_a"), r.get("time_ms_mean_b")
        rows.append({**{k: r[k] for k in run_keys}, "run": _run_name(r),
                     "time_ms_a": ta, "time_ms_b": tb,
                     "time_ms_delta": tb - ta if _finite(ta) and _finite(tb) else math.nan,
                     "only_in": {"left_only": "A", "right_only": "B"}.get(r["_merge"], "")})
    return _in_table_order(pd.DataFrame(rows), run_keys) if rows else pd.DataFrame(rows)


#: per-run quantities of the third table: (column of results_frame, title, digits)
RUN_QUANTITIES = (("ape_trans_m", "APE [m]", 3), ("kitti_trans_pct", "KITTI trans. [%]", 2),
                  ("kitti_rot_deg_per_100m", "KITTI rot. [deg/100 m]", 2),
                  ("velocity_err_mps", "Velocity err. [m/s]", 3))


def compare_run_metrics(a: Path, b: Path) -> pd.DataFrame:
    """One row per run: each of ``RUN_QUANTITIES`` in A and B (``<q>_a``, ``<q>_b``), the APE
    alignment of each side and ``only_in``."""
    da, db, run_keys = _pair(a, b)
    cols = [*run_keys, "run", "ape_alignment", *(q for q, _, _ in RUN_QUANTITIES)]
    runs_a, runs_b = (d.drop_duplicates(subset=run_keys)[cols] for d in (da, db))
    merged = runs_a.merge(runs_b, on=run_keys, suffixes=("_a", "_b"), how="outer",
                          indicator=True)
    rows = []
    for _, r in merged.iterrows():
        row = {**{k: r[k] for k in run_keys}, "run": _run_name(r),
               "only_in": {"left_only": "A", "right_only": "B"}.get(r["_merge"], "")}
        for q, _, _ in RUN_QUANTITIES:
            row[f"{q}_a"], row[f"{q}_b"] = r.get(f"{q}_a"), r.get(f"{q}_b")
        row["ape_alignment_a"], row["ape_alignment_b"] = r.get("ape_alignment_a"), \
            r.get("ape_alignment_b")
        rows.append(row)
    return _in_table_order(pd.DataFrame(rows), run_keys) if rows else pd.DataFrame(rows)


# ---- output ----------------------------------------------------------------------------------

def _fmt(x, digits: int = 3) -> str:
    return f"{x:.{digits}f}" if _finite(x) else "-"


def _fmt_ci(r, q: str, side: str, digits: int = 3) -> str:
    """The value of quantity ``q`` on ``side`` with its interval: "0.697 [0.523, 0.889]"."""
    value = r[f"{q}_{side}"]
    text = _fmt(value, digits)
    low, high = r.get(f"{q}_ci_low_{side}"), r.get(f"{q}_ci_high_{side}")
    if text != "-" and _finite(low) and _finite(high):
        low, high = shown_interval(float(value), (float(low), float(high)))
        text += f" [{low:.{digits}f}, {high:.{digits}f}]"
    return text


def _change(a, b, digits: int = 3) -> str:
    """B - A with its sign, and the relative change when A is not zero: "+0.012 (+4.1%)"."""
    if not (_finite(a) and _finite(b)):
        return "-"
    text = f"{b - a:+.{digits}f}"
    return text + (f" ({(b - a) / a:+.1%})" if a != 0 else "")


def _length(x) -> str:
    return f"{x:g}" if _finite(x) else "-"


def markdown_table(header: list[str], rows: list[list[str]], right: set[int]) -> list[str]:
    """A pipe table, every column padded to its widest cell (``right``: right-aligned column
    indices); the caller escapes text from data (``md_escape``); '|' is escaped in every cell."""
    cells = [[str(c).replace(r"\|", "|").replace("|", r"\|") for c in row]
             for row in [header, *rows]]
    widths = [max(3, *(len(row[i]) for row in cells)) for i in range(len(header))]

    def line(row):
        return "| " + " | ".join(c.rjust(w) if i in right else c.ljust(w)
                                 for i, (c, w) in enumerate(zip(row, widths, strict=True))) + " |"

    sep = "| " + " | ".join("-" * (w - 1) + ":" if i in right else "-" * w
                            for i, w in enumerate(widths)) + " |"
    return [line(cells[0]), sep, *(line(row) for row in cells[1:])]


def to_markdown(cells: pd.DataFrame, times: pd.DataFrame, a: Path, b: Path,
                threshold: float, per_run: pd.DataFrame | None = None) -> str:
    """The relative-error table (one row per cell), the time table (one row per run), the
    per-run metrics (APE, KITTI drift, velocity error) and a one-line summary, as markdown."""
    out = [f"A = `{a}`, B = `{b}`", "",
           "Mean relative error over the segments of each length: rotation [deg], translation "
           "[m], each with its 95 % confidence interval [low, high] (block bootstrap along the "
           "trajectory); change = B - A; \"worse\" / \"better\" beyond the intervals: A's and "
           "B's printed intervals do not meet:", ""]
    rows = []
    for _, r in cells.iterrows():
        row = [md_escape(r["sequence"]), md_escape(r["run"]), _length(r["length_m"])]
        for q in QUANTITIES:
            row += [_fmt_ci(r, q, "a"), _fmt_ci(r, q, "b"), _change(r[f"{q}_a"], r[f"{q}_b"])]
        rows.append([*row, md_escape(r["note"])])
    out += markdown_table(["Sequence", "Run", "Length [m]", "Rot. A", "Rot. B", "Rot. change",
                           "Trans. A", "Trans. B", "Trans. change", "Note"], rows,
                          right=set(range(2, 9)))
    out += ["", "Mean time per frame [ms] (all per-frame work, `time_ms`):", ""]
    rows = [[md_escape(r["sequence"]), md_escape(r["run"]), _fmt(r["time_ms_a"], 2),
             _fmt(r["time_ms_b"], 2),
             _change(r["time_ms_a"], r["time_ms_b"], 2),
             f"only in {r['only_in']}" if r["only_in"] else ""] for _, r in times.iterrows()]
    out += markdown_table(["Sequence", "Run", "Time A", "Time B", "Change", "Note"],
                          rows, right={2, 3, 4})
    if per_run is not None and len(per_run):
        aligned = sorted({str(x) for side in "ab" for x in per_run[f"ape_alignment_{side}"]
                          if isinstance(x, str)})
        out += ["", "Per run: APE (alignment: " + (", ".join(aligned) or "-") + "), KITTI drift "
                "over 100-800 m and ego-velocity error (mean norm); A -> B:", ""]
        rows = [[md_escape(r["sequence"]), md_escape(r["run"]), *(
            f"{_fmt(r[f'{q}_a'], d)} -> {_fmt(r[f'{q}_b'], d)}" for q, _, d in RUN_QUANTITIES),
            f"only in {r['only_in']}" if r["only_in"] else ""] for _, r in per_run.iterrows()]
        out += markdown_table(["Sequence", "Run", *(t for _, t, _ in RUN_QUANTITIES), "Note"],
                              rows, right={2, 3, 4, 5})
    out += ["", summary(cells, threshold)]
    return "\n".join(out) + "\n"


def summary(cells: pd.DataFrame, threshold: float) -> str:
    """"12 cells (2 only in A, 0 only in B), 1 regression (...)", and how many of the
    regressions the intervals cannot tell from noise."""
    n = len(cells)
    only = cells["only_in"].value_counts() if n else pd.Series(dtype=int)
    regressions = int(cells["regression"].sum()) if n else 0
    unsure = int(cells["note"].str.contains("cannot tell it from noise").sum()) if n else 0
    return (f"{n} {'cell' if n == 1 else 'cells'} ({only.get('A', 0)} only in A, "
            f"{only.get('B', 0)} only in B), {regressions} "
            f"{'regression' if regressions == 1 else 'regressions'} (> {threshold:.0%} growth "
            "or newly diverged" + (f"; {unsure} of them by value only: A's and B's intervals "
                                   "meet, so they cannot tell it from noise" if unsure else "")
            + ")")
