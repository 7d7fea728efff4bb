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
    # (a hit point moved along its own ray, o - t D, changes u by w x (-2 t D), normal to D:
    # the radial velocity cannot tell, so that mutant is equivalent; o + t / D is caught)
    np.testing.assert_allclose(out["doppler"], expected, atol=1e-9)
    np.testing.assert_allclose(out["doppler"], [1.0, -1.24], atol=1e-9)


# ---- constructor options ---------------------------------------------------------------------

def test_attitude_default_is_the_documented_one():
    # OPTIONS["attitude_deg"]: "pitch/roll oscillation amplitude [deg] (0 = flat, default 0.6)"
    assert "default 0.6" in G.OPTIONS["attitude_deg"]
    default = G.SyntheticSequence("straight-wall", "lidar-dense", 2, seed=3, noise=False)
    explicit = G.SyntheticSequence("straight-wall", "lidar-dense", 2, seed=3, noise=False,
                                   attitude_deg=0.6)
    t = np.linspace(0.0, 5.0, 51)
    np.testing.assert_allclose(default.motion.sensor_pose(t), explicit.motion.sensor_pose(t),
                               atol=1e-12)
    # the amplitude bounds pitch and roll (two sinusoids of total amplitude <= 0.6 deg)
    pitch, _, roll, _ = default.motion.profile.attitude(np.linspace(-50.0, 50.0, 2001))
    assert np.degrees(np.abs(pitch)).max() <= 0.6 + 1e-9
    assert np.degrees(np.abs(roll)).max() <= 0.6 + 1e-9


def test_slow_drive_motion_reaches_back_beyond_the_sensor_range():
    # a drive at 1-1.5 m/s: the motion starts far enough back that the ego has travelled more
    # than the sensor's range plus the scene's 250 m placement margin before t = 0 (the speed
    # floor of the margin is 1 m/s: margin = (max_range + 250) / max(v_low, 1))
    seq = G.SyntheticSequence("straight-wall", "lidar-dense", 1, seed=0, noise=False,
                              speed=(1.0, 1.5))
    max_range = seq.spec.max_range
    sigma = seq.motion.planar_state(np.array([seq.motion.t0, 0.0]))["sigma"]
    assert sigma[1] - sigma[0] >= max_range + 250.0


def test_plan_and_motion_streams_are_independent():
    # the plan (curved-wall: the road radius, uniform in 150-250 m) and the motion (the initial
    # speed, uniform in the speed range) use their own RNG streams: their uniform variates
    # must differ
    for seed in range(3):
        seq = G.SyntheticSequence("curved-wall", "lidar-dense", 1, seed=seed, noise=False,
                                  speed=(10.0, 14.0))
        prof = seq.motion.profile
        u_radius = (1.0 / abs(prof.curvature) - 150.0) / 100.0
        u_speed = (prof.v0 - 10.0) / 4.0
        assert 0.0 <= u_radius <= 1.0 and 0.0 <= u_speed <= 1.0
        assert abs(u_radius - u_speed) > 1e-9


# ---- the points option (_calibrated) ---------------------------------------------------------

def test_radar_calibration_meets_its_tolerance_for_moderate_targets():
    # _calibrated: radar probes the middle frame until target / points is within 5 % of 1
    # (at most 6 probes); for targets well inside the sensor's limits it converges
    for scene, seed, target in (("campus", 0, 250), ("loop", 1, 300), ("campus", 3, 600),
                                ("loop", 2, 700)):
        seq = G.SyntheticSequence(scene, "radar-sparse", 3, seed=seed, points=target)
        n = len(seq.scan(1))
        assert abs(target / n - 1.0) < 0.05, (scene, seed, target, n)


def test_radar_target_already_met_leaves_the_spec_unchanged():
    # a target within the 5 % tolerance of what the sensor already gives on the middle frame:
    # the first probe meets it, so the calibrated spec is the sensor's own
    plain = G.SyntheticSequence("campus", "radar-sparse", 3, seed=0)
    n = len(plain.scan(1))
    assert n > 60
    seq = G.SyntheticSequence("campus", "radar-sparse", 3, seed=0, points=n + 2)
    assert seq.spec == plain.spec
    assert len(seq.scan(1)) == n


def test_jitter_stream_is_not_shared_with_another_component():
    # each component draws from its own stream of the seed (the plan 1, the motion 2, the scene
    # 3, the radar scatterers 5, the ground truth 6): the stamp jitter's normal draws must not
    # be any of theirs
    seed, jitter, frames = 4, 1e-3, 6
    seq = G.SyntheticSequence("campus", "radar-sparse", frames, seed=seed, noise=False,
                              jitter_s=jitter)
    period = seq.spec.period_s
    offsets = seq.stamps - period * np.arange(frames)
    assert np.abs(offsets).max() < period / 4  # not clipped
    assert np.std(offsets) > 0.2 * jitter
    for stream in (1, 2, 3, 5, 6):
        other = np.random.default_rng([seed, stream]).normal(0.0, jitter, frames)
        assert not np.allclose(offsets, other, rtol=0.0, atol=1e-12), stream
