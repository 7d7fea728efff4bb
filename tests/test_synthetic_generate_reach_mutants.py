"""Known answers of ``SyntheticSequence._cast`` and of the constructor's documented options
(loaders/synthetic/generate.py), on hand-made inputs: a frozen scene of one or two boxes seen
from a fixed sensor pose, so that the hit distances, the hit points and their velocities (rigid
body: u = v + w x r) are worked out by hand.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from loaders.synthetic import generate as G
from loaders.synthetic.raycast import Geometry
from loaders.synthetic.sensors import SENSORS


class _FixedMotion:
    """A sensor standing at ``origin`` (identity attitude) with velocity ``v`` (sensor frame)."""

    def __init__(self, origin, v) -> None:
        self.T = np.eye(4)
        self.T[:3, 3] = origin
        self.v = np.asarray(v, float)

    def sensor_pose(self, t):
        return np.repeat(self.T[None], len(t), axis=0)

    def sensor_twist(self, t):
        return np.repeat(self.v[None], len(t), axis=0), np.zeros((len(t), 3))


class _FrozenScene:
    def __init__(self, geom: Geometry) -> None:
        self.geom = geom

    def geometry(self, t):
        return self.geom


def _bare_sequence(geom: Geometry, origin, v_sensor, min_range: float, max_range: float):
    """A LiDAR ``SyntheticSequence`` bypassing the scene construction: only what ``_cast``
    reads."""
    seq = object.__new__(G.SyntheticSequence)
    seq.spec = replace(SENSORS["lidar-dense"], min_range=min_range, max_range=max_range)
    seq.options, seq.scatterers = {}, None
    seq.motion = _FixedMotion(origin, v_sensor)
    seq.scene_model = _FrozenScene(geom)
    return seq


def _boxes(boxes, dynamic=None, velocity=None, ref=None, yaw_rate=None) -> Geometry:
    n = len(boxes)
    return Geometry(
        ground_z=None, boxes=[(i, *b) for i, b in enumerate(boxes)],
        material=np.full(n, 3), dynamic=np.zeros(n, bool) if dynamic is None else dynamic,
        velocity=np.zeros((n, 3)) if velocity is None else velocity,
        ref=np.zeros((n, 3)) if ref is None else ref,
        yaw_rate=np.zeros(n) if yaw_rate is None else yaw_rate)


def test_cast_drops_a_surface_nearer_than_min_range_and_rays_without_hit():
    # box 0: its face at x = 1 m (nearer than min_range = 2 m); box 1: its face at y = 5 m
    geom = _boxes([(np.array([1.5, 0.0, 0.0]), np.array([0.5, 0.5, 0.5]), 0.0),
                   (np.array([0.0, 5.5, 0.0]), np.array([0.5, 0.5, 0.5]), 0.0)])
    seq = _bare_sequence(geom, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 2.0, 50.0)
    D = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    out = seq._cast(D, 0.0, None)
    np.testing.assert_allclose(out["points"], [[0.0, 5.0, 0.0]], atol=1e-9)
    assert out["prim"].tolist() == [1]


def test_cast_point_velocity_of_a_turning_mover_is_rigid_body():
    # a box turning at w = 0.4 rad/s about its reference c = (11, 0, 0.5) that moves at
    # v = (2, 1, 0) m/s; its face x = 10 is hit from o = (0, 0, 0.5) by two rays
    c, v, w = np.array([11.0, 0.0, 0.5]), np.array([2.0, 1.0, 0.0]), 0.4
    geom = _boxes([(c, np.array([1.0, 10.0, 10.0]), 0.0)], dynamic=np.array([True]),
                  velocity=v[None], ref=c[None], yaw_rate=np.array([w]))
    v_s = np.array([1.0, 0.0, 0.0])
    seq = _bare_sequence(geom, [0.0, 0.0, 0.5], v_s, 0.5, 100.0)
    D = np.array([[1.0, 0.0, 0.0], [0.8, 0.6, 0.0]])
    out = seq._cast(D, 0.0, None)
    # hit points: t = 10 and t = 12.5 -> (10, 0), (10, 7.5) relative to the sensor
    np.testing.assert_allclose(out["points"], [[10.0, 0.0, 0.0], [10.0, 7.5, 0.0]], atol=1e-9)
    assert out["dynamic"].tolist() == [True, True]
    # r = p - c = (-1, 0, 0) and (-1, 7.5, 0); u = v + w x r = (v_x - w r_y, v_y + w r_x)
    u = np.array([[2.0, 1.0 - 0.4, 0.0], [2.0 - 0.4 * 7.5, 1.0 - 0.4, 0.0]])
    expected = np.einsum("ij,ij->i", D, u - v_s)  # (1, -1.24)
    np.testing.assert_allclose(out["doppler"], expected, atol=1e-9)
    np.testing.assert_allclose(out["doppler"], [1.0, -1.24], atol=1e-9)
