"""`bench score` on a store `bench calibrate` corrected scores exactly the frames `bench run`
scores: the calibration frames are registered by the run but scored by neither (a mutant that
scored them in `bench score` survived before)."""

from pathlib import Path

import numpy as np
import pytest

from bench.runs.external.score import ExternalSpec, score_external
from bench.runs.folders import read_run
from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence
from loaders.scan import MemorySequence
from loaders.store import write_store

CALIBRATION = [0, 20]


def _store(tmp_path: Path, calibrated: bool) -> Path:
    base = constant_twist_sequence(n_frames=60, n_points=800, noise_m=0.02, max_range_m=70)
    provenance = {"calibration": {"frames": CALIBRATION}} if calibrated else {}
    seq = MemorySequence("calib", base.sensor, list(base), base.ground_truth,
                         provenance=provenance)
    return write_store(seq, tmp_path / ("cal.h5" if calibrated else "plain.h5"))


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("calibrated")
    out = {}
    for calibrated in (True, False):
        store = _store(tmp, calibrated)
        results = tmp / f"results-{'calibrated' if calibrated else 'plain'}"  # a root each:
        # both stores hold a sequence "calib", and one folder holds one store's runs
        done = run_job(Job(store=store, method="doppler", seed=None, out_root=results))
        assert done.status == "done", done.message
        scored = score_external(store, ExternalSpec(done.run_dir / "est_tum.txt", "ext"),
                                results)
        out[calibrated] = (read_run(done.run_dir).result, read_run(scored.run_dir).result,
                           scored.coverage)
    return out


def test_score_leaves_out_the_calibration_frames_as_run_does(runs):
    own, ext, coverage = runs[True]
    n_cal = CALIBRATION[1] - CALIBRATION[0]
    assert coverage["scans_with_gt"] == 60 - n_cal and coverage["scored"] == 60 - n_cal
    assert ext.frames_scored == own.frames_scored == 60 - n_cal
    for length in (4.0, 8.0):
        a, b = own.relative(length), ext.relative(length)
        if a is None:
            assert b is None
            continue
        assert a.n == b.n > 0
        np.testing.assert_allclose(b.trans_m_mean, a.trans_m_mean, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(b.rot_deg_mean, a.rot_deg_mean, rtol=1e-9, atol=1e-12)


def test_the_same_store_uncalibrated_scores_every_frame(runs):
    """The control: without the calibration record both score all 60 frames, so the 40 above
    are the calibration's doing (and a scorer that ignored it would score 60 there)."""
    own, ext, coverage = runs[False]
    assert coverage["scored"] == 60 and ext.frames_scored == own.frames_scored == 60
    cal_own = runs[True][0]
    assert cal_own.relative(8.0).n < own.relative(8.0).n
