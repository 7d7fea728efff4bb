"""Small SE(3) helpers shared by loaders and methods.

Poses are 4x4 homogeneous matrices named by their frames: ``T_a_b`` maps points given in
frame ``b`` into frame ``a`` (``p_a = T_a_b @ p_b``). Rotations go through
``scipy.spatial.transform.Rotation``; quaternions are in TUM order (x, y, z, w).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp


def make_T(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Stack rotation(s) (..., 3, 3) and translation(s) (..., 3) into (..., 4, 4) poses."""
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = t
    T[..., 3, 3] = 1.0
    return T


def inv_T(T: np.ndarray) -> np.ndarray:
    """Inverse of (..., 4, 4) rigid transforms, using R^T instead of a general inverse."""
    R = T[..., :3, :3]
    t = T[..., :3, 3]
    Rt = np.swapaxes(R, -1, -2)
    return make_T(Rt, -np.einsum("...ij,...j->...i", Rt, t))


def transform_points(T_a_b: np.ndarray, points_b: np.ndarray) -> np.ndarray:
    """Map (N, 3) points from frame b into frame a."""
    return points_b @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def T_from_tum(xyz: np.ndarray, quat_xyzw: np.ndarray) -> np.ndarray:
    """(N, 3) positions and (N, 4) quaternions (x, y, z, w) -> (N, 4, 4) poses."""
    R = Rotation.from_quat(np.asarray(quat_xyzw, dtype=float)).as_matrix()
    return make_T(R, xyz)


def tum_from_T(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, 4, 4) poses -> (N, 3) positions and (N, 4) quaternions (x, y, z, w), w >= 0."""
    quat = Rotation.from_matrix(T[:, :3, :3]).as_quat()
    quat[quat[:, 3] < 0] *= -1.0
    return T[:, :3, 3].copy(), quat


def rotation_angle_deg(R: np.ndarray) -> np.ndarray:
    """Rotation angle(s) of (..., 3, 3) matrices in degrees, robust near 0 and 180 deg."""
    return np.degrees(Rotation.from_matrix(R).magnitude())


def exp_se3(xi: np.ndarray) -> np.ndarray:
    """Pose from a twist (rho, phi): translation-then-rotation vector, (6,) -> (4, 4).

    Uses the closed form with the left Jacobian of SO(3), so a constant twist integrated over
    time gives the exact screw motion.
    """
    rho, phi = np.asarray(xi[:3], float), np.asarray(xi[3:], float)
    theta = np.linalg.norm(phi)
    K = skew(phi)
    if theta < 1e-9:
        V = np.eye(3) + 0.5 * K
    else:
        V = (
            np.eye(3)
            + (1 - np.cos(theta)) / theta**2 * K
            + (theta - np.sin(theta)) / theta**3 * (K @ K)
        )
    return make_T(Rotation.from_rotvec(phi).as_matrix(), V @ rho)


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix of a 3-vector."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def interpolate_poses(
    stamps: np.ndarray, poses: np.ndarray, query_stamps: np.ndarray
) -> np.ndarray:
    """SE(3) interpolation: slerp on rotation, linear on translation.

    ``stamps`` must be strictly increasing and every query inside [stamps[0], stamps[-1]].
    """
    stamps = np.asarray(stamps, float)
    query = np.asarray(query_stamps, float)
    slerp = Slerp(stamps, Rotation.from_matrix(poses[:, :3, :3]))
    R = slerp(query).as_matrix()
    t = np.stack([np.interp(query, stamps, poses[:, :3, 3][:, k]) for k in range(3)], axis=1)
    return make_T(R, t)
