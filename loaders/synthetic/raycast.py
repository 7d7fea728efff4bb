"""Vectorised ray casting against simple primitives (nearest hit over all primitives).

All rays of a scan share one origin ``o`` (the sensor origin, world frame [m]); directions
``D`` (N, 3) are unit vectors in the world frame. Every ``hit_*`` function returns the ray
parameter ``t`` (N,) [m] of the first hit in front of the origin (``inf`` for a miss) and the
outward surface normal (N, 3) at the hit (world frame, pointing towards the free space the ray
came from).

Primitives: horizontal ground plane, yaw-oriented finite boxes, vertical cylinders (solid from
outside, or a wall seen from inside), spheres, and a straight tunnel (inner tube surface around
an axis parallel to world x, with periodic ring ribs or smooth).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

EPS = 1e-9


def hit_plane_z(o: np.ndarray, D: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal plane z = const seen from above."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (z - o[2]) / D[:, 2]
    t = np.where((D[:, 2] < 0) & (t > EPS), t, np.inf)
    n = np.zeros_like(D)
    n[:, 2] = 1.0
    return t, n


def hit_box(o, D, center, half, yaw) -> tuple[np.ndarray, np.ndarray]:
    """Box with half sizes ``half`` (3,) rotated by ``yaw`` about z around ``center`` (3,)."""
    c, s = np.cos(yaw), np.sin(yaw)
    ox, oy = o[0] - center[0], o[1] - center[1]
    lo = np.array([c * ox + s * oy, -s * ox + c * oy, o[2] - center[2]])
    dl = np.stack([c * D[:, 0] + s * D[:, 1], -s * D[:, 0] + c * D[:, 1], D[:, 2]], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dl
        t1 = (-half - lo) * inv
        t2 = (half - lo) * inv
    tmin = np.minimum(t1, t2)
    tnear = tmin.max(axis=1)
    tfar = np.maximum(t1, t2).min(axis=1)
    ok = (tnear <= tfar) & (tnear > EPS)
    t = np.where(ok, tnear, np.inf)
    axis = tmin.argmax(axis=1)
    rows = np.arange(len(D))
    nl = np.zeros_like(D)
    nl[rows, axis] = -np.sign(dl[rows, axis])
    n = np.stack([c * nl[:, 0] - s * nl[:, 1], s * nl[:, 0] + c * nl[:, 1], nl[:, 2]], axis=1)
    return t, n


def hit_vcylinder(o, D, cx, cy, r, z0, z1) -> tuple[np.ndarray, np.ndarray]:
    """Vertical cylinder surface r around (cx, cy), z in [z0, z1]: a solid seen from outside
    when the origin is outside, a wall seen from inside otherwise (no caps)."""
    ox, oy = o[0] - cx, o[1] - cy
    a = D[:, 0] ** 2 + D[:, 1] ** 2
    b = ox * D[:, 0] + oy * D[:, 1]
    c = ox * ox + oy * oy - r * r
    disc = b * b - a * c
    sq = np.sqrt(np.maximum(disc, 0.0))
    inside = c < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((-b + sq) if inside else (-b - sq)) / a
        z = o[2] + t * D[:, 2]
    ok = (disc > 0) & (t > EPS) & (z >= z0) & (z <= z1) & (a > 1e-12)
    t = np.where(ok, t, np.inf)
    tt = np.where(ok, t, 0.0)
    n = np.stack([ox + tt * D[:, 0], oy + tt * D[:, 1], np.zeros(len(D))], axis=1) / r
    return t, (-n if inside else n)


def hit_sphere(o, D, center, r) -> tuple[np.ndarray, np.ndarray]:
    """Solid sphere seen from outside."""
    oc = o - center
    b = D @ oc
    c = oc @ oc - r * r
    disc = b * b - c
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    ok = (disc > 0) & (t > EPS) & (c > 0)
    t = np.where(ok, t, np.inf)
    n = (oc + np.where(ok, t, 0.0)[:, None] * D) / r
    return t, n


@dataclass(frozen=True)
class Tunnel:
    """Straight tube around the axis (y = axis_y, z = axis_z), x in [x0, x1], radius [m];
    ring ribs of inner radius ``radius - rib_depth`` start every ``rib_spacing`` from x0 and are
    ``rib_width`` long. The road plane (added separately) hides the tube below it."""

    axis_y: float
    axis_z: float
    radius: float
    x0: float
    x1: float
    rib_spacing: float
    rib_width: float
    rib_depth: float


def _tube_far_root(o, D, ya, za, r):
    dy, dz = D[:, 1], D[:, 2]
    oy, oz = o[1] - ya, o[2] - za
    a = dy * dy + dz * dz
    b = oy * dy + oz * dz
    c = oy * oy + oz * oz - r * r
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (-b + np.sqrt(np.maximum(b * b - a * c, 0.0))) / a
    return np.where(a > 1e-12, t, np.inf)


def hit_tunnel(o, D, tun: Tunnel) -> tuple[np.ndarray, np.ndarray]:
    """Inner surface of the tube and its ribs, seen from inside (the origin must be inside);
    ``rib_spacing <= 0``: a smooth tube without ribs."""
    t_wall = _tube_far_root(o, D, tun.axis_y, tun.axis_z, tun.radius)
    if tun.rib_spacing <= 0:
        n = np.zeros_like(D)
        n[:, 1] = tun.axis_y - (o[1] + t_wall * D[:, 1])
        n[:, 2] = tun.axis_z - (o[2] + t_wall * D[:, 2])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        return t_wall, n
    r_rib = tun.radius - tun.rib_depth
    t_rib = _tube_far_root(o, D, tun.axis_y, tun.axis_z, r_rib)
    with np.errstate(invalid="ignore"):
        x_rib = o[0] + t_rib * D[:, 0]
        x_wall = o[0] + t_wall * D[:, 0]
        k = np.floor((x_rib - tun.x0) / tun.rib_spacing)
        in_rib = (x_rib - tun.x0 - k * tun.rib_spacing) <= tun.rib_width
    t = np.where(in_rib, t_rib, t_wall)
    n = np.zeros_like(D)
    n[:, 1] = tun.axis_y - (o[1] + t * D[:, 1])
    n[:, 2] = tun.axis_z - (o[2] + t * D[:, 2])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    with np.errstate(invalid="ignore", divide="ignore"):
        # the ray crosses the rib radius in a gap: it may hit the next rib's end face first
        fwd = D[:, 0] > 0
        face_x = np.where(fwd, tun.x0 + (k + 1) * tun.rib_spacing,
                          tun.x0 + k * tun.rib_spacing + tun.rib_width)
        face = ~in_rib & np.where(fwd, face_x <= x_wall, face_x >= x_wall)
        t_face = (face_x - o[0]) / D[:, 0]
    face &= np.isfinite(t_face)
    t = np.where(face, t_face, t)
    n[face] = 0.0
    n[face, 0] = np.where(fwd[face], -1.0, 1.0)
    x = o[0] + t * D[:, 0]
    ok = np.isfinite(t) & (t > EPS) & (x >= tun.x0) & (x <= tun.x1)
    return np.where(ok, t, np.inf), n


@dataclass
class Geometry:
    """A scene frozen at one time. Per-primitive metadata is indexed by a global primitive id:
    ``material[id]`` (int), ``dynamic[id]`` (bool), ``velocity[id]`` (3,) world velocity of the
    reference point ``ref[id]`` (3,), and ``yaw_rate[id]`` [rad/s] (rigid motion about z).
    ``mover_pid[k]`` is the primitive id of the scene's mover k (-1 when it is off its lane)."""

    ground_z: float | None = 0.0
    ground_material: int = 0
    boxes: list = field(default_factory=list)  # (id, center(3), half(3), yaw)
    vcylinders: list = field(default_factory=list)  # (id, cx, cy, r, z0, z1)
    spheres: list = field(default_factory=list)  # (id, center(3), r)
    tunnel: Tunnel | None = None
    tunnel_material: int = 0
    material: np.ndarray = field(default_factory=lambda: np.zeros(0, int))
    dynamic: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    ref: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    yaw_rate: np.ndarray = field(default_factory=lambda: np.zeros(0))
    mover_pid: np.ndarray = field(default_factory=lambda: np.zeros(0, int))  # -1: inactive

    def point_velocity(self, prim: np.ndarray, points_w: np.ndarray) -> np.ndarray:
        """World velocity (N, 3) of hit points on primitives ``prim`` (ids >= 0)."""
        u = self.velocity[prim].copy()
        r = points_w - self.ref[prim]
        w = self.yaw_rate[prim]
        u[:, 0] -= w * r[:, 1]
        u[:, 1] += w * r[:, 0]
        return u


# ids used for the ground and the tunnel (not in the per-primitive lists)
GROUND_ID = -2
TUNNEL_ID = -3


def _bounds(kind: str, items: list) -> tuple[np.ndarray, np.ndarray]:
    """Bounding-sphere centers (K, 3) and radii (K,) of a list of primitives."""
    if not items:
        return np.zeros((0, 3)), np.zeros(0)
    if kind == "box":
        return (np.array([it[1] for it in items], float),
                np.array([np.linalg.norm(it[2]) for it in items]))
    if kind == "cyl":
        a = np.array([it[1:] for it in items], float)  # cx, cy, r, z0, z1
        return (np.column_stack([a[:, 0], a[:, 1], 0.5 * (a[:, 3] + a[:, 4])]),
                np.hypot(a[:, 2], 0.5 * (a[:, 4] - a[:, 3])))
    return np.array([it[1] for it in items], float), np.array([it[2] for it in items], float)


def cast(geom: Geometry, o: np.ndarray, D: np.ndarray, D_sensor: np.ndarray,
         R_world_sensor: np.ndarray, max_range: float, t_limit: np.ndarray | None = None):
    """Nearest hit of every ray. ``D_sensor`` are the same rays in the sensor frame (used to
    cull primitives by their bounding cone). Returns t (N,) [m] (inf = no hit within
    ``max_range``), primitive id (N,) (-1 none, GROUND_ID, TUNNEL_ID or >= 0) and normals.
    ``t_limit`` (N,) [m], optional: only hits closer than this are looked for (an occlusion
    test); a ray with no such hit returns t = t_limit and primitive -1."""
    n_rays = len(D)
    t_best = np.full(n_rays, np.inf) if t_limit is None else np.array(t_limit, dtype=float)
    prim = np.full(n_rays, -1, dtype=np.int64)
    normal = np.zeros((n_rays, 3))

    def update(idx, t, n, pid):
        closer = t < t_best[idx]
        closer_idx = idx[closer]
        t_best[closer_idx] = t[closer]
        prim[closer_idx] = pid
        normal[closer_idx] = n[closer]

    everything = np.arange(n_rays)
    if geom.ground_z is not None:
        t, n = hit_plane_z(o, D, geom.ground_z)
        update(everything, t, n, GROUND_ID)
    if geom.tunnel is not None:
        t, n = hit_tunnel(o, D, geom.tunnel)
        update(everything, t, n, TUNNEL_ID)

    az = np.arctan2(D_sensor[:, 1], D_sensor[:, 0])
    order = np.argsort(az, kind="stable")
    az_sorted = az[order]
    # cull by bounding sphere (range, azimuth span, cone), nearest primitives first so that
    # rays already blocked closer than a primitive's bounding sphere are skipped
    jobs = []
    for kind, items in (("box", geom.boxes), ("cyl", geom.vcylinders), ("sph", geom.spheres)):
        centers, radii = _bounds(kind, items)
        if not len(radii):
            continue
        cs = (centers - o) @ R_world_sensor
        dist = np.linalg.norm(cs, axis=1)
        d_xy = np.hypot(cs[:, 0], cs[:, 1])
        near = dist - radii <= max_range
        outside = d_xy > radii * 1.0001
        half_az = np.arcsin(np.clip(radii / np.maximum(d_xy, 1e-12), 0.0, 1.0))
        azc = np.arctan2(cs[:, 1], cs[:, 0])
        lo = np.searchsorted(az_sorted, azc - half_az)
        hi = np.searchsorted(az_sorted, azc + half_az)
        if kind == "box":  # tighter azimuth span: the corners' (box entirely in front)
            half = np.array([it[2] for it in items], float)
            yaw = np.array([it[3] for it in items], float)
            sgn = np.array([[sx, sy, sz] for sz in (-1.0, 1.0) for sx, sy in
                            ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))])
            local = sgn[None] * half[:, None, :]  # (K, 8, 3)
            cz, sz = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
            corners = np.stack([centers[:, None, 0] + cz * local[..., 0] - sz * local[..., 1],
                                centers[:, None, 1] + sz * local[..., 0] + cz * local[..., 1],
                                centers[:, None, 2] + local[..., 2]], axis=-1)
            cs_c = (corners - o) @ R_world_sensor
            front = np.all(cs_c[..., 0] > 1e-3, axis=1) & near & outside
            a = np.arctan2(cs_c[front, :, 1], cs_c[front, :, 0])
            lo[front] = np.searchsorted(az_sorted, a.min(axis=1))
            hi[front] = np.searchsorted(az_sorted, a.max(axis=1))
        keep = near & (~outside | (hi > lo))
        for k in np.flatnonzero(keep):
            jobs.append((dist[k] - radii[k], kind, items[k], bool(outside[k]), lo[k], hi[k],
                         cs[k] / dist[k], np.sqrt(max(0.0, 1.0 - (radii[k] / dist[k]) ** 2))))
    jobs.sort(key=lambda j: j[0])
    for front, kind, item, outside, lo, hi, axis, cos_half in jobs:
        if outside:
            idx = order[lo:hi]
            idx = idx[D_sensor[idx] @ axis >= cos_half]
        else:
            idx = everything
        idx = idx[t_best[idx] > front]
        if len(idx) == 0:
            continue
        Dsub = D[idx]
        if kind == "box":
            t, n = hit_box(o, Dsub, np.asarray(item[1]), np.asarray(item[2]), item[3])
        elif kind == "cyl":
            t, n = hit_vcylinder(o, Dsub, *item[1:])
        else:
            t, n = hit_sphere(o, Dsub, np.asarray(item[1]), item[2])
        update(idx, t, n, item[0])
    t_best[t_best > max_range] = np.inf
    prim[~np.isfinite(t_best)] = -1
    return t_best, prim, normal
