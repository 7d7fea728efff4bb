"""Identity everywhere (issue 46, item 5), through the `bench` command line on tiny synthetic
stores: `bench compare`, `bench table` and `bench report` never pair stores whose content
differs (two stores named alike are told apart on both sides of a comparison), and one
content under two names (one recording converted twice, ``--name a`` and ``--name b``) is
said so and counted once in the cross-dataset ranks and the pairwise sign test."""

from __future__ import annotations

import re

import pytest
from helpers_cli import run_bench

from bench.report.summary.overview import summary_table
from bench.report.summary.pairwise import pairwise_table
from bench.report.tables.paper import select
from bench.runs.folders import load_runs
from bench.runs.sequence_identity import content_digest
from conftest import constant_twist_sequence
from loaders.scan import MemorySequence
from loaders.store import write_store


def _store(path, name, seed, dataset="D1"):
    seq = constant_twist_sequence(n_frames=40, n_points=800, seed=seed, noise_m=0.02,
                                  max_range_m=70)
    renamed = MemorySequence(name, seq.sensor, [seq.scan(i) for i in range(len(seq))],
                             seq.ground_truth, {"dataset": dataset})
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_store(renamed, path)


def _run(capsys, monkeypatch, method, store, out):
    code, text = run_bench(["run", "--method", method, "--data", store, "--out", out],
                           capsys, monkeypatch)
    assert code == 0, text


def _rows(text, first_cell):
    """The cells of every row of the first pipe table whose first cell starts so."""
    return [[c.strip() for c in line.strip().strip("|").split("|")]
            for line in text.splitlines()
            if line.startswith("|") and line.strip("| ").startswith(first_cell)]


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("identity")
    return tmp, {"a": _store(tmp / "a" / "twist.h5", "twist", 0),
                 "b": _store(tmp / "b" / "twist.h5", "twist", 1)}


def test_compare_never_pairs_two_stores_of_one_name(stores, capsys, monkeypatch):
    """A ran doppler on one store named twist, B on another store named twist: no cell pairs
    them (each is only on its side, and says B / A holds another content of that name);
    B run on A's own store is paired as before."""
    tmp, s = stores
    _run(capsys, monkeypatch, "doppler", s["a"], tmp / "A" / "twist" / "doppler")
    _run(capsys, monkeypatch, "doppler", s["b"], tmp / "B" / "twist" / "doppler")
    _run(capsys, monkeypatch, "doppler", s["a"], tmp / "C" / "twist" / "doppler")
    code, text = run_bench(["compare", tmp / "A", tmp / "B", "--fail-on-regression"], capsys,
                           monkeypatch)
    assert code == 0, text  # nothing paired, so nothing regressed
    rows = _rows(text, "twist")
    assert rows
    labels = {r[0] for r in rows}
    assert len(labels) == 2 and all(re.fullmatch(r"twist \[.+\]", x) for x in labels), labels
    for r in rows:
        note = r[-1]
        assert "only in A" in note or "only in B" in note, r
    cells = [r for r in rows if len(r) == 10]  # the relative-error table
    assert cells and all(r[5] == "-" and r[8] == "-" for r in cells)  # no change computed
    assert "another content of twist" in text
    assert "0 only in A" not in text and "0 only in B" not in text
    # the same store on both sides: paired, one label, a change in every cell
    code, text = run_bench(["compare", tmp / "A", tmp / "C"], capsys, monkeypatch)
    assert code == 0, text
    rows = [r for r in _rows(text, "twist") if len(r) == 10]
    assert rows and {r[0] for r in rows} == {"twist"}
    assert all(r[5] != "-" for r in rows) and "(0 only in A, 0 only in B)" in text


def test_table_of_both_folders_keeps_the_two_stores_apart(stores, capsys, monkeypatch):
    tmp, _ = stores
    if not (tmp / "B" / "twist" / "doppler" / "metrics.json").exists():
        test_compare_never_pairs_two_stores_of_one_name(stores, capsys, monkeypatch)
    code, text = run_bench(["table", tmp / "A", tmp / "B", "--out", tmp / "tables"], capsys,
                           monkeypatch)
    assert code == 0, text
    assert len(set(re.findall(r"twist \[[^\]]+\]", text))) == 2


@pytest.fixture(scope="module")
def renamed(tmp_path_factory):
    """One recording converted twice (loopA, loopB: one content, two names, two files whose
    bytes differ), another recording of that dataset (loopC) and one of a second dataset
    (town), each run by doppler and icp-p2p."""
    tmp = tmp_path_factory.mktemp("renamed")
    stores = {"loopA": _store(tmp / "loopA.h5", "loopA", 0),
              "loopB": _store(tmp / "loopB.h5", "loopB", 0),
              "loopC": _store(tmp / "loopC.h5", "loopC", 3),
              "town": _store(tmp / "town.h5", "town", 5, dataset="D2")}
    return tmp, stores


def test_one_content_under_two_names_is_counted_once_and_said(renamed, capsys, monkeypatch):
    tmp, stores = renamed
    a, b = stores["loopA"], stores["loopB"]
    assert a.read_bytes() != b.read_bytes()  # two files ...
    assert content_digest(a) == content_digest(b)  # ... of one content
    assert content_digest(a) != content_digest(stores["loopC"])
    for name, store in stores.items():
        for method in ("doppler", "icp-p2p"):
            _run(capsys, monkeypatch, method, store, tmp / "R" / name / method)
    runs = load_runs(tmp / "R")
    assert {r.config["sequence"]["content_sha256"] for r in runs
            if r.result.sequence in ("loopA", "loopB")} == {content_digest(a)}
    rows, _ = select(tmp / "R")
    summary = summary_table(rows)
    for row in summary.rows:  # loopA = loopB, loopC, town: three sequences, not four
        assert row.cells[0].values["sequences"] == 3, row.keys
    assert "loopA = loopB" in summary.caption and "counted once" in summary.caption
    pairwise = pairwise_table(rows)
    ns = [c.values["sequences"] for r in pairwise.rows for c in r.cells if c.values]
    assert ns and max(ns) <= 3
    assert "loopA = loopB" in pairwise.caption
    code, text = run_bench(["report", tmp / "R"], capsys, monkeypatch)
    assert code == 0, text
    page = (tmp / "R" / "report.html").read_text()
    assert "Across datasets" in page
    assert "counted once (as the first): loopA = loopB" in page


def test_each_name_of_another_content_is_its_own_sequence(renamed):
    """Control: the summary counts a sequence per content, so loopC (another recording of
    the dataset) and town stay sequences of their own beside loopA = loopB."""
    tmp, _ = renamed
    rows, _ = select(tmp / "R")
    from bench.report.summary.ranks import counted_as

    counted = counted_as(rows)
    assert counted["loopB"] == counted["loopA"] == "loopA"
    assert counted["loopC"] == "loopC" and counted["town"] == "town"


def test_the_content_digest_reads_the_numbers_not_the_name(tmp_path):
    """Known answers on tiny HDF5 files: the name and the provenance do not change the digest;
    a value, a dataset's dtype or shape, a dataset's name or another attribute does; a dataset
    longer than one read (``_ROWS``) is hashed whole."""
    import h5py
    import numpy as np

    from bench.runs import sequence_identity as si

    def write(name, **change):
        path = tmp_path / f"{name}.h5"
        values = change.get("values", np.arange(12.0).reshape(4, 3))
        with h5py.File(path, "w") as f:
            f.attrs["name"] = change.get("store_name", "a")
            f.attrs["provenance"] = change.get("provenance", "{}")
            f.attrs["period_s"] = change.get("period_s", 0.1)
            f.create_dataset(change.get("dataset", "points/xyz"), data=values)
            f.create_dataset("frames/stamp", data=np.array(change.get("stamp", [0.0, 0.1])))
        return si.content_digest(path)

    base = write("base")
    assert write("renamed", store_name="b", provenance='{"source": "x"}') == base
    assert write("value", values=np.arange(12.0).reshape(4, 3) + 1e-9) != base
    assert write("dtype", values=np.arange(12.0, dtype=np.float32).reshape(4, 3)) != base
    assert write("shape", values=np.arange(12.0).reshape(3, 4)) != base
    assert write("where", dataset="points/xyz2") != base
    assert write("period", period_s=0.2) != base
    assert write("stamp", stamp=[0.0, 0.2]) != base
    big = np.arange(3 * (si._ROWS + 5), dtype=np.float64).reshape(-1, 3)
    tail = big.copy()
    tail[-1, -1] += 1.0  # a change in the second read only
    assert write("big", values=big) != write("bigtail", values=tail)


def test_one_content_maps_each_label_to_the_first_of_its_content():
    from bench.runs.sequence_identity import one_content

    def cfg(sha, own=None):
        return {"identity": {"store_sha256": sha, "frame_range": own},
                "sequence": {"content_sha256": sha}}

    labels = ["b", "a", "c", "d", "e"]
    configs = [cfg("x"), cfg("x"), cfg("x", [0, 10]), cfg("y"), {"sequence": {}}]
    assert one_content(labels, configs) == {"a": "a", "b": "a", "c": "c", "d": "d", "e": "e"}
