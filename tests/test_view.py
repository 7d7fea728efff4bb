"""bench view writes a rerun recording that rerun's own reader loads."""

from typer.testing import CliRunner

from bench.cli import app
from bench.report.view import doppler_colors
from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence, dev_dependency
from loaders.store import write_store


def test_view_writes_a_recording_rerun_can_read(tmp_path):
    chunk = dev_dependency("rerun.chunk")
    store = write_store(constant_twist_sequence(n_frames=12, n_points=800), tmp_path / "t.h5")
    run = run_job(Job(store=store, method="doppler", seed=None, out_root=tmp_path)).run_dir
    out = tmp_path / "t.rrd"
    res = CliRunner().invoke(app, ["view", str(store), "--run", str(run), "--pair", "3",
                                   "--out", str(out)])
    assert res.exit_code == 0, res.output
    reader = chunk.RrdReader(out)
    assert [r.application_id for r in reader.recordings()] == ["doppler-bench"]
    paths = {str(c.entity_path) for c in reader.stream()}
    assert {"/world/scan", "/world/ground_truth", "/world/estimate",
            "/world/pair/doppler_correspondences",
            "/world/pair/closest_correspondences"} <= paths


def test_doppler_colours_run_from_blue_to_red():
    import numpy as np

    c = doppler_colors(np.array([-5.0, 0.0, 5.0]), 5.0)
    assert c[0, 2] > c[0, 0] and c[2, 0] > c[2, 2] and c[1, 0] == c[1, 2]
