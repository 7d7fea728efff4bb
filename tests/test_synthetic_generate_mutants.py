"""Known answers of ``SyntheticSequence`` (loaders/synthetic/generate.py): Doppler sign and
value, input checks, stamps and jitter, ground truth of the generated motion, the sensor twist,
scan geometry (points on the surfaces they hit), determinism by seed and point counts.

Expected values come from definitions (radial velocity, finite differences of the motion's
poses, the surfaces' equations), not from the generator's output."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from loaders.se3 import inv_T
from loaders.synthetic import generate as G
from loaders.synthetic.raycast import GROUND_ID, TUNNEL_ID
from loaders.synthetic.scenes import GROUND, SCENES, TUNNEL_WALL
from loaders.synthetic.sensors import SENSORS, point_snr_db


def _world(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return p @ T[:3, :3].T + T[:3, 3]


# the sequences are built inside each test (mutmut counts only in-test calls as reaching the
# constructor)
def _tunnel():
    return G.SyntheticSequence("tunnel", "lidar-dense", 4, seed=2, noise=False, rib_spacing=0,
                               t0=5.0)


def _campus():
    return G.SyntheticSequence("campus", "radar-sparse", 3, seed=1, noise=False)


# ---- Doppler ---------------------------------------------------------------------------------

def test_doppler_is_the_radial_velocity_positive_receding():
    pts = np.array([[10.0, 0.0, 0.0], [0.0, 5.0, 0.0], [3.0, 4.0, 0.0], [0.0, 0.0, -2.0]])
    # the sensor drives forward at 5 m/s: a static point ahead approaches (negative), one to
    # the side has no radial velocity, one at (3, 4) closes at 3 m/s
    np.testing.assert_allclose(G.doppler_of(pts, [5.0, 0.0, 0.0]), [-5.0, 0.0, -3.0, 0.0])
    np.testing.assert_allclose(G.doppler_of(pts, np.array([0.0, 0.0, 1.0])),
                               [0.0, 0.0, 0.0, 1.0])
    # a point moving away from a static sensor recedes (positive)
    u = np.array([[1.0, 0.0, 0.0], [0.0, -2.0, 0.0], [5.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    np.testing.assert_allclose(G.doppler_of(pts, np.zeros(3), u), [1.0, -2.0, 3.0, 0.0])
    np.testing.assert_allclose(G.doppler_of(pts, [5.0, 0.0, 0.0], u), [-4.0, -2.0, 0.0, 0.0])


# ---- parameters, listings, input checks ------------------------------------------------------

def test_params_hash_is_order_free_and_value_sensitive():
    a = G.params_hash({"scene": "loop", "seed": 1, "options": {"t0": 0.0}})
    b = G.params_hash({"options": {"t0": 0.0}, "seed": 1, "scene": "loop"})
    c = G.params_hash({"scene": "loop", "seed": 2, "options": {"t0": 0.0}})
    assert a == b != c
    assert len(a) == 16 and int(a, 16) >= 0
    # values JSON cannot hold are hashed by their text
    assert G.params_hash({"p": Path("x")}) == G.params_hash({"p": "x"})


def test_listings():
    assert G.list_scenes() == SCENES and G.list_scenes() is not SCENES
    assert G.list_sensors() == {n: s.description for n, s in SENSORS.items()}


def test_bad_input_messages():
    with pytest.raises(ValueError) as err:
        G.SyntheticSequence("loop", "radar-semidense", 5, uturm=True, zzz=1)
    assert str(err.value) == (f"unknown synthetic option(s) ['uturm', 'zzz']; known: "
                              f"{sorted(G.OPTIONS)}")
    with pytest.raises(ValueError) as err:
        G.SyntheticSequence("forest", "radar-semidense", 5)
    assert str(err.value) == f"unknown scene 'forest'; known: {', '.join(SCENES)}"
    with pytest.raises(ValueError) as err:
        G.SyntheticSequence("tunnel", "lidar-dense", 0)
    assert str(err.value) == "frames must be >= 1, got 0"
    with pytest.raises(ValueError, match="unknown sensor 'sonar'"):
        G.SyntheticSequence("tunnel", "sonar", 2)


def test_one_frame_is_enough():
    default = G.SyntheticSequence("tunnel", "lidar-dense", 1)
    assert default.seed == 0 and default.noise is True and default.name.endswith("_s0")
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 1, seed=3)
    assert len(seq) == 1 and seq.stamps.tolist() == [0.0]
    # the motion spans at least one period after the stamp
    assert seq.motion.grid[-1] >= seq.spec.period_s


# ---- stamps, provenance, ground truth --------------------------------------------------------

def test_stamps_are_periodic_from_t0_and_copied():
    tunnel = _tunnel()
    np.testing.assert_allclose(tunnel.stamps, 5.0 + 0.1 * np.arange(4))
    s = tunnel.stamps
    s[:] = -1.0
    assert tunnel.stamps[0] == 5.0
    assert tunnel.name == "tunnel_lidar-dense_s2"
    info = tunnel.sensor
    assert info.kind == "lidar" and info.period_s == 0.1 and info.model == "lidar-dense"
    np.testing.assert_allclose(info.T_body_sensor[:3, 3], [1.5, 0.0, 1.8])


def test_jitter_is_seeded_gaussian_and_clipped_to_a_quarter_period():
    def offsets(seed, jitter, frames=400):
        seq = G.SyntheticSequence("tunnel", "lidar-dense", frames, seed=seed, jitter_s=jitter)
        return seq.stamps - 0.1 * np.arange(frames)

    small = offsets(4, 0.005)
    assert abs(small.std() / 0.005 - 1.0) < 0.12 and abs(small.mean()) < 0.0008
    np.testing.assert_array_equal(small, offsets(4, 0.005))
    assert not np.allclose(small, offsets(5, 0.005))
    big = offsets(4, 1.0, 50)
    assert np.abs(big).max() == pytest.approx(0.025)
    assert np.mean(np.isclose(np.abs(big), 0.025)) > 0.9
    np.testing.assert_array_equal(offsets(4, 0.0, 5), 0.0)


def test_name_meta_and_provenance():
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 2, seed=7, name="mine",
                              meta={"note": "x"}, rib_spacing=4.0)
    p = seq.provenance
    assert seq.name == "mine" and p["note"] == "x" and p["source"] == "synthetic"
    params = {"scene": "tunnel", "sensor": "lidar-dense", "frames": 2, "seed": 7,
              "noise": True, "options": {"rib_spacing": 4.0}}
    assert {k: p[k] for k in params} == params
    assert p["params_hash"] == G.params_hash(params)
    assert p["sensor_spec"] == SENSORS["lidar-dense"].as_dict()
    assert p["gt_pipeline"] == {"name": "exact"}
    assert p["scene_summary"]["tunnel"] is True
    assert p["generator_code_hash"] == G.current_code_hash()
    assert seq.scene_name == "tunnel"
    json.dumps(p, default=str)


def test_exact_ground_truth_is_the_sensor_pose_at_the_stamps():
    tunnel = _tunnel()
    gt = tunnel.ground_truth
    np.testing.assert_allclose(gt.stamps, tunnel.stamps)
    # T_world_sensor = T_world_body @ T_body_sensor (lever arm 1.5, 0, 1.8)
    body = tunnel.motion.body_pose(0.1 * np.arange(4))
    np.testing.assert_allclose(gt.poses, body @ SENSORS["lidar-dense"].T_body_sensor,
                               atol=1e-12)
    # the first pose: the body starts at the origin, on the road; the sensor 1.8 m above it
    np.testing.assert_allclose(gt.poses[0, :2, 3], [1.5, 0.0], atol=0.1)
    assert abs(gt.poses[0, 2, 3] - 1.8) < 0.05


def test_sensor_twist_is_the_derivative_of_the_ground_truth():
    campus = _campus()
    h = 1e-4
    for i in range(3):
        t = 0.06 * i
        Ta, Tb = campus.motion.sensor_pose(np.array([t - h, t + h]))
        v_world = (Tb[:3, 3] - Ta[:3, 3]) / (2 * h)
        R = campus.ground_truth.poses[i][:3, :3]
        v_s, w_s = campus.sensor_twist(i)
        np.testing.assert_allclose(v_s, R.T @ v_world, atol=1e-5)
        dR = R.T @ (Tb[:3, :3] - Ta[:3, :3]) / (2 * h)
        np.testing.assert_allclose(w_s, [dR[2, 1], dR[0, 2], dR[1, 0]], atol=1e-5)
        assert 6.0 < np.linalg.norm(v_s) < 10.0  # the radar preset speeds 7-9.5 m/s
    v_s, _ = campus.sensor_twist(0)
    v_s[:] = 0.0
    assert np.linalg.norm(campus.sensor_twist(0)[0]) > 1.0


def test_motion_covers_the_range_before_and_after():
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=1, speed=(20.0, 25.0))
    # margin (max range + 250 m) / lowest speed: 400 m / 20 m/s = 20 s either side (the speed
    # may rise to 25 m/s)
    assert seq.motion.grid[0] == pytest.approx(-20.0, abs=2e-3)
    assert seq.motion.grid[-1] == pytest.approx(0.2 + 20.0, abs=3e-3)


def test_curved_road_flat_attitude_and_seeded_plan_and_ground_truth():
    a = G.SyntheticSequence("curved-wall", "lidar-dense", 2, seed=3)
    b = G.SyntheticSequence("curved-wall", "lidar-dense", 2, seed=3)
    # the road radius (150-250 m) and side come from the seed
    k = a.provenance["motion_profile"]["curvature"]
    assert 1 / 250 <= abs(k) <= 1 / 150 and b.provenance["motion_profile"]["curvature"] == k
    fixed = G.SyntheticSequence("curved-wall", "lidar-dense", 2, seed=3, road_radius=200.0)
    assert abs(fixed.provenance["motion_profile"]["curvature"]) == pytest.approx(1 / 200)
    # attitude_deg=0: no pitch or roll, the sensor's z axis stays vertical
    flat = G.SyntheticSequence("tunnel", "lidar-dense", 20, seed=3, attitude_deg=0.0)
    np.testing.assert_allclose(flat.ground_truth.poses[:, 2, 2], 1.0, atol=1e-12)
    tilted = G.SyntheticSequence("tunnel", "lidar-dense", 20, seed=3)
    assert np.max(np.abs(tilted.ground_truth.poses[:, 2, :2])) > 1e-4
    # a noisy ground-truth pipeline is seeded too
    g1 = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=3, gt="campus")
    g2 = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=3, gt="campus")
    np.testing.assert_array_equal(g1.ground_truth.poses, g2.ground_truth.poses)


# ---- scans -----------------------------------------------------------------------------------

def test_lidar_hits_lie_on_the_surfaces_they_hit():
    tunnel = _tunnel()
    raw = tunnel.raw_hits(2)
    T = tunnel.ground_truth.poses[2]
    pw = _world(T, raw["points"])
    ground = raw["prim"] == GROUND_ID
    wall = raw["prim"] == TUNNEL_ID
    assert ground.sum() > 1000 and wall.sum() > 1000 and np.all(ground | wall)
    np.testing.assert_allclose(pw[ground, 2], 0.0, atol=1e-9)
    tun = tunnel.scene_model.tunnel
    radial = np.hypot(pw[wall, 1] - tun.axis_y, pw[wall, 2] - tun.axis_z)
    np.testing.assert_allclose(radial, tun.radius, atol=1e-6)
    np.testing.assert_array_equal(raw["material"][ground], GROUND)
    np.testing.assert_array_equal(raw["material"][wall], TUNNEL_WALL)
    assert not raw["dynamic"].any()
    # incidence cosine on the road: the vertical component of the world ray direction
    d_w = (pw - T[:3, 3]) / np.linalg.norm(pw - T[:3, 3], axis=1, keepdims=True)
    np.testing.assert_allclose(raw["cos_inc"][ground], np.abs(d_w[ground, 2]), atol=1e-9)
    r = np.linalg.norm(raw["points"], axis=1)
    assert r.min() >= 1.0 and r.max() <= 150.0


def test_static_doppler_without_noise_is_exact():
    tunnel = _tunnel()
    scan = tunnel.scan(1)
    v_s, _ = tunnel.sensor_twist(1)
    d = scan.points / np.linalg.norm(scan.points, axis=1, keepdims=True)
    np.testing.assert_allclose(scan.doppler, -(d @ v_s), atol=1e-9)
    assert scan.stamp == pytest.approx(5.1) and len(scan) > 20_000
    assert scan.source == "tunnel_lidar-dense_s2, frame 1"


def test_moving_vehicles_doppler_includes_their_velocity():
    seq = G.SyntheticSequence("tunnel-vehicles", "lidar-dense", 3, seed=5, noise=False)
    raw = seq.raw_hits(1)
    dyn = raw["dynamic"]
    assert dyn.sum() > 100
    T = seq.ground_truth.poses[1]
    geom = seq.scene_model.geometry(0.1)
    pw = _world(T, raw["points"][dyn])
    u_s = geom.point_velocity(raw["prim"][dyn], pw) @ T[:3, :3]
    v_s, _ = seq.sensor_twist(1)
    d = raw["points"][dyn] / np.linalg.norm(raw["points"][dyn], axis=1, keepdims=True)
    np.testing.assert_allclose(raw["doppler"][dyn], np.einsum("ij,ij->i", d, u_s - v_s),
                               atol=1e-9)
    np.testing.assert_array_equal(raw["material"][dyn], geom.material[raw["prim"][dyn]])
    assert np.all(raw["prim"][dyn] >= 0)
    # every object hit (primitive 0, the first mover here, too) has its primitive's material
    # and motion
    obj = raw["prim"] >= 0
    assert np.any(raw["prim"] == 0)
    np.testing.assert_array_equal(raw["material"][obj], geom.material[raw["prim"][obj]])
    np.testing.assert_array_equal(raw["dynamic"][obj], geom.dynamic[raw["prim"][obj]])


def test_scans_are_reproducible_in_any_order():
    a = G.SyntheticSequence("campus", "radar-sparse", 3, seed=6)
    b = G.SyntheticSequence("campus", "radar-sparse", 3, seed=6)
    late = a.scan(2)
    early = b.scan(0)
    np.testing.assert_array_equal(b.scan(2).points, late.points)
    np.testing.assert_array_equal(a.scan(0).points, early.points)
    np.testing.assert_array_equal(a.scan(0).doppler, early.doppler)
    c = G.SyntheticSequence("campus", "radar-sparse", 3, seed=7)
    assert len(c.scan(0)) != len(early) or not np.allclose(c.scan(0).points, early.points)
    assert len(late) != len(early) or not np.allclose(late.points, early.points)


def test_radar_scatterers_seen_without_noise_are_exact():
    campus = _campus()
    raw = campus.raw_hits(1)
    sc = campus.scatterers
    rows = np.flatnonzero(raw["scatterer"] >= 0)
    assert len(rows) > 50
    # scatterer rows first, then the diffuse returns
    np.testing.assert_array_equal(rows, np.arange(len(rows)))
    ids = raw["scatterer"][rows]
    T = campus.ground_truth.poses[1]
    pw = _world(T, raw["points"][rows])
    fixed = (sc.owner[ids] < 0) & (sc.radius[ids] == 0)
    assert fixed.sum() > 20
    np.testing.assert_allclose(pw[fixed], sc.pos[ids[fixed]], atol=1e-6)
    # detected now: SNR with this frame's fading above the threshold
    p = raw["points"][rows]
    r = np.linalg.norm(p, axis=1)
    snr = raw["fading_db"][rows] + point_snr_db(
        campus.spec, raw["rcs_db"][rows], r, np.arctan2(p[:, 1], p[:, 0]), np.arcsin(p[:, 2] / r))
    assert snr.min() > campus.spec.snr_threshold_db - 1e-6
    np.testing.assert_array_equal(raw["swerling"][rows], sc.swerling[ids])
    np.testing.assert_array_equal(raw["angle_bias"][rows], sc.bias[ids])
    diffuse = raw["scatterer"] < 0
    assert diffuse.sum() > 10
    np.testing.assert_array_equal(raw["swerling"][diffuse], 1)
    np.testing.assert_array_equal(raw["angle_bias"][diffuse], 0.0)
    np.testing.assert_array_equal(raw["fading_db"][diffuse], 0.0)
    assert np.isnan(raw["rcs_db"][diffuse]).all()
    # static scene points: Doppler = -d . v_s; scatterers on movers: d . (R^T u - v_s)
    v_s, _ = campus.sensor_twist(1)
    static = ~raw["dynamic"]
    d = raw["points"] / np.linalg.norm(raw["points"], axis=1, keepdims=True)
    np.testing.assert_allclose(raw["doppler"][static], -(d[static] @ v_s), atol=1e-9)
    moving = raw["dynamic"] & (raw["scatterer"] >= 0)
    assert moving.sum() > 5
    geom = campus.scene_model.geometry(0.06)
    u_s = geom.point_velocity(raw["prim"][moving], _world(T, raw["points"][moving])) @ T[:3, :3]
    np.testing.assert_allclose(raw["doppler"][moving],
                               np.einsum("ij,ij->i", d[moving], u_s - v_s), atol=1e-9)
    # the scan reports each scatterer with its id; without noise the SNR is above threshold
    scan = campus.scan(1)
    f = scan.fields
    point = f["gt_scatterer"] >= 0
    assert point.sum() > 0.8 * len(rows) and set(f["gt_scatterer"][point]) <= set(ids)
    np.testing.assert_array_equal(f["gt_scatterer"][~point], -1.0)
    assert f["snr"].min() > campus.spec.snr_threshold_db


def test_radar_edge_band_option_widens_the_candidates():
    wide = G.SyntheticSequence("campus", "radar-sparse", 2, seed=1, noise=False)
    narrow = G.SyntheticSequence("campus", "radar-sparse", 2, seed=1, noise=False,
                                 edge_band=False)
    az = {}
    for key, seq in (("wide", wide), ("narrow", narrow)):
        raw = seq.raw_hits(0)
        p = raw["points"][raw["scatterer"] >= 0]
        az[key] = np.degrees(np.abs(np.arctan2(p[:, 1], p[:, 0])))
    assert az["narrow"].max() <= 75.0
    assert az["wide"].max() > 75.0 and len(az["wide"]) > len(az["narrow"])


def test_sweep_casts_each_ray_group_at_its_own_time():
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 2, seed=2, noise=False, rib_spacing=0,
                              sweep=True, points=3000)
    raw = seq.raw_hits(1)
    off = raw["time_offset_s"]
    assert len(np.unique(off)) > 4 and off.min() >= 0.0 and off.max() < 0.1
    for tau in np.unique(off)[[0, -1]]:
        rows = off == tau
        t = 0.1 + tau
        T = seq.motion.sensor_pose(np.array([t]))[0]
        v_s = seq.motion.sensor_twist(np.array([t]))[0][0]
        pw = _world(T, raw["points"][rows])
        ground = raw["prim"][rows] == GROUND_ID
        np.testing.assert_allclose(pw[ground, 2], 0.0, atol=1e-9)
        d = raw["points"][rows] / np.linalg.norm(raw["points"][rows], axis=1, keepdims=True)
        np.testing.assert_allclose(raw["doppler"][rows], -(d @ v_s), atol=1e-9)
    scan = seq.scan(1)
    assert "time_offset_s" in scan.fields and len(scan) > 1000
    # each ray is cast once, in its own group: at most one hit per ray, per offset too
    offsets = G.sweep_offsets(seq.spec, len(G.ray_directions(seq.spec, None)))
    assert len(off) <= len(offsets)
    taus, counts = np.unique(off, return_counts=True)
    per_tau = {t: int(np.sum(offsets == t)) for t in taus}
    assert all(c <= per_tau[t] for t, c in zip(taus, counts, strict=True))


def test_lidar_points_option_calibrates_the_ray_count():
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=2, points=3000)
    assert 3000 <= seq.spec.rays <= 12_000
    # rays scaled by target / points of an 8,000-ray probe (a ray gives at most one point)
    assert abs(len(seq.scan(1)) / 3000 - 1.0) < 0.04
    assert seq.provenance["sensor_spec"]["rays"] == seq.spec.rays


def test_radar_points_option_calibrates_the_count():
    seq = G.SyntheticSequence("campus", "radar-sparse", 3, seed=2, points=500)
    # the probe loop stops within 5 % of the target on the middle frame
    assert abs(len(seq.scan(1)) / 500 - 1.0) < 0.05
    assert seq.spec.rays != SENSORS["radar-sparse"].rays
    assert seq.spec.point_gain_db != SENSORS["radar-sparse"].point_gain_db


def test_ground_truth_pipeline_option():
    seq = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=2, gt="campus")
    assert seq.gt_pipeline == "campus"
    assert seq.provenance["gt_pipeline"] == {"name": "campus",
                                             **G.pipeline_params("campus")}
    assert "rate_hz" in seq.provenance["gt_pipeline"]
    exact = G.SyntheticSequence("tunnel", "lidar-dense", 3, seed=2)
    # the campus pipeline adds pose noise: not the exact poses, but within a metre of them
    err = np.linalg.norm(seq.ground_truth.poses[:, :3, 3] - exact.ground_truth.poses[:, :3, 3],
                         axis=1)
    assert err.max() > 0 and err.max() < 1.0
    rel = inv_T(exact.ground_truth.poses[0]) @ exact.ground_truth.poses[2]
    assert 2.0 < np.linalg.norm(rel[:3, 3]) < 3.5  # 12-16.5 m/s over 0.2 s


# ---- the scan's noise, bias and clutter come from the sequence ---------------------------------

def _noisy_campus():
    return G.SyntheticSequence("campus", "radar-sparse", 3, seed=4)


def test_noisy_radar_scans_carry_each_scatterers_persistent_bias():
    noisy_campus = _noisy_campus()
    seq = noisy_campus
    sc = seq.scatterers
    err, bias = [], []
    for i in range(3):
        scan = seq.scan(i)
        ids = scan.fields["gt_scatterer"].astype(int)
        ok = ids >= 0
        ok[ok] = (sc.owner[ids[ok]] < 0) & (sc.radius[ids[ok]] == 0)
        T = seq.ground_truth.poses[i]
        exact = (sc.pos[ids[ok]] - T[:3, 3]) @ T[:3, :3]
        az_exact = np.arctan2(exact[:, 1], exact[:, 0])
        az = np.arctan2(scan.points[ok, 1], scan.points[ok, 0])
        # the neighbouring-cell detections of a semi-dense radar do not apply here (peaks only)
        err.append(np.angle(np.exp(1j * (az - az_exact))))
        bias.append(np.radians(seq.spec.sigma_bias_deg) * sc.bias[ids[ok], 0])
    err, bias = np.concatenate(err), np.concatenate(bias)
    assert len(err) > 200
    slope = (err @ bias) / (bias @ bias)  # the measured error follows the bias one to one
    assert 0.6 < slope < 1.4


def test_noisy_scans_are_noisy_and_clutter_doppler_follows_the_ego_motion():
    noisy_campus = _noisy_campus()
    seq = noisy_campus
    resid, n_clutter = [], 0
    for i in range(3):
        scan = seq.scan(i)
        v_s, _ = seq.sensor_twist(i)
        d = scan.points / np.linalg.norm(scan.points, axis=1, keepdims=True)
        r = scan.doppler + d @ v_s
        clutter = scan.fields["gt_label"] == 2
        n_clutter += clutter.sum()
        resid.append(r[clutter])
    resid = np.concatenate(resid)
    # ghosts keep their source's Doppler, clutter the static-world Doppler plus N(0, 3 m/s)
    assert n_clutter > 30 and abs(resid.mean()) < 1.0
    lidar = G.SyntheticSequence("tunnel", "lidar-dense", 2, seed=2)
    scan = lidar.scan(1)
    v_s, _ = lidar.sensor_twist(1)
    d = scan.points / np.linalg.norm(scan.points, axis=1, keepdims=True)
    assert abs(np.std(scan.doppler + d @ v_s) / 0.03 - 1.0) < 0.2
