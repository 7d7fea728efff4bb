"""`bench reproduce` on real stores says what it did: the paper's sequences found and missing,
each store checked against its dataset config (a 15 m LiDAR store is not Loop1_0), only the
tables that have rows written (no table5 without a tunnel, an old one removed), the summary
naming what was written, `reproduction.json` and the results page; `--synthetic-only` with a
real store present says it ignores it."""

import io
import json

import pytest
from rich.console import Console

from bench import guard
from bench.cli import main
from bench.studies.reproduce import _choose_data
from conftest import constant_twist_sequence
from loaders.store import write_store


@pytest.fixture(scope="module")
def data_dir(tmp_path_factory):
    """data/real/Loop1_0.h5: 20 LiDAR frames, 15 m of ground truth (Loop1_0 is a radar
    sequence of about 1.4 km)."""
    root = tmp_path_factory.mktemp("data")
    (root / "real").mkdir()
    seq = constant_twist_sequence(n_frames=20, n_points=500, max_range_m=60)
    write_store(seq, root / "real" / "Loop1_0.h5")
    return root


def test_a_real_reproduction_says_what_it_found_checked_and_wrote(data_dir, tmp_path, capsys,
                                                                  monkeypatch):
    out = tmp_path / "paper-real"
    out.mkdir()
    # an earlier reproduction's table5 (the harness wrote it: its folder's ledger lists it)
    guard.write_text(out / "table5.md", "an old table5\n", guard.derived, "a table")
    monkeypatch.setattr("sys.argv", ["bench", "reproduce", "--data-dir", str(data_dir), "--out",
                                     str(out), "--jobs", "1", "--executor", "local"])
    with pytest.raises(SystemExit) as exit_:
        main()
    said = capsys.readouterr()
    text = " ".join((said.out + " " + said.err).split())
    assert exit_.value.code == 0, text
    assert "1 of the paper's 11 sequences found (Loop1_0)" in text
    assert "missing (10 of 11): Campus1, Campus2, CurvedWall, Loop1_1" in text
    # the store checked against configs/datasets/Loop1_0.yaml
    assert "a lidar store, but Loop1_0 is a radar sequence" in text
    assert "its ground truth's path is 15 m" in text and "about 1390 m" in text
    assert "the store's duration is far off" in text  # 1390 m in a few seconds
    # only the tables with rows: no table5 (no tunnel), the old one removed
    assert (out / "table3.md").exists() and (out / "table4.md").exists()
    assert not (out / "table5.md").exists()
    for stem in ("table3", "table3_kitti", "table3_velocity", "table4"):
        assert f"{out}/{stem}.{{md,tex,csv}}" in text
    assert f"{out}/table5.{{md,tex,csv}}" not in text
    assert "table5.{" not in text
    assert ("not written: table5 (none of its sequences found (Tunnel_Empty, "
            "Tunnel_Vehicles))") in text
    record = json.loads((out / "reproduction.json").read_text())
    assert record["found"] == ["Loop1_0"] and len(record["missing"]) == 10
    assert sorted(record["tables_written"]) == ["table3", "table3_kitti", "table3_velocity",
                                                 "table4"]
    assert "table5" in record["tables_not_written"]
    page = (out / "report.html").read_text()
    assert "Missing (10)" in page and "Tunnel_Vehicles" in page and "table3.md" in page
    assert f"results page: {out / 'report.html'}" in text


def test_synthetic_only_with_a_real_store_says_it_ignores_it(data_dir):
    buf = io.StringIO()
    real, notes = _choose_data(data_dir, True, Console(file=buf, width=200))
    said = buf.getvalue()
    assert real == [] and notes == []
    assert "synthetic only (as asked): using the synthetic suite 'synthetic-paper'" in said
    assert "ignoring 1 real store(s)" in said and "Loop1_0" in said
    assert "no real stores" not in said
