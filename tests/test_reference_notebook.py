"""External reference check: the authors' published figures on one real scan pair.

The paper's reference repository (github.com/Tars0523/Doppler_Correspondence, commit 97a6b0e,
``example/example.ipynb``) registers NTU4DRadLM loop-1 frames 099 -> 100 (its
``example/data_odom``; store index 98 -> 99 of the vendored ``samples/ntu4dradlm-loop1.h5``,
which holds those files' exact values) and prints, with 6 decimals, the translation error
|t_est - t_gt| [m] of T_target_source against the ground-truth motion
inv(T_world_100) @ T_world_099 (tests/data/reference-pair/README.md has every setting):

    point-to-point ICP (20 iterations, 1e-5, 2 m, identity start)     0.076703
    Doppler Correspondence, non-iterative (dT 1/12 s, gates 2 m / 10)  0.073144
    the same + RANSAC (3 pairs, 200 hypotheses, 1 m, stop at 80 %)     0.072084

Tolerances:
- ``PRINTED`` (5e-7 m, half the last printed digit): a float64 pipeline identical to the
  notebook's. Our ``icp-p2p`` is one (float64 throughout; it reaches a fixed point, a change
  of 2e-15 m at iteration 6, far from the 1e-5 stopping threshold), and so is the float64
  reference written here, which pins the data, the parameters and the error definition.
- ``FLOAT32`` (2e-5 m) for our ``doppler``: it computes features in float32 (a design choice
  of the method, methods/doppler.py). On this pair that changes exactly one of 3,588 pairs:
  a point at 122 m whose two candidate targets are 4.5e-5 m^2 apart in feature space, below
  float32's spacing there (9.8e-4 m^2); the other candidate moves the result by 4.6e-6 m
  (non-iterative) and 1.1e-5 m (RANSAC's modal result). The test asserts that this tie is the
  only difference. The smallest parameter slip visible on this pair (tau_doppler 5 instead of
  10) moves the error by 7e-5 m, so 2e-5 m still tells a wrong setting from float32 rounding.
- RANSAC: the notebook's generator is unseeded (``default_rng()``), so its figure is one
  random draw and cannot be replayed. What is reproducible is the distribution over seeds: one
  consensus set wins for about two seeds in three, and its error is the published figure. The
  test takes seeds 0-99 and asserts that the most frequent result is the published one and wins
  more than half the draws (a single unseeded run shows it more often than not).
"""

from __future__ import annotations

import hashlib
import io
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from conftest import real_sample_store
from loaders.scan import Scan
from loaders.store import StoreSequence
from methods.doppler import DopplerCorrespondence, doppler_pairs, ransac_rigid
from methods.icp import PointToPointIcp
from methods.rigid import fit_rigid

REFERENCE = Path(__file__).resolve().parent / "data" / "reference-pair"

PUBLISHED_ICP_M = 0.076703
PUBLISHED_DOPPLER_M = 0.073144
PUBLISHED_DOPPLER_RANSAC_M = 0.072084
#: the notebook's ground-truth translation of T_100_099, as it prints it (8 decimals) and uses it
GT_TRANSLATION_M = np.array([-0.45290601, 0.00552683, -0.03021261])
PRINTED = 5e-7
FLOAT32 = 2e-5

DT_S = 1 / 12  # the notebook's delta_t (12 Hz)
TAU_SPATIAL_M = 2.0
TAU_DOPPLER = 10.0
RANSAC = {"ransac_iterations": 200, "ransac_threshold_m": 1.0, "ransac_stop_ratio": 0.8}
SEEDS = range(100)

#: git blob ids of the authors' files (their tree at 97a6b0e, example/data_odom/)
UPSTREAM_BLOBS = {
    "frame_099.npy": "2fc6368dfae48d201cc03130d257fdb880bd8b6a",
    "frame_099_dop.npy": "0ea5e58524d2899ed22136cffa3b10f3e8415214",
    "frame_100.npy": "7ff557183e43a7c5b569ff0f6ce583188edd88b0",
    "frame_100_dop.npy": "f6138644ce07bdf12e64c330890f678744d02c11",
}


@pytest.fixture(scope="module")
def pair() -> tuple[Scan, Scan]:
    """Source (frame 099) and target (frame 100), float64, dT = 1/12 s as in the notebook."""
    seq = StoreSequence(real_sample_store())
    try:
        a, b = seq[98], seq[99]
    finally:
        seq.close()
    as64 = np.float64
    return (Scan(0.0, a.points.astype(as64), a.doppler.astype(as64)),
            Scan(DT_S, b.points.astype(as64), b.doppler.astype(as64)))


def _error_m(T_target_source: np.ndarray) -> float:
    """The notebook's "translation error": |t_est - t_gt| [m]."""
    return float(np.linalg.norm(T_target_source[:3, 3] - GT_TRANSLATION_M))


def _git_blob_id(data: bytes) -> str:
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def _npy_bytes(array: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, array)
    return buffer.getvalue()


def _reference_pairs(source: Scan, target: Scan) -> tuple[np.ndarray, np.ndarray]:
    """Independent float64 Algorithm 2 matching (scipy's kd-tree on the 1-D features):
    indices of the kept source points and of their matched target points."""
    r_p = np.linalg.norm(source.points, axis=1)
    r_q = np.linalg.norm(target.points, axis=1)
    f = r_p**2 + r_p * source.doppler * DT_S
    g = r_q**2 - r_q * target.doppler * DT_S
    feature_gap, match = cKDTree(g[:, None]).query(f[:, None], k=1)
    gap_m = np.linalg.norm(source.points - target.points[match], axis=1)
    keep = np.flatnonzero((gap_m <= TAU_SPATIAL_M) & (feature_gap <= TAU_DOPPLER))
    return keep, match[keep]


def _ransac_mode(P: np.ndarray, Q: np.ndarray) -> tuple[float, float]:
    """The most frequent RANSAC result over ``SEEDS``: (its error [m], its share of seeds)."""
    errors = []
    for seed in SEEDS:
        T, _ = ransac_rigid(P, Q, RANSAC["ransac_iterations"], RANSAC["ransac_threshold_m"],
                            RANSAC["ransac_stop_ratio"], np.random.default_rng(seed))
        errors.append(round(_error_m(T), 9))
    value, count = Counter(errors).most_common(1)[0]
    return value, count / len(errors)


def test_the_pair_is_the_authors_files(pair):
    """The vendored values rebuild the authors' .npy files byte for byte."""
    arrays = {"frame_099.npy": pair[0].points, "frame_099_dop.npy": pair[0].doppler,
              "frame_100.npy": pair[1].points, "frame_100_dop.npy": pair[1].doppler}
    for name, array in arrays.items():
        assert _git_blob_id(_npy_bytes(array)) == UPSTREAM_BLOBS[name], name


def test_the_ground_truth_motion_is_the_notebooks():
    """T_target_source = inv(T_world_100) @ T_world_099 from the authors' GT rows gives the
    translation the notebook prints (8 decimals)."""
    rows = np.loadtxt(REFERENCE / "gt_tum.txt")
    T_world = []
    for row in rows:
        T = np.eye(4)
        T[:3, :3] = Rotation.from_quat(row[4:8]).as_matrix()  # TUM order qx qy qz qw
        T[:3, 3] = row[1:4]
        T_world.append(T)
    T_target_source = np.linalg.inv(T_world[1]) @ T_world[0]
    np.testing.assert_allclose(T_target_source[:3, 3], GT_TRANSLATION_M, rtol=0, atol=5e-9)


def test_icp_p2p_reproduces_the_published_icp_error(pair):
    m = PointToPointIcp(max_iterations=20, convergence=1e-5, downsample=1,
                        tau_spatial_m=TAU_SPATIAL_M)
    res = m.register(m.preprocess(pair[0]), m.preprocess(pair[1]), np.eye(4))
    assert res.converged
    assert _error_m(res.T_target_source) == pytest.approx(PUBLISHED_ICP_M, abs=PRINTED)


def test_a_float64_pipeline_reproduces_the_published_doppler_errors(pair):
    """With the notebook's float64 arithmetic, both Doppler figures come out to the printed
    digit: the data, the settings and the error definition are the notebook's."""
    src_idx, tgt_idx = _reference_pairs(*pair)
    P, Q = pair[0].points[src_idx], pair[1].points[tgt_idx]
    assert _error_m(fit_rigid(P, Q)) == pytest.approx(PUBLISHED_DOPPLER_M, abs=PRINTED)
    mode_m, share = _ransac_mode(P.T.copy(), Q.T.copy())
    assert mode_m == pytest.approx(PUBLISHED_DOPPLER_RANSAC_M, abs=PRINTED)
    assert share > 0.5


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_doppler_reproduces_the_published_error(pair, backend):
    m = DopplerCorrespondence(tau_spatial_m=TAU_SPATIAL_M, tau_doppler=TAU_DOPPLER,
                              downsample=1, backend=backend)
    res = m.register(m.preprocess(pair[0]), m.preprocess(pair[1]), np.eye(4))
    assert res.converged
    assert _error_m(res.T_target_source) == pytest.approx(PUBLISHED_DOPPLER_M, abs=FLOAT32)


def test_doppler_ransac_mode_reproduces_the_published_error(pair):
    m = DopplerCorrespondence(tau_spatial_m=TAU_SPATIAL_M, tau_doppler=TAU_DOPPLER,
                              downsample=1, **RANSAC)
    source, target = m.preprocess(pair[0]), m.preprocess(pair[1])
    errors = []
    for seed in SEEDS:
        seeded = DopplerCorrespondence(m.params, ransac_seed=seed)
        errors.append(round(_error_m(seeded.register(source, target, np.eye(4))
                                     .T_target_source), 9))
    mode_m, count = Counter(errors).most_common(1)[0]
    assert count > len(SEEDS) / 2
    assert mode_m == pytest.approx(PUBLISHED_DOPPLER_RANSAC_M, abs=FLOAT32)


def test_float32_features_are_the_only_difference_from_the_notebook(pair):
    """Our pairs are the float64 reference's, except where a source point's two candidate
    targets lie within float32 resolution of each other in feature space (one pair here):
    the basis of the ``FLOAT32`` tolerance."""
    m = DopplerCorrespondence(tau_spatial_m=TAU_SPATIAL_M, tau_doppler=TAU_DOPPLER,
                              backend="numpy")
    ours_src, ours_tgt = doppler_pairs(m.preprocess(pair[0]), m.preprocess(pair[1]),
                                       TAU_SPATIAL_M, TAU_DOPPLER)
    ref_src, ref_tgt = _reference_pairs(*pair)
    np.testing.assert_array_equal(ours_src, ref_src)
    differ = np.flatnonzero(ours_tgt != ref_tgt)
    assert len(differ) == 1
    source, target = pair
    r_p = np.linalg.norm(source.points, axis=1)
    r_q = np.linalg.norm(target.points, axis=1)
    f = r_p**2 + r_p * source.doppler * DT_S
    g = r_q**2 - r_q * target.doppler * DT_S
    for k in differ:
        i = ours_src[k]
        gap_ours = abs(f[i] - g[ours_tgt[k]])
        gap_ref = abs(f[i] - g[ref_tgt[k]])
        assert gap_ref <= gap_ours  # the float64 reference took the truly nearest
        assert gap_ours - gap_ref < np.spacing(np.float32(f[i]))  # a float32 tie
