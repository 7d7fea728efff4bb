"""Known answers of the scattering-centre sampler (loaders/synthetic/scatterers.py) on hand-made
scenes: a path given by closed-form planar states (a straight line or a circle), boxes placed by
hand, so that the kerbs' geometry and the box-footprint exclusion are checked against geometry
worked out independently.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from loaders.synthetic import scatterers as SC
from loaders.synthetic.raycast import GROUND_ID
from loaders.synthetic.scenes import BUILDING, CROWN, GROUND, PEDESTRIAN, WALL


class _Path:
    """A path at unit speed (t = arc length): a straight line along x (radius None) or a
    left-turning circle of ``radius`` starting at the origin heading +x."""

    def __init__(self, lo: float, hi: float, radius: float | None = None) -> None:
        self.sigma_span = (lo, hi)
        self.radius = radius

    def time_at_arclength(self, sigma):
        return np.asarray(sigma, float)

    def planar_state(self, t):
        t = np.asarray(t, float)
        if self.radius is None:
            return {"x": t, "y": np.zeros_like(t), "yaw": np.zeros_like(t)}
        r = self.radius
        return {"x": r * np.sin(t / r), "y": r * (1.0 - np.cos(t / r)), "yaw": t / r}


def _scene(name, path, boxes=()):
    return SimpleNamespace(name=name, motion=path, boxes=list(boxes), vcylinders=[], spheres=[],
                           tunnel=None, movers=[])


def _ground(scene, seed=0) -> SC.Scatterers:
    b = SC._Builder(np.random.default_rng(seed))
    SC._ground(b, scene)
    return b.build()


def _kerbs(sc: SC.Scatterers) -> np.ndarray:
    """Kerb stones: the ground scatterers above the ground plane."""
    return np.flatnonzero((sc.prim == GROUND_ID) & (sc.pos[:, 2] > 0.0))


def test_kerbs_on_a_turning_loop_face_the_road():
    # a circle of radius 40 m (yaw turns through 2.5 rad): every kerb lies beside the path and
    # its outward normal points back towards the nearest path point (the road side)
    path = _Path(0.0, 100.0, radius=40.0)
    sc = _ground(_scene("loop", path))
    kerbs = _kerbs(sc)
    assert len(kerbs) > 50
    np.testing.assert_allclose(sc.material[kerbs], GROUND)
    s = np.linspace(0.0, 100.0, 100001)
    st = path.planar_state(s)
    xy = np.column_stack([st["x"], st["y"]])
    p = sc.pos[kerbs, :2]
    nearest = xy[np.argmin(((p[:, None, :] - xy[None, ::50, :]) ** 2).sum(-1), axis=1) * 50]
    to_road = nearest - p
    to_road /= np.linalg.norm(to_road, axis=1, keepdims=True)
    n = sc.normal[kerbs, :2]
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.einsum("ij,ij->i", n, to_road), 1.0, atol=1e-3)
    # kerbs on both sides: on the circle's inside (nearer the centre) and outside
    r = np.hypot(p[:, 0], p[:, 1] - 40.0)
    assert (r < 40.0).any() and (r > 40.0).any()
    np.testing.assert_allclose(np.abs(r - 40.0), np.abs(r - 40.0)[0], atol=1e-6)


def test_kerbs_only_in_the_urban_scenes():
    path = _Path(0.0, 60.0)
    for name in ("loop", "campus"):
        assert len(_kerbs(_ground(_scene(name, path)))) > 0, name
    for name in ("straight-wall", "tunnel", "curved-wall"):
        assert len(_kerbs(_ground(_scene(name, path)))) == 0, name


def _inside_rotated(p, center, half, yaw):
    """Points strictly inside a rectangle (half sizes ``half``) rotated by ``yaw`` about
    ``center``: rotate the points by -yaw into the box frame."""
    c, s = np.cos(-yaw), np.sin(-yaw)
    q = (p - center) @ np.array([[c, -s], [s, c]]).T
    return (np.abs(q[:, 0]) < half[0]) & (np.abs(q[:, 1]) < half[1])


def test_no_ground_feature_inside_a_rotated_box_footprint():
    # the same RNG draws with and without a box (the exclusion draws nothing): the features
    # removed by the box are exactly those inside its rotated footprint
    path = _Path(0.0, 300.0)
    center, half, yaw = np.array([150.0, 20.0, 4.0]), np.array([40.0, 12.0, 4.0]), 0.6
    free = _ground(_scene("straight-wall", path), seed=4)
    boxed = _ground(_scene("straight-wall", path, [(center, half, yaw, BUILDING)]), seed=4)
    p = free.pos[:, :2]
    inside = _inside_rotated(p, center[:2], half[:2], yaw)
    assert inside.sum() > 50  # the footprint is 1920 m^2 at 0.05 features / m^2
    np.testing.assert_allclose(boxed.pos[:, :2], p[~inside])


def _edges(sc: SC.Scatterers) -> np.ndarray:
    """Vertical-edge scatterers of a box: the only ones visible from behind their diagonal
    normal (cos_min = -0.7, scatterers.py's _box_local)."""
    return np.flatnonzero(np.isclose(sc.cos_min, -0.7))


def test_building_boxes_get_building_edges_and_base_wall_boxes_do_not():
    # a tall building and an equal wall: the module's per-material table (EDGE_RCS) gives the
    # mean edge RCS of each; a building also has the wall-ground dihedral line (BASE_RCS)
    path = _Path(0.0, 10.0)
    half = np.array([10.0, 10.0, 15.0])
    out = {}
    for mat in (BUILDING, WALL):
        scene = _scene("straight-wall", path, [(np.array([0.0, 30.0, 15.0]), half, 0.3, mat)])
        sc = SC.build_scatterers(scene, np.random.default_rng(1))
        box = np.flatnonzero(sc.prim == 0)
        assert len(box) > 0
        np.testing.assert_allclose(sc.material[box], mat)
        out[mat] = (sc, box)
    for mat, (sc, box) in out.items():
        edges = _edges(sc)
        mean, std = SC.EDGE_RCS[mat]
        assert len(edges) > 20
        # mean of n normals: within 4 standard errors of the table's mean
        assert abs(sc.rcs_db[edges].mean() - mean) < 4 * std / np.sqrt(len(edges)), mat
        n_base = np.sum(np.isclose(sc.pos[box, 2], 0.05))  # foot of the facade, z = 0.05 m
        assert (n_base > 0) == (mat == BUILDING), mat


def test_crown_scatterers_facing_the_sensor_are_visible():
    # Scatterers: visible when cos(normal, towards sensor) > cos_min; vegetation on a crown
    # (outward normals) faces the sensor on its near side, so cos = 1 there must be visible
    scene = _scene("straight-wall", _Path(0.0, 10.0))
    centre = np.array([0.0, 20.0, 5.0])
    scene.spheres = [(centre, 2.5, CROWN)]
    sc = SC.build_scatterers(scene, np.random.default_rng(2))
    crown = np.flatnonzero(sc.material == CROWN)
    assert len(crown) > 50  # about 2 per m^2 of a 78.5 m^2 crown surface
    np.testing.assert_allclose(sc.normal[crown], (sc.pos[crown] - centre) / 2.5, atol=1e-9)
    assert (sc.cos_min[crown] < 1.0).all()


def test_pedestrians_are_weak_radar_targets():
    # a pedestrian's RCS at 77 GHz is measured around -15 to 0 dBsm (far below a car's ~10
    # dBsm): the incoherent sum of a pedestrian's scatterers stays below a few dBsm
    scene = _scene("straight-wall", _Path(0.0, 10.0))
    scene.movers = [SimpleNamespace(half=(0.3, 0.3, 0.9), material=PEDESTRIAN)
                    for _ in range(200)]
    sc = SC.build_scatterers(scene, np.random.default_rng(3))
    ped = np.flatnonzero(sc.owner >= 0)
    assert (sc.material[ped] == PEDESTRIAN).all()
    total = np.zeros(200)
    np.add.at(total, sc.owner[ped], 10.0 ** (sc.rcs_db[ped] / 10.0))
    assert np.median(10.0 * np.log10(total)) < 3.0
