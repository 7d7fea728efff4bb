"""`bench speed --threads N`: every method on 1 thread and, where it takes a thread count, on N
too, both in the table and in speed.csv. No timed assertions."""

from __future__ import annotations

import csv

from rich.console import Console

from bench.studies import speed


def test_threads_n_reports_one_and_n_threads(tmp_path, capsys):
    console = Console(record=True, width=300)
    speed.run_speed([1000], ["doppler", "kiss-icp", "icp-p2p"], 1, tmp_path, console,
                    memory=False, radar=False, threads=2)
    with open(tmp_path / "speed.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    got = {(r["method"], r["threads_setting"], r["threads"]): r["clock"] for r in rows}
    with_count = {name for name in ("doppler", "kiss-icp", "icp-p2p")
                  if speed.method_params(name, 2)}
    assert "doppler" in with_count  # the base of the ratios runs at both settings
    expected = {(name, "1", "1") for name in ("doppler", "kiss-icp", "icp-p2p")}
    expected |= {(name, "2", "2") for name in with_count}
    assert set(got) == expected
    assert all(got[(name, "2", "2")] == "wall" for name in with_count)
    # a 1-thread row is timed by the thread's CPU clock; only where the process's CPU time
    # exceeded the thread's (native worker threads of earlier work in the process still
    # spinning, as in a long test session) does it fall back to the wall clock, and then it
    # says so (methods.timing.CPU_LEAK_LIMIT); a broken CPU path would turn every row to wall
    said = capsys.readouterr().err
    ones = {name: got[(name, "1", "1")] for name in ("doppler", "kiss-icp", "icp-p2p")}
    assert "cpu" in ones.values(), ones
    for name, clock in ones.items():
        assert clock == "cpu" or (f"warning: {name}: process CPU time was" in said
                                  and "timed again by wall clock" in said), (name, ones)
    text = console.export_text()
    assert "threads" in text and text.count("lidar") >= 2  # one table row per setting
