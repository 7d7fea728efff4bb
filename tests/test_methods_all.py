"""Every registered method runs as odometry over a short sequence, seeded and not: one pose
per scan, the first the identity, finite, timed, and close to the truth on easy data."""

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
    # 5 steps of about 1 m: every method ends within a few metres of the truth
    gt = sequence.ground_truth.poses
    E = inv_T(inv_T(gt[0]) @ gt[-1]) @ result.poses[-1]
    assert np.linalg.norm(E[:3, 3]) < 3.0, name
