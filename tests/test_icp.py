"""Point-to-point ICP (icp-p2p): the compiled kd-tree version against independent references."""

import numpy as np
import pytest
import small_gicp
from scipy.spatial import cKDTree

from conftest import constant_twist_sequence
from loaders.se3 import exp_se3, inv_T, rotation_angle_deg, transform_points
from methods.icp import PointToPointIcp, closest_points
from methods.registry import make_method


def _kabsch(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """T minimising sum |q - (R p + t)|^2, written independently of methods.rigid."""
    mp, mq = p.mean(axis=0), q.mean(axis=0)
    U, _, Vt = np.linalg.svd((p - mp).T @ (q - mq))
    R = Vt.T @ np.diag([1.0, 1.0, np.linalg.det(Vt.T @ U.T)]) @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, mq - R @ mp
    return T


def _reference_icp(src, tgt, init, nearest, tau_m=3.0, max_iterations=100, convergence=1e-5):
    """The paper's point-to-point ICP with a given nearest-neighbour function
    (moved points -> (distance, index))."""
    T, prev = init.copy(), np.inf
    for iteration in range(1, max_iterations + 1):
        moved = transform_points(T, src)
        dist, idx = nearest(moved)
        keep = dist <= tau_m
        T = _kabsch(moved[keep], tgt[idx[keep]]) @ T
        error = dist[keep].mean()
        if abs(prev - error) < convergence:
            return T, iteration, int(keep.sum())
        prev = error
    return T, max_iterations, int(keep.sum())


def _pair(n_points, noise_m, seed=0):
    seq = constant_twist_sequence(n_frames=3, n_points=n_points, noise_m=noise_m,
                                  max_range_m=60, seed=seed)
    m = PointToPointIcp()
    return m, m.preprocess(seq[1]), m.preprocess(seq[2])


def test_matches_a_brute_force_reference_on_a_small_pair():
    m, src, tgt = _pair(1200, noise_m=0.05)
    init = exp_se3(np.array([-0.5, 0.1, 0.0, 0.0, 0.0, -0.01]))

    def brute(moved):
        d = np.linalg.norm(moved[:, None, :] - tgt.points[None, :, :], axis=2)
        idx = d.argmin(axis=1)
        return d[np.arange(len(moved)), idx], idx

    T_ref, iterations, pairs = _reference_icp(src.points, tgt.points, init, brute)
    fast = m.register(src, tgt, init)
    assert iterations > 3  # a real iterative case, not a one-step fit
    np.testing.assert_allclose(fast.T_target_source, T_ref, atol=1e-9)
    assert (fast.iterations, fast.correspondences) == (iterations, pairs)
    assert fast.converged


@pytest.mark.parametrize("seed", [0, 1])
def test_matches_the_scipy_kdtree_version(seed):
    # the implementation before the compiled kd-tree: scipy's cKDTree queried in the loop
    m, src, tgt = _pair(4000, noise_m=0.02, seed=seed)
    tree = cKDTree(tgt.points)
    T_ref, iterations, pairs = _reference_icp(
        src.points, tgt.points, np.eye(4),
        lambda moved: tree.query(moved, distance_upper_bound=3.0))
    fast = m.register(src, tgt, np.eye(4))
    np.testing.assert_allclose(fast.T_target_source, T_ref, atol=1e-9)
    assert (fast.iterations, fast.correspondences) == (iterations, pairs)


def test_closest_points_gate_against_brute_force():
    rng = np.random.default_rng(5)
    target = rng.uniform(-10, 10, (500, 3))
    query = rng.uniform(-14, 14, (300, 3))
    idx, dist = closest_points(small_gicp.KdTree(target), query, 2.0, num_threads=2)
    d = np.linalg.norm(query[:, None] - target[None], axis=2)
    near = d.min(axis=1) <= 2.0
    assert 0 < near.sum() < len(query)  # both cases occur
    np.testing.assert_array_equal(idx[near], d.argmin(axis=1)[near])
    np.testing.assert_allclose(dist[near], d.min(axis=1)[near], rtol=1e-12)
    assert np.all(idx[~near] == -1) and np.all(np.isinf(dist[~near]))


def test_noise_free_motion_from_a_seed_and_threads_agree():
    seq = constant_twist_sequence(n_frames=4, n_points=5000, max_range_m=1e3)
    T_true = inv_T(seq.ground_truth.poses[3]) @ seq.ground_truth.poses[2]
    answers = []
    for threads in (1, 2):
        m = make_method("icp-p2p", {"num_threads": threads})
        seed = exp_se3(np.array([0.7, 0.0, 0.0, 0.0, 0.0, 0.004]))  # near the true step
        res = m.register(m.preprocess(seq[2]), m.preprocess(seq[3]), seed)
        E = inv_T(T_true) @ res.T_target_source
        assert np.linalg.norm(E[:3, 3]) < 1e-3 and rotation_angle_deg(E[:3, :3]) < 0.05
        answers.append(res.T_target_source)
    # one nearest neighbour per query: the thread count cannot change the pairs
    np.testing.assert_allclose(answers[0], answers[1], atol=1e-12)


def test_the_compiled_fit_equals_the_shared_rigid_fit():
    """icp-p2p's compiled per-iteration fit (``methods.rigid.rigid_update_from_sums``) against
    ``methods.rigid.rigid_from_sums`` (the NumPy fit every point-to-point method shares) on
    random pair sums, a reflected configuration, and the degenerate cases (fewer than 3 pairs,
    collinear points) it must refuse."""
    from methods.rigid import rigid_from_sums, rigid_update_from_sums

    rng = np.random.default_rng(7)
    T0 = exp_se3(np.array([0.3, -0.1, 0.2, 0.05, -0.02, 0.1]))
    for case in range(20):
        p = rng.normal(size=(50, 3)) * 5
        q = p @ exp_se3(rng.normal(size=6) * 0.3)[:3, :3].T + rng.normal(size=3)
        q += rng.normal(size=q.shape) * 0.05
        if case == 0:
            q = q * np.array([1.0, 1.0, -1.0])  # a mirrored target: the guard keeps det(R) = 1
        sums = (len(p), p.sum(axis=0), q.sum(axis=0), p.T @ q)
        T, fitted = rigid_update_from_sums(*sums, T0)
        expected = rigid_from_sums(*sums)
        assert fitted and expected is not None
        np.testing.assert_allclose(T, expected @ T0, atol=1e-10)
        assert np.linalg.det(T[:3, :3]) > 0
    line = np.outer(np.arange(10.0), [1.0, 2.0, 3.0])
    for sums in ((2, np.ones(3), np.ones(3), np.eye(3)),
                 (10, line.sum(axis=0), line.sum(axis=0) + 10, line.T @ (line + 1))):
        T, fitted = rigid_update_from_sums(*sums, T0)
        assert not fitted and rigid_from_sums(*sums) is None
        np.testing.assert_array_equal(T, T0)
