"""Vehicle motion: smooth speed, yaw-rate and attitude profiles integrated on a fine time grid.

Frames (x forward, y left, z up everywhere):
- world: horizontal x-y plane, z up; the body starts at the origin heading +x at t = 0;
- body: origin on the road surface below the rear axle; the vehicle drives along its x axis
  on a flat road (velocity s * (cos yaw, sin yaw, 0) in the world), while small pitch and roll
  (suspension) rotate the body about its origin: R_world_body = Rz(yaw) Ry(pitch) Rx(roll);
- sensor: mounted by ``T_body_sensor`` (lever arm), so its velocity includes w x lever arm.

Units: s, m, rad, m/s, rad/s. Profiles are analytic (values and first derivatives); yaw,
position and arc length are integrated with the end-corrected trapezoid rule (4th order) on a
1 ms grid and by one exact-order partial step to any query time, so positions are accurate to
~1e-10 m. Velocities come straight from the model (exact).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from loaders.se3 import make_T

TWO_PI = 2.0 * np.pi


def smoothstep(u: np.ndarray) -> np.ndarray:
    """C2 step from 0 (u <= 0) to 1 (u >= 1): u - sin(2 pi u) / (2 pi)."""
    u = np.clip(u, 0.0, 1.0)
    return u - np.sin(TWO_PI * u) / TWO_PI


def smoothstep_d(u: np.ndarray) -> np.ndarray:
    """d smoothstep / du (zero outside [0, 1])."""
    inside = (u > 0.0) & (u < 1.0)
    return np.where(inside, 1.0 - np.cos(TWO_PI * np.clip(u, 0.0, 1.0)), 0.0)


@dataclass(frozen=True)
class MotionProfile:
    """Analytic driving profile.

    speed(t) = v0 + sum_k dv_k * S((t - t_k) / dur_k)                          [m/s]
    yaw_rate(t) = curvature * speed(t) + sum_k a_k * bump_k(t) + wiggle         [rad/s]
        bump_k rises over ``ramp`` from t_k, holds ``hold``, falls over ``ramp``;
        wiggle = A * 2 pi f cos(2 pi f t + phase) (lane keeping, yaw amplitude A).
    pitch(t), roll(t) = sum_i a_i sin(2 pi f_i t + phase_i)                     [rad]
    """

    v0: float
    speed_steps: tuple[tuple[float, float, float], ...] = ()  # (t_k, dur_k, dv_k)
    curvature: float = 0.0  # [1/m]
    yaw_bumps: tuple[tuple[float, float, float, float], ...] = ()  # (t_k, ramp, hold, a_k)
    wiggle: tuple[float, float, float] = (0.0, 0.1, 0.0)  # (yaw amplitude, f, phase)
    pitch: tuple[tuple[float, float, float], ...] = ()  # (amplitude, f, phase)
    roll: tuple[tuple[float, float, float], ...] = ()

    def as_dict(self) -> dict:
        return asdict(self)

    def speed(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Speed [m/s] and its time derivative [m/s^2]."""
        t = np.asarray(t, dtype=float)
        s = np.full_like(t, self.v0)
        ds = np.zeros_like(t)
        for tk, dur, dv in self.speed_steps:
            u = (t - tk) / dur
            s = s + dv * smoothstep(u)
            ds = ds + dv * smoothstep_d(u) / dur
        return s, ds

    def yaw_rate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Yaw rate [rad/s] and its time derivative [rad/s^2]."""
        t = np.asarray(t, dtype=float)
        s, ds = self.speed(t)
        w = self.curvature * s
        dw = self.curvature * ds
        for tk, ramp, hold, a in self.yaw_bumps:
            u1, u2 = (t - tk) / ramp, (t - tk - ramp - hold) / ramp
            w = w + a * (smoothstep(u1) - smoothstep(u2))
            dw = dw + a * (smoothstep_d(u1) - smoothstep_d(u2)) / ramp
        amp, f, ph = self.wiggle
        if amp:
            arg = TWO_PI * f * t + ph
            w = w + amp * TWO_PI * f * np.cos(arg)
            dw = dw - amp * (TWO_PI * f) ** 2 * np.sin(arg)
        return w, dw

    @staticmethod
    def _sines(terms, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = np.asarray(t, dtype=float)
        v, dv = np.zeros_like(t), np.zeros_like(t)
        for a, f, ph in terms:
            v = v + a * np.sin(TWO_PI * f * t + ph)
            dv = dv + a * TWO_PI * f * np.cos(TWO_PI * f * t + ph)
        return v, dv

    def attitude(self, t: np.ndarray) -> tuple[np.ndarray, ...]:
        """pitch, pitch rate, roll, roll rate [rad, rad/s]."""
        p, dp = self._sines(self.pitch, t)
        r, dr = self._sines(self.roll, t)
        return p, dp, r, dr


def _rot_zyx(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), shape (N, 3, 3)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    R = np.empty(np.shape(yaw) + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


class Motion:
    """A profile integrated over [t_min, t_max] (t = 0 is the origin pose), with a lever arm."""

    def __init__(self, profile: MotionProfile, T_body_sensor: np.ndarray, t_min: float,
                 t_max: float, dt: float = 1e-3) -> None:
        self.profile = profile
        self.T_body_sensor = np.asarray(T_body_sensor, dtype=float)
        self.dt = dt
        n_before = int(np.ceil(max(0.0, -t_min) / dt))
        n = n_before + int(np.ceil(max(t_max, 0.0) / dt)) + 2
        self.t0 = -n_before * dt
        self.grid = self.t0 + dt * np.arange(n)
        t = self.grid
        w, dw = profile.yaw_rate(t)
        self._yaw = self._cumulate(w, dw, n_before)
        s, ds = profile.speed(t)
        self._sigma = self._cumulate(s, ds, n_before)
        gx, gy, dgx, dgy = self._planar(self._yaw, s, ds, w)
        self._x = self._cumulate(gx, dgx, n_before)
        self._y = self._cumulate(gy, dgy, n_before)

    def _cumulate(self, f: np.ndarray, df: np.ndarray, i0: int) -> np.ndarray:
        h = self.dt
        steps = h / 2 * (f[:-1] + f[1:]) + h * h / 12 * (df[:-1] - df[1:])
        out = np.concatenate([[0.0], np.cumsum(steps)])
        return out - out[i0]

    @staticmethod
    def _planar(yaw, s, ds, w):
        c, sn = np.cos(yaw), np.sin(yaw)
        return s * c, s * sn, ds * c - s * w * sn, ds * sn + s * w * c

    def _partial(self, t: np.ndarray):
        """Index of the grid node at or before t, and the remaining step (clipped to grid)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if np.any(t < self.grid[0] - 1e-9) or np.any(t > self.grid[-1] + 1e-9):
            raise ValueError(f"time outside the integrated span [{self.grid[0]}, {self.grid[-1]}]")
        k = np.clip(np.floor((t - self.t0) / self.dt).astype(int), 0, len(self.grid) - 2)
        return t, k, t - self.grid[k]

    def planar_state(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """x, y, yaw, speed, yaw_rate and arc length ``sigma`` of the body at times t."""
        p = self.profile
        t, k, d = self._partial(t)
        tk = self.grid[k]
        w_k, dw_k = p.yaw_rate(tk)
        w, dw = p.yaw_rate(t)
        yaw = self._yaw[k] + d / 2 * (w_k + w) + d * d / 12 * (dw_k - dw)
        s_k, ds_k = p.speed(tk)
        s, ds = p.speed(t)
        sigma = self._sigma[k] + d / 2 * (s_k + s) + d * d / 12 * (ds_k - ds)
        gx_k, gy_k, dgx_k, dgy_k = self._planar(self._yaw[k], s_k, ds_k, w_k)
        gx, gy, dgx, dgy = self._planar(yaw, s, ds, w)
        x = self._x[k] + d / 2 * (gx_k + gx) + d * d / 12 * (dgx_k - dgx)
        y = self._y[k] + d / 2 * (gy_k + gy) + d * d / 12 * (dgy_k - dgy)
        return {"x": x, "y": y, "yaw": yaw, "speed": s, "yaw_rate": w, "sigma": sigma}

    def body_pose(self, t: np.ndarray) -> np.ndarray:
        """T_world_body (N, 4, 4) at times t."""
        st = self.planar_state(t)
        pitch, _, roll, _ = self.profile.attitude(np.atleast_1d(t))
        R = _rot_zyx(st["yaw"], pitch, roll)
        return make_T(R, np.stack([st["x"], st["y"], np.zeros_like(st["x"])], axis=1))

    def sensor_pose(self, t: np.ndarray) -> np.ndarray:
        """T_world_sensor (N, 4, 4) at times t (the ground truth)."""
        return self.body_pose(t) @ self.T_body_sensor

    def sensor_twist_world(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Sensor origin velocity and angular velocity in the world frame, (N, 3) each."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        st = self.planar_state(t)
        pitch, dpitch, roll, droll = self.profile.attitude(t)
        yaw, s, w = st["yaw"], st["speed"], st["yaw_rate"]
        zeros = np.zeros_like(yaw)
        Rz = _rot_zyx(yaw, zeros, zeros)
        Rzy = _rot_zyx(yaw, pitch, zeros)
        omega = (w[:, None] * np.array([0.0, 0.0, 1.0])
                 + dpitch[:, None] * Rz[:, :, 1] + droll[:, None] * Rzy[:, :, 0])
        R_wb = _rot_zyx(yaw, pitch, roll)
        lever = R_wb @ self.T_body_sensor[:3, 3]
        v_body = np.stack([s * np.cos(yaw), s * np.sin(yaw), zeros], axis=1)
        return v_body + np.cross(omega, lever), omega

    def sensor_twist(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(v_s, w_s): sensor linear and angular velocity in the sensor frame, (N, 3) each."""
        v_w, w_w = self.sensor_twist_world(t)
        R_ws = self.sensor_pose(t)[:, :3, :3]
        return (np.einsum("nji,nj->ni", R_ws, v_w), np.einsum("nji,nj->ni", R_ws, w_w))

    def time_at_arclength(self, sigma: np.ndarray) -> np.ndarray:
        """Times at which the body has travelled arc length ``sigma`` [m] since t = 0."""
        sigma = np.atleast_1d(np.asarray(sigma, dtype=float))
        t = np.interp(sigma, self._sigma, self.grid)
        for _ in range(2):  # Newton on the exact arc length (speed > 0)
            st = self.planar_state(np.clip(t, self.grid[0], self.grid[-1]))
            t = np.clip(t + (sigma - st["sigma"]) / st["speed"], self.grid[0], self.grid[-1])
        return t

    @property
    def sigma_span(self) -> tuple[float, float]:
        return float(self._sigma[0]), float(self._sigma[-1])


# ---------------------------------------------------------------------------------------------
# Profile presets (deterministic from a numpy Generator)

def _attitude_terms(rng: np.random.Generator, max_deg: float) -> tuple:
    """Two sinusoids with total amplitude <= max_deg (< 1 deg)."""
    a = np.radians(max_deg) * rng.uniform(0.3, 0.5, size=2)
    f = rng.uniform(0.1, 0.6, size=2)
    ph = rng.uniform(0, TWO_PI, size=2)
    return tuple((float(a[i]), float(f[i]), float(ph[i])) for i in range(2))


def _speed_steps(rng, duration, v_lo, v_hi, v0, n_steps) -> tuple[tuple, list]:
    steps, v = [], v0
    for k in range(n_steps):
        tk = duration * (k + 0.3 + 0.4 * rng.uniform()) / n_steps
        target = rng.uniform(v_lo, v_hi)
        steps.append((float(tk), float(rng.uniform(2.0, 4.0)), float(target - v)))
        v = target
    return tuple(steps), steps


def make_profile(kind: str, rng: np.random.Generator, duration: float, speed: tuple[float, float],
                 attitude_deg: float = 0.6, curvature: float = 0.0) -> MotionProfile:
    """Preset profiles. kind: 'straight' (lane keeping), 'curve' (constant curvature),
    'gentle' (turns of ~0.1 rad/s), 'uturn' (gentle turns plus a ~0.55 rad/s U-turn)."""
    v_lo, v_hi = speed
    v0 = float(rng.uniform(v_lo, v_hi))
    att = dict(pitch=_attitude_terms(rng, attitude_deg),
               roll=_attitude_terms(rng, attitude_deg)) if attitude_deg > 0 else {}
    wiggle = (float(rng.uniform(0.003, 0.008)), float(rng.uniform(0.08, 0.15)),
              float(rng.uniform(0, TWO_PI)))
    if kind in ("straight", "curve"):
        steps, _ = _speed_steps(rng, duration, v_lo, v_hi, v0, 1)
        return MotionProfile(v0=v0, speed_steps=steps, curvature=curvature, wiggle=wiggle,
                             **att)
    if kind == "gentle":
        steps, _ = _speed_steps(rng, duration, v_lo, v_hi, v0, 2)
        bumps, t = [], rng.uniform(0.5, 2.0)
        while t + 4.0 < duration:
            ramp, hold = rng.uniform(1.0, 1.5), rng.uniform(1.5, 3.0)
            a = rng.choice([-1.0, 1.0]) * rng.uniform(0.09, 0.105)
            bumps.append((float(t), float(ramp), float(hold), float(a)))
            t += 2 * ramp + hold + rng.uniform(1.0, 3.0)
        return MotionProfile(v0=v0, speed_steps=steps, yaw_bumps=tuple(bumps), **att)
    if kind == "uturn":
        # cruise, slow to ~5 m/s, U-turn at ~0.55 rad/s (pi rad), speed up again
        t_u = 0.35 * duration
        ramp = 1.0
        a = float(rng.uniform(0.53, 0.57)) * float(rng.choice([-1.0, 1.0]))
        hold = np.pi / abs(a) - ramp  # integral of the bump = |a| (hold + ramp) = pi
        v_turn = float(rng.uniform(4.8, 5.5))
        steps = ((float(t_u - 3.0), 2.5, v_turn - v0),
                 (float(t_u + 2 * ramp + hold + 0.2), 3.0, float(rng.uniform(v_lo, v_hi)) - v_turn))
        bumps = [(float(t_u), ramp, float(hold), a)]
        t_g = t_u + 2 * ramp + hold + 2.0
        if t_g + 5.0 < duration:
            bumps.append((float(t_g), 1.2, 2.0, float(rng.choice([-1.0, 1.0]) * 0.1)))
        return MotionProfile(v0=v0, speed_steps=steps, yaw_bumps=tuple(bumps), **att)
    raise ValueError(f"unknown motion profile {kind!r}")
