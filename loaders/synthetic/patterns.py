"""LiDAR scan patterns: ray directions and per-ray firing times of one frame.

Sensor frame: x forward, y left, z up; azimuth = atan2(y, x), elevation = asin(z) [rad].

- ``grid``: a uniform azimuth x elevation grid over the spec's field of view with about
  ``spec.rays`` rays (row-major (elevation, azimuth)); with the sweep its columns fire from
  the right edge to the left edge over one period in ``GRID_SWEEP_STEPS`` groups.
- ``aeva-64``: Aeva's own CARLA FMCW-LiDAR pattern ``64-19.2-Uniform`` (Aeva's CARLA fork,
  2024, ``ScanPatterns.yaml`` and ``FMCWLidarPattern.h``; shared/REFERENCE.md): 4 beams scan at
  once, each with an elevation offset ``AEVA_BEAM_OFFSETS_DEG``; each beam sweeps 16 lines, line
  k at elevation ``AEVA_STEPS_DEG[k]`` + the beam's offset, so 64 lines at about 0.3 deg spacing
  over -9.5..+9.2 deg (19.2 deg nominal); each line holds ``AEVA_POINTS_PER_LINE`` points evenly
  over azimuth -72..+72 deg (0.047 deg). Here every k-th point of a line is kept (``spec.rays``
  / 64 points a line) so that a frame holds tens of thousands of points, not 195k. Firing order
  (the pattern's point raycast mode): the 16 lines one after the other over the period, each
  line swept across the azimuth range, the 4 beams at once. CARLA's frame is left-handed (y to
  the right): its azimuth -72 deg (the start of a line) is our +72 deg (left).
"""

from __future__ import annotations

import numpy as np

#: grid sweep: the grid's azimuth columns fire in this many groups, evenly over one period
GRID_SWEEP_STEPS = 50
#: Aeva 64-19.2-Uniform: the beams' elevation offsets [deg] (0.01 and 0.03 rad)
AEVA_BEAM_OFFSETS_DEG = (0.5729578, -1.718873, 1.718873, -0.5729578)
#: Aeva 64-19.2-Uniform: the 16 elevation steps of each beam [deg], in firing order
AEVA_STEPS_DEG = (-7.8, -7.5, -7.2, -6.9, -3.0, -2.7, -2.4, -2.1, 1.8, 2.1, 2.4, 2.7,
                  6.6, 6.9, 7.2, 7.5)
#: Aeva 64-19.2-Uniform: horizontal field of view [deg] and points per line
AEVA_HFOV_DEG = 72.0
AEVA_POINTS_PER_LINE = 3051
#: Aeva sweep: each line is cast in this many groups of columns (a group shares one time:
#: 0.1 s / 16 lines / 8 = 0.78 ms, 1.3 cm of travel at 17 m/s)
AEVA_SWEEP_GROUPS_PER_LINE = 8

PATTERNS = ("grid", "aeva-64")


def unit_vectors(az: np.ndarray, el: np.ndarray) -> np.ndarray:
    """(N, 3) unit vectors of azimuth / elevation [rad]."""
    ce = np.cos(el)
    return np.stack([ce * np.cos(az), ce * np.sin(az), np.sin(el)], axis=1)


def grid_shape(rays: int, az_half_deg: float, el_half_deg: float) -> tuple[int, int]:
    """(n_az, n_el) of the uniform grid: equal angular spacing, about ``rays`` rays."""
    aspect = az_half_deg / el_half_deg
    n_el = max(2, int(round(np.sqrt(rays / aspect))))
    return max(2, int(round(rays / n_el))), n_el


def aeva_columns(rays: int) -> int:
    """Points kept per line of the Aeva pattern for about ``rays`` rays (2..3051)."""
    lines = len(AEVA_STEPS_DEG) * len(AEVA_BEAM_OFFSETS_DEG)
    return int(min(max(round(rays / lines), 2), AEVA_POINTS_PER_LINE))


def aeva_angles(n_cols: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Azimuth, elevation [rad], line (step) index and column (firing order within the line) of
    every ray of the Aeva pattern with ``n_cols`` points a line, ordered (beam, step, column)."""
    step = np.radians(np.array(AEVA_STEPS_DEG))
    beam = np.radians(np.array(AEVA_BEAM_OFFSETS_DEG))
    # the kept columns: every k-th of the 3051 azimuths, centred; a line fires from +72 deg
    keep = np.linspace(0, AEVA_POINTS_PER_LINE - 1, n_cols).round().astype(int)
    az_line = np.radians(AEVA_HFOV_DEG - 2 * AEVA_HFOV_DEG * keep / (AEVA_POINTS_PER_LINE - 1))
    b, s, c = np.meshgrid(np.arange(len(beam)), np.arange(len(step)), np.arange(n_cols),
                          indexing="ij")
    b, s, c = b.ravel(), s.ravel(), c.ravel()
    return az_line[c], step[s] + beam[b], s, c


def directions(pattern: str, rays: int, az_half_deg: float, el_half_deg: float) -> np.ndarray:
    """Unit ray directions (N, 3) in the sensor frame of one frame of ``pattern``."""
    if pattern == "grid":
        n_az, n_el = grid_shape(rays, az_half_deg, el_half_deg)
        a, e = np.radians(az_half_deg), np.radians(el_half_deg)
        az, el = np.meshgrid(np.linspace(-a, a, n_az), np.linspace(-e, e, n_el))
        return unit_vectors(az.ravel(), el.ravel())
    if pattern == "aeva-64":
        az, el, _, _ = aeva_angles(aeva_columns(rays))
        return unit_vectors(az, el)
    raise ValueError(f"unknown LiDAR scan pattern {pattern!r}; known: {', '.join(PATTERNS)}")


def firing_offsets(pattern: str, rays: int, az_half_deg: float, el_half_deg: float,
                   period_s: float) -> np.ndarray:
    """Time [s] after the stamp at which each ray of ``directions`` fires (same order), in
    [0, period_s): quantised to groups that share one time (``GRID_SWEEP_STEPS`` column groups
    of the grid; ``AEVA_SWEEP_GROUPS_PER_LINE`` groups of each Aeva line)."""
    if pattern == "grid":
        n_az, n_el = grid_shape(rays, az_half_deg, el_half_deg)
        column = np.arange(n_az * n_el) % n_az
        return np.floor(column * GRID_SWEEP_STEPS / n_az) * period_s / GRID_SWEEP_STEPS
    if pattern == "aeva-64":
        n_cols = aeva_columns(rays)
        _, _, line, col = aeva_angles(n_cols)
        groups = AEVA_SWEEP_GROUPS_PER_LINE
        group = np.floor(col * groups / n_cols)
        return (line + group / groups) * period_s / len(AEVA_STEPS_DEG)
    raise ValueError(f"unknown LiDAR scan pattern {pattern!r}; known: {', '.join(PATTERNS)}")
