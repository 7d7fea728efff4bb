"""Row and column order of the reports: the paper's Table III order of sensor classes,
sequences and methods (paper/table3.csv, transcribed from the paper), whatever order the runs
come in."""

import csv
import random
from pathlib import Path

from bench.paths import PAPER_TABLE3
from bench.report.names import PAPER_SEQUENCES, sequence_key
from bench.report.tables.paper import RunRow, runs
from bench.runs.folders import RunRecord
from bench.runs.result import RunResult


def Row(klass, seq, method, seed, label, *_):
    """A table row of a run (only what the order reads)."""
    return RunRow(RunRecord(Path("."), RunResult(sequence=seq, method=method, seed=seed,
                                                 display_name=seq, sensor_class=klass), {}),
                  label)


def row_order(row: RunRow) -> tuple:
    return row.order()


def _paper_rows() -> list[tuple[str, str, str, bool | None]]:
    """(sensor class, display name, method, seed) of every row of the paper's Table III."""
    display = dict(PAPER_SEQUENCES)
    with PAPER_TABLE3.open() as f:
        return [(r["sensor_class"], display[r["sequence"]], r["method"],
                 None if r["seed"] == "" else r["seed"] == "true") for r in csv.DictReader(f)]


def test_table_rows_sort_in_the_papers_order():
    paper = _paper_rows()
    assert [p[1] for p in paper if p[0] == "Dense 4D LiDAR"][::3] == [
        "Straight Wall", "Curved Wall", "Baker-Barry Tunnel (Empty)",
        "Baker-Barry Tunnel (Vehicles)"]  # the LiDAR rows the user saw out of order
    rows = [Row(k, seq, m, s, f"{m} {s}", {}, {}, 1.0, False) for k, seq, m, s in paper]
    for seed in range(5):
        shuffled = rows[:]
        random.Random(seed).shuffle(shuffled)
        got = sorted(shuffled, key=row_order)
        assert [(r.sensor_class, r.sequence, r.method, r.seed.option) for r in got] == paper


def test_methods_follow_the_papers_order_and_extra_methods_come_last():
    methods = ["doppler-ego", "kiss-icp", "doppler-icp", "doppler", "dicp", "vgicp", "gicp",
               "icp-p2plane", "icp-p2p"]
    rows = [Row("Semi-Dense 4D Radar", "Loop1_0", m, s, f"{m} {s}", {}, {}, 1.0, False)
            for m in methods for s in ((None,) if m.startswith("doppler") and m != "doppler-icp"
                                       else (False, True))]
    got = [(r.method, r.seed.option) for r in sorted(rows, key=row_order)]
    assert got == [("icp-p2p", True), ("icp-p2p", False), ("icp-p2plane", True),
                   ("icp-p2plane", False), ("gicp", True), ("gicp", False), ("vgicp", True),
                   ("vgicp", False), ("dicp", True), ("dicp", False), ("doppler", None),
                   ("doppler-icp", True), ("doppler-icp", False), ("kiss-icp", True),
                   ("kiss-icp", False), ("doppler-ego", None)]


def test_other_sequences_follow_the_papers_in_natural_order():
    names = ["run10", "Straight Wall", "run2", "Loop1_0 (GT calibrated on frames 0-124, not "
             "scored)", "Campus1", "Loop1_10", "Loop1_1"]
    assert sorted(names, key=sequence_key) == [
        "Campus1", "Loop1_0 (GT calibrated on frames 0-124, not scored)", "Loop1_1",
        "Straight Wall", "Loop1_10", "run2", "run10"]


def test_collect_rows_orders_real_run_folders(tmp_path):
    # metrics.json + config.yaml as bench run writes them, in a folder order unlike the paper's
    import json

    import yaml

    for seq, disp in (("Tunnel_Empty", "Baker-Barry Tunnel (Empty)"),
                      ("CurvedWall", "Curved Wall"), ("StraightWall", "Straight Wall")):
        for method, seed in (("doppler", None), ("dicp", False), ("dicp", True)):
            d = tmp_path / seq / f"{method}{'' if seed is None else '_' + str(seed)}"
            d.mkdir(parents=True)
            (d / "metrics.json").write_text(json.dumps({
                "sequence": seq, "method": method, "seed": seed, "diverged": False,
                "relative_error": {"8": {"rot_deg_mean": 1.0, "trans_m_mean": 1.0,
                                         "rot_deg_median": 1.0, "trans_m_median": 1.0, "n": 3}},
                "time_ms": {"mean": 1.0}}))
            (d / "config.yaml").write_text(yaml.safe_dump({"sequence": {
                "name": seq, "display_name": disp, "sensor_class": "Dense 4D LiDAR"}}))
    rows = runs(tmp_path)
    assert [(r.sequence, r.method, r.seed.option) for r in rows] == [
        (s, m, x) for s in ("Straight Wall", "Curved Wall", "Baker-Barry Tunnel (Empty)")
        for m, x in (("dicp", True), ("dicp", False), ("doppler", None))]
