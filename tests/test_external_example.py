"""The route end to end: a store exported as a bag, a standalone external odometry
(examples/external_odometry.py, no harness imports) run on the bag, its TUM output scored with
`bench score` beside the harness's own `doppler` run, and the table and report page that show
both."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cli import main
from bench.runs.folders import read_run
from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence
from loaders.store import write_store

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "external_odometry.py"
ALLOWED = {"argparse", "time", "pathlib", "__future__", "numpy", "scipy", "rosbags"}


def test_the_example_imports_nothing_of_the_harness():
    tree = ast.parse(EXAMPLE.read_text())
    names = {alias.name.split(".")[0] for node in ast.walk(tree)
             if isinstance(node, ast.Import) for alias in node.names}
    names |= {node.module.split(".")[0] for node in ast.walk(tree)
              if isinstance(node, ast.ImportFrom)}
    assert names and names <= ALLOWED, names - ALLOWED


def _bench(args, capsys, monkeypatch) -> str:
    monkeypatch.setattr("sys.argv", ["bench", *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    assert exit_.value.code == 0, out.out + out.err
    return out.out + out.err


def test_export_external_odometry_score_beside_doppler(tmp_path, capsys, monkeypatch):
    seq = constant_twist_sequence(n_frames=40, n_points=1500, noise_m=0.02, max_range_m=70)
    store = write_store(seq, tmp_path / "twist.h5")
    results = tmp_path / "results"
    assert run_job(Job(store=store, method="doppler", seed=None,
                       out_root=results)).status == "done"
    _bench(["export", str(store), "--format", "mcap", "--out", str(tmp_path / "twist_mcap")],
           capsys, monkeypatch)
    tum = tmp_path / "odometry.tum"
    # isolated: neither PYTHONPATH nor the working folder can lend it the harness
    done = subprocess.run([sys.executable, "-I", str(EXAMPLE), str(tmp_path / "twist_mcap"),
                           str(tum), "--times"], cwd=tmp_path, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert "wrote" in done.stdout and len(tum.read_text().splitlines()) == 41  # header + 40
    out = _bench(["score", str(tum), "--store", str(store), "--name", "ext-icp", "--out",
                  str(results)], capsys, monkeypatch)
    assert "40 of the 40 scans with ground truth scored (100.0 %" in out
    ext = read_run(results / "twist" / "ext-icp").result
    own = read_run(results / "twist" / "doppler").result
    # frame-to-frame ICP on static points with 2 cm noise: a few cm over 8 m at most
    assert 0 < ext.relative(8.0).trans_m_mean < 0.05
    assert ext.relative(8.0).n == own.relative(8.0).n > 0
    assert ext.clock == "reported by the method" and ext.time_ms.mean > 0
    table = _bench(["table", str(results)], capsys, monkeypatch)
    rows = [line for line in table.splitlines() if line.startswith("|")]
    assert any("ext-icp (external)" in r and "[reported]" in r for r in rows)
    assert any("Doppler Correspondence" in r for r in rows)
    _bench(["report", str(results)], capsys, monkeypatch)
    assert "ext-icp (external)" in (results / "report.html").read_text()
