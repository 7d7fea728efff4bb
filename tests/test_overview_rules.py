"""The cross-dataset summary (bench.report.summary.overview) on hand-made runs and marks.

The marks per sequence (``figure_ranks``) and which name a sequence is counted under
(``counted_as``) are given by hand, the runs are stand-ins with just what the summary reads, so
every figure below follows from the module's definition: a method's mean mark over the figures
it is marked on (1 bold, 2 underlined, 3 neither), how many of them are bold, the sequences it
finished on (two names of one content: one), its failed / diverged / fell-back runs, and why a
method has no row's figures on a class."""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from bench.report.summary import overview
from bench.report.summary.overview import (
    _dataset_and_licence,
    _unknown_classes_note,
    _why_not,
    sources,
    sources_table,
    summary_table,
)
from loaders.registry import LOADERS
from loaders.sensor_classes import SEMI_DENSE_RADAR, SPARSE_RADAR

CUSTOM = "Custom radar"
LENGTHS = (8.0, 48.0)
FIGS = [(L, q) for L in LENGTHS for q in ("rot_deg", "trans_m")]


def _run(seq, cls, method, label="", failed=False, diverged=False, fell_back=False,
         kind="radial", lengths=LENGTHS):
    result = SimpleNamespace(relative=lambda L: SimpleNamespace(n=5) if L in lengths else None,
                             fell_back=fell_back)
    run = SimpleNamespace(label=label or None, doppler_kind=kind, config={}, dir=Path("."))
    return SimpleNamespace(sequence=seq, sensor_class=cls, method=method, run=run,
                           result=result, failed=failed, diverged=diverged)


IP, GI, DO = ("icp-p2p", None), ("gicp", None), ("doppler", None)
#: sequence -> contender -> its marks on the four figures (None: not marked)
MARKS = {
    "s1": {IP: [2, 2, 2, 2], GI: [1, 1, 1, 1]},
    "s2": {IP: [1, 1, 3, 3], GI: [1, 1, None, 1]},
    "t1": {DO: [1, 2, 1, 2]},
    "c2": {GI: [3, 3, 3, 3]},
}


def _figures(marks=MARKS):
    # a sequence nobody is marked on in a figure is not in it (as figure_ranks gives it)
    out = {fig: {s: {k: r[j] for k, r in ks.items() if r[j] is not None}
                 for s, ks in marks.items()} for j, fig in enumerate(FIGS)}
    return {fig: {s: ks for s, ks in f.items() if ks} for fig, f in out.items()}


@pytest.fixture
def rows(monkeypatch):
    figures = _figures()
    calls = []

    def figure_ranks(rows, length_m, quantity):
        assert rows is out
        calls.append((length_m, quantity))
        return figures[(length_m, quantity)]

    def ranked_lengths(rows):
        assert rows is out
        return LENGTHS

    monkeypatch.setattr(overview, "figure_ranks", figure_ranks)
    monkeypatch.setattr(overview, "counted_as",
                        lambda rows: {r.sequence: ("s2" if r.sequence == "s2b" else r.sequence)
                                      for r in rows})
    monkeypatch.setattr(overview, "ranked_lengths", ranked_lengths)
    monkeypatch.setattr(overview, "same_content_note",
                        lambda rows: " Sequences holding one content: s2 = s2b.")
    out = [
        # semi-dense radar (ego-motion Doppler only)
        _run("s1", SEMI_DENSE_RADAR, "icp-p2p", kind="ego", diverged=True),
        _run("s2", SEMI_DENSE_RADAR, "icp-p2p", kind="ego", fell_back=True),
        _run("s2b", SEMI_DENSE_RADAR, "icp-p2p", kind="ego"),  # s2 under another name
        _run("s1", SEMI_DENSE_RADAR, "gicp", kind="ego", diverged=True),
        _run("s2", SEMI_DENSE_RADAR, "gicp", kind="ego"),
        _run("s3", SEMI_DENSE_RADAR, "gicp", kind="ego", failed=True, diverged=True,
             fell_back=True),
        # sparse radar (raw Doppler): only the Doppler method
        _run("t1", SPARSE_RADAR, "doppler"),
        # a class outside the paper's three: one failed run
        _run("c1", CUSTOM, "icp-p2p", failed=True),
        _run("c2", CUSTOM, "gicp"),
        # an external trajectory scored on sparse radar
        _run("t1", SPARSE_RADAR, "kiss", label="kiss-ext (external)", lengths=()),
    ]
    return out, calls


def _by(table):
    return {(r.keys[0], r.keys[1]): r for r in table.rows}


def test_rows_per_class_and_method_in_the_papers_order(rows):
    rr, calls = rows
    table = summary_table(rr)
    assert sorted(set(calls)) == sorted(FIGS)
    assert table.keys == ["Sensor class", "Method"]
    assert table.columns == ["Sequences", "Mean mark", "Bold", "Failed", "Diverged",
                             "Fell back"]
    # classes in the paper's order, the unknown one last; methods by their order, then name
    assert [tuple(r.keys) for r in table.rows] == [
        (c, m) for c in (SPARSE_RADAR, SEMI_DENSE_RADAR, CUSTOM)
        for m in ("icp-p2p", "gicp", "doppler", "kiss-ext (external)")]
    assert all(r.group == (r.keys[0],) for r in table.rows)
    assert all(len(r.cells) == 6 for r in table.rows)
    b = _by(table)
    assert b[(SPARSE_RADAR, "kiss-ext (external)")].meta == {"method": "kiss",
                                                             "label": "kiss-ext (external)"}
    assert b[(SEMI_DENSE_RADAR, "gicp")].meta == {"method": "gicp", "label": None}
    assert b[(SPARSE_RADAR, "gicp")].meta == {"method": "gicp", "label": None}


def test_mean_mark_bold_count_and_the_lowest_in_bold(rows):
    rr, _ = rows
    b = _by(summary_table(rr))
    ip = b[(SEMI_DENSE_RADAR, "icp-p2p")].cells
    gi = b[(SEMI_DENSE_RADAR, "gicp")].cells
    # icp-p2p: s1 and s2 (s2b is s2): eight marks, an independent mean with numpy
    ip_marks = MARKS["s1"][IP] + MARKS["s2"][IP]
    assert ip[0].parts[0].text == "2" and ip[0].values == {"sequences": 2}
    assert ip[1].values["mean_mark"] == pytest.approx(np.mean(ip_marks))
    assert ip[1].values["marked_figures"] == 8
    assert ip[1].parts[0].text == f"{np.mean(ip_marks):.2f}" == "2.00"
    assert ip[2].parts[0].text == "2 of 8" and ip[2].values == {"bold_figures": 2}
    # gicp: s3 failed, so two sequences; seven marks (one figure of s2 unmarked), all bold
    assert gi[0].parts[0].text == "2"
    assert gi[1].values["marked_figures"] == 7
    assert gi[1].values["mean_mark"] == pytest.approx(1.0)
    assert gi[2].parts[0].text == "7 of 7"
    # the lowest mean mark of the class is bold, the other is not
    assert gi[1].parts[0].rank == 0 and ip[1].parts[0].rank != 0
    # sparse radar: the Doppler method alone, mean 1.5, bold (the lowest of its class)
    do = b[(SPARSE_RADAR, "doppler")].cells
    assert do[1].values["mean_mark"] == pytest.approx(1.5) and do[1].parts[0].text == "1.50"
    assert do[2].parts[0].text == "2 of 4" and do[1].parts[0].rank == 0


def test_failed_diverged_and_fell_back_count_runs(rows):
    rr, _ = rows
    b = _by(summary_table(rr))
    gi = b[(SEMI_DENSE_RADAR, "gicp")].cells
    # s3 failed (its diverged / fell-back flags do not count: it did not finish); s1 diverged
    assert [c.parts[0].text for c in gi[3:]] == ["1", "1", "0"]
    assert gi[3].values == {"failed": 1} and gi[4].values == {"diverged": 1}
    assert gi[5].values == {"fell_back": 0}
    ip = b[(SEMI_DENSE_RADAR, "icp-p2p")].cells
    assert [c.parts[0].text for c in ip[3:]] == ["0", "1", "1"]
    # a class where the method only failed: no sequence, no mark, not bold
    c = b[(CUSTOM, "icp-p2p")].cells
    assert c[0].parts[0].text == "0" and c[3].parts[0].text == "1"
    assert c[1].parts[0].text == "-" and c[2].parts[0].text == "-"
    assert math.isnan(c[1].values["mean_mark"]) and c[1].values["marked_figures"] == 0
    assert c[1].parts[0].rank != 0
    # the only marked method of that class: the lowest of its class, bold, though others'
    # are lower
    c = b[(CUSTOM, "gicp")].cells
    assert c[1].values["mean_mark"] == pytest.approx(3.0) and c[1].parts[0].rank == 0


def test_why_a_method_has_no_runs_on_a_class(rows):
    rr, _ = rows
    b = _by(summary_table(rr))
    why = {k: r.cells[0].status for k, r in b.items() if r.cells[0].status}
    assert "needs raw (radial) Doppler" in why[(SEMI_DENSE_RADAR, "doppler")]
    assert "these stores have ego Doppler" in why[(SEMI_DENSE_RADAR, "doppler")]
    assert "did not ask for it" in why[(SPARSE_RADAR, "icp-p2p")]
    # the Doppler method on raw-Doppler stores it was not run on: simply not asked for
    assert "did not ask for it" in why[(CUSTOM, "doppler")]
    assert why[(SEMI_DENSE_RADAR, "kiss-ext (external)")] == (
        "not scored on this class (an external trajectory: `bench score` it on these stores)")
    assert why[(SPARSE_RADAR, "gicp")] == (
        "not run on this class (the experiment did not ask for it)")
    assert all(c.status == "" for c in b[(SPARSE_RADAR, "icp-p2p")].cells[1:])
    # rows with figures have no status
    assert (SEMI_DENSE_RADAR, "gicp") not in why
    # a method that is not registered (a plugin not loaded): not asked for, no registry
    assert _why_not("my-plugin", "", []) == (
        "not run on this class (the experiment did not ask for it)")
    kinds = [_run("x", SPARSE_RADAR, "icp-p2p", kind=k) for k in ("ego", "none", "ego")]
    assert _why_not("doppler", "", kinds).endswith("these stores have ego, none Doppler")
    assert "did not ask" in _why_not("doppler", "", kinds + [_run("y", SPARSE_RADAR, "x")])
    assert "did not ask" in _why_not("gicp", "", kinds)


def test_the_caption_says_lengths_rule_and_notes(rows):
    rr, _ = rows
    caption = summary_table(rr).caption
    assert "at 8 m and 48 m, the shortest and the longest" in caption
    assert "1 = bold, 2 = underlined, 3 = neither" in caption
    for words in ("the seed and no-seed rows of a method count as one, its better mark",
                  "figures on fewer than 2 independent segments are not marked and not counted)",
                  ". Bold: on how many of those figures the method is bold. The lowest mean "
                  "mark of a class is bold (by value: a summary, not a test). Failed / "
                  "Diverged: runs that did not finish / diverged; Fell back: runs with more "
                  "than 5 % of their frames replaced by the motion prior or not converged."):
        assert words in caption
    assert caption.startswith("Across datasets, per sensor class: the sequences each method "
                              "was scored on and its mean mark over them (the mean rotation")
    assert "NumPy frames, a ROS bag converted without --model" in caption
    assert "(the Oculii Eagle: Semi-Dense 4D Radar)" in caption
    assert "convert with --model (e.g. radar-semidense) to rank it in one." in caption
    assert f" {CUSTOM}: stores whose loader does not know" in caption
    assert caption.endswith(" Sequences holding one content: s2 = s2b.")
    # lengths no run has are left out; none left: nothing ranked
    t = summary_table(rr, (8.0, 100.0))
    assert "at 8 m, the shortest" in t.caption
    mean = _by(t)[(SEMI_DENSE_RADAR, "icp-p2p")].cells[1]
    assert mean.values["marked_figures"] == 4  # two figures at 8 m on two sequences
    assert mean.values["mean_mark"] == pytest.approx(np.mean([2, 2, 1, 1]))
    t = summary_table(rr, (100.0,))
    assert "(no run has segments at any length: nothing is ranked; on each figure" in t.caption
    assert all(not r.cells[1].parts or r.cells[1].parts[0].text == "-" for r in t.rows)


def test_a_tie_for_the_lowest_mean_mark_bolds_both(monkeypatch, rows):
    rr, _ = rows
    marks = {"s1": {IP: [1, 2, 1, 2], GI: [2, 1, 2, 1]}, "s2": {}, "t1": {}}
    monkeypatch.setattr(overview, "figure_ranks", lambda rows, L, q: _figures(marks)[(L, q)])
    b = _by(summary_table(rr))
    assert b[(SEMI_DENSE_RADAR, "icp-p2p")].cells[1].parts[0].rank == 0
    assert b[(SEMI_DENSE_RADAR, "gicp")].cells[1].parts[0].rank == 0


def test_unknown_classes_note():
    assert _unknown_classes_note([SPARSE_RADAR, SEMI_DENSE_RADAR]) == ""
    note = _unknown_classes_note([SPARSE_RADAR, "A", "B"])
    assert note.startswith(" A, B: stores whose loader does not know the sensor's density")
    assert "--model" in note


def test_dataset_and_licence_in_order_of_trust():
    ntu = LOADERS["ntu4dradlm"] if "ntu4dradlm" in LOADERS else next(
        e for e in LOADERS.values() if "NTU4DRadLM" in e.dataset)
    generic = next(e for e in LOADERS.values() if e.licence == "yours")
    # the store's own metadata first
    assert _dataset_and_licence({}, {"dataset": "D", "licence": "L"}, ntu) == ("D", "L")
    # a licence named in the source text, the dataset its first words (generic route)
    src = "NTU4DRadLM loop 1, first 300 frames (MIT); see its page"
    assert _dataset_and_licence({}, {"source": src}, generic) == ("NTU4DRadLM loop 1", "MIT")
    assert _dataset_and_licence({}, {"source": "Mine (CC BY 4.0)"}, None) == (
        "Mine", "CC BY 4.0")
    # the run's configuration names the dataset before the store
    assert _dataset_and_licence({"dataset": "Cfg"}, {"dataset": "D"}, ntu)[0] == "Cfg"
    # a known loader's catalogue entry
    assert _dataset_and_licence({}, {}, ntu) == (ntu.dataset, ntu.licence)
    # a generic route with an unlicensed source: not recorded, the source's first words
    assert _dataset_and_licence({}, {"source": "my bag; 2024"}, generic) == (
        "my bag", "not recorded (your own data)")
    assert _dataset_and_licence({}, {}, generic) == (generic.dataset,
                                                     "not recorded (your own data)")
    assert _dataset_and_licence({}, {}, None) == ("", "")
    # a known loader's own source text is the dataset only after its catalogue entry
    assert _dataset_and_licence({}, {"source": "x, y"}, ntu)[0] == ntu.dataset


def test_sources_one_per_sequence_in_class_order(monkeypatch):
    prov = {"a.h5": {"loader": "npy", "options": {"k": 1, "z": None, "b": "x"},
                     "source": "Own drive (MIT)"}}

    def provenance(store, run_dir):
        assert run_dir == Path("runs") / str(store)  # each store looked up beside its run
        return prov.get(store, {})

    monkeypatch.setattr(overview, "_provenance", provenance)

    def run(seq, cls, store=None, model=None):
        r = _run(seq, cls, "icp-p2p")
        r.run.config = {"sequence": {"store": store, "sensor_model": model}}
        r.run.dir = Path("runs") / str(store)
        return r

    rows = [run("b", SEMI_DENSE_RADAR, "a.h5"), run("a", SEMI_DENSE_RADAR),
            run("b", SEMI_DENSE_RADAR, "other.h5"), run("z", SPARSE_RADAR),
            run("v", SPARSE_RADAR, "v.h5", model="vod")]
    found = sources(rows)
    assert [s["sequence"] for s in found] == ["v", "z", "a", "b"]
    # no provenance: the loader named by the run's sensor model, its catalogue entry
    v = found[0]
    assert v["loader"] == "vod" and v["dataset"] == "View-of-Delft"
    assert v["licence"] == LOADERS["vod"].licence and v["source"] == ""
    b = found[3]
    assert b["store"] == "a.h5" and b["loader"] == "npy" and b["options"] == {"k": 1, "b": "x"}
    assert b["licence"] == "MIT" and b["source"] == "Own drive (MIT)"
    assert b["sensor_class"] == SEMI_DENSE_RADAR
    table = sources_table(rows)
    assert table.keys == ["Sensor class", "Sequence"]
    assert table.columns == ["Dataset", "Licence", "Loader and options", "Store"]
    assert [r.group for r in table.rows] == [(SPARSE_RADAR,)] * 2 + [(SEMI_DENSE_RADAR,)] * 2
    last = table.rows[-1]
    assert last.keys == [SEMI_DENSE_RADAR, "b"]
    assert last.cells[2].parts[0].text == "npy (b=x, k=1)"
    assert last.cells[3].parts[0].text == "a.h5"
    first = table.rows[1]
    assert [c.parts[0].text for c in first.cells] == ["-", "-", "", "-"]
    assert table.caption.startswith("The source of every sequence: its dataset and licence")
    assert table.caption.endswith("the loader and options that made its store (the store's "
                                  "provenance).")


def test_provenance_is_read_from_the_store(tmp_path, monkeypatch):
    import json

    import h5py

    store = tmp_path / "a.h5"
    with h5py.File(store, "w") as f:
        f.attrs["provenance"] = json.dumps({"loader": "npy", "source": "S (MIT)"})
    with h5py.File(tmp_path / "bare.h5", "w"):
        pass
    (tmp_path / "broken.h5").write_text("not hdf5")
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    assert overview._provenance(str(store), run_dir) == {"loader": "npy", "source": "S (MIT)"}
    assert overview._provenance(None, run_dir) == {} and overview._provenance("", run_dir) == {}
    assert overview._provenance(str(tmp_path / "bare.h5"), run_dir) == {}
    assert overview._provenance(str(tmp_path / "broken.h5"), run_dir) == {}
    assert overview._provenance("missing.h5", run_dir) == {}
    # a path relative to the working directory, or to the run's folder
    monkeypatch.chdir(tmp_path)
    assert overview._provenance("a.h5", run_dir)["loader"] == "npy"
    monkeypatch.chdir(run_dir)
    assert overview._provenance("../a.h5", run_dir)["loader"] == "npy"
    monkeypatch.chdir("/")
    assert overview._provenance("../a.h5", run_dir)["loader"] == "npy"


def test_the_page_across_datasets_only_for_two_datasets_or_more(monkeypatch):
    from bench.report.tables import paper

    rows = [SimpleNamespace(sequence=s) for s in ("a1", "a2", "b1", "x1")]
    datasets = {"a1": "A", "a2": "A", "b1": "B", "x1": ""}
    built = []
    monkeypatch.setattr(paper, "select", lambda d: (rows, [8.0]) if d == Path("r") else None)
    monkeypatch.setattr(paper, "build", lambda metric, rs, lengths, ci: built.append(
        (metric, [r.sequence for r in rs], lengths, ci)) or f"table {len(built)}")
    monkeypatch.setattr(overview, "sources",
                        lambda rs: [{"sequence": r.sequence, "dataset": datasets[r.sequence]}
                                    for r in rs])
    monkeypatch.setattr(overview, "summary_table", lambda rs: "summary" if rs is rows else None)
    monkeypatch.setattr(overview, "sources_table", lambda rs: "sources" if rs is rows else None)
    pair = SimpleNamespace(rows=["a row"])
    monkeypatch.setattr(overview, "pairwise_table", lambda rs: pair if rs is rows else None)
    out = overview.cross_dataset(Path("r"))
    assert [t for t, _ in out] == [
        "Across datasets: mean mark per method",
        "Across sequences: pairwise verdicts (k/n, sign test)", "Sources of the sequences",
        "Dataset: A", "Dataset: B", "Dataset: dataset not recorded"]
    assert out[0][1] == "summary" and out[1][1] is pair and out[2][1] == "sources"
    assert built == [("relative", ["a1", "a2"], [8.0], True), ("relative", ["b1"], [8.0], True),
                     ("relative", ["x1"], [8.0], True)]
    # no class with two sequences: no pairwise table
    pair.rows = []
    assert "Across sequences: pairwise verdicts (k/n, sign test)" not in [
        t for t, _ in overview.cross_dataset(Path("r"))]
    # one dataset (besides unrecorded ones): nothing
    datasets.update({"b1": "A"})
    assert overview.cross_dataset(Path("r")) == []
    for error in (FileNotFoundError, ValueError):
        def fail(d, error=error):
            raise error("x")
        monkeypatch.setattr(paper, "select", fail)
        assert overview.cross_dataset(Path("r")) == []
