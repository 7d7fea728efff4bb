"""Every registered method runs as odometry over a short sequence, seeded and not: one pose
per scan, the first the identity, finite, timed, and close to the truth on easy data (the
path's length travelled, the end near the truth's)."""

import numpy as np
import pytest

from loaders.se3 import inv_T
from methods.registry import METHODS, make_method


@pytest.fixture(scope="module")
def sequence():
    from loaders.scan import MemorySequence
    from loaders.synthetic import SyntheticSequence

    seq = SyntheticSequence("loop", "radar-semidense", frames=6, seed=3)
    return MemorySequence(seq.name, seq.sensor, list(seq), seq.ground_truth)


@pytest.mark.parametrize("name", sorted(n for n in METHODS if not n.startswith("test-")))
@pytest.mark.parametrize("seed", [True, False])
def test_method_runs_as_odometry(name, seed, sequence):
    method = make_method(name, {}, sequence.sensor)
    result = method.run(sequence, seed=seed)
    n = len(sequence)
    assert result.poses.shape == (n, 4, 4) and np.all(np.isfinite(result.poses))
    np.testing.assert_allclose(result.poses[0], np.eye(4), atol=1e-12)
    np.testing.assert_allclose(result.stamps, sequence.stamps)
    times = [f.time_ms for f in result.frames[1:]]
    assert len(result.frames) == n and all(t > 0 for t in times)
    # 5 steps, 2.94 m of path: every method travels the path's length (within 10 %; measured
    # 0-4.4 %) and ends well within it (15 % of it; measured 2 mm - 30 cm, the most vgicp with
    # the coarse voxels chosen on the real radar): a method that never moves (2.94 m off), or
    # moves the wrong way, fails both
    gt = sequence.ground_truth.poses
    gt_length, est_length = _path_length_m(gt), _path_length_m(result.poses)
    assert gt_length > 2.5
    assert abs(est_length - gt_length) < 0.1 * gt_length, (name, est_length, gt_length)
    E = inv_T(inv_T(gt[0]) @ gt[-1]) @ result.poses[-1]
    assert np.linalg.norm(E[:3, 3]) < 0.15 * gt_length, (name, E[:3, 3])


def _path_length_m(poses: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(poses[:, :3, 3], axis=0), axis=1).sum())
