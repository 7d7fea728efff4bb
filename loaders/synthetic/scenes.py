"""Synthetic scenes built around the vehicle's path (world frame, z up, road surface z = 0).

A scene is a list of static primitives (boxes, vertical cylinders, spheres, optional tunnel)
plus movers: boxes that drive along lanes. Lanes are either the ego path shifted sideways
(``offset`` [m], + = left) or straight lines; a mover's arc length along its lane is
``sigma0 + speed * t`` (speed < 0 drives against the lane direction). ``Scene.geometry(t)``
freezes everything at time t for the ray caster, with each mover's exact velocity and yaw rate.
Everything is deterministic from the numpy Generator given to ``build_scene``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from loaders.synthetic.motion import Motion
from loaders.synthetic.raycast import Geometry, Tunnel

# material ids (their radar / lidar reflectivity lives in sensors.py)
GROUND, BUILDING, WALL, TUNNEL_WALL, RIB, CAR, TRUCK, PEDESTRIAN, POLE, TRUNK, CROWN = range(11)
MATERIAL_NAMES = ("ground", "building", "wall", "tunnel", "rib", "car", "truck", "pedestrian",
                  "pole", "trunk", "crown")

SCENES = {
    "straight-wall": "two long featureless parallel walls and a flat road (CARLA Town04-like)",
    "curved-wall": "concentric curved walls around a road of radius 150-250 m (Town05-like)",
    "tunnel": "long tube (radius 6-7 m) with periodic ribs every few metres (option "
              "rib_spacing=0: smooth), no traffic",
    "tunnel-vehicles": "the tunnel with moving vehicles in both directions (10-30 % dynamic); "
                       "option one_lane=True: only a queue ahead in the ego's lane",
    "campus": "buildings, trees, poles, parked cars, walking pedestrians, some traffic",
    "loop": "urban blocks with moving cars, gentle turns; option uturn=True adds a U-turn",
}

VEHICLES = {  # half sizes [m] and material
    "car": ((2.25, 0.9, 0.75), CAR), "van": ((2.5, 1.0, 1.1), CAR),
    "truck": ((5.0, 1.25, 1.7), TRUCK), "bus": ((6.0, 1.25, 1.6), TRUCK),
}


def motion_spec(name: str, sensor_kind: str, rng: np.random.Generator, options: dict) -> dict:
    """Motion preset for a scene: profile kind, speed range [m/s] and curvature [1/m]."""
    speed = (12.0, 16.5) if sensor_kind == "lidar" else (7.0, 9.5)
    speed = tuple(options.get("speed", speed))
    if name == "curved-wall":
        radius = float(options.get("road_radius", rng.uniform(150.0, 250.0)))
        side = float(rng.choice([-1.0, 1.0]))
        return {"kind": "curve", "speed": speed, "curvature": side / radius}
    if name == "loop":
        return {"kind": "uturn" if options.get("uturn") else "gentle", "speed": speed,
                "curvature": 0.0}
    if name == "campus":
        return {"kind": "gentle", "speed": speed, "curvature": 0.0}
    if name in ("straight-wall", "tunnel", "tunnel-vehicles"):
        return {"kind": "straight", "speed": speed, "curvature": 0.0}
    raise ValueError(f"unknown scene {name!r}; known: {', '.join(SCENES)}")


@dataclass(frozen=True)
class Mover:
    half: tuple[float, float, float]
    material: int
    sigma0: float
    speed: float
    offset: float = 0.0  # lateral offset from the ego path (path lanes)
    line: tuple[float, float, float] | None = None  # straight lane (x0, y0, heading)


@dataclass
class Scene:
    name: str
    motion: Motion
    boxes: list = field(default_factory=list)  # (center, half, yaw, material)
    vcylinders: list = field(default_factory=list)  # (cx, cy, r, z0, z1, material)
    spheres: list = field(default_factory=list)  # (center, r, material)
    movers: list[Mover] = field(default_factory=list)
    tunnel: Tunnel | None = None
    params: dict = field(default_factory=dict)

    def summary(self) -> dict:
        return {"boxes": len(self.boxes), "cylinders": len(self.vcylinders),
                "spheres": len(self.spheres), "movers": len(self.movers),
                "tunnel": self.tunnel is not None, **self.params}

    def _mover_states(self, t: float):
        """Center xy, yaw, velocity xy and yaw rate of every mover at time t."""
        out = np.full((len(self.movers), 6), np.nan)
        path = [i for i, m in enumerate(self.movers) if m.line is None]
        lo, hi = self.motion.sigma_span
        if path:
            sig = np.array([self.movers[i].sigma0 + self.movers[i].speed * t for i in path])
            ok = (sig > lo + 1) & (sig < hi - 1)
            idx = np.array(path)[ok]
            st = self.motion.planar_state(self.motion.time_at_arclength(sig[ok]))
            kappa = st["yaw_rate"] / st["speed"]
            for j, i in enumerate(idx):
                m = self.movers[i]
                yaw = st["yaw"][j]
                tang = np.array([np.cos(yaw), np.sin(yaw)])
                nrm = np.array([-tang[1], tang[0]])
                xy = np.array([st["x"][j], st["y"][j]]) + m.offset * nrm
                vel = m.speed * (1.0 - m.offset * kappa[j]) * tang
                heading = yaw + (np.pi if m.speed < 0 else 0.0)
                out[i] = [xy[0], xy[1], heading, vel[0], vel[1], m.speed * kappa[j]]
        for i, m in enumerate(self.movers):
            if m.line is not None:
                x0, y0, h = m.line
                s = m.sigma0 + m.speed * t
                d = np.array([np.cos(h), np.sin(h)])
                heading = h + (np.pi if m.speed < 0 else 0.0)
                out[i] = [x0 + s * d[0], y0 + s * d[1], heading, m.speed * d[0],
                          m.speed * d[1], 0.0]
        return out

    def geometry(self, t: float) -> Geometry:
        """The scene frozen at time t [s] for ray casting."""
        g = Geometry(ground_z=0.0, ground_material=GROUND, tunnel=self.tunnel,
                     tunnel_material=TUNNEL_WALL)
        mat, dyn, vel, ref, wz = [], [], [], [], []

        def meta(material, dynamic=False, v=(0.0, 0.0, 0.0), r=(0.0, 0.0, 0.0), w=0.0):
            mat.append(material)
            dyn.append(dynamic)
            vel.append(v)
            ref.append(r)
            wz.append(w)
            return len(mat) - 1

        for center, half, yaw, m in self.boxes:
            g.boxes.append((meta(m), center, half, yaw))
        for cx, cy, r, z0, z1, m in self.vcylinders:
            g.vcylinders.append((meta(m), cx, cy, r, z0, z1))
        for center, r, m in self.spheres:
            g.spheres.append((meta(m), center, r))
        states = self._mover_states(t) if self.movers else np.zeros((0, 6))
        mover_pid = np.full(len(self.movers), -1, dtype=np.int64)
        for k, (m, st) in enumerate(zip(self.movers, states, strict=True)):
            if not np.isfinite(st[0]):
                continue
            center = np.array([st[0], st[1], m.half[2]])
            pid = meta(m.material, True, (st[3], st[4], 0.0), tuple(center), st[5])
            g.boxes.append((pid, center, np.asarray(m.half), st[2]))
            mover_pid[k] = pid
        g.mover_pid = mover_pid
        g.material = np.array(mat, dtype=np.int64)
        g.dynamic = np.array(dyn, dtype=bool)
        g.velocity = np.array(vel, dtype=float).reshape(-1, 3)
        g.ref = np.array(ref, dtype=float).reshape(-1, 3)
        g.yaw_rate = np.array(wz, dtype=float)
        return g


class _Placer:
    """Places static objects beside the ego path, rejecting any that come too close to any
    part of the path (needed where the path turns back on itself)."""

    def __init__(self, motion: Motion, sigma_lo: float, sigma_hi: float) -> None:
        self.motion = motion
        sig = np.arange(motion.sigma_span[0] + 0.5, motion.sigma_span[1] - 0.5, 1.0)
        st = motion.planar_state(motion.time_at_arclength(sig))
        self.tree = cKDTree(np.column_stack([st["x"], st["y"]]))
        self.lo, self.hi = sigma_lo, sigma_hi

    def anchor(self, sigma: float, offset: float):
        st = self.motion.planar_state(self.motion.time_at_arclength(np.array([sigma])))
        yaw = float(st["yaw"][0])
        xy = np.array([st["x"][0], st["y"][0]]) + offset * np.array([-np.sin(yaw), np.cos(yaw)])
        return xy, yaw

    def clear(self, xy: np.ndarray, half_xy, yaw: float, clearance: float) -> bool:
        c, s = np.cos(yaw), np.sin(yaw)
        hx, hy = half_xy
        pts = [xy] + [xy + np.array([c * a - s * b, s * a + c * b])
                      for a in (-hx, 0.0, hx) for b in (-hy, hy)]
        dist, _ = self.tree.query(np.array(pts))
        return bool(np.all(dist >= clearance))


def _line_lanes(rng, movers, lane_y, direction, spacing, speed, sigma_range, kinds, weights):
    """Vehicles on a straight lane along +x at y = lane_y (direction +1 or -1)."""
    s = sigma_range[0] + rng.uniform(0, spacing[1])
    while s < sigma_range[1]:
        kind = rng.choice(kinds, p=weights)
        half, mat = VEHICLES[str(kind)]
        movers.append(Mover(half, mat, float(s), float(direction * rng.uniform(*speed)),
                            line=(0.0, float(lane_y), 0.0)))
        s += rng.uniform(*spacing) + 2 * half[0]


def build_scene(name: str, motion: Motion, spec: dict, rng: np.random.Generator,
                options: dict, sigma_end: float, max_range: float) -> Scene:
    """Build scene ``name`` around ``motion`` travelling ``sigma_end`` metres after t = 0."""
    scene = Scene(name=name, motion=motion)
    lo, hi = -max_range - 20.0, sigma_end + max_range + 20.0
    v_max = spec["speed"][1]
    if name == "straight-wall":
        left, right = rng.uniform(6.0, 8.0), rng.uniform(4.5, 6.0)
        height = rng.uniform(4.0, 6.0)
        for y in (left + 0.25, -right - 0.25):
            scene.boxes.append((np.array([(lo + hi) / 2, y, height / 2]),
                                np.array([(hi - lo) / 2, 0.25, height / 2]), 0.0, WALL))
        scene.params = {"wall_left_m": left, "wall_right_m": right, "wall_height_m": height}
    elif name == "curved-wall":
        radius = 1.0 / abs(spec["curvature"])
        cy = radius * np.sign(spec["curvature"])
        inner, outer = rng.uniform(4.5, 6.0), rng.uniform(6.0, 8.0)
        height = rng.uniform(4.0, 6.0)
        for r in (radius - inner, radius + outer):
            scene.vcylinders.append((0.0, cy, r, 0.0, height, WALL))
        scene.params = {"road_radius_m": radius, "wall_height_m": height}
    elif name in ("tunnel", "tunnel-vehicles"):
        radius = rng.uniform(6.0, 7.0)
        spacing = float(options.get("rib_spacing", rng.uniform(3.0, 5.0)))
        scene.tunnel = Tunnel(axis_y=1.9, axis_z=2.0, radius=radius, x0=lo, x1=hi,
                              rib_spacing=spacing, rib_width=0.4, rib_depth=0.3)
        scene.params = {"tunnel_radius_m": radius, "rib_spacing_m": spacing}
        if name == "tunnel-vehicles":
            kinds, w = ["car", "van", "truck", "bus"], [0.5, 0.2, 0.2, 0.1]
            # a queue ahead in the ego lane (slightly faster than the ego); option
            # one_lane=False adds dense oncoming traffic (the Baker-Barry tunnel has one lane
            # and a signal that alternates the direction, so its traffic drives with the ego)
            _line_lanes(rng, scene.movers, 0.0, 1.0, (6.0, 20.0), (v_max + 0.3, v_max + 1.5),
                        (14.0, hi + 200.0), kinds, w)
            if not options.get("one_lane", False):
                _line_lanes(rng, scene.movers, 3.8, -1.0, (4.0, 14.0), (11.0, 16.0),
                            (lo - 100.0, hi + 400.0), kinds, w)
    elif name in ("campus", "loop"):
        _urban(scene, motion, rng, name, lo, hi, v_max)
    else:
        raise ValueError(f"unknown scene {name!r}; known: {', '.join(SCENES)}")
    return scene


#: loop scene buildings: half length along the road, half height, setback of the facade from
#: the road centre line (uniform ranges) and the gaps between them [m]. Half height 3-8 m
#: (6-16 m tall; was 5-15): the real loop-1 sample's returns at 20-100 m lie 3.0 / 5.7 / 7.3 /
#: 8.9 m above the radar (25/50/75/90 %, radar frame pitched ~2 deg down, REFERENCE.md) and
#: their elevation spread is 2.2 deg (IQR) at 50-100 m; see README.md section 2
LOOP_BUILDINGS = {"half_length_m": (8.0, 25.0), "half_height_m": (3.0, 8.0),
                  "setback_m": (9.0, 14.0), "gaps_m": (0.5, 1.0, 15.0)}

#: roadside trees (uniform ranges): offset from the road centre line, trunk height below the
#: crown, crown radius, spacing along the road [m]
CAMPUS_TREES = {"offset_m": (7.5, 10.5), "trunk_m": (2.0, 3.5), "crown_radius_m": (1.5, 3.0),
                "spacing_m": (8.0, 16.0)}
LOOP_TREES = {"offset_m": (7.5, 10.5), "trunk_m": (2.0, 3.5), "crown_radius_m": (1.5, 3.0),
              "spacing_m": (10.0, 25.0)}


def _urban(scene: Scene, motion: Motion, rng, name: str, lo: float, hi: float,
           v_max: float) -> None:
    placer = _Placer(motion, lo, hi)
    campus = name == "campus"

    def box(sigma, offset, half, material, clearance, z0=0.0):
        xy, yaw = placer.anchor(sigma, offset)
        if placer.clear(xy, half[:2], yaw, clearance):
            scene.boxes.append((np.array([xy[0], xy[1], z0 + half[2]]), np.asarray(half),
                                yaw, material))

    for side in (-1.0, 1.0):
        s = lo
        while s < hi:  # buildings (campus: detached; loop: blocks with cross streets)
            lb = LOOP_BUILDINGS
            hx = rng.uniform(5.0, 18.0) if campus else rng.uniform(*lb["half_length_m"])
            hy = rng.uniform(4.0, 10.0)
            hz = rng.uniform(3.0, 10.0) if campus else rng.uniform(*lb["half_height_m"])
            front = rng.uniform(12.0, 22.0) if campus else rng.uniform(*lb["setback_m"])
            box(s + hx, side * (front + hy), (hx, hy, hz), BUILDING, front - 1.0)
            gap = rng.uniform(6.0, 25.0) if campus else rng.choice(lb["gaps_m"])
            s += 2 * hx + gap
        s = lo + rng.uniform(0, 10)
        while s < hi:  # trees
            lt = CAMPUS_TREES if campus else LOOP_TREES
            xy, _ = placer.anchor(s, side * rng.uniform(*lt["offset_m"]))
            if placer.tree.query(xy)[0] >= 6.5:
                h, r_c = rng.uniform(*lt["trunk_m"]), rng.uniform(*lt["crown_radius_m"])
                scene.vcylinders.append((xy[0], xy[1], rng.uniform(0.15, 0.3), 0.0, h + r_c,
                                         TRUNK))
                scene.spheres.append((np.array([xy[0], xy[1], h + 0.7 * r_c]), r_c, CROWN))
            s += rng.uniform(*lt["spacing_m"])
        s = lo + rng.uniform(0, 20)
        while s < hi:  # poles
            xy, _ = placer.anchor(s, side * 6.2)
            if placer.tree.query(xy)[0] >= 5.5:
                scene.vcylinders.append((xy[0], xy[1], rng.uniform(0.08, 0.15), 0.0,
                                         rng.uniform(5.0, 8.0), POLE))
            s += rng.uniform(18.0, 35.0)
        s = lo + rng.uniform(0, 10)
        while not campus and s < hi:  # fences / low walls along the sidewalk
            hx = rng.uniform(5.0, 15.0)
            box(s + hx, side * 8.6, (hx, 0.15, rng.uniform(0.5, 0.8)), WALL, 7.5)
            s += 2 * hx + rng.uniform(3.0, 20.0)
    if campus:
        s = lo
        while s < hi:  # parked cars, right side, in groups
            for _ in range(int(rng.integers(1, 6))):
                half, mat = VEHICLES["car" if rng.uniform() < 0.8 else "van"]
                box(s + half[0], -4.2, half, mat, 2.8)
                s += 2 * half[0] + rng.uniform(0.8, 2.0)
            s += rng.uniform(10.0, 40.0)
        for side in (-1.0, 1.0):  # pedestrians on the sidewalks, both directions
            s = lo + rng.uniform(0, 20)
            while s < hi:
                scene.movers.append(Mover((0.25, 0.3, 0.875), PEDESTRIAN, float(s),
                                          float(rng.choice([-1, 1]) * rng.uniform(1.0, 1.6)),
                                          offset=float(side * rng.uniform(7.0, 8.0))))
                s += rng.uniform(20.0, 50.0)
    kinds, w = ["car", "van", "truck", "bus"], [0.65, 0.2, 0.1, 0.05]
    lanes = [(3.5, -1.0, (60.0, 160.0) if campus else (40.0, 120.0), (7.0, 11.0))]
    if not campus:
        lanes += [(-3.5, 1.0, (60.0, 150.0), (5.0, 10.0)),
                  (0.0, 1.0, (80.0, 160.0), (v_max + 0.5, v_max + 2.0))]
    for offset, direction, spacing, speed in lanes:
        # the ego lane only holds faster cars ahead of the ego (never behind it)
        s = lo - 150.0 if direction < 0 else (40.0 if offset == 0.0 else lo)
        while s < hi + 150.0:
            kind = str(rng.choice(kinds, p=w))
            half, mat = VEHICLES[kind]
            scene.movers.append(Mover(half, mat, float(s), float(direction * rng.uniform(*speed)),
                                      offset=offset))
            s += rng.uniform(*spacing) + 2 * half[0]
