"""Known answers of the radar scattering centres (loaders/synthetic/scatterers.py): where they
are sampled (on the surfaces of boxes, cylinders, spheres, the ground, kerbs and tunnel ribs),
the grid index, and which are seen from a sensor (field of view, range, facing, occlusion,
RCS towards the sensor, mover velocity).

Expected values come from the documented geometry, worked out by hand on small hand-made
scenes, or from the scene's own primitives (boxes, cylinders, spheres)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from helpers_angles import on_azimuth_edge
from loaders.synthetic import scatterers as SC
from loaders.synthetic.generate import SyntheticSequence
from loaders.synthetic.raycast import GROUND_ID, TUNNEL_ID, Geometry
from loaders.synthetic.scenes import BUILDING, CAR, CROWN, POLE, RIB, TRUNK, TUNNEL_WALL, WALL
from loaders.synthetic.sensors import SENSORS, detection_margin_deg

RADAR = SENSORS["radar-sparse"]


def _build(adds, seed=0) -> SC.Scatterers:
    b = SC._Builder(np.random.default_rng(seed))
    for args, kw in adds:
        b.add(*args, **kw)
    return b.build()


def _campus():
    """Built inside each test that checks it (mutmut counts in-test calls only)."""
    return SyntheticSequence("campus", "radar-sparse", 2, seed=1, noise=False)


# ---- the builder -----------------------------------------------------------------------------

def test_builder_fills_every_field_and_draws_the_random_ones():
    n = 20_000
    pos = np.zeros((n, 3))
    sc = _build([((pos, (0.0, 1.0, 0.0)), {"rcs": (4.0, 2.0), "material": WALL, "owner": 3,
                                            "prim": 7, "cos_min": 0.2, "aspect_exp": 0.5,
                                            "radius": 0.3, "lobe_db": 2.5,
                                            "lobe_k": (2.0, 5.0), "swerling": 1})])
    assert len(sc) == n
    np.testing.assert_array_equal(sc.normal, np.broadcast_to([0.0, 1.0, 0.0], (n, 3)))
    for name, value in (("cos_min", 0.2), ("aspect_exp", 0.5), ("radius", 0.3),
                        ("lobe_db", 2.5), ("swerling", 1), ("material", WALL), ("owner", 3),
                        ("prim", 7)):
        np.testing.assert_array_equal(getattr(sc, name), value)
    for name in ("swerling", "material", "owner", "prim"):
        assert getattr(sc, name).dtype == np.int64
    assert abs(sc.rcs_db.mean() - 4.0) < 0.05 and abs(sc.rcs_db.std() - 2.0) < 0.05
    assert sc.lobe_k.min() >= 2.0 and sc.lobe_k.max() < 5.0 and abs(sc.lobe_k.mean() - 3.5) < 0.05
    assert sc.lobe_phase.min() >= 0.0 and sc.lobe_phase.max() < 2 * np.pi
    assert abs(sc.lobe_phase.mean() - np.pi) < 0.05
    assert sc.bias.shape == (n, 2) and abs(sc.bias.std() - 1.0) < 0.02
    assert abs(sc.bias.mean()) < 0.02


def test_builder_defaults_isotropic_and_empty():
    sc = _build([(([[1.0, 2.0, 3.0]],), {"rcs": (0.0, 0.0), "material": POLE}),
                 ((np.zeros((0, 3)), (1.0, 0.0, 0.0)), {"rcs": (0.0, 1.0), "material": WALL}),
                 (([[0.0, 0.0, 1.0]], (1.0, 0.0, 0.0)), {"rcs": (1.0, 0.0), "material": WALL})])
    assert len(sc) == 2
    # isotropic: no normal, always facing (cos_min below -1), no incidence loss
    np.testing.assert_array_equal(sc.normal[0], 0.0)
    assert sc.cos_min[0] == -2.0 and sc.aspect_exp[0] == 0.0
    # the defaults of a faced scatterer
    assert sc.cos_min[1] == 0.05 and sc.aspect_exp[1] == 1.0 and sc.radius[1] == 0.0
    assert sc.lobe_db[1] == 3.0 and 1.0 <= sc.lobe_k[1] < 6.0 and sc.swerling[1] == 3
    np.testing.assert_array_equal(sc.owner, -1)
    np.testing.assert_array_equal(sc.prim, -1)
    np.testing.assert_array_equal(sc.rcs_db, [0.0, 1.0])
    empty = SC._Builder(np.random.default_rng(0)).build()
    assert len(empty) == 0 and empty.pos.shape == (0, 3) and empty.normal.shape == (0, 3)
    assert empty.bias.shape == (0, 2)
    for name in ("cos_min", "aspect_exp", "radius", "rcs_db", "lobe_db", "lobe_k", "lobe_phase",
                 "swerling", "material", "owner", "prim"):
        assert getattr(empty, name).shape == (0,)
    for name in ("material", "owner", "swerling", "prim"):
        assert getattr(empty, name).dtype == np.int64
    assert len(empty.static_in_sector(np.zeros(2), 0.0, 1.0, 100.0)) == 0
    assert len(empty.of_mover(0)) == 0


# ---- the grid index --------------------------------------------------------------------------

def test_sector_query_is_a_superset_of_the_sector_and_skips_far_cells():
    xs, ys = np.meshgrid(np.arange(-100.0, 101.0, 3.0), np.arange(-100.0, 101.0, 3.0))
    pos = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)])
    mover = np.array([[1.0, 1.0, 0.0], [2.0, 0.0, 0.0]])
    sc = _build([((pos,), {"rcs": (0.0, 1.0), "material": WALL}),
                 ((mover,), {"rcs": (0.0, 1.0), "material": CAR, "owner": 0}),
                 ((mover[:1],), {"rcs": (0.0, 1.0), "material": CAR, "owner": 2})])
    apex, heading, half, radius = np.array([5.0, -3.0]), np.radians(100.0), np.radians(30.0), 50.0
    got = set(sc.static_in_sector(apex, heading, half, radius).tolist())
    d = pos[:, :2] - apex
    dist = np.hypot(d[:, 0], d[:, 1])
    bearing = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - heading)))
    inside = set(np.flatnonzero((dist <= radius) & (np.abs(bearing) <= half)).tolist())
    assert inside <= got
    # nothing from cells wholly beyond the radius or behind the apex
    diag = SC.GRID_CELL * np.sqrt(2.0)
    far = set(np.flatnonzero(dist > radius + diag).tolist())
    behind = set(np.flatnonzero((np.abs(bearing) > half + np.radians(60.0))
                                & (dist > 2 * diag)).tolist())
    assert not got & far and not got & behind
    assert len(got) < 0.5 * len(pos)
    assert max(got) < len(pos)  # no mover scatterer
    # the apex cell is always included (a scatterer right beside the sensor)
    near = set(sc.static_in_sector(np.array([0.5, 0.5]), np.pi, 0.01, 1.0).tolist())
    at_origin = int(np.flatnonzero((pos[:, 0] == 2.0) & (pos[:, 1] == 2.0))[0])
    assert at_origin in near
    np.testing.assert_array_equal(np.sort(sc.of_mover(0)), [len(pos), len(pos) + 1])
    np.testing.assert_array_equal(sc.of_mover(2), [len(pos) + 2])
    assert len(sc.of_mover(1)) == 0 and len(sc.of_mover(5)) == 0


def test_sector_query_keeps_a_narrow_sector_between_cell_centres():
    """A thin sector along +x reaches the scatterers of every cell it crosses."""
    x = np.arange(1.0, 60.0, 2.0)
    pos = np.column_stack([x, np.full(len(x), 0.1), np.zeros(len(x))])
    sc = _build([((pos,), {"rcs": (0.0, 1.0), "material": WALL})])
    got = np.sort(sc.static_in_sector(np.array([0.0, 0.0]), 0.0, 0.001, 60.0))
    np.testing.assert_array_equal(got, np.arange(len(x)))
    assert len(sc.static_in_sector(np.array([0.0, 0.0]), np.pi, 0.001, 60.0)) == 0


# ---- sampling on a scene's surfaces ----------------------------------------------------------

def _box_frame(p, center, yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    d = p - np.asarray(center)
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])


def test_box_scatterers_lie_on_faces_edges_and_the_foot():
    campus = _campus()
    scene, sc = campus.scene_model, campus.scatterers
    n_box = 0
    for pid, (center, half, yaw, mat) in enumerate(scene.boxes):
        mine = np.flatnonzero((sc.prim == pid) & (sc.owner < 0))
        if not len(mine):
            continue
        n_box += 1
        q = _box_frame(sc.pos[mine], center, yaw)
        hx, hy, hz = half
        on_x = np.isclose(np.abs(q[:, 0]), hx)
        on_y = np.isclose(np.abs(q[:, 1]), hy)
        assert np.all(on_x | on_y)
        assert np.all(np.abs(q[:, 0]) <= hx + 1e-9) and np.all(np.abs(q[:, 1]) <= hy + 1e-9)
        assert np.all(q[:, 2] >= -hz - 1e-9) and np.all(q[:, 2] <= hz + 1e-9)
        nl = _box_frame(sc.normal[mine], np.zeros(3), yaw)
        # faces: the outward axis normal; edges (on both): the diagonal, seen from behind too
        face = on_x ^ on_y
        want = np.where(on_x[:, None], [[1.0, 0, 0]], [[0, 1.0, 0]]) * np.sign(q)
        np.testing.assert_allclose(nl[face], want[face], atol=1e-9)
        edge = on_x & on_y
        np.testing.assert_allclose(nl[edge], np.sign(q[edge]) * [1, 1, 0] / np.sqrt(2),
                                   atol=1e-9)
        assert np.all(sc.cos_min[mine[edge]] == -0.7) and np.all(sc.aspect_exp[mine[edge]] == 0)
        assert np.all(sc.lobe_db[mine[edge]] == 2.0)
        np.testing.assert_array_equal(sc.material[mine], mat)
        if mat == BUILDING:  # the wall-ground dihedral line 5 cm above the foot
            foot = np.isclose(q[:, 2], -hz + 0.05) & face
            assert foot.sum() >= 1
            assert np.all(sc.aspect_exp[mine[foot]] == 0.5)
        if mat in (BUILDING, WALL):  # faces Swerling 1, edges Swerling 3
            assert np.all(sc.swerling[mine[edge]] == 3)
    assert n_box > 5


def test_face_density_and_edge_spacing_of_a_box():
    half = (10.0, 4.0, 5.0)
    faces, edges, foot = [], [], []
    for seed in range(20):
        b = SC._Builder(np.random.default_rng(seed))
        SC._box_local(b, half, BUILDING, owner=-1, face_density=0.7, face_rcs=(-3.0, 5.0),
                      edge_spacing=0.6, edge_rcs=(11.0, 4.0), base=True)
        sc = b.build()
        on_x, on_y = np.isclose(np.abs(sc.pos[:, 0]), 10.0), np.isclose(np.abs(sc.pos[:, 1]), 4.0)
        edge = on_x & on_y
        low = np.isclose(sc.pos[:, 2], -5.0 + 0.05) & ~edge & (sc.aspect_exp == 0.5)
        faces.append(int((~edge & ~low).sum()))
        edges.append(int(edge.sum()))
        foot.append(int(low.sum()))
        assert np.all(sc.swerling[~edge & ~low] == 1)
    # faces: Poisson(0.7 / m^2 x 4 faces' area 2 (20 + 8) x 10 m^2 = 392); edges: 4 x 16 rows
    # (10 m / 0.6 m) kept with p 0.8; foot: 4 faces' length / 2 m -> 10 + 10 + 4 + 4 = 28 slots
    # kept with p 0.7
    assert abs(np.mean(faces) - 392.0) < 3 * np.sqrt(392.0 / 20)
    assert abs(np.mean(edges) - 64 * 0.8) < 3 * np.sqrt(64 * 0.16 / 20)
    assert abs(np.mean(foot) - 28 * 0.7) < 3 * np.sqrt(28 * 0.21 / 20)


def test_vehicle_wheels_and_bumpers():
    b = SC._Builder(np.random.default_rng(0))
    half = (2.25, 0.9, 0.75)
    SC._vehicle(b, half, CAR, 4)
    sc = b.build()
    np.testing.assert_array_equal(sc.owner, 4)
    np.testing.assert_array_equal(sc.material, CAR)
    wheels = np.isclose(sc.pos[:, 2], -0.75 + 0.35)
    want = {(sx * 1.5, sy * 0.9) for sx in (-1, 1) for sy in (-1, 1)}
    assert {(round(x, 9), round(y, 9)) for x, y in sc.pos[wheels, :2]} == want
    np.testing.assert_allclose(sc.normal[wheels], np.column_stack(
        [np.zeros(4), np.sign(sc.pos[wheels, 1]), np.zeros(4)]))
    np.testing.assert_array_equal(sc.cos_min[wheels], -0.3)
    bump = np.isclose(sc.pos[:, 2], -0.75 + 0.55)
    assert bump.sum() == 6
    np.testing.assert_allclose(np.sort(sc.pos[bump, 1]), np.repeat([-0.54, 0.0, 0.54], 2))
    np.testing.assert_allclose(np.abs(sc.pos[bump, 0]), 2.25)
    np.testing.assert_allclose(sc.normal[bump], np.sign(sc.pos[bump, :1]) * [[1.0, 0, 0]])
    np.testing.assert_array_equal(sc.cos_min[bump], 0.1)
    # the body's faces start 0.25 m above its bottom
    body = ~wheels & ~bump
    assert sc.pos[body, 2].min() >= -0.75 + 0.25 - 1e-9


def test_cylinders_spheres_and_ground_of_a_campus():
    campus = _campus()
    scene, sc = campus.scene_model, campus.scatterers
    pid0 = len(scene.boxes)
    n_pole = n_trunk = 0
    for k, (cx, cy, r, z0, z1, mat) in enumerate(scene.vcylinders):
        mine = np.flatnonzero(sc.prim == pid0 + k)
        assert len(mine) >= 2
        np.testing.assert_array_equal(sc.material[mine], mat)
        # points on the axis with the cylinder's radius (the visible centre is found per view)
        np.testing.assert_allclose(sc.pos[mine, :2], np.broadcast_to([cx, cy], (len(mine), 2)))
        np.testing.assert_allclose(sc.radius[mine], r)
        z = np.sort(sc.pos[mine, 2])
        if mat == POLE:
            n_pole += 1
            assert z[0] == pytest.approx(z0 + 0.15) and z[-1] == pytest.approx(z1 - 0.2)
            assert 3 <= len(mine) <= 5
        elif mat == TRUNK:
            n_trunk += 1
            assert z[0] == pytest.approx(z0 + 0.2) and z[-1] <= z0 + min(z1 - z0, 3.0)
            assert 2 <= len(mine) <= 4
        assert np.all(sc.cos_min[mine] < -1.0)
    assert n_pole > 0 and n_trunk > 0
    pid1 = pid0 + len(scene.vcylinders)
    for k, (center, r, mat) in enumerate(scene.spheres):
        mine = np.flatnonzero(sc.prim == pid1 + k)
        assert mat == CROWN
        d = sc.pos[mine] - np.asarray(center)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), r)
        np.testing.assert_allclose(sc.normal[mine], d / r, atol=1e-9)
        np.testing.assert_array_equal(sc.swerling[mine], 1)
    ground = np.flatnonzero((sc.prim == GROUND_ID) & (sc.pos[:, 2] == 0.0))
    kerb = np.flatnonzero((sc.prim == GROUND_ID) & (sc.pos[:, 2] == 0.08))
    assert len(ground) > 50 and len(kerb) > 20
    np.testing.assert_allclose(sc.normal[ground], np.broadcast_to([0.0, 0.0, 1.0],
                                                                  (len(ground), 3)))
    for center, half, yaw, _ in scene.boxes:  # never under a box
        q = _box_frame(sc.pos[ground], center, yaw)
        assert not np.any((np.abs(q[:, 0]) < half[0]) & (np.abs(q[:, 1]) < half[1]))
    # within 60 m of the path, kerbs 5.4 m beside it and facing it
    m = campus.motion
    lo, hi = m.sigma_span
    st = m.planar_state(m.time_at_arclength(np.arange(lo + 1.0, hi - 1.0, 0.25)))
    path = np.column_stack([st["x"], st["y"]])
    from scipy.spatial import cKDTree

    tree = cKDTree(path)
    assert tree.query(sc.pos[ground, :2])[0].max() <= 60.0 + 0.3
    dist, idx = tree.query(sc.pos[kerb, :2])
    np.testing.assert_allclose(dist, 5.4, atol=0.05)
    towards = path[idx] - sc.pos[kerb, :2]
    cos = np.einsum("ij,ij->i", towards / dist[:, None], sc.normal[kerb, :2])
    assert cos.min() > 0.99
    # movers: body-frame points inside their box, owned by their index
    for i, mv in enumerate(scene.movers):
        mine = sc.of_mover(i)
        assert len(mine) > 0
        assert np.all(np.abs(sc.pos[mine]) <= np.asarray(mv.half) + 1e-9)


def test_tunnel_ribs_and_wall_features():
    seq = SyntheticSequence("tunnel", "radar-sparse", 2, seed=3, rib_spacing=4.0)
    tun, sc = seq.scene_model.tunnel, seq.scatterers
    rib = sc.material == RIB
    wall = sc.material == TUNNEL_WALL
    assert rib.sum() > 100 and wall.sum() > 10
    np.testing.assert_array_equal(sc.prim[rib | wall], TUNNEL_ID)
    radial = np.hypot(sc.pos[:, 1] - tun.axis_y, sc.pos[:, 2] - tun.axis_z)
    np.testing.assert_allclose(radial[rib], tun.radius - tun.rib_depth)
    np.testing.assert_allclose(radial[wall], tun.radius)
    assert sc.pos[rib | wall, 2].min() > 0.1
    # one ring on every rib, half a rib width after its start
    phase = (sc.pos[rib, 0] - tun.x0 - 0.5 * tun.rib_width) / 4.0
    np.testing.assert_allclose(phase, np.round(phase), atol=1e-9)
    assert len(np.unique(np.round(phase))) > 0.9 * (tun.x1 - tun.x0) / 4.0
    # ring points about 0.6 m apart, 60 % kept
    per_ring = rib.sum() / len(np.unique(np.round(phase)))
    r_rib = tun.radius - tun.rib_depth
    above = np.mean(tun.axis_z + r_rib * np.sin(np.linspace(0, 2 * np.pi, 1000)) > 0.1)
    assert abs(per_ring - 0.6 * above * 2 * np.pi * r_rib / 0.6) < 1.5
    # wall features: Poisson(0.05 / m^2 over the tube), those above the road
    area = 2 * np.pi * tun.radius * (tun.x1 - tun.x0)
    assert abs(wall.sum() - 0.05 * area * above) < 5 * np.sqrt(0.05 * area)
    smooth = SyntheticSequence("tunnel", "radar-sparse", 2, seed=3, rib_spacing=0)
    assert not (smooth.scatterers.material == RIB).any()


# ---- what a sensor sees ----------------------------------------------------------------------

def _geom(boxes=(), movers=()) -> Geometry:
    """A geometry without ground: static boxes then mover boxes (id, center, half, yaw)."""
    g = Geometry(ground_z=None)
    n = len(boxes) + len(movers)
    for k, (center, half, yaw) in enumerate([*boxes, *[m[:3] for m in movers]]):
        g.boxes.append((k, np.asarray(center, float), np.asarray(half, float), yaw))
    g.material = np.full(n, WALL)
    g.dynamic = np.array([False] * len(boxes) + [True] * len(movers))
    g.velocity = np.array([(0.0, 0.0, 0.0)] * len(boxes) + [m[3] for m in movers]).reshape(-1, 3)
    g.ref = np.array([b[0] for b in [*boxes, *movers]], float).reshape(-1, 3)
    g.yaw_rate = np.array([0.0] * len(boxes) + [m[4] for m in movers])
    g.mover_pid = np.arange(len(boxes), n)
    return g


def _fixed(sc: SC.Scatterers, **values) -> SC.Scatterers:
    out = dataclasses.replace(sc, **{k: np.asarray(v, float) for k, v in values.items()})
    return out.finalize()


def test_field_of_view_range_and_facing():
    spec = RADAR  # +-75 x +-15 deg, 0.5-100 m
    pts = [[10.0, 0.0, 0.0],  # 0 seen
           [10.0, 10.0 * np.tan(np.radians(74.0)), 0.0],  # 1 inside the azimuth edge
           [10.0, 10.0 * np.tan(np.radians(76.0)), 0.0],  # 2 outside
           [10.0, 0.0, 10.0 * np.tan(np.radians(16.0))],  # 3 above
           [10.0, 0.0, -10.0 * np.tan(np.radians(14.0))],  # 4 inside, below
           [99.0, 0.0, 0.0], [101.0, 0.0, 0.0], [0.3, 0.0, 0.0],  # 5 seen, 6 far, 7 near
           [-10.0, 0.0, 0.0]]  # 8 behind
    sc = _build([((pts,), {"rcs": (0.0, 1.0), "material": WALL})])
    o, R = np.zeros(3), np.eye(3)
    cand = SC.candidates(sc, Geometry(ground_z=None), o, R, spec, edge_band=False)
    assert sorted(cand["ids"].tolist()) == [0, 1, 4, 5]
    wide = SC.candidates(sc, Geometry(ground_z=None), o, R, spec, edge_band=True)
    # the band: +-(75 + margin) x +-(15 + margin) deg, margin 1.6-1.7 deg for this radar
    assert detection_margin_deg(spec).min() > 1.0
    assert sorted(wide["ids"].tolist()) == [0, 1, 2, 3, 4, 5]
    # facing: a normal pointing away is not seen, a diagonal at 60 deg is
    faced = _build([(([[10.0, 0.0, 0.0]] * 3, [(-1.0, 0.0, 0.0)]), {"rcs": (0.0, 1.0),
                                                                      "material": WALL})])
    faced = _fixed(faced, normal=[[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0],
                                  [-0.5, np.sqrt(0.75), 0.0]])
    cand = SC.candidates(faced, Geometry(ground_z=None), o, R, spec, edge_band=False)
    assert sorted(cand["ids"].tolist()) == [0, 2]
    np.testing.assert_allclose(cand["cos_n"][np.argsort(cand["ids"])], [1.0, 0.5])


def test_sensor_pose_rotates_and_shifts_the_view():
    sc = _build([(([[30.0, 2.0, 1.0], [0.0, 10.0, 1.0]],), {"rcs": (0.0, 1.0),
                                                             "material": WALL})])
    yaw = np.pi / 2  # the sensor at (0, 1, 1) looks along +y
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.array([0.0, 1.0, 1.0]), R, RADAR,
                         edge_band=False)
    assert cand["ids"].tolist() == [1]
    np.testing.assert_allclose(cand["points_s"], [[9.0, 0.0, 0.0]], atol=1e-12)
    np.testing.assert_allclose(cand["points_w"], [[0.0, 10.0, 1.0]])
    np.testing.assert_allclose(cand["range"], [9.0])
    assert yaw == pytest.approx(np.arctan2(R[1, 0], R[0, 0]))


def test_rcs_towards_the_sensor_aspect_loss_and_lobe():
    sc = _build([(([[10.0, 0.0, 0.0]] * 3, (-1.0, 0.0, 0.0)), {"rcs": (0.0, 1.0),
                                                                "material": WALL})])
    sc = _fixed(sc, rcs_db=[10.0, 10.0, 10.0], aspect_exp=[1.0, 2.0, 1.0],
                lobe_db=[3.0, 0.0, 2.0], lobe_k=[1.0, 1.0, 2.0], lobe_phase=[0.0, 0.0, 0.5],
                normal=[[-1.0, 0.0, 0.0], [-0.5, np.sqrt(0.75), 0.0],
                        [-0.01, np.sqrt(1 - 1e-4), 0.0]], cos_min=[0.0, 0.0, -1.0])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    order = np.argsort(cand["ids"])
    # the view azimuth from the scatterer to the sensor is pi: lobe 3 cos(pi) = -3;
    # 2 x 10 log10(0.5); incidence cosine 0.01 clipped at 0.05 and a lobe 2 cos(2 pi + 0.5)
    np.testing.assert_allclose(cand["rcs_db"][order],
                               [10.0 - 3.0, 10.0 + 20 * np.log10(0.5),
                                10.0 + 10 * np.log10(0.05) + 2 * np.cos(0.5)])


def test_cylinder_scatterer_is_seen_on_the_surface_facing_the_sensor():
    sc = _build([(([[10.0, 5.0, 1.0]],), {"rcs": (0.0, 1.0), "material": POLE,
                                          "radius": 0.5})])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.array([0.0, 5.0, 1.0]), np.eye(3),
                         RADAR, edge_band=False)
    np.testing.assert_allclose(cand["points_w"], [[9.5, 5.0, 1.0]])
    np.testing.assert_allclose(cand["range"], [9.5])
    np.testing.assert_allclose(sc.pos, [[10.0, 5.0, 1.0]])  # the stored axis point stays


def test_occlusion_and_the_visible_fields():
    sc = _build([(([[20.0, 0.0, 0.0], [20.0, 6.0, 0.0], [5.0, 0.0, 0.0]],),
                  {"rcs": (0.0, 1.0), "material": WALL, "swerling": 1})])
    sc = _fixed(sc, cos_min=[-2.0, -2.0, -2.0])
    # a wall at x = 10 .. 11 in front of scatterer 0 only
    geom = _geom(boxes=[((10.5, 0.0, 0.0), (0.5, 1.0, 5.0), 0.0)])
    vis = SC.visible(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert sorted(vis["ids"].tolist()) == [1, 2]
    np.testing.assert_array_equal(vis["velocity_w"], 0.0)
    assert not vis["dynamic"].any()
    np.testing.assert_array_equal(vis["cos_inc"], 1.0)  # isotropic: no incidence
    np.testing.assert_array_equal(vis["swerling"], 1)
    np.testing.assert_array_equal(vis["material"], WALL)
    np.testing.assert_array_equal(vis["bias"], sc.bias[vis["ids"]])
    # a surface just behind the scatterer (within OCCLUSION_TOL) does not hide it
    cand = SC.candidates(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    t = cand["range"] - SC.OCCLUSION_TOL
    assert len(SC.finish(sc, geom, np.zeros(3), cand, t)["ids"]) == len(cand["ids"])
    t = cand["range"] - SC.OCCLUSION_TOL - 1e-3
    assert len(SC.finish(sc, geom, np.zeros(3), cand, t)["ids"]) == 0


def test_mover_scatterers_move_with_their_box():
    b = SC._Builder(np.random.default_rng(0))
    b.add([[1.0, 0.0, 0.0], [-1.0, 0.5, 0.2]], (1.0, 0.0, 0.0), rcs=(0.0, 1.0), material=CAR,
          owner=0, cos_min=-1.5)
    sc = b.build()
    yaw = np.pi / 2
    center = (20.0, 0.0, 0.75)
    geom = _geom(boxes=[((0.0, 50.0, 0.0), (1.0, 1.0, 1.0), 0.0)],
                 movers=[(center, (2.0, 1.0, 0.75), yaw, (0.0, 3.0, 0.0), 0.5)])
    cand = SC.candidates(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    order = np.argsort(cand["ids"])
    # body frame rotated by the box's yaw about its centre
    want = np.array([[20.0, 1.0, 0.75], [19.5, -1.0, 0.95]])
    np.testing.assert_allclose(cand["points_w"][order], want, atol=1e-12)
    np.testing.assert_array_equal(cand["prim"], 1)
    t = np.full(len(cand["ids"]), np.inf)
    vis = SC.finish(sc, geom, np.zeros(3), cand, t)
    o = np.argsort(vis["ids"])
    # rigid motion: v + w x (p - centre), w = 0.5 rad/s about z
    r = want - np.asarray(center)
    v = np.column_stack([-0.5 * r[:, 1], 3.0 + 0.5 * r[:, 0], np.zeros(2)])
    np.testing.assert_allclose(vis["velocity_w"][o], v, atol=1e-12)
    assert vis["dynamic"].all()
    # the normal turns with the box: (1, 0, 0) -> (0, 1, 0); cos_n = n . (o - p) / r
    np.testing.assert_allclose(cand["cos_n"][order],
                               [(-want[0] @ [0, 1, 0]) / np.linalg.norm(want[0]),
                                (-want[1] @ [0, 1, 0]) / np.linalg.norm(want[1])])
    # a mover beyond reach (max range + 1 + 15 m) is skipped whole
    far = _geom(movers=[((120.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (0.0, 0.0, 0.0), 0.0)])
    assert len(SC.candidates(sc, far, np.zeros(3), np.eye(3), RADAR, False)["ids"]) == 0
    inactive = _geom(movers=[(center, (2.0, 1.0, 0.75), yaw, (0.0, 3.0, 0.0), 0.5)])
    inactive.mover_pid = np.array([-1])
    assert len(SC.candidates(sc, inactive, np.zeros(3), np.eye(3), RADAR, False)["ids"]) == 0


def test_box_index_of_movers_after_the_static_boxes():
    geom = _geom(boxes=[((0, 0, 0), (1, 1, 1), 0.0)] * 3,
                 movers=[((0, 0, 0), (1, 1, 1), 0.0, (0, 0, 0), 0.0)] * 2)
    geom.mover_pid = np.array([3, -1, 4])
    geom.boxes = geom.boxes[:5]
    assert SC._box_index(geom, 3) == 3 and SC._box_index(geom, 4) == 4


# ---- edge cases of the sector query and the candidates ----------------------------------------

@pytest.mark.parametrize("apex", [(0.0, 100.0), (100.0, 0.0), (500.0, 500.0),
                                  (-500.0, -500.0)])
def test_sector_query_anywhere_in_the_world(apex):
    apex = np.array(apex)
    ang = np.radians(np.arange(-170.0, 180.0, 20.0))
    dist = np.array([3.0, 15.0, 30.0])
    pts = np.array([[apex[0] + d * np.cos(a), apex[1] + d * np.sin(a), 0.0]
                    for a in ang for d in dist])
    sc = _build([((pts,), {"rcs": (0.0, 1.0), "material": WALL})])
    got = set(sc.static_in_sector(apex, np.pi / 4, np.pi, 31.0).tolist())
    assert got == set(range(len(pts)))


def _on_el_edge(half_deg: float, x: float) -> float:
    """A z with |z| exactly |(x, 0, z)| sin(half_deg) (as ``candidates`` computes them)."""
    s = np.sin(np.radians(half_deg))
    z = x * np.tan(np.radians(half_deg))
    for _ in range(400):
        lim = np.linalg.norm(np.array([[x, 0.0, z]]), axis=1)[0] * s
        if z == lim:
            return z
        z = np.nextafter(z, np.inf if z < lim else -np.inf)
    raise AssertionError("no exact edge point found")


def test_candidate_limits_are_inclusive():
    y = on_azimuth_edge(75.0)
    z = _on_el_edge(15.0, 10.0)
    pts = [[100.0, 0.0, 0.0], [0.5, 0.0, 0.0], [10.0, 10.0 * y, 0.0], [10.0, 0.0, z],
           [10.0, 0.0, -z]]
    sc = _build([((pts,), {"rcs": (0.0, 1.0), "material": WALL})])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    assert sorted(cand["ids"].tolist()) == [0, 1, 2, 3, 4]


def test_facing_cut_is_strict():
    # cos_n = n . (o - p) / r = (-0.5)(-10) / 10 = 0.5 exactly, against cos_min 0.5 and 0.49
    sc = _build([(([[10.0, 0.0, 0.0]] * 2, (-0.5, np.sqrt(0.75), 0.0)),
                  {"rcs": (0.0, 1.0), "material": WALL})])
    sc = _fixed(sc, cos_min=[0.5, 0.49])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    assert cand["ids"].tolist() == [1]


def test_candidates_within_a_metre_of_the_sensor():
    # a faced scatterer 0.6 m ahead: incidence cosine 1; a pole of radius 0.3 m whose axis is
    # 0.9 m ahead: seen on its surface 0.6 m ahead
    sc = _build([(([[0.6, 0.0, 0.0]], (-1.0, 0.0, 0.0)), {"rcs": (0.0, 1.0), "material": WALL}),
                 (([[0.9, 0.0, 0.0]],), {"rcs": (0.0, 1.0), "material": POLE, "radius": 0.3})])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    order = np.argsort(cand["ids"])
    np.testing.assert_allclose(cand["cos_n"][order][0], 1.0)
    np.testing.assert_allclose(cand["points_w"][order], [[0.6, 0.0, 0.0], [0.6, 0.0, 0.0]],
                               atol=1e-12)


def test_default_edge_band_and_its_switch():
    # 76 deg: outside the +-75 deg field of view, inside the band (margin > 1 deg)
    p = [[10.0, 10.0 * np.tan(np.radians(76.0)), 0.0]]
    sc = _build([((p,), {"rcs": (0.0, 1.0), "material": WALL})])
    geom = Geometry(ground_z=None)
    o, R = np.zeros(3), np.eye(3)
    assert len(SC.candidates(sc, geom, o, R, RADAR)["ids"]) == 1
    assert len(SC.visible(sc, geom, o, R, RADAR)["ids"]) == 1
    assert len(SC.visible(sc, geom, o, R, RADAR, edge_band=True)["ids"]) == 1
    assert len(SC.visible(sc, geom, o, R, RADAR, edge_band=False)["ids"]) == 0


def test_heading_of_a_turned_sensor():
    yaw = np.radians(-100.0)
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    # at bearings -30 and -170 deg: 70 deg either side of the heading, 60 m away
    pts = [[60 * np.cos(np.radians(b)), 60 * np.sin(np.radians(b)), 0.0] for b in (-30.0, -170.0)]
    sc = _build([((pts,), {"rcs": (0.0, 1.0), "material": WALL})])
    cand = SC.candidates(sc, Geometry(ground_z=None), np.zeros(3), R, RADAR, edge_band=False)
    assert sorted(cand["ids"].tolist()) == [0, 1]


def test_static_cell_near_the_range_limit():
    """A scatterer 99.9 m away on the near corner of its 8 m cell (centre 105.6 m away)."""
    o = np.array([72.0 - 99.9 / np.sqrt(2), 72.0 - 99.9 / np.sqrt(2), 0.0]) - 1e-3
    sc = _build([(([[72.0, 72.0, 0.0]],), {"rcs": (0.0, 1.0), "material": WALL})])
    R = np.array([[np.sqrt(0.5), -np.sqrt(0.5), 0], [np.sqrt(0.5), np.sqrt(0.5), 0], [0, 0, 1.0]])
    cand = SC.candidates(sc, Geometry(ground_z=None), o, R, RADAR, edge_band=False)
    assert cand["ids"].tolist() == [0] and cand["range"][0] < 100.0


def test_view_azimuth_from_an_offset_sensor():
    sc = _build([(([[11.0, 7.0, 1.5]],), {"rcs": (0.0, 1.0), "material": WALL})])
    sc = _fixed(sc, rcs_db=[0.0], lobe_db=[2.0], lobe_k=[3.0], lobe_phase=[0.4])
    o = np.array([1.0, 2.0, 0.5])
    cand = SC.candidates(sc, Geometry(ground_z=None), o, np.eye(3), RADAR, edge_band=False)
    view = np.arctan2(2.0 - 7.0, 1.0 - 11.0)
    np.testing.assert_allclose(cand["rcs_db"], [2.0 * np.cos(3.0 * view + 0.4)])


def test_mover_order_and_skips():
    """Movers without scatterers, inactive or out of reach do not stop the next ones; a mover
    can have primitive id 0 (no static primitive)."""
    b = SC._Builder(np.random.default_rng(0))
    for owner in (1, 2, 3):
        b.add([[1.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=owner)
    sc = b.build()
    sc = _fixed(sc, rcs_db=[0.0, 0.0, 0.0], lobe_db=[0.0, 0.0, 0.0])
    m = ((30.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (0.0, 0.0, 0.0), 0.0)
    far = ((300.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (0.0, 0.0, 0.0), 0.0)
    # mover 0: no scatterers; 1: inactive; 2: active (pid 0); 3: active (pid 1)
    geom = _geom(movers=[m, m])
    geom.mover_pid = np.array([-1, -1, 0, 1])
    cand = SC.candidates(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert sorted(cand["ids"].tolist()) == [1, 2]
    np.testing.assert_array_equal(np.sort(cand["prim"]), [0, 1])
    assert SC._box_index(geom, 0) == 0 and SC._box_index(geom, 1) == 1
    # mover 0 without scatterers first
    b = SC._Builder(np.random.default_rng(0))
    b.add([[1.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=1)
    sc1 = b.build()
    geom = _geom(movers=[m, m])
    cand = SC.candidates(sc1, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert cand["ids"].tolist() == [0]
    # a mover out of reach first
    geom = _geom(movers=[far, m])
    b = SC._Builder(np.random.default_rng(0))
    for owner in (0, 1):
        b.add([[1.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=owner)
    cand = SC.candidates(b.build(), geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert cand["ids"].tolist() == [1]


def test_mover_reach_is_from_the_sensor():
    b = SC._Builder(np.random.default_rng(0))
    b.add([[0.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=0)
    sc = b.build()
    # 95 m ahead of the sensor (within reach); the sensor itself 60 m from the origin
    m = ((155.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (0.0, 0.0, 0.0), 0.0)
    o = np.array([60.0, 0.0, 0.75])
    cand = SC.candidates(sc, _geom(movers=[m]), o, np.eye(3), RADAR, edge_band=False)
    assert cand["ids"].tolist() == [0]
    np.testing.assert_allclose(cand["range"], [95.0])


def test_mover_lobe_uses_the_view_azimuth_in_its_body_frame():
    b = SC._Builder(np.random.default_rng(0))
    b.add([[0.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=0)
    sc = _fixed(b.build(), rcs_db=[1.0], lobe_db=[3.0], lobe_k=[1.0], lobe_phase=[0.0])
    yaw = 0.7
    m = ((20.0, 5.0, 0.75), (2.0, 1.0, 0.75), yaw, (0.0, 0.0, 0.0), 0.0)
    cand = SC.candidates(sc, _geom(movers=[m]), np.zeros(3), np.eye(3), RADAR,
                         edge_band=False)
    view = np.arctan2(-5.0, -20.0) - yaw
    np.testing.assert_allclose(cand["rcs_db"], [1.0 + 3.0 * np.cos(view)])


def test_visible_fields_and_the_occlusion_tolerance_edge():
    sc = _build([(([[20.0, 0.0, 0.0], [20.0, 4.0, 0.0], [30.0, -3.0, 0.0]],
                   (-1.0, 0.0, 0.0)), {"rcs": (0.0, 1.0), "material": WALL})])
    sc = _fixed(sc, cos_min=[-1.0, 0.05, -2.0], normal=[[-0.6, -0.8, 0.0], [-0.6, 0.8, 0.0],
                                                          [0.0, 0.0, 0.0]])
    # a wall behind the first two (x = 25 .. 26) does not hide them
    geom = _geom(boxes=[((25.5, 0.0, 0.0), (0.5, 10.0, 5.0), 0.0)])
    vis = SC.visible(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert vis["ids"].tolist() == [0, 1]
    cand = SC.candidates(sc, geom, np.zeros(3), np.eye(3), RADAR, edge_band=False)
    np.testing.assert_allclose(vis["points_s"], cand["points_s"][:2])
    np.testing.assert_array_equal(vis["prim"], -1)
    np.testing.assert_allclose(vis["rcs_db"], cand["rcs_db"][:2])
    # incidence: cos_min -1 is not isotropic (only below -1)
    d0 = np.array([-20.0, 0.0, 0.0]) / 20.0
    d1 = np.array([-20.0, -4.0, 0.0]) / np.hypot(20.0, 4.0)
    np.testing.assert_allclose(vis["cos_inc"], [d0 @ [-0.6, -0.8, 0.0], d1 @ [-0.6, 0.8, 0.0]])
    # a first hit exactly at range - OCCLUSION_TOL - 1e-9 still counts as seen
    t = cand["range"] - SC.OCCLUSION_TOL - 1e-9
    assert len(SC.finish(sc, geom, np.zeros(3), cand, t)["ids"]) == 3
    # the caller's fading is passed through
    cand["fading_db"] = np.array([1.0, 2.0, 3.0])
    out = SC.finish(sc, geom, np.zeros(3), cand, np.full(3, np.inf))
    np.testing.assert_array_equal(out["fading_db"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(out["cos_inc"][2], 1.0)


def test_visible_reports_mover_velocity():
    b = SC._Builder(np.random.default_rng(0))
    b.add([[-2.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=0)  # on its rear
    sc = b.build()
    m = ((20.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (4.0, 1.0, 0.0), 0.0)
    vis = SC.visible(sc, _geom(movers=[m]), np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert vis["ids"].tolist() == [0] and vis["dynamic"].tolist() == [True]
    np.testing.assert_allclose(vis["velocity_w"], [[4.0, 1.0, 0.0]])


# ---- sampling details of boxes and vehicles ---------------------------------------------------

def _box_samples(half, seeds, **kw):
    """Faces, edges and foot of ``_box_local`` over several seeds, in the box frame."""
    out = []
    for seed in seeds:
        b = SC._Builder(np.random.default_rng(seed))
        SC._box_local(b, half, BUILDING, owner=3, face_density=0.7, face_rcs=(-3.0, 5.0),
                      edge_spacing=0.6, edge_rcs=(11.0, 4.0), base=True, **kw)
        sc = b.build()
        on_x = np.isclose(np.abs(sc.pos[:, 0]), half[0])
        on_y = np.isclose(np.abs(sc.pos[:, 1]), half[1])
        edge = on_x & on_y
        foot = (sc.aspect_exp == 0.5) & ~edge
        out.append((sc, edge, foot, ~edge & ~foot, on_x))
    return out


def test_box_faces_cover_all_four_sides_uniformly():
    hx, hy, hz = 10.0, 4.0, 5.0
    runs = _box_samples((hx, hy, hz), range(20))
    per_face = np.zeros(4)
    u_x, u_y, z_face, lobes = [], [], [], []
    for sc, _edge, foot, face, on_x in runs:
        np.testing.assert_array_equal(sc.owner, 3)
        p = sc.pos[face]
        fx = on_x[face]
        per_face += [np.sum(fx & (p[:, 0] > 0)), np.sum(fx & (p[:, 0] < 0)),
                     np.sum(~fx & (p[:, 1] > 0)), np.sum(~fx & (p[:, 1] < 0))]
        u_x.append(p[fx, 1])
        u_y.append(p[~fx, 0])
        # each face's own points spread along it and over its height (not one shared draw)
        for rows in (fx & (p[:, 0] > 0), ~fx & (p[:, 1] < 0)):
            assert p[rows, 2].std() > 0.15 * 2 * hz
        z_face.append(p[:, 2])
        lobes.append(sc.lobe_k[face])
        np.testing.assert_array_equal(sc.lobe_db[face], 4.0)
        np.testing.assert_array_equal(sc.lobe_db[foot], 3.0)
    # Poisson(0.7 x area): x faces 8 x 10 m^2 -> 56, y faces 20 x 10 m^2 -> 140
    want = np.array([56.0, 56.0, 140.0, 140.0])
    assert np.all(np.abs(per_face / 20 - want) < 4 * np.sqrt(want / 20))
    u_x, u_y, z_face, lobes = (np.concatenate(a) for a in (u_x, u_y, z_face, lobes))
    for u, h in ((u_x, hy), (u_y, hx), (z_face, hz)):
        assert u.min() < -0.95 * h and u.max() > 0.95 * h and abs(u.mean()) < 0.1 * h
        assert abs(u.std() - 2 * h / np.sqrt(12)) < 0.05 * h
    assert lobes.min() >= 2.0 and lobes.min() < 2.05 and lobes.max() < 10.0
    assert lobes.max() > 9.95


def test_box_foot_and_edges_are_jittered_slots():
    hx, hy, hz = 10.0, 4.0, 5.0
    runs = _box_samples((hx, hy, hz), range(20))
    frac, foot_u, edge_z, partial_foot, partial_edge = [], [], [], 0, 0
    corners = set()
    for sc, edge, foot, _face, _on_x in runs:
        p = sc.pos[foot]
        np.testing.assert_allclose(p[:, 2], -hz + 0.05)
        along = np.where(np.isclose(np.abs(p[:, 0]), hx), p[:, 1] + hy, p[:, 0] + hx)
        length = np.where(np.isclose(np.abs(p[:, 0]), hx), 2 * hy, 2 * hx)
        m = np.floor(length / 2.0)
        frac.append(np.mod(along / (length / m), 1.0))
        foot_u.append(np.where(np.isclose(np.abs(p[:, 0]), hx), p[:, 1] / hy, p[:, 0] / hx))
        # a long face keeps 7 of its 10 slots on average, never all-or-nothing every time
        long_face = np.isclose(p[:, 1], hy)
        partial_foot += 0 < long_face.sum() < 10
        if long_face.sum() > 2:  # each slot its own offset
            assert np.mod((p[long_face, 0] + hx) / 2.0, 1.0).std() > 0.02
        q = sc.pos[edge]
        edge_z.append(q[:, 2])
        for sx in (-1, 1):
            for sy in (-1, 1):
                k = np.sum((np.sign(q[:, 0]) == sx) & (np.sign(q[:, 1]) == sy))
                if k:
                    corners.add((sx, sy))
                if k > 2:  # each row its own offset
                    zc = q[(np.sign(q[:, 0]) == sx) & (np.sign(q[:, 1]) == sy), 2]
                    assert np.mod((zc + hz) / (2 * hz / 16), 1.0).std() > 0.02
                partial_edge += 0 < k < 16
    frac, foot_u, edge_z = (np.concatenate(a) for a in (frac, foot_u, edge_z))
    # slot offsets U(0.2, 0.8) of the slot width; slots span the whole face
    assert frac.min() >= 0.2 - 1e-9 and frac.max() <= 0.8 + 1e-9 and frac.std() > 0.1
    assert foot_u.min() < -0.85 and foot_u.max() > 0.85 and abs(foot_u.mean()) < 0.1
    # edge rows U(0.1, 0.9) of their 10 m / 16 rows over the whole height
    assert edge_z.min() < -hz + 0.3 and edge_z.max() > hz - 0.3 and abs(edge_z.mean()) < 0.3
    slot = np.mod((edge_z + hz) / (2 * hz / 16), 1.0)
    assert slot.min() >= 0.1 - 1e-9 and slot.max() <= 0.9 + 1e-9 and slot.std() > 0.1
    assert corners == {(-1, -1), (-1, 1), (1, -1), (1, 1)}
    assert partial_foot > 10 and partial_edge > 40


def test_small_box_has_one_foot_slot_and_one_edge_row_a_side():
    runs = _box_samples((1.5, 1.5, 0.2), range(40))
    feet = [int(foot.sum()) for _, _, foot, _, _ in runs]
    edges = [int(edge.sum()) for _, edge, _, _, _ in runs]
    # faces 3 m long: one slot (p 0.7) each; 0.4 m high with 0.6 m spacing: one row (p 0.8)
    assert max(feet) <= 4 and abs(np.mean(feet) - 2.8) < 0.5
    assert max(edges) <= 4 and abs(np.mean(edges) - 3.2) < 0.4


def test_place_rotates_positions_and_normals_about_the_centre():
    part = {"pos": np.array([[1.0, 0.0, 0.5], [0.0, 2.0, 0.0]]),
            "normal": np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])}
    SC._place(part, [10, 20, 1], np.pi / 2)
    np.testing.assert_allclose(part["pos"], [[10.0, 21.0, 1.5], [8.0, 20.0, 1.0]], atol=1e-12)
    np.testing.assert_allclose(part["normal"], [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]], atol=1e-12)


def test_vehicle_parts_statistics_over_many_cars():
    b = SC._Builder(np.random.default_rng(3))
    half = (2.25, 0.9, 0.75)
    for k in range(300):
        SC._vehicle(b, half, CAR, k)
    sc = b.build()
    wheels = np.isclose(sc.pos[:, 2], -0.75 + 0.35) & np.isclose(np.abs(sc.pos[:, 1]), 0.9) \
        & np.isclose(np.abs(sc.pos[:, 0]), 1.5)
    bump = np.isclose(sc.pos[:, 2], -0.75 + 0.55) & np.isclose(np.abs(sc.pos[:, 0]), 2.25) \
        & (sc.cos_min == 0.1)
    assert wheels.sum() == 1200 and bump.sum() == 1800
    np.testing.assert_array_equal(sc.aspect_exp[wheels], 0.0)
    np.testing.assert_array_equal(sc.aspect_exp[bump], 1.0)
    assert np.sum(sc.pos[bump, 0] > 0) == 900
    for rows, mean in ((wheels, 3.0), (bump, 5.0)):
        assert abs(sc.rcs_db[rows].mean() - mean) < 0.3
        assert abs(sc.rcs_db[rows].std() - 3.0) < 0.3
    body = ~wheels & ~bump
    # the body's faces and edges span from 0.25 m above the bottom to the top
    assert sc.pos[body, 2].min() < -0.75 + 0.3 and sc.pos[body, 2].max() > 0.7


def test_a_mover_beside_an_empty_static_sector():
    b = SC._Builder(np.random.default_rng(0))
    b.add([[500.0, 500.0, 0.0]], None, rcs=(0.0, 1.0), material=WALL)  # far static
    b.add([[-2.0, 0.0, 0.0]], None, rcs=(0.0, 1.0), material=CAR, owner=0)
    sc = b.build()
    m = ((20.0, 0.0, 0.75), (2.0, 1.0, 0.75), 0.0, (0.0, 0.0, 0.0), 0.0)
    assert sc.static_in_sector(np.zeros(2), 0.0, 1.0, 100.0).dtype == np.int64
    cand = SC.candidates(sc, _geom(movers=[m]), np.zeros(3), np.eye(3), RADAR, edge_band=False)
    assert cand["ids"].tolist() == [1]


def test_large_cylinders_are_walls_with_features_on_their_surface():
    from loaders.synthetic.scenes import Scene

    motion = SyntheticSequence("tunnel", "lidar-dense", 1, seed=1).motion
    cyl = [(0.0, 40.0, 20.0, 0.0, 5.0, WALL), (30.0, -40.0, 1.5, 1.0, 4.0, WALL)]
    counts = []
    for seed in range(10):
        scene = Scene("test", motion, vcylinders=cyl)
        sc = build_scatterers_of(scene, seed)
        for k, (cx, cy, r, z0, z1, mat) in enumerate(cyl):
            mine = np.flatnonzero(sc.prim == k)
            counts.append(len(mine))
            radial = np.hypot(sc.pos[mine, 0] - cx, sc.pos[mine, 1] - cy)
            np.testing.assert_allclose(radial, r)
            assert sc.pos[mine, 2].min() >= z0 and sc.pos[mine, 2].max() <= z1
            np.testing.assert_array_equal(sc.material[mine], mat)
            np.testing.assert_array_equal(sc.normal[mine], 0.0)  # seen from either side
            np.testing.assert_array_equal(sc.swerling[mine], 1)
            np.testing.assert_array_equal(sc.lobe_db[mine], 4.0)
            np.testing.assert_array_equal(sc.radius[mine], 0.0)
            assert np.all((sc.lobe_k[mine] >= 2.0) & (sc.lobe_k[mine] < 10.0))
            ang = np.arctan2(sc.pos[mine, 1] - cy, sc.pos[mine, 0] - cx)
            if k == 0:  # uniform around the axis and over the height
                assert abs(np.mean(np.cos(ang))) < 0.15 and abs(np.mean(np.sin(ang))) < 0.15
                assert abs(sc.pos[mine, 2].std() - (z1 - z0) / np.sqrt(12)) < 0.1
    # Poisson(0.8 / m^2 x 2 pi r h): 502.7 on the large one, 22.6 on the small one
    big, small = np.array(counts[0::2]), np.array(counts[1::2])
    assert abs(big.mean() - 0.8 * 2 * np.pi * 20.0 * 5.0) < 4 * np.sqrt(502.7 / 10)
    assert abs(small.mean() - 0.8 * 2 * np.pi * 1.5 * 3.0) < 4 * np.sqrt(22.6 / 10)


def build_scatterers_of(scene, seed):
    return SC.build_scatterers(scene, np.random.default_rng(seed))


def test_tunnel_sampling_known_answers():
    from loaders.synthetic.raycast import Tunnel

    tun = Tunnel(axis_y=0.0, axis_z=2.0, radius=6.0, x0=0.0, x1=600.0, rib_spacing=0.5,
                 rib_width=0.3, rib_depth=0.3)
    b = SC._Builder(np.random.default_rng(11))
    SC._tunnel(b, tun)
    sc = b.build()
    rib, wall = sc.material == RIB, sc.material == TUNNEL_WALL
    # ribs every 0.5 m (1,200 rings), ring points on the grid 2 pi k / 59 (5.7 m / 0.6 m)
    n_ring = int(2 * np.pi * 5.7 / 0.6)
    assert n_ring == 59
    assert len(np.unique(np.round(sc.pos[rib, 0], 6))) == 1200
    ang = np.arctan2(sc.pos[rib, 2] - 2.0, sc.pos[rib, 1])
    k = np.mod(ang, 2 * np.pi) / (2 * np.pi / n_ring)
    np.testing.assert_allclose(k, np.round(k), atol=1e-6)
    ring0 = np.isclose(sc.pos[:, 0], 0.15) & rib
    assert len(np.unique(np.round(sc.pos[ring0], 6), axis=0)) == ring0.sum()
    np.testing.assert_array_equal(sc.lobe_db[rib], 2.0)
    assert abs(sc.rcs_db[rib].mean() - 2.0) < 0.1 and abs(sc.rcs_db[rib].std() - 4.0) < 0.1
    # wall features: Poisson(0.05 / m^2) over the tube, angles uniform, those above 0.1 m
    a = np.mod(np.arctan2(sc.pos[wall, 2] - 2.0, sc.pos[wall, 1]), 2 * np.pi)
    above = np.pi + 2 * np.arcsin(1.9 / 6.0)  # the arc above z = 0.1
    n_all = 0.05 * 2 * np.pi * 6.0 * 600.0
    assert abs(wall.sum() - n_all * above / (2 * np.pi)) < 4 * np.sqrt(n_all)
    lower = np.mean(a > np.pi)  # the two short arcs below the axis
    assert abs(lower - (above - np.pi) / above) < 0.03
    assert np.mean(a < 1.0) > 0.6 / above
    assert sc.pos[wall, 2].min() < 0.3 and sc.pos[wall, 2].min() > 0.1
    np.testing.assert_array_equal(sc.swerling[wall], 1)
    assert abs(sc.rcs_db[wall].mean() + 8.0) < 0.3 and abs(sc.rcs_db[wall].std() - 5.0) < 0.25
    np.testing.assert_array_equal(sc.prim[rib | wall], TUNNEL_ID)


def test_ground_features_and_kerbs_of_a_campus():
    from scipy.spatial import cKDTree

    campus = _campus()
    scene, sc = campus.scene_model, campus.scatterers
    ground = (sc.prim == GROUND_ID) & (sc.pos[:, 2] == 0.0)
    kerb = (sc.prim == GROUND_ID) & (sc.pos[:, 2] == 0.08)
    np.testing.assert_array_equal(sc.cos_min[ground], -1.0)
    np.testing.assert_array_equal(sc.aspect_exp[ground], 0.0)
    np.testing.assert_array_equal(sc.swerling[ground], 1)
    np.testing.assert_array_equal(sc.lobe_db[ground], 4.0)
    assert sc.lobe_k[ground].min() >= 2.0 and sc.lobe_k[ground].max() < 10.0
    assert sc.lobe_k[ground].min() < 2.5 and sc.lobe_k[ground].max() > 9.5
    np.testing.assert_array_equal(sc.cos_min[kerb], -0.2)
    np.testing.assert_array_equal(sc.aspect_exp[kerb], 0.0)
    np.testing.assert_array_equal(sc.lobe_db[kerb], 3.0)
    np.testing.assert_array_equal(sc.swerling[kerb], 3)
    m = campus.motion
    lo, hi = m.sigma_span
    sig = np.arange(lo + 1.0, hi - 1.0, 1.0)
    st = m.planar_state(m.time_at_arclength(sig))
    path = np.column_stack([st["x"], st["y"]])
    # kerbs: each metre of path, each side, kept with p 1 / 1.5
    assert abs(kerb.sum() - 2 * len(sig) / 1.5) < 4 * np.sqrt(2 * len(sig) * 0.22)
    idx = cKDTree(path).query(sc.pos[kerb, :2])[1]
    tang = np.column_stack([np.cos(st["yaw"]), np.sin(st["yaw"])])[idx]
    off = sc.pos[kerb, :2] - path[idx]
    side = np.sign(tang[:, 0] * off[:, 1] - tang[:, 1] * off[:, 0])
    assert abs(np.mean(side > 0) - 0.5) < 0.05
    # ground features: Poisson(0.05 / m^2) over the ground within 60 m of the path and outside
    # every box (area counted on a 1 m grid)
    x0, y0 = path.min(axis=0) - 60.0
    x1, y1 = path.max(axis=0) + 60.0
    gx, gy = np.meshgrid(np.arange(x0, x1, 1.0) + 0.5, np.arange(y0, y1, 1.0) + 0.5)
    g = np.column_stack([gx.ravel(), gy.ravel()])
    free = cKDTree(path).query(g, distance_upper_bound=60.0)[0] <= 60.0
    for center, half, yaw, _ in scene.boxes:
        q = _box_frame(np.column_stack([g, np.zeros(len(g))]), center, yaw)
        free &= ~((np.abs(q[:, 0]) < half[0]) & (np.abs(q[:, 1]) < half[1]))
    want = 0.05 * free.sum()
    assert abs(ground.sum() - want) < 4 * np.sqrt(want) + 0.01 * want


def test_pedestrians_poles_and_crowns_of_a_campus():
    campus = _campus()
    scene, sc = campus.scene_model, campus.scatterers
    from loaders.synthetic.scenes import PEDESTRIAN

    n_ped = 0
    for i, mv in enumerate(scene.movers):
        if mv.material != PEDESTRIAN:
            continue
        n_ped += 1
        mine = sc.of_mover(i)
        hz = mv.half[2]
        # torso and legs on the body axis, seen on the cylinder of the body's half width
        np.testing.assert_allclose(np.sort(sc.pos[mine, 2]), [-0.5 * hz, 0.3 * hz])
        np.testing.assert_array_equal(sc.pos[mine, :2], 0.0)
        np.testing.assert_allclose(sc.radius[mine], max(mv.half[:2]))
        np.testing.assert_array_equal(sc.swerling[mine], 1)
        np.testing.assert_array_equal(sc.lobe_db[mine], 3.0)
    assert n_ped > 0
    pid0 = len(scene.boxes)
    base, top = [], []
    for k, (_, _, _, _, _, mat) in enumerate(scene.vcylinders):
        if mat != POLE:
            continue
        mine = np.flatnonzero(sc.prim == pid0 + k)
        z = sc.pos[mine, 2]
        base.append(sc.rcs_db[mine[np.argmin(z)]])
        top.append(sc.rcs_db[mine[np.argmax(z)]])
    # the base dihedral N(12, 3) dBsm, the lamp N(9, 3): spread, not constant
    base, top = np.array(base), np.array(top)
    assert len(base) >= 5 and base.std() > 1.0
    assert abs(base.mean() - 12.0) < 4 * 3 / np.sqrt(len(base))
    assert abs(top.mean() - 9.0) < 4 * 3 / np.sqrt(len(top))
    # crowns: Poisson(2 / m^2 x 4 pi r^2) each
    pid1 = pid0 + len(scene.vcylinders)
    want = sum(2.0 * 4 * np.pi * r * r for _, r, _ in scene.spheres)
    got = np.sum((sc.prim >= pid1) & (sc.prim < pid1 + len(scene.spheres)))
    assert abs(got - want) < 4 * np.sqrt(want)
