"""Persistent radar scattering centres: sampled once per scene, seen frame after frame.

Real automotive radar detections come mostly from discrete scattering centres that persist
from scan to scan (building corners and facade features, poles, trunks, car bodies, fences,
kerbs) plus a smaller share of diffuse returns. ``build_scatterers`` samples such centres
deterministically (from its own RNG stream) on the surfaces of a ``Scene``:

- static objects: world-fixed points with an RCS [dBsm] drawn per object type: vertical
  building edges and the wall-ground dihedral line (strong), facade features (medium), fence
  posts and wall features, poles (strong, with a strong base dihedral) and tree trunks,
  vegetation on crown surfaces (weak and numerous, strongly fluctuating), sparse weak ground
  features and kerbs, tunnel ribs;
- movers (cars, trucks, pedestrians): points fixed in the mover's body frame (relative to its
  box centre, before its yaw), so they move rigidly with it and their Doppler includes the
  object's velocity.

Per scatterer: ``normal`` (outward, same frame as ``pos``; zero = isotropic) with a visibility
cosine ``cos_min`` (back-facing scatterers are skipped), ``aspect_exp`` (RCS loss
``aspect_exp * 10 log10(cos)`` with the incidence cosine), ``radius`` (> 0: a point on the axis
of a vertical cylinder whose visible centre is the surface point facing the sensor), and an
aspect lobe pattern ``lobe_db * cos(lobe_k * view_azimuth + lobe_phase)`` (slow RCS variation
with the viewing direction). ``swerling`` is 1 (many comparable scatterers: vegetation, facade
texture) or 3 (one dominant reflector plus small ones: corners, poles, car bodies). ``bias``
holds standard normals scaled by the sensor's ``sigma_bias_deg``: a persistent angle error of
each scatterer (array calibration, multipath), the same in every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from loaders.synthetic.raycast import GROUND_ID, TUNNEL_ID
from loaders.synthetic.scenes import (
    BUILDING,
    CAR,
    GROUND,
    PEDESTRIAN,
    POLE,
    RIB,
    TRUCK,
    TUNNEL_WALL,
    WALL,
    Scene,
)
from loaders.synthetic.sensors import detection_margin_deg

# per-material sampling: face density [1/m^2], face RCS mean/std [dBsm], edge spacing [m],
# edge RCS mean/std [dBsm]
FACE_DENSITY = {BUILDING: 0.7, WALL: 0.8, CAR: 1.0, TRUCK: 0.8}
FACE_RCS = {BUILDING: (-3.0, 5.0), WALL: (-5.0, 5.0), CAR: (-5.0, 5.0), TRUCK: (-3.0, 5.0)}
EDGE_SPACING = {BUILDING: 0.6, WALL: 1.5, CAR: 0.5, TRUCK: 0.6}
EDGE_RCS = {BUILDING: (11.0, 4.0), WALL: (4.0, 4.0), CAR: (4.0, 4.0), TRUCK: (7.0, 4.0)}
BASE_RCS = (8.0, 4.0)  # wall-ground dihedral at the foot of building facades
CROWN_DENSITY, CROWN_RCS = 2.0, (-13.0, 5.0)
GROUND_DENSITY, GROUND_RCS, GROUND_HALF_WIDTH = 0.05, (-12.0, 5.0), 60.0
KERB_OFFSET, KERB_SPACING, KERB_RCS = 5.4, 1.5, (-7.0, 4.0)
GRID_CELL, GRID_STRIDE = 8.0, 1 << 32  # [m] horizontal grid of the static scatterers


@dataclass
class Scatterers:
    pos: np.ndarray  # (N, 3) world (owner -1) or mover body frame (owner >= 0) [m]
    normal: np.ndarray  # (N, 3) outward normal, same frame; zero = isotropic
    cos_min: np.ndarray  # (N,) visible when cos(normal, towards sensor) > cos_min
    aspect_exp: np.ndarray  # (N,)
    radius: np.ndarray  # (N,) > 0: cylinder axis point (visible centre on the surface)
    rcs_db: np.ndarray  # (N,) [dBsm]
    lobe_db: np.ndarray  # (N,) aspect lobe amplitude [dB]
    lobe_k: np.ndarray  # (N,) lobes per radian of viewing azimuth
    lobe_phase: np.ndarray  # (N,)
    swerling: np.ndarray  # (N,) 1 or 3
    material: np.ndarray  # (N,) material id (scenes.MATERIAL_NAMES)
    owner: np.ndarray  # (N,) -1 static, else mover index
    prim: np.ndarray  # (N,) static: primitive id in Scene.geometry (or GROUND_ID / TUNNEL_ID)
    bias: np.ndarray  # (N, 2) standard normals: the persistent (azimuth, elevation) angle bias

    def __len__(self) -> int:
        return len(self.rcs_db)

    def finalize(self) -> Scatterers:
        """Index the static scatterers on a horizontal grid and group the movers' ones."""
        static = np.flatnonzero(self.owner < 0)
        cell = np.floor(self.pos[static, :2] / GRID_CELL).astype(np.int64)
        key = cell[:, 0] * GRID_STRIDE + cell[:, 1]
        order = np.argsort(key, kind="stable")
        self._static_sorted = static[order]
        self._cell_keys, self._cell_start, counts = np.unique(
            key[order], return_index=True, return_counts=True)
        self._cell_end = self._cell_start + counts
        order = np.argsort(self.owner, kind="stable")
        owners = self.owner[order]
        self._mover_order = order
        self._mover_bounds = {int(m): (int(np.searchsorted(owners, m)),
                                       int(np.searchsorted(owners, m, side="right")))
                              for m in np.unique(owners[owners >= 0])}
        return self

    def static_in_sector(self, xy: np.ndarray, heading: float, half_angle: float,
                         radius: float) -> np.ndarray:
        """Ids of the static scatterers in the grid cells that overlap the horizontal sector
        (apex ``xy``, direction ``heading``, +-``half_angle`` [rad], ``radius`` [m]): a
        superset of the scatterers in the sector."""
        if not len(self._cell_keys):
            return np.zeros(0, np.int64)
        lo = np.floor((xy - radius) / GRID_CELL).astype(np.int64)
        hi = np.floor((xy + radius) / GRID_CELL).astype(np.int64)
        cx, cy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1),
                             indexing="ij")
        cx, cy = cx.ravel(), cy.ravel()
        d = np.column_stack([(cx + 0.5) * GRID_CELL - xy[0], (cy + 0.5) * GRID_CELL - xy[1]])
        dist = np.hypot(d[:, 0], d[:, 1])
        half_diag = GRID_CELL / np.sqrt(2.0)
        rel = np.angle(np.exp(1j * (np.arctan2(d[:, 1], d[:, 0]) - heading)))
        margin = np.arcsin(np.clip(half_diag / np.maximum(dist, 1e-9), 0.0, 1.0))
        ok = (dist <= radius + half_diag) & ((dist <= half_diag)
                                             | (np.abs(rel) <= half_angle + margin))
        keys = cx[ok] * GRID_STRIDE + cy[ok]
        pos = np.minimum(np.searchsorted(self._cell_keys, keys), len(self._cell_keys) - 1)
        pos = pos[self._cell_keys[pos] == keys]
        starts, ends = self._cell_start[pos], self._cell_end[pos]
        n = ends - starts
        if not n.sum():
            return np.zeros(0, np.int64)
        idx = np.repeat(starts - np.concatenate([[0], np.cumsum(n)[:-1]]), n) + np.arange(n.sum())
        return self._static_sorted[idx]

    def of_mover(self, mover: int) -> np.ndarray:
        lo, hi = self._mover_bounds.get(int(mover), (0, 0))
        return self._mover_order[lo:hi]


class _Builder:
    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.parts: list[dict] = []

    def add(self, pos, normal=None, *, rcs, material, owner=-1, prim=-1, cos_min=0.05,
            aspect_exp=1.0, radius=0.0, lobe_db=3.0, lobe_k=(1.0, 6.0), swerling=3) -> None:
        pos = np.asarray(pos, float).reshape(-1, 3)
        n = len(pos)
        if n == 0:
            return
        rng = self.rng
        if normal is None:  # isotropic: always facing the sensor, no incidence loss
            normal, cos_min, aspect_exp = np.zeros((n, 3)), -2.0, 0.0
        else:
            normal = np.broadcast_to(np.asarray(normal, float), (n, 3)).copy()
        self.parts.append({
            "pos": pos, "normal": normal, "cos_min": np.full(n, float(cos_min)),
            "aspect_exp": np.full(n, float(aspect_exp)), "radius": np.broadcast_to(
                np.asarray(radius, float), (n,)).copy(),
            "rcs_db": rng.normal(rcs[0], rcs[1], n), "lobe_db": np.full(n, float(lobe_db)),
            "lobe_k": rng.uniform(lobe_k[0], lobe_k[1], n),
            "lobe_phase": rng.uniform(0.0, 2 * np.pi, n), "swerling": np.full(n, swerling),
            "material": np.full(n, material), "owner": np.full(n, owner),
            "prim": np.full(n, prim), "bias": rng.normal(size=(n, 2))})

    def build(self) -> Scatterers:
        keys = ("pos", "normal", "cos_min", "aspect_exp", "radius", "rcs_db", "lobe_db",
                "lobe_k", "lobe_phase", "swerling", "material", "owner", "prim", "bias")
        if not self.parts:
            empty = {k: np.zeros((0, 3) if k in ("pos", "normal") else 0) for k in keys}
            empty["bias"] = np.zeros((0, 2))
            for k in ("material", "owner", "swerling", "prim"):
                empty[k] = empty[k].astype(np.int64)
            return Scatterers(**empty).finalize()
        cat = {k: np.concatenate([p[k] for p in self.parts]) for k in keys}
        for k in ("material", "owner", "swerling", "prim"):
            cat[k] = cat[k].astype(np.int64)
        return Scatterers(**cat).finalize()


def _box_local(b: _Builder, half, material, *, owner, face_density, face_rcs, edge_spacing,
               edge_rcs, base=False, zmin=0.0):
    """Scatterers of a box in its own frame (centre at the origin, before yaw): vertical faces,
    vertical edges and (``base``) the wall-ground dihedral line. Returns nothing; positions are
    local and transformed by the caller through ``b.parts``."""
    rng = b.rng
    hx, hy, hz = half
    z_lo = -hz + zmin
    for axis, sign in ((0, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)):
        length = 2 * (hy if axis == 0 else hx)
        area = length * (hz - z_lo)
        n = int(rng.poisson(face_density * area))
        u = rng.uniform(-length / 2, length / 2, n)
        z = rng.uniform(z_lo, hz, n)
        pos = np.zeros((n, 3))
        pos[:, axis] = sign * (hx if axis == 0 else hy)
        pos[:, 1 - axis] = u
        pos[:, 2] = z
        nrm = np.zeros(3)
        nrm[axis] = sign
        b.add(pos, nrm, rcs=face_rcs, material=material, owner=owner, swerling=1,
              lobe_db=4.0, lobe_k=(2.0, 10.0))
        if base:  # wall-ground dihedral: strong, along the foot of the facade
            m = max(1, int(length / 2.0))
            u = (np.arange(m) + rng.uniform(0.2, 0.8, m)) * length / m - length / 2
            pos = np.zeros((m, 3))
            pos[:, axis] = sign * (hx if axis == 0 else hy)
            pos[:, 1 - axis] = u
            pos[:, 2] = -hz + 0.05
            keep = rng.uniform(size=m) < 0.7
            b.add(pos[keep], nrm, rcs=BASE_RCS, material=material, owner=owner,
                  aspect_exp=0.5, lobe_db=3.0)
    for sx in (-1.0, 1.0):
        for sy in (-1.0, 1.0):
            m = max(1, int((hz - z_lo) / edge_spacing))
            z = z_lo + (np.arange(m) + rng.uniform(0.1, 0.9, m)) * (hz - z_lo) / m
            keep = rng.uniform(size=m) < 0.8
            pos = np.column_stack([np.full(m, sx * hx), np.full(m, sy * hy), z])[keep]
            nrm = np.array([sx, sy, 0.0]) / np.sqrt(2.0)
            b.add(pos, nrm, rcs=edge_rcs, material=material, owner=owner, cos_min=-0.7,
                  aspect_exp=0.0, lobe_db=2.0)


def _place(part: dict, center, yaw) -> None:
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    part["pos"] = part["pos"] @ R.T + np.asarray(center, float)
    part["normal"] = part["normal"] @ R.T


def _vehicle(b: _Builder, half, material, owner) -> None:
    """Car / truck body (box faces and rounded corners) plus wheel houses and bumpers."""
    _box_local(b, half, material, owner=owner, face_density=FACE_DENSITY[material],
               face_rcs=FACE_RCS[material], edge_spacing=EDGE_SPACING[material],
               edge_rcs=EDGE_RCS[material], zmin=0.25)
    hx, hy, hz = half
    wheels = np.array([[sx * (hx - 0.75), sy * hy, -hz + 0.35]
                       for sx in (-1.0, 1.0) for sy in (-1.0, 1.0)])
    b.add(wheels, np.column_stack([np.zeros(4), np.sign(wheels[:, 1]), np.zeros(4)]),
          rcs=(3.0, 3.0), material=material, owner=owner, cos_min=-0.3, aspect_exp=0.0)
    for sx in (-1.0, 1.0):  # bumper / licence plate / rear lights: strong, facing +-x
        m = 3
        pos = np.column_stack([np.full(m, sx * hx), np.linspace(-0.6 * hy, 0.6 * hy, m),
                               np.full(m, -hz + 0.55)])
        b.add(pos, np.array([sx, 0.0, 0.0]), rcs=(5.0, 3.0), material=material, owner=owner,
              cos_min=0.1, aspect_exp=1.0)


def build_scatterers(scene: Scene, rng: np.random.Generator) -> Scatterers:
    """Sample the scattering centres of ``scene`` (deterministic from ``rng``)."""
    b = _Builder(rng)
    pid = 0  # primitive ids in the order of Scene.geometry: boxes, cylinders, spheres
    for center, half, yaw, mat in scene.boxes:
        start = len(b.parts)
        if mat in (CAR, TRUCK):
            _vehicle(b, tuple(half), mat, -1)
        else:
            key = mat if mat in FACE_DENSITY else WALL
            _box_local(b, tuple(half), mat, owner=-1, face_density=FACE_DENSITY[key],
                       face_rcs=FACE_RCS[key], edge_spacing=EDGE_SPACING[key],
                       edge_rcs=EDGE_RCS[key], base=mat == BUILDING)
        for part in b.parts[start:]:
            _place(part, center, yaw)
            part["prim"][:] = pid
        pid += 1
    for cx, cy, r, z0, z1, mat in scene.vcylinders:
        h = z1 - z0
        if r > 1.0:  # large cylinder: a wall (seen from either side), features on its surface
            n = int(rng.poisson(FACE_DENSITY[WALL] * 2 * np.pi * r * h))
            ang, z = rng.uniform(0, 2 * np.pi, n), rng.uniform(z0, z1, n)
            pos = np.column_stack([cx + r * np.cos(ang), cy + r * np.sin(ang), z])
            b.add(pos, None, rcs=FACE_RCS[WALL], material=mat, prim=pid, swerling=1,
                  lobe_db=4.0, lobe_k=(2.0, 10.0))
        elif mat == POLE:  # base dihedral, a few features, the lamp / sign on top
            zs = np.concatenate([[z0 + 0.15], rng.uniform(z0 + 1.0, z1 - 0.5,
                                                          int(rng.integers(1, 4))), [z1 - 0.2]])
            rcs = np.concatenate([[12.0], np.full(len(zs) - 2, 5.0), [9.0]])
            pos = np.column_stack([np.full(len(zs), cx), np.full(len(zs), cy), zs])
            b.add(pos, None, rcs=(0.0, 3.0), material=mat, prim=pid, radius=r, lobe_db=1.5,
                  lobe_k=(0.5, 3.0))
            b.parts[-1]["rcs_db"] += rcs
        else:  # tree trunk (below the crown): base and a few bark features
            top = z0 + min(h, 3.0)
            zs = np.concatenate([[z0 + 0.2], rng.uniform(z0 + 0.6, top, int(rng.integers(1, 4)))])
            pos = np.column_stack([np.full(len(zs), cx), np.full(len(zs), cy), zs])
            b.add(pos, None, rcs=(1.0, 4.0), material=mat, prim=pid, radius=r, lobe_db=2.0,
                  lobe_k=(1.0, 5.0))
        pid += 1
    for center, r, mat in scene.spheres:  # vegetation: weak, numerous, strongly fluctuating
        n = int(rng.poisson(CROWN_DENSITY * 4 * np.pi * r * r))
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        b.add(np.asarray(center) + r * v, v, rcs=CROWN_RCS, material=mat, prim=pid,
              cos_min=0.1, aspect_exp=0.5, swerling=1, lobe_db=6.0, lobe_k=(4.0, 15.0))
        pid += 1
    _ground(b, scene)
    if scene.tunnel is not None:
        _tunnel(b, scene.tunnel)
    for i, m in enumerate(scene.movers):
        start = len(b.parts)
        if m.material == PEDESTRIAN:  # torso and legs: the visible side of the body
            hz = m.half[2]
            b.add([[0.0, 0.0, 0.3 * hz], [0.0, 0.0, -0.5 * hz]], None, rcs=(-7.0, 3.0),
                  material=m.material, radius=max(m.half[:2]), swerling=1, lobe_db=3.0)
        else:
            _vehicle(b, m.half, m.material, i)
        for part in b.parts[start:]:  # body frame of the mover: relative to its box centre
            part["owner"][:] = i
    return b.build()


def _ground(b: _Builder, scene: Scene) -> None:
    """Sparse weak ground features (cracks, manholes, markings, gravel, vegetation) within
    ``GROUND_HALF_WIDTH`` of the path and outside building footprints, and kerbs on urban
    roads."""
    from scipy.spatial import cKDTree

    motion, rng = scene.motion, b.rng
    lo, hi = motion.sigma_span
    sig = np.arange(lo + 1.0, hi - 1.0, 1.0)
    st = motion.planar_state(motion.time_at_arclength(sig))
    tang = np.column_stack([np.cos(st["yaw"]), np.sin(st["yaw"])])
    nrm = np.column_stack([-tang[:, 1], tang[:, 0]])
    xy = np.column_stack([st["x"], st["y"]])
    w = GROUND_HALF_WIDTH
    x0, y0 = xy.min(axis=0) - w
    x1, y1 = xy.max(axis=0) + w
    n = int(rng.poisson(GROUND_DENSITY * (x1 - x0) * (y1 - y0)))
    p = np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])
    keep = cKDTree(xy).query(p, distance_upper_bound=w)[0] <= w
    for center, half, yaw, _ in scene.boxes:  # not under buildings, walls or parked cars
        c, s = np.cos(yaw), np.sin(yaw)
        d = p - np.asarray(center)[:2]
        keep &= ~((np.abs(c * d[:, 0] + s * d[:, 1]) < half[0])
                  & (np.abs(-s * d[:, 0] + c * d[:, 1]) < half[1]))
    p = p[keep]
    b.add(np.column_stack([p, np.zeros(len(p))]), (0.0, 0.0, 1.0), rcs=GROUND_RCS,
          material=GROUND, prim=GROUND_ID, cos_min=-1.0, aspect_exp=0.0, swerling=1,
          lobe_db=4.0, lobe_k=(2.0, 10.0))
    if scene.name not in ("campus", "loop"):
        return
    for side in (-1.0, 1.0):  # kerb stones at the road edge, facing the road
        keep = np.flatnonzero(rng.uniform(size=len(sig)) < 1.0 / KERB_SPACING)
        p = xy[keep] + side * KERB_OFFSET * nrm[keep]
        b.add(np.column_stack([p, np.full(len(keep), 0.08)]),
              np.column_stack([-side * nrm[keep], np.zeros(len(keep))]), rcs=KERB_RCS,
              material=GROUND, prim=GROUND_ID, cos_min=-0.2, aspect_exp=0.0, lobe_db=3.0)


def _tunnel(b: _Builder, tun) -> None:
    """Rib edges (a ring on every rib) and sparse wall features of a tunnel."""
    rng = b.rng
    r_rib = tun.radius - tun.rib_depth
    ang = np.linspace(0, 2 * np.pi, int(2 * np.pi * r_rib / 0.6), endpoint=False)
    ang = ang[tun.axis_z + r_rib * np.sin(ang) > 0.1]  # above the road
    for x in (np.arange(tun.x0, tun.x1, tun.rib_spacing) if tun.rib_spacing > 0 else ()):
        a = ang[rng.uniform(size=len(ang)) < 0.6]
        pos = np.column_stack([np.full(len(a), x + 0.5 * tun.rib_width),
                               tun.axis_y + r_rib * np.cos(a), tun.axis_z + r_rib * np.sin(a)])
        b.add(pos, None, rcs=(2.0, 4.0), material=RIB, prim=TUNNEL_ID, lobe_db=2.0)
    n = int(rng.poisson(0.05 * 2 * np.pi * tun.radius * (tun.x1 - tun.x0)))
    a = rng.uniform(0, 2 * np.pi, n)
    pos = np.column_stack([rng.uniform(tun.x0, tun.x1, n), tun.axis_y + tun.radius * np.cos(a),
                           tun.axis_z + tun.radius * np.sin(a)])
    b.add(pos[pos[:, 2] > 0.1], None, rcs=(-8.0, 5.0), material=TUNNEL_WALL, prim=TUNNEL_ID,
          swerling=1)


OCCLUSION_TOL = 0.15  # [m] a scatterer is visible when the first hit is at most this closer


def visible(sc: Scatterers, geom, o: np.ndarray, R: np.ndarray, spec, edge_band: bool = True
            ) -> dict[str, np.ndarray]:
    """Scatterers seen from the sensor at ``o`` (world) with orientation ``R`` (world <- sensor)
    in the scene frozen as ``geom``: inside the field of view (widened, see ``candidates``)
    and range limits, facing the sensor and not occluded (the ray cast towards the scatterer
    first hits a surface no closer than ``OCCLUSION_TOL`` before it). Returns the ids,
    sensor-frame points, world velocities of the points (zero for static ones), primitive ids,
    the RCS towards the sensor (with aspect loss and lobe) [dBsm], the incidence cosine,
    material, dynamic flag, Swerling case and angle bias."""
    from loaders.synthetic.raycast import cast

    cand = candidates(sc, geom, o, R, spec, edge_band)
    D_s = cand["points_s"] / cand["range"][:, None]
    t, _, _ = cast(geom, o, D_s @ R.T, D_s, R, spec.max_range, cand["range"] - OCCLUSION_TOL)
    return finish(sc, geom, o, cand, t)


def candidates(sc: Scatterers, geom, o: np.ndarray, R: np.ndarray, spec,
               edge_band: bool = True) -> dict:
    """Scatterers inside the field of view (``edge_band``: widened by
    ``sensors.detection_margin_deg``) and inside the range limits that face the sensor (before
    the occlusion test): ids, world and sensor-frame points, range, incidence cosine, RCS
    towards the sensor [dBsm] and primitive id."""
    reach = spec.max_range + 1.0
    heading = float(np.arctan2(R[1, 0], R[0, 0]))
    # a scatterer just outside the field of view is detected inside it through its neighbouring
    # resolution cells and its angle errors: candidates reach that far beyond (the sensor
    # model reports only the detections whose measured angles fall inside)
    margin = detection_margin_deg(spec) if edge_band else np.zeros(2)
    az_half, el_half = np.radians(np.array([spec.az_half_deg, spec.el_half_deg]) + margin)
    ids = [sc.static_in_sector(o[:2], heading, az_half + 0.05, reach)]
    P, Nrm, yaw_of = [sc.pos[ids[0]]], [sc.normal[ids[0]]], [np.zeros(len(ids[0]))]
    prim = [sc.prim[ids[0]]]
    for k, pid in enumerate(geom.mover_pid):
        if pid < 0:
            continue
        mine = sc.of_mover(k)
        if not len(mine):
            continue
        box = geom.boxes[_box_index(geom, pid)]
        center, yaw = np.asarray(box[1]), box[3]
        if np.hypot(*(center[:2] - o[:2])) > reach + 15.0:
            continue
        c, s = np.cos(yaw), np.sin(yaw)
        Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        ids.append(mine)
        P.append(sc.pos[mine] @ Rz.T + center)
        Nrm.append(sc.normal[mine] @ Rz.T)
        yaw_of.append(np.full(len(mine), yaw))
        prim.append(np.full(len(mine), pid))
    ids, P, Nrm = np.concatenate(ids), np.concatenate(P), np.concatenate(Nrm)
    yaw_of, prim = np.concatenate(yaw_of), np.concatenate(prim)
    rad = sc.radius[ids]
    cyl = rad > 0  # vertical cylinder: the visible centre is on the surface facing the sensor
    if cyl.any():
        dxy = o[:2] - P[cyl, :2]
        P[cyl, :2] += rad[cyl, None] * dxy / np.maximum(np.linalg.norm(dxy, axis=1), 1e-9)[:, None]
    ps = (P - o) @ R
    r = np.linalg.norm(ps, axis=1)
    r_safe = np.maximum(r, 1e-9)
    cos_n = np.einsum("ij,ij->i", Nrm, o - P) / r_safe
    ok = ((r >= spec.min_range) & (r <= spec.max_range) & (cos_n > sc.cos_min[ids])
          & (np.abs(np.arctan2(ps[:, 1], ps[:, 0])) <= az_half)
          & (np.abs(ps[:, 2]) <= r * np.sin(el_half)))
    ids, P, ps, r, cos_n, yaw_of, prim = (a[ok] for a in (ids, P, ps, r, cos_n, yaw_of, prim))
    # RCS towards the sensor: incidence loss and aspect lobe (viewing azimuth in the owner frame)
    view_az = np.arctan2(o[1] - P[:, 1], o[0] - P[:, 0]) - yaw_of
    rcs = (sc.rcs_db[ids] + sc.aspect_exp[ids] * 10.0 * np.log10(np.clip(cos_n, 0.05, 1.0))
           + sc.lobe_db[ids] * np.cos(sc.lobe_k[ids] * view_az + sc.lobe_phase[ids]))
    return {"ids": ids, "points_w": P, "points_s": ps, "range": r, "cos_n": cos_n,
            "rcs_db": rcs, "prim": prim}


def finish(sc: Scatterers, geom, o: np.ndarray, cand: dict, t: np.ndarray) -> dict:
    """The candidates that are not occluded, given the first-hit distance ``t`` of the rays
    cast towards them; see ``visible``."""
    seen = t >= cand["range"] - OCCLUSION_TOL - 1e-9
    cand = {k: v[seen] for k, v in cand.items()}
    ids, P, ps, cos_n, rcs, prim = (cand[k] for k in (
        "ids", "points_w", "points_s", "cos_n", "rcs_db", "prim"))
    iso = sc.cos_min[ids] < -1.0
    u = np.zeros_like(P)
    moving = sc.owner[ids] >= 0
    if moving.any():
        u[moving] = geom.point_velocity(prim[moving], P[moving])
    return {"ids": ids, "points_s": ps, "velocity_w": u, "prim": prim,
            "rcs_db": rcs, "cos_inc": np.where(iso, 1.0, cos_n),
            "material": sc.material[ids], "dynamic": moving, "swerling": sc.swerling[ids],
            "bias": sc.bias[ids], **{k: v for k, v in cand.items() if k == "fading_db"}}


def _box_index(geom, pid: int) -> int:
    """Index in ``geom.boxes`` of the box with primitive id ``pid`` (movers come last)."""
    n_static = len(geom.boxes) - int((geom.mover_pid >= 0).sum())
    return n_static + int(np.searchsorted(geom.mover_pid[geom.mover_pid >= 0], pid))
