"""One page across datasets: how each method fares over every sequence of a results folder.

Per sensor class (the paper's order) one row per method: the sequences it was scored on, its
**mean mark** over them and how often it is bold, and how many of its runs failed, diverged or
fell back. A method's mark on one figure of one sequence (the mean rotation and the mean
translation relative error at the shortest and the longest length the runs have,
``ranked_lengths``) is the mark the tables of the same page print for it (1 bold, 2 underlined,
3 neither: ``bench.report.summary.ranks``, from ``bench.report.tables.significance``), so the
page has one rule: a method whose cells are underlined in its class's tables cannot have the
best mean mark unless every other method's cells are marked no better. A method's seed and
no-seed rows are one contender (its better mark). A figure resting on fewer than two
independent segments is not marked, so not counted. A method run in the folder but not on a
sensor class says why (a Doppler method on stores without raw Doppler; an external trajectory
(``bench score``) not scored on that class's stores; otherwise: not run on that class).
"Sequences" counts the sequences a method has a finished run on (its seed and no-seed runs of
one sequence are one sequence; two names holding one content are one sequence, named in the
caption: ``bench.report.summary.ranks.counted_as``).
Across sequences, pairwise (``bench.report.summary.pairwise``): on how many sequences each
method ranks better than another and whether that holds (an exact sign test).

``sources``: every sequence's store with its dataset, licence and loader options (the store's
provenance and ``loaders.registry``), for the page.
"""

from __future__ import annotations

import json
import math
import re
from collections import defaultdict
from pathlib import Path

from bench.report.names import order_key
from bench.report.summary.pairwise import pairwise_table
from bench.report.summary.ranks import (
    contender_name,
    counted_as,
    figure_ranks,
    ranked_lengths,
    same_content_note,
)
from bench.report.tables.model import Cell, Part, Row, Table
from bench.report.tables.paper import RunRow
from bench.runs.result import EXTERNAL_MARK
from loaders.sensor_classes import CLASS_ORDER, class_rank
from methods.registry import METHODS, get_method


def _why_not(method: str, label: str, class_rows: list[RunRow]) -> str:
    if label.endswith(EXTERNAL_MARK) or method not in METHODS:
        # a trajectory made elsewhere (bench score) or a plugin not loaded now: no registry
        return ("not scored on this class (an external trajectory: `bench score` it on these "
                "stores)" if label.endswith(EXTERNAL_MARK) else
                "not run on this class (the experiment did not ask for it)")
    cls = get_method(method)
    kinds = {rr.run.doppler_kind for rr in class_rows}
    if getattr(cls, "needs_doppler", False) and "radial" not in kinds:
        return (f"not run: needs raw (radial) Doppler; these stores have "
                f"{', '.join(sorted(kinds))} Doppler")
    return "not run on this class (the experiment did not ask for it)"


def summary_table(rows: list[RunRow], lengths_m: tuple[float, ...] | None = None) -> Table:
    """The cross-dataset summary (see the module docstring); ranked at ``lengths_m``, by
    default the shortest and the longest length the runs have (``ranked_lengths``)."""
    usable = [L for L in (ranked_lengths(rows) if lengths_m is None else lengths_m)
              if any(rr.result.relative(L) is not None for rr in rows)]
    ranks = {(L, q): figure_ranks(rows, L, q) for L in usable for q in ("rot_deg", "trans_m")}
    counted = counted_as(rows)
    table = Table(["Sensor class", "Method"],
                  ["Sequences", "Mean mark", "Bold", "Failed", "Diverged", "Fell back"], [])
    classes = sorted({rr.sensor_class for rr in rows}, key=lambda c: (class_rank(c), c))
    methods = sorted({(rr.method, rr.run.label or "") for rr in rows},
                     key=lambda m: (order_key(m[0]), m))
    for cls_name in classes:
        class_rows = [rr for rr in rows if rr.sensor_class == cls_name]
        for method, label in methods:
            mine = [rr for rr in class_rows if rr.method == method
                    and (rr.run.label or "") == label]
            name = contender_name(method, label)
            if not mine:
                table.rows.append(Row([cls_name, name], (cls_name,),
                                      [Cell(status=_why_not(method, label, class_rows))]
                                      + [Cell(status="") for _ in range(5)],
                                      {"method": method, "label": label or None}))
                continue
            key = (method, label or None)
            # scored on (two names of one content: one sequence)
            seqs = sorted({counted[rr.sequence] for rr in mine if not rr.failed})
            got = [per_q[seq][key] for per_q in ranks.values() for seq in seqs
                   if key in per_q.get(seq, {})]
            mean = sum(got) / len(got) if got else math.nan
            bold = sum(g == 1 for g in got)
            failed = sum(rr.failed for rr in mine)
            diverged = sum(not rr.failed and rr.diverged for rr in mine)
            fell_back = sum(not rr.failed and rr.result.fell_back for rr in mine)
            cells = [Cell([Part(str(len(seqs)))], values={"sequences": len(seqs)}),
                     Cell([Part(f"{mean:.2f}" if got else "-")],
                          values={"mean_mark": mean, "marked_figures": len(got)}),
                     Cell([Part(f"{bold} of {len(got)}" if got else "-")],
                          values={"bold_figures": bold}),
                     Cell([Part(str(failed))], values={"failed": failed}),
                     Cell([Part(str(diverged))], values={"diverged": diverged}),
                     Cell([Part(str(fell_back))], values={"fell_back": fell_back})]
            table.rows.append(Row([cls_name, name], (cls_name,), cells,
                                  {"method": method, "label": label or None}))
    # within a class, the lowest mean mark in bold (a summary of marks: by value, said so)
    for group in {r.group for r in table.rows}:
        members = [r for r in table.rows if r.group == group and r.cells[1].parts
                   and math.isfinite(r.cells[1].values.get("mean_mark", math.nan))]
        if members:
            low = min(r.cells[1].values["mean_mark"] for r in members)
            for r in members:
                if r.cells[1].values["mean_mark"] == low:
                    r.cells[1].parts[0].rank = 0
    lengths = " and ".join(f"{L:g} m" for L in usable)
    where = (f"the mean rotation and the mean translation relative error at {lengths}, the "
             "shortest and the longest length the runs have" if usable else
             "no run has segments at any length: nothing is ranked")
    table.caption = (
        "Across datasets, per sensor class: the sequences each method was scored on and its mean "
        f"mark over them ({where}; on each figure the mark the relative-error tables on this "
        "page print for it, counted 1 = bold, 2 = underlined, 3 = neither, so the summary "
        "follows the tables' one rule; the seed and no-seed rows of a method count as one, "
        "its better mark; figures on fewer than 2 independent segments are not marked and not "
        "counted). Bold: on how many of those figures the method is bold. The lowest mean mark "
        "of a class is bold (by value: a summary, not a test). "
        "Failed / Diverged: runs that did not finish / diverged; Fell back: runs with more "
        "than 5 % of their frames replaced by the motion prior or not converged."
        + _unknown_classes_note(classes) + same_content_note(rows))
    return table


def _unknown_classes_note(classes: list[str]) -> str:
    """Classes outside the paper's three (a store whose loader does not know the sensor's
    density): said, since the same drive from its own loader lands in a paper class."""
    odd = [c for c in classes if c not in CLASS_ORDER]
    if not odd:
        return ""
    return (f" {', '.join(odd)}: stores whose loader does not know the sensor's density "
            "(NumPy frames, a ROS bag converted without --model); the same drive converted by "
            "its own loader lands in its paper class (the Oculii Eagle: Semi-Dense 4D Radar), "
            "so one drive can appear in two classes here: convert with --model (e.g. "
            "radar-semidense) to rank it in one.")


def sources(rows: list[RunRow]) -> list[dict]:
    """Every sequence's source: its name, sensor class, store, dataset, licence and the
    loader with its options (from the store's provenance and ``loaders.registry``)."""
    from loaders.registry import LOADERS as entries
    seen: dict[str, dict] = {}
    for rr in rows:
        seq = rr.run.config.get("sequence") or {}
        store = seq.get("store")
        if rr.sequence in seen:
            continue
        prov = _provenance(store, rr.run.dir)
        loader = prov.get("loader") or seq.get("sensor_model")
        entry = entries.get(loader)
        options = {k: v for k, v in (prov.get("options") or {}).items() if v is not None}
        dataset, licence = _dataset_and_licence(seq, prov, entry)
        seen[rr.sequence] = {
            "sequence": rr.sequence, "sensor_class": rr.sensor_class, "store": store,
            "dataset": dataset, "licence": licence,
            "loader": loader or "", "options": options, "source": prov.get("source", "")}
    return sorted(seen.values(), key=lambda s: (class_rank(s["sensor_class"]), s["sequence"]))


#: a licence named in parentheses in a store's ``source`` text ("... (MIT); see ...")
_LICENCE = re.compile(r"\((MIT|BSD[^)]*|Apache[^)]*|L?GPL[^)]*|CC[ -]BY[^)]*|CC0[^)]*"
                      r"|ODbL[^)]*|MPL[^)]*)\)")
#: the licence of the loader table's generic routes (any recording of the user's)
_YOURS = "yours"


def _dataset_and_licence(seq: dict, prov: dict, entry) -> tuple[str, str]:
    """A sequence's dataset and licence from the store's own metadata first (its provenance's
    ``dataset`` / ``licence``, else what its ``source`` text names: the vendored sample says
    "NTU4DRadLM loop 1 ... (MIT)"), then the run's configuration, then the loader table, whose
    generic routes (NumPy frames, any ROS bag) know no dataset or licence of their own."""
    source = str(prov.get("source") or "")
    generic = entry is None or entry.licence == _YOURS
    named = _LICENCE.search(source)
    licence = (prov.get("licence") or (named.group(1) if named else None)
               or (entry.licence if not generic else None)
               or ("not recorded (your own data)" if source or entry is not None else ""))
    dataset = (seq.get("dataset") or prov.get("dataset")
               or (re.split(r" \(|, |; ", source)[0] if generic and source else None)
               or (entry.dataset if entry else "") or source)
    return str(dataset), str(licence)


def _provenance(store: str | None, run_dir: Path) -> dict:
    if not store:
        return {}
    path = Path(store)
    for candidate in (path, Path.cwd() / path, run_dir / path):
        if candidate.exists():
            try:
                import h5py

                with h5py.File(candidate, "r") as f:
                    return json.loads(f.attrs.get("provenance", "{}"))
            except (OSError, ValueError):
                return {}
    return {}


def sources_table(rows: list[RunRow]) -> Table:
    """Every sequence's source (``sources``) as a table."""
    table = Table(["Sensor class", "Sequence"],
                  ["Dataset", "Licence", "Loader and options", "Store"], [])
    for s in sources(rows):
        options = ", ".join(f"{k}={v}" for k, v in sorted(s["options"].items()))
        table.rows.append(Row([s["sensor_class"], s["sequence"]], (s["sensor_class"],), [
            Cell([Part(s["dataset"] or "-")]), Cell([Part(s["licence"] or "-")]),
            Cell([Part(s["loader"] + (f" ({options})" if options else ""))]),
            Cell([Part(str(s["store"] or "-"))])]))
    table.caption = ("The source of every sequence: its dataset and licence (loaders.registry), "
                     "the loader and options that made its store (the store's provenance).")
    return table


def cross_dataset(results_dir: Path) -> list[tuple[str, Table]]:
    """(title, table) of the page across datasets: when the folder's runs span more than one
    dataset (recorded in the run's configuration or the store's provenance), a relative-error
    table per dataset (with intervals), the summary and the sources; nothing for a single
    dataset."""
    from bench.report.tables.paper import build, select

    try:
        rows, lengths = select(Path(results_dir))
    except (FileNotFoundError, ValueError):
        return []
    by_dataset: dict[str, list[RunRow]] = defaultdict(list)
    names = {s["sequence"]: s["dataset"] for s in sources(rows)}
    for rr in rows:
        by_dataset[names.get(rr.sequence) or "dataset not recorded"].append(rr)
    if len([d for d in by_dataset if d != "dataset not recorded"]) < 2:
        return []  # one dataset (or none recorded): the ordinary tables say it all
    out = [("Across datasets: mean mark per method", summary_table(rows))]
    pairwise = pairwise_table(rows)
    if pairwise.rows:  # a class with two or more sequences
        out.append(("Across sequences: pairwise verdicts (k/n, sign test)", pairwise))
    out.append(("Sources of the sequences", sources_table(rows)))
    for dataset in sorted(by_dataset):
        out.append((f"Dataset: {dataset}", build("relative", by_dataset[dataset], lengths,
                                                 ci=True)))
    return out
