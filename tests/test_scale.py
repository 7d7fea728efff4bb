"""``bench speed --scale`` (bench.studies.scale): the harness at dataset scale. Run here on tiny
sizes: it runs end to end, prints every column of both tables and writes consistent CSVs (the
figures themselves are timings: not asserted)."""

from __future__ import annotations

import csv
import math

import pytest
from typer.testing import CliRunner

from bench.cli import app, main

SCALE_COLUMNS = ("poses", "score", "score peak", "table", "table peak", "table x scorings",
                 "report", "report peak", "report x scorings", "doppler / frame")
EXECUTOR_COLUMNS = ("executor", "frames", "method (mean)", "harness CPU", "harness / method",
                    "all CPU", "wall", "main peak [MB]", "doppler on the sample")


def _rows(path):
    with open(path) as f:
        return [{k: (v if k == "executor" else float(v)) for k, v in r.items()}
                for r in csv.DictReader(f)]


def test_the_scale_command_runs_on_tiny_sizes_and_prints_every_column(tmp_path):
    res = CliRunner().invoke(app, ["speed", "--scale", "--poses", "200,400", "--scale-frames",
                                   "20", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    for col in SCALE_COLUMNS + EXECUTOR_COLUMNS:
        assert col in res.output, col
    assert "marginal per pose 200 -> 400" in res.output
    scale = _rows(tmp_path / "scale.csv")
    assert [r["poses"] for r in scale] == [200, 400]
    for r in scale:
        for k in ("score", "table", "report"):
            assert r[f"{k}_ms"] > 0 and r[f"{k}_wall_ms"] > 0
            # peak RSS in MB of a Python process that imported NumPy: tens to thousands
            assert 30 < r[f"{k}_mb"] < 5000, (k, r[f"{k}_mb"])
        for k in ("table", "report"):  # both over the 2N poses of the two runs
            assert r[f"{k}_x_scorings"] == pytest.approx(r[f"{k}_ms"] / r["score_ms"], rel=1e-4)
        assert 0 < r["doppler_sample_ms"] < 50
    executors = _rows(tmp_path / "scale_executors.csv")
    assert [r["executor"] for r in executors] == ["process", "dask"]
    for r in executors:
        assert r["frames"] == 3 * 20 and r["sequences"] == 3
        assert r["method_ms"] > 0 and r["wall_ms"] > 0 and math.isfinite(r["harness_ms"])
        # the harness's share is the whole command's CPU less the method's own time (its
        # mean over the timed frames: every frame but each sequence's first)
        assert r["timed_frames"] == 3 * 19
        method = r["method_ms"] * r["timed_frames"] / r["frames"]
        assert r["harness_ms"] == pytest.approx(r["cpu_ms"] - method, rel=1e-4)


@pytest.mark.parametrize("poses", ["40000,abc", "50", ""])
def test_bad_pose_counts_are_one_clear_error(poses, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["bench", "speed", "--scale", "--poses", poses])
    with pytest.raises(SystemExit) as exit_:
        main()
    err = " ".join(capsys.readouterr().err.split())
    assert exit_.value.code == 2
    assert f"--poses {poses!r}" in err and "at least 100" in err and "Traceback" not in err
