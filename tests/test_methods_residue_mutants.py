"""Residue survivors of methods.dicp: the pair gate of the several-thread search is inclusive
(a source point exactly at the gate has its pair), as the one-thread search's."""

import numpy as np
import pytest

from loaders.scan import Scan
from methods.dicp import Dicp


def _grid_scans():
    """A target of 3 x 3 x 3 integer grid points (1 m apart, 5 m ahead of the sensor); the
    source: the same points plus one 0.5 m from the corner (5, -1, -1) along -x, farther
    than 0.5 m from every other grid point (exactly representable: its squared distance is
    0.25). Doppler zero: no motion, as the identity start says."""
    g = np.arange(-1.0, 2.0)
    grid = np.array([[5.0 + x, y, z] for x in g for y in g for z in g])
    extra = np.array([[4.5 - 1.0, -1.0, -1.0]])
    src = np.vstack([grid, extra])
    return Scan(0.0, src, np.zeros(len(src))), Scan(0.1, grid, np.zeros(len(grid)))


@pytest.mark.parametrize("threads", [1, 2])
def test_a_point_exactly_at_the_gate_is_paired(threads):
    # kills DICP _iterate 71 (several threads: the gate test made strict): 27 points at
    # distance 0 and one at exactly 0.5 m = the gate; with one step the pairs counted are
    # those of the start, all 28 of them
    dicp = Dicp(max_correspondence_m=0.5, max_iterations=1, downsample=1, num_threads=threads)
    source, target = (dicp.preprocess(s) for s in _grid_scans())
    result = dicp.register(source, target, np.eye(4))
    assert result.correspondences == 28


def _room_scans(seed):
    """Noisy points on the floor, two walls and a pillar of a room (target); the source: the
    same surfaces seen after a motion of (0.4, 0.1, 0) m and 0.02 rad of yaw over 0.1 s, its
    Doppler that of the motion, plus noise."""
    rng = np.random.default_rng(seed)
    n = 50
    floor = np.column_stack([rng.uniform(-10, 10, (n, 2)), np.full(n, -1.5)])
    wall = np.column_stack([np.full(n, 8.0), rng.uniform(-10, 10, n), rng.uniform(-1.5, 2, n)])
    side = np.column_stack([rng.uniform(-10, 10, n), np.full(n, 6.0), rng.uniform(-1.5, 2, n)])
    angle = rng.uniform(0, 2 * np.pi, n)
    pillar = np.column_stack([3 + 0.5 * np.cos(angle), -4 + 0.5 * np.sin(angle),
                              rng.uniform(-1.5, 2, n)])
    target = np.vstack([floor, wall, side, pillar]) + rng.normal(0, 0.01, (4 * n, 3))
    c, s = np.cos(0.02), np.sin(0.02)
    R, t = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]), np.array([0.4, 0.1, 0.0])
    source = (target - t) @ R  # target = R source + t
    source = source + rng.normal(0, 0.01, source.shape)
    v = t / 0.1  # sensor velocity: its Doppler -dir . v (receding positive)
    doppler = -(source / np.linalg.norm(source, axis=1, keepdims=True)) @ v
    return Scan(0.0, source, doppler + rng.normal(0, 0.02, len(source))), target


def test_the_answer_does_not_depend_on_the_order_of_the_target_points():
    # kills DICP _iterate 96/97 (the pair with target point 0 left out of the inlier RMSE of
    # the convergence test): the run must not depend on which target point comes first; each
    # of the 200 target points comes first once (a scene where the run then stops 1 step apart)
    source_scan, target = _room_scans(0)
    dicp = Dicp(downsample=1)
    source = dicp.preprocess(source_scan)
    runs = []
    for shift in range(len(target)):
        target_scan = Scan(0.1, np.roll(target, -shift, axis=0), np.zeros(len(target)))
        runs.append(dicp.register(source, dicp.preprocess(target_scan), np.eye(4)))
    for run in runs[1:]:
        assert (run.iterations, run.converged, run.correspondences) == \
            (runs[0].iterations, runs[0].converged, runs[0].correspondences)
        np.testing.assert_allclose(run.T_target_source, runs[0].T_target_source, atol=1e-9)
