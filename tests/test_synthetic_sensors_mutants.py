"""Known answers of the synthetic sensor model (loaders/synthetic/sensors.py): spec look-up,
field of view, radar equation, fading statistics, noise levels, spread, ghosts and clutter.

Every expected value is worked out from the module's documented model (docstrings), not read
from its output; the statistical checks use many points and tolerances of several standard
errors, with fixed seeds."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from helpers_angles import on_azimuth_edge
from loaders.synthetic import patterns
from loaders.synthetic import sensors as S

RADAR = S.SENSORS["radar-sparse"]
SEMI = S.SENSORS["radar-semidense"]
LIDAR = S.SENSORS["lidar-dense"]


def _quiet_radar(**changes) -> S.SensorSpec:
    """radar-sparse without dropouts, ghosts, clutter or a point limit (unless changed)."""
    base = {"dropout": 0.0, "ghost_frac": 0.0, "clutter_frac": 0.0, "max_points": 0,
            "sigma_bias_deg": 0.0}
    return dataclasses.replace(RADAR, **{**base, **changes})


def _cart(r, az, el) -> np.ndarray:
    r, az, el = np.broadcast_arrays(np.asarray(r, float), np.asarray(az, float),
                                    np.asarray(el, float))
    return np.column_stack([r * np.cos(el) * np.cos(az), r * np.cos(el) * np.sin(az),
                            r * np.sin(el)])


def _radar_call(spec, points, *, seed=0, noise=False, material=None, cos_inc=None,
                dynamic=None, v_sensor=(0.0, 0.0, 0.0), doppler=None, **kw):
    n = len(points)
    return S.measure(spec, np.random.default_rng(seed), points,
                     np.zeros(n) if doppler is None else doppler,
                     np.ones(n) if cos_inc is None else cos_inc,
                     np.full(n, 1) if material is None else material,
                     np.zeros(n, bool) if dynamic is None else dynamic,
                     np.asarray(v_sensor, float), noise, **kw)


# ---- spec look-up ----------------------------------------------------------------------------

def test_get_sensor_returns_each_spec_and_names_the_unknown_one():
    for name, spec in S.SENSORS.items():
        assert S.get_sensor(name) is spec and spec.name == name
    with pytest.raises(ValueError) as err:
        S.get_sensor("radar-nope")
    text = str(err.value)
    assert text.startswith("unknown sensor 'radar-nope'; known: ")
    assert text.endswith(", ".join(S.SENSORS))


def test_with_rays_sets_an_integer_count_and_nothing_else():
    spec = S.with_rays(LIDAR, 1234.9)
    assert spec.rays == 1234 and isinstance(spec.rays, int)
    assert dataclasses.replace(spec, rays=LIDAR.rays) == LIDAR


def test_body_to_sensor_transform_is_the_lever_arm():
    T = SEMI.T_body_sensor
    np.testing.assert_allclose(T[:3, :3], np.eye(3))
    np.testing.assert_allclose(T[:3, 3], [3.6, 0.0, 0.7])
    np.testing.assert_allclose(T[3], [0.0, 0.0, 0.0, 1.0])
    d = SEMI.as_dict()
    assert d["name"] == "radar-semidense" and d["resolution"] == (0.25, 1.0, 2.0)
    assert set(d) == {f.name for f in dataclasses.fields(S.SensorSpec)}


def test_grid_shape_and_sweep_offsets_follow_the_pattern():
    assert S.grid_shape(LIDAR) == patterns.grid_shape(LIDAR.rays, 60.0, 15.0)
    aeva = S.SENSORS["lidar-aeva"]
    off = S.sweep_offsets(aeva, 64 * 509)
    assert len(off) == 64 * 509
    assert off.min() >= 0.0 and off.max() < aeva.period_s
    # the grid: columns fired in 50 groups, 2 ms apart over the 0.1 s period
    grid = S.sweep_offsets(LIDAR, len(S.ray_directions(LIDAR, np.random.default_rng(0))))
    np.testing.assert_allclose(np.unique(grid), 0.002 * np.arange(50), atol=1e-12)
    with pytest.raises(ValueError, match=r"sweep_offsets: 10 rays, expected the pattern's "
                                         r"32576"):
        S.sweep_offsets(aeva, 10)


# ---- ray directions and angles ---------------------------------------------------------------

def test_radar_rays_are_uniform_in_the_field_of_view():
    rays = S.ray_directions(SEMI, np.random.default_rng(1))
    assert rays.shape == (1200, 3)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0)
    az = np.degrees(np.arctan2(rays[:, 1], rays[:, 0]))
    el = np.degrees(np.arcsin(rays[:, 2]))
    assert np.abs(az).max() <= 60.0 and np.abs(el).max() <= 15.0
    # uniform: the extremes come near both edges, the means near 0
    assert az.min() < -57 and az.max() > 57 and el.min() < -14 and el.max() > 14
    assert abs(az.mean()) < 3.0 and abs(el.mean()) < 1.0
    again = S.ray_directions(SEMI, np.random.default_rng(1))
    np.testing.assert_array_equal(rays, again)


def test_lidar_rays_are_the_fixed_pattern():
    rays = S.ray_directions(LIDAR, np.random.default_rng(0))
    np.testing.assert_array_equal(rays, patterns.directions("grid", LIDAR.rays, 60.0, 15.0))


def test_spherical_known_points():
    r, az, el = S._spherical(np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 2.0], [0.0, -1.0, -1.0]]))
    np.testing.assert_allclose(r, [5.0, 2.0, np.sqrt(2.0)])
    np.testing.assert_allclose(az, [np.arctan2(4, 3), 0.0, -np.pi / 2])
    np.testing.assert_allclose(el, [0.0, np.pi / 2, -np.pi / 4])


# ---- radar equation, antenna, fading, margin -------------------------------------------------

def test_antenna_taper_known_answers():
    spec = _quiet_radar(edge_loss_db=4.0)
    a, e = np.radians(75.0), np.radians(15.0)
    got = S.antenna_db(spec, np.array([0.0, a, 0.0, a, a / 2]), np.array([0.0, 0.0, e, e, 0.0]))
    np.testing.assert_allclose(got, [0.0, -2.0, -2.0, -4.0, -0.5])


def test_point_snr_follows_the_radar_equation():
    spec = _quiet_radar(point_gain_db=40.0, edge_loss_db=3.0)
    r = np.array([10.0, 20.0, 1.0, 0.2, 10.0])
    az = np.array([0.0, 0.0, 0.0, 0.0, np.radians(75.0)])
    got = S.point_snr_db(spec, np.array([0.0, 6.0, 0.0, 0.0, 0.0]), r, az, np.zeros(5))
    # r^-4: -12.04 dB per doubling; below 0.5 m the range is clamped at 0.5 m
    np.testing.assert_allclose(got, [40.0, 46.0 - 40 * np.log10(2.0), 80.0,
                                     40.0 - 40 * np.log10(0.05), 38.5])


@pytest.mark.parametrize("swerling, var", [(1, 1.0), (3, 0.5)])
def test_fading_has_unit_mean_power_and_the_swerling_variance(swerling, var):
    f = S.fading_db(np.random.default_rng(5), np.full(200_000, swerling))
    p = 10 ** (f / 10)
    assert abs(p.mean() - 1.0) < 0.01
    assert abs(p.var() - var) < 0.03


def test_detection_margin_is_a_cell_plus_three_sigma():
    spec = dataclasses.replace(SEMI, sigma_bias_deg=0.4, sigma_az_deg=1.0, sigma_el_deg=2.0,
                               noise_floor=0.5, angle_accuracy_deg=0.3,
                               resolution=(0.25, 1.5, 2.5))
    np.testing.assert_allclose(S.detection_margin_deg(spec),
                               [1.5 + 3 * np.sqrt(0.16 + 0.25 + 0.09),
                                2.5 + 3 * np.sqrt(0.16 + 1.0 + 0.09)])
    peak = dataclasses.replace(spec, resolution=())
    np.testing.assert_allclose(S.detection_margin_deg(peak),
                               [3 * np.sqrt(0.5), 3 * np.sqrt(1.25)])
    np.testing.assert_array_equal(S.detection_margin_deg(LIDAR), [0.0, 0.0])


# ---- LiDAR measurement -----------------------------------------------------------------------

def _lidar_call(spec, points, *, seed=0, noise=False, material=None, cos_inc=None,
                dynamic=None, **kw):
    n = len(points)
    return S.measure(spec, np.random.default_rng(seed), points, np.zeros(n),
                     np.ones(n) if cos_inc is None else cos_inc,
                     np.full(n, 1) if material is None else material,
                     np.zeros(n, bool) if dynamic is None else dynamic, np.zeros(3), noise,
                     **kw)


def _on_el_edge(half_deg: float) -> float:
    """A z with arcsin(z / |(1, 0, z)|) exactly the radians of ``half_deg``."""
    target = np.radians(half_deg)
    z = np.tan(target)
    for _ in range(200):
        got = S._spherical(np.array([[1.0, 0.0, z]]))[2][0]
        if got == target:
            return z
        z = np.nextafter(z, np.inf if got < target else -np.inf)
    raise AssertionError("no exact edge point found")


def test_lidar_field_of_view_and_range_limits_are_inclusive():
    spec = dataclasses.replace(LIDAR, dropout=0.0)
    y = on_azimuth_edge(60.0)
    z = _on_el_edge(15.0)
    pts = np.array([[1.0, 0.0, 0.0],  # at min_range: kept
                    [150.0, 0.0, 0.0],  # at max_range: kept
                    [0.99, 0.0, 0.0],  # too near
                    [150.01, 0.0, 0.0],  # too far
                    [10.0, 10.0 * y, 0.0],  # on the azimuth edge: kept
                    [10.0, -10.0 * y, 0.0],
                    [10.0, 10.0 * np.tan(np.radians(60.01)), 0.0],  # just outside
                    [10.0, -10.0 * np.tan(np.radians(60.01)), 0.0],
                    [10.0, 0.0, 10.0 * np.tan(np.radians(15.01))],  # above
                    [10.0, 0.0, -10.0 * np.tan(np.radians(15.01))],  # below
                    [10.0, 0.0, 10.0 * np.tan(np.radians(14.99))],  # just inside
                    [1.0, 0.0, z], [1.0, 0.0, -z]])  # on the elevation edges: kept
    out, dop, fields = _lidar_call(spec, pts)
    np.testing.assert_array_equal(out, pts[[0, 1, 4, 5, 10, 11, 12]])
    assert len(dop) == 7 and set(fields) == {"intensity", "gt_label"}


def test_lidar_intensity_and_weak_return_cut():
    spec = dataclasses.replace(LIDAR, dropout=0.0)
    # intensity = reflectivity(material) * cos; kept when intensity / max(r / 100, 0.1)^2 > 0.01
    pts = np.array([[120.0, 0, 0], [120.0, 0, 0], [5.0, 0, 0], [5.0, 0, 0], [20.0, 0, 0]])
    cos = np.array([0.1, 0.09, 0.05, 0.03, 0.5])
    mat = np.array([0, 0, 0, 0, 5])
    dyn = np.array([False, False, True, False, True])
    out, _, fields = _lidar_call(spec, pts, cos_inc=cos, material=mat, dynamic=dyn)
    # 0.015 / 1.44 = 0.0104 kept; 0.0135 / 1.44 dropped; 0.0075 / 0.01 kept; 0.0045 / 0.01 kept
    np.testing.assert_array_equal(out, pts[[0, 2, 3, 4]])
    np.testing.assert_allclose(fields["intensity"], [0.015, 0.0075, 0.0045, 0.25])
    np.testing.assert_array_equal(fields["gt_label"], [0.0, 1.0, 0.0, 1.0])
    # below 10 m the range factor is clamped at 0.1: an incidence of 0.001 at 5 m gives
    # 0.00015 / 0.01 = 0.015 (kept), 0.0005 gives 0.0075 (dropped; unclamped it would be 0.03)
    out, _, _ = _lidar_call(spec, np.array([[5.0, 0, 0], [5.0, 0, 0]]),
                            cos_inc=np.array([0.001, 0.0005]), material=np.array([0, 0]))
    np.testing.assert_array_equal(out, [[5.0, 0, 0]])
    # 1 % below the cut at 120 m (0.15 x 0.095 / 1.44 = 0.0098958) and exactly on it at 50 m
    # (0.5 x 0.005 / 0.25 = 0.01, not above it): both dropped; 1 % above kept
    pts = np.array([[120.0, 0, 0], [50.0, 0, 0], [120.0, 0, 0]])
    out, _, _ = _lidar_call(spec, pts, cos_inc=np.array([0.095, 0.005, 0.097]),
                            material=np.array([0, 2, 0]))
    np.testing.assert_array_equal(out, pts[2:])


def test_lidar_dropout_share_and_time_offsets():
    spec = dataclasses.replace(LIDAR, dropout=0.3)
    n = 20_000
    pts = _cart(np.full(n, 20.0), np.zeros(n), np.zeros(n))
    off = np.linspace(0.0, 0.09, n).astype(np.float32)
    out, _, fields = _lidar_call(spec, pts, time_offset_s=off)
    assert abs(len(out) / n - 0.7) < 0.015
    # each kept point keeps its own offset
    kept = np.flatnonzero(np.random.default_rng(0).uniform(size=n) >= 0.3)
    np.testing.assert_array_equal(fields["time_offset_s"], off[kept])
    assert fields["time_offset_s"].dtype == np.float64


def test_lidar_noise_levels():
    spec = dataclasses.replace(LIDAR, dropout=0.0, sigma_range=0.05, sigma_az_deg=0.1,
                               sigma_el_deg=0.2, sigma_doppler=0.3)
    n = 20_000
    r0, az0, el0 = 30.0, 0.2, 0.05
    pts = _cart(np.full(n, r0), np.full(n, az0), np.full(n, el0))
    out, dop, _ = _lidar_call(spec, pts, noise=True, seed=3)
    assert len(out) == n
    r, az, el = S._spherical(out)
    for got, mean, sd in ((r, r0, 0.05), (az, az0, np.radians(0.1)), (el, el0, np.radians(0.2)),
                          (dop, 0.0, 0.3)):
        assert abs(got.mean() - mean) < 4 * sd / np.sqrt(n)
        assert abs(got.std() / sd - 1.0) < 0.03


# ---- radar measurement -----------------------------------------------------------------------

def test_radar_point_scatterer_snr_rcs_and_power_known_answers():
    spec = _quiet_radar(snr_threshold_db=-100.0, point_gain_db=40.0, snr_gain_db=30.0)
    pts = _cart([10.0, 20.0, 1.0], [0.0, 0.0, np.radians(37.5)], [0.0, 0.0, 0.0])
    scat = np.array([4, 7, 0])
    rcs = np.array([5.0, 5.0, 0.0])
    fad = np.array([-1.0, 2.0, 0.0])
    out, _, f = _radar_call(spec, pts, scatterer=scat, rcs_db=rcs, fading=fad)
    np.testing.assert_allclose(out, pts)
    # edge loss 3 dB at the azimuth edge, quadratic: 37.5 deg of 75 -> 0.375 dB
    snr = np.array([40.0 + 5.0 - 1.0, 40.0 + 5.0 - 40 * np.log10(2.0) + 2.0,
                    40.0 + 40.0 - 0.375])
    np.testing.assert_allclose(f["snr"], snr)
    np.testing.assert_allclose(f["rcs"], [4.0, 7.0, -0.375])
    np.testing.assert_allclose(f["power"], snr + 40.0)
    np.testing.assert_array_equal(f["gt_scatterer"], [4.0, 7.0, 0.0])
    np.testing.assert_array_equal(f["gt_label"], [0.0, 0.0, 0.0])
    assert set(f) == {"snr", "gt_scatterer", "rcs", "power", "gt_label"}


def test_radar_diffuse_snr_differences_follow_material_incidence_and_range():
    """Same seed and row count: the same fading draws, so SNR differences are exact."""
    spec = _quiet_radar(snr_threshold_db=-300.0, min_range=0.1)
    base = _cart([10.0] * 4, [0.0] * 4, [0.0] * 4)
    mat = np.array([1, 0, 4, 1])
    cos = np.array([1.0, 1.0, 1.0, 1.0])
    ref = _radar_call(spec, base, material=mat, cos_inc=cos)[2]["snr"]
    # incidence: rough surfaces 10 log10(cos), the road (material 0) 30 log10(cos)
    got = _radar_call(spec, base, material=mat, cos_inc=np.array([0.5, 0.5, 1e-5, 1.0]))[2]
    np.testing.assert_allclose(got["snr"] - ref, [10 * np.log10(0.5), 30 * np.log10(0.5),
                                                  10 * np.log10(1e-3), 0.0])
    # material reflectivity and r^-2 range loss (clamped at 0.5 m)
    far = _cart([20.0, 1.0, 0.3, 10.0], [0.0] * 4, [0.0] * 4)
    got = _radar_call(spec, far, material=np.array([1, 0, 1, 6]), cos_inc=cos)[2]
    np.testing.assert_allclose(got["snr"] - ref, [-20 * np.log10(2.0), 20.0,
                                                  -20 * np.log10(0.05) + 8.0 - 10.0,
                                                  15.0 - 8.0])
    # the antenna taper: 3 dB at the field of view's corner, 1.5 dB at an azimuth edge
    edge = _cart([10.0] * 4, np.radians([75.0, -75.0, 0.0, 75.0]), np.radians([0, 0, 0, 15.0]))
    got = _radar_call(spec, edge, material=mat, cos_inc=cos)[2]
    np.testing.assert_allclose(got["snr"] - ref, [-1.5, -1.5, 0.0, -3.0], atol=1e-9)
    np.testing.assert_array_equal(got["gt_scatterer"], [-1.0] * 4)


def test_radar_diffuse_rcs_is_the_reflectivity_plus_fading():
    spec = _quiet_radar(snr_threshold_db=-300.0)
    pts = _cart([10.0, 20.0, 40.0], [0.0] * 3, [0.0] * 3)
    mat = np.array([6, 6, 6])
    f = _radar_call(spec, pts, material=mat, seed=4)[2]
    fading = f["rcs"] - 15.0  # reflectivity of material 6: 15 dB; boresight, cos 1
    # the same fading reappears in the SNR: snr = 15 + fading - 20 log10(r / 10) + snr_gain
    np.testing.assert_allclose(f["snr"], 15.0 + fading - 20 * np.log10([1.0, 2.0, 4.0]) + 30.0)
    np.testing.assert_allclose(f["power"], f["snr"] + 40.0)


def test_radar_diffuse_fading_is_swerling_1_on_average():
    spec = _quiet_radar(snr_threshold_db=-300.0)
    n = 100_000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    f = _radar_call(spec, pts, material=np.full(n, 6), seed=8)[2]
    p = 10 ** ((f["snr"] - 15.0 - 30.0) / 10)
    assert abs(p.mean() - 1.0) < 0.015 and abs(p.var() - 1.0) < 0.05


@pytest.mark.parametrize("swerling, var", [(None, 0.5), (1, 1.0)])
def test_radar_scatterer_fading_drawn_here_has_the_swerling_case(swerling, var):
    spec = _quiet_radar(snr_threshold_db=-300.0, point_gain_db=40.0)
    n = 100_000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    kw = {} if swerling is None else {"swerling": np.full(n, swerling)}
    f = _radar_call(spec, pts, scatterer=np.arange(n), rcs_db=np.zeros(n), seed=9, **kw)[2]
    p = 10 ** ((f["snr"] - 40.0) / 10)
    assert abs(p.mean() - 1.0) < 0.015 and abs(p.var() - var) < 0.05


def test_radar_caller_fading_is_kept_for_scatterers_and_drawn_for_diffuse_rows():
    spec = _quiet_radar(snr_threshold_db=-300.0, point_gain_db=40.0)
    n = 40_000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    scat = np.where(np.arange(n) < n // 2, np.arange(n), -1)
    fad = np.full(n, 3)  # integer dB: the diffuse rows' fading is still continuous
    f = _radar_call(spec, pts, scatterer=scat, rcs_db=np.zeros(n), fading=fad,
                    material=np.full(n, 6), seed=2)[2]
    point = f["gt_scatterer"] >= 0
    np.testing.assert_allclose(f["snr"][point], 43.0)
    p = 10 ** ((f["snr"][~point] - 45.0) / 10)
    assert abs(p.mean() - 1.0) < 0.03 and p.std() > 0.9
    frac = np.abs(f["snr"][~point] - np.round(f["snr"][~point]))
    assert frac.mean() > 0.2
    np.testing.assert_array_equal(fad, 3)  # the caller's array is not changed


def test_radar_detection_threshold_is_strict():
    spec = _quiet_radar(snr_threshold_db=12.0, point_gain_db=40.0)
    pts = _cart([10.0] * 3, [0.0] * 3, [0.0] * 3)
    out, _, f = _radar_call(spec, pts, scatterer=np.arange(3), rcs_db=np.array([-28.0] * 3),
                            fading=np.array([0.0, 0.5, -0.5]))
    np.testing.assert_array_equal(f["gt_scatterer"], [1.0])


def test_radar_dropout_share():
    spec = _quiet_radar(snr_threshold_db=-300.0, dropout=0.25)
    n = 20_000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    out = _radar_call(spec, pts, scatterer=np.arange(n), rcs_db=np.zeros(n),
                      fading=np.zeros(n))[0]
    assert abs(len(out) / n - 0.75) < 0.015


def test_radar_keeps_the_strongest_max_points():
    spec = _quiet_radar(snr_threshold_db=-300.0, max_points=5)
    n = 12
    pts = _cart(np.full(n, 10.0), np.linspace(-0.5, 0.5, n), np.zeros(n))
    rcs = np.array([3.0, 9.0, -2.0, 8.0, 1.0, 7.0, 0.0, 12.0, 4.0, -5.0, 2.0, 6.0])
    out, _, f = _radar_call(spec, pts, scatterer=np.arange(n), rcs_db=rcs,
                            fading=np.zeros(n))
    # the antenna taper is symmetric and below 0.1 dB here: the order is the RCS order
    assert sorted(f["gt_scatterer"].astype(int)) == [1, 3, 5, 7, 11]
    np.testing.assert_allclose(out, pts[[1, 3, 5, 7, 11]])
    # out-of-view rows never take a place: a strong scatterer behind the sensor is dropped
    pts[7] = [-10.0, 0.0, 0.0]
    f = _radar_call(spec, pts, scatterer=np.arange(n), rcs_db=rcs, fading=np.zeros(n))[2]
    assert sorted(f["gt_scatterer"].astype(int)) == [1, 3, 5, 8, 11]


def test_radar_max_points_ties_keep_the_earlier_rows():
    spec = _quiet_radar(snr_threshold_db=-300.0, max_points=30)
    n = 200
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    rcs = np.tile([3.0, 1.0, 2.0, 3.0, 2.0], 40)  # 80 rows tie at the top
    f = _radar_call(spec, pts, scatterer=np.arange(n), rcs_db=rcs, fading=np.zeros(n))[2]
    top = np.flatnonzero(rcs == 3.0)[:30]
    np.testing.assert_array_equal(np.sort(f["gt_scatterer"]), top)


def test_radar_noise_scales_with_snr_between_the_floor_and_1_5():
    spec = _quiet_radar(snr_threshold_db=-300.0, point_gain_db=40.0, snr_ref_db=20.0,
                        noise_floor=0.4, sigma_range=0.1, sigma_az_deg=0.5, sigma_el_deg=0.8,
                        sigma_doppler=0.2)
    n = 30_000
    r0, az0, el0 = 30.0, 0.1, 0.05
    pts = _cart(np.full(4 * n, r0), np.full(4 * n, az0), np.full(4 * n, el0))
    # SNR 20 dB (scale 1), 40 dB (10^-1 -> floor 0.4), 4 dB (10^0.8 = 6.3 -> cap 1.5),
    # 26 dB (10^-0.3 = 0.501); the antenna taper at (0.1, 0.05) rad is added back
    taper = S.antenna_db(spec, np.array([az0]), np.array([el0]))[0]
    snr = np.repeat([20.0, 40.0, 4.0, 26.0], n)
    rcs = snr - 40.0 + 40 * np.log10(3.0) - taper
    out, dop, f = _radar_call(spec, pts, noise=True, seed=11, scatterer=np.arange(4 * n),
                              rcs_db=rcs, fading=np.zeros(4 * n), doppler=np.full(4 * n, 1.0))
    assert len(out) == 4 * n
    order = np.argsort(f["gt_scatterer"])
    r, az, el = S._spherical(out[order])
    dop = dop[order]
    for k, scale in enumerate((1.0, 0.4, 1.5, 10 ** -0.3)):
        rows = slice(k * n, (k + 1) * n)
        for got, mean, sd in ((r, r0, 0.1 * scale), (az, az0, np.radians(0.5) * scale),
                              (el, el0, np.radians(0.8) * scale), (dop, 1.0, 0.2)):
            assert abs(got[rows].mean() - mean) < 4.5 * sd / np.sqrt(n)
            assert abs(got[rows].std() / sd - 1.0) < 0.015


def test_radar_angle_accuracy_adds_in_quadrature_and_bias_shifts():
    spec = _quiet_radar(snr_threshold_db=-300.0, point_gain_db=40.0, snr_ref_db=20.0,
                        sigma_range=0.01, sigma_az_deg=0.3, sigma_el_deg=0.4,
                        angle_accuracy_deg=0.4, sigma_bias_deg=0.5)
    n = 30_000
    pts = _cart(np.full(n, 30.0), np.zeros(n), np.zeros(n))
    rcs = np.full(n, 20.0 - 40.0 + 40 * np.log10(3.0))  # SNR 20 dB: scale 1
    bias = np.column_stack([np.ones(n), -2.0 * np.ones(n)])
    out, _, f = _radar_call(spec, pts, noise=True, seed=12, scatterer=np.arange(n),
                            rcs_db=rcs, fading=np.zeros(n), angle_bias=bias)
    _, az, el = S._spherical(out)
    np.testing.assert_allclose(np.degrees(az.std()), 0.5, rtol=0.03)
    np.testing.assert_allclose(np.degrees(el.std()), np.sqrt(0.4**2 + 0.4**2), rtol=0.03)
    np.testing.assert_allclose(np.degrees(az.mean()), 0.5, atol=0.02)
    np.testing.assert_allclose(np.degrees(el.mean()), -1.0, atol=0.02)
    # without noise the bias is not applied
    out, _, _ = _radar_call(spec, pts[:10], scatterer=np.arange(10), rcs_db=rcs[:10],
                            fading=np.zeros(10), angle_bias=bias[:10])
    np.testing.assert_allclose(out, pts[:10])


def test_radar_spread_reports_strong_scatterers_in_the_neighbouring_cells():
    spec = dataclasses.replace(SEMI, dropout=0.0, ghost_frac=0.0, clutter_frac=0.0,
                               max_points=0, sigma_bias_deg=0.0, sigma_range=1e-7,
                               sigma_az_deg=1e-7, sigma_el_deg=1e-7, sigma_doppler=1e-7,
                               snr_threshold_db=10.0, point_gain_db=40.0)
    pts = _cart([20.0], [0.1], [0.02])
    out, dop, f = _radar_call(spec, pts, noise=True, scatterer=np.array([5]),
                              rcs_db=np.array([40.0]), fading=np.zeros(1),
                              doppler=np.array([-2.5]), dynamic=np.array([True]),
                              angle_bias=np.zeros((1, 2)))
    r, az, el = S._spherical(out)
    cells = np.column_stack([r - 20.0, np.degrees(az - 0.1), np.degrees(el - 0.02)])
    want = [[0, 0, 0], [-0.25, 0, 0], [0.25, 0, 0], [0, -1, 0], [0, 1, 0], [0, 0, -2], [0, 0, 2]]
    np.testing.assert_allclose(cells, want, atol=1e-4)
    np.testing.assert_allclose(dop, -2.5, atol=1e-5)
    np.testing.assert_array_equal(f["gt_scatterer"], 5.0)
    np.testing.assert_array_equal(f["gt_label"], 1.0)
    snr0 = 40.0 + 40.0 - 40 * np.log10(2.0) + S.antenna_db(spec, np.array([0.1]),
                                                          np.array([0.02]))[0]
    loss = np.array([0, 6, 6, 6, 6, 9, 9])
    assert np.all(np.abs(f["snr"] - (snr0 - loss)) < 7.5)  # 5 sigma of the 1.5 dB variation
    assert f["snr"][0] == pytest.approx(snr0)


def test_radar_spread_needs_a_source_3_db_above_the_nearest_cell():
    """Sources: SNR - min loss + 3 dB above the threshold; a scatterer 2.5 dB above the
    threshold is never spread, one 8 dB above spreads in range and azimuth about half of the
    time (neighbour SNR: thr + 2 + N(0, 1.5))."""
    spec = dataclasses.replace(SEMI, dropout=0.0, ghost_frac=0.0, clutter_frac=0.0,
                               max_points=0, sigma_bias_deg=0.0, snr_threshold_db=10.0,
                               point_gain_db=40.0, edge_loss_db=0.0)
    n = 500
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    kw = {"scatterer": np.arange(n), "fading": np.zeros(n), "noise": True}
    out = _radar_call(spec, pts, rcs_db=np.full(n, 12.5 - 40.0), **kw)[0]
    assert len(out) == n
    out = _radar_call(spec, pts, rcs_db=np.full(n, 18.0 - 40.0), **kw)[0]
    extra = len(out) - n
    # 4 range / azimuth neighbours pass with p = P(N(0, 1.5) > -2) = 0.909; elevation (9 dB):
    # P(N > 1) = 0.252 each
    assert abs(extra - n * (4 * 0.909 + 2 * 0.252)) < 5 * np.sqrt(n * 6 * 0.25)
    # without noise there is no spread
    out = _radar_call(spec, pts, rcs_db=np.full(n, 18.0 - 40.0), scatterer=np.arange(n),
                      fading=np.zeros(n))[0]
    assert len(out) == n


def test_radar_ghosts_are_further_copies_with_the_same_doppler():
    spec = _quiet_radar(snr_threshold_db=-300.0, point_gain_db=40.0, ghost_frac=0.5,
                        sigma_range=1e-6, sigma_az_deg=1e-6, sigma_el_deg=1e-6,
                        sigma_doppler=1e-6, angle_accuracy_deg=0.0)
    n = 4000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.full(n, 0.1))
    rcs = np.full(n, -20.0)  # SNR 20 dB
    out, dop, f = _radar_call(spec, pts, noise=True, seed=13, scatterer=np.arange(n),
                              rcs_db=rcs, fading=np.zeros(n), doppler=np.full(n, 1.25))
    ghost = f["gt_label"] == 2
    assert abs(ghost.sum() - 0.5 * n) < 5 * np.sqrt(0.5 * n)
    assert np.all(f["gt_label"][~ghost] == 0) and (~ghost).sum() == n
    r, az, el = S._spherical(out[ghost])
    assert r.min() >= 11.0 - 1e-4 and r.max() <= 17.0 + 1e-4
    assert r.min() < 11.2 and r.max() > 16.8 and abs(r.mean() - 14.0) < 0.1
    np.testing.assert_allclose(np.abs(el), 0.1, atol=1e-4)  # mirrored in elevation or not
    assert abs(np.mean(el < 0) - 0.5) < 0.05
    assert abs(np.degrees(az.std()) - 3.0) < 0.15 and abs(np.degrees(az.mean())) < 0.3
    np.testing.assert_allclose(dop[ghost], 1.25, atol=1e-4)
    np.testing.assert_array_equal(f["gt_scatterer"][ghost], -1.0)
    # the source's SNR (20 dB less the antenna taper at 0.1 rad elevation) minus U(3, 10) dB
    src = 20.0 - 1.5 * (0.1 / np.radians(15.0)) ** 2
    g_snr = f["snr"][ghost] - src
    assert g_snr.min() >= -10.0 - 1e-9 and g_snr.max() <= -3.0 + 1e-9
    assert g_snr.min() < -9.8 and g_snr.max() > -3.2


def test_radar_clutter_is_uniform_with_unrelated_doppler():
    spec = _quiet_radar(snr_threshold_db=12.0, point_gain_db=40.0, clutter_frac=0.5,
                        sigma_doppler=1e-6)
    n = 4000
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    v = np.array([5.0, 0.0, 0.0])
    out, dop, f = _radar_call(spec, pts, noise=True, seed=14, scatterer=np.arange(n),
                              rcs_db=np.full(n, -20.0), fading=np.zeros(n), v_sensor=v,
                              doppler=np.zeros(n))
    clut = f["gt_label"] == 2
    assert abs(clut.sum() - 0.5 * n) < 5 * np.sqrt(0.5 * n)
    r, az, el = S._spherical(out[clut])
    # ranges uniform in [min_range, 0.8 max_range] (plus up to 1.5 sigma_range of noise)
    assert r.min() > 0.5 - 0.5 and r.max() < 80.0 + 0.5 and r.max() > 78.0
    assert abs(r.mean() - (0.5 + 80.0) / 2) < 1.5
    assert np.degrees(np.abs(az)).max() > 73.0 and np.degrees(np.abs(el)).max() > 14.0
    # Doppler of a static point seen from the moving sensor plus N(0, 3 m/s)
    resid = dop[clut] + _cart(np.ones(clut.sum()), az, el) @ v
    assert abs(resid.mean()) < 0.3 and abs(resid.std() - 3.0) < 0.2
    snr = f["snr"][clut]
    assert snr.min() >= 12.0 and abs((snr - 12.0).mean() - 3.0) < 0.25
    np.testing.assert_array_equal(f["gt_scatterer"][clut], -1.0)
    # no noise: no clutter and no ghosts
    f = _radar_call(spec, pts, seed=14, scatterer=np.arange(n), rcs_db=np.full(n, -20.0),
                    fading=np.zeros(n))[2]
    assert len(f["gt_label"]) == n and not np.any(f["gt_label"] == 2)


def test_radar_noise_with_no_detection_adds_no_ghost_or_clutter():
    spec = _quiet_radar(snr_threshold_db=100.0, ghost_frac=0.5, clutter_frac=0.5)
    pts = _cart([10.0, 20.0], [0.0, 0.0], [0.0, 0.0])
    out, dop, f = _radar_call(spec, pts, noise=True, scatterer=np.arange(2),
                              rcs_db=np.zeros(2), fading=np.zeros(2))
    assert out.shape == (0, 3) and len(dop) == 0 and len(f["gt_label"]) == 0
    out, _, _ = _radar_call(spec, np.zeros((0, 3)), noise=True)
    assert out.shape == (0, 3)


def test_radar_ghosts_of_a_single_detection():
    spec = _quiet_radar(snr_threshold_db=-300.0, ghost_frac=6.0, sigma_range=1e-6)
    pts = _cart([10.0], [0.0], [0.0])
    out, _, f = _radar_call(spec, pts, noise=True, seed=3, scatterer=np.array([0]),
                            rcs_db=np.zeros(1), fading=np.zeros(1))
    ghost = f["gt_label"] == 2
    assert ghost.sum() >= 1 and (~ghost).sum() == 1
    r = np.linalg.norm(out[ghost], axis=1)
    assert r.min() >= 11.0 - 1e-4 and r.max() <= 17.0 + 1e-4


def _spread_spec(**changes) -> S.SensorSpec:
    base = {"dropout": 0.0, "ghost_frac": 0.0, "clutter_frac": 0.0, "max_points": 0,
            "sigma_bias_deg": 0.0, "sigma_range": 1e-7, "sigma_az_deg": 1e-7,
            "sigma_el_deg": 1e-7, "sigma_doppler": 1e-7, "snr_threshold_db": 10.0,
            "point_gain_db": 40.0, "edge_loss_db": 0.0}
    return dataclasses.replace(SEMI, **{**base, **changes})


def _cells(out, r0, az0, el0):
    r, az, el = S._spherical(out)
    return np.column_stack([r - r0, np.degrees(az - az0), np.degrees(el - el0)])


def test_radar_spread_of_scatterer_0_with_integer_cells_and_its_bias():
    spec = _spread_spec(resolution=(1, 2, 3), spread_loss_db=(6, 6, 9), sigma_bias_deg=0.5)
    pts = _cart([20.0], [0.0], [0.0])
    out, _, f = _radar_call(spec, pts, noise=True, scatterer=np.array([0]),
                            rcs_db=np.array([30.0]), fading=np.zeros(1),
                            angle_bias=np.array([[1.0, -1.0]]))
    # every detection carries the scatterer's persistent bias (+0.5, -0.5 deg)
    want = [[0, 0, 0], [-1, 0, 0], [1, 0, 0], [0, -2, 0], [0, 2, 0], [0, 0, -3], [0, 0, 3]]
    np.testing.assert_allclose(_cells(out, 20.0, np.radians(0.5), np.radians(-0.5)), want,
                               atol=1e-4)
    np.testing.assert_array_equal(f["gt_scatterer"], 0.0)


def test_radar_spread_source_condition_is_strict():
    """SNR exactly min loss - 3 dB above the threshold (13 dB): not a source."""
    spec = _spread_spec()
    n = 500
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    out = _radar_call(spec, pts, noise=True, scatterer=np.arange(n),
                      rcs_db=np.full(n, 13.0 - 40.0), fading=np.zeros(n))[0]
    assert len(out) == n


def test_radar_spread_draws_each_neighbour_independently():
    """Equal losses and an SNR 6 dB above the threshold: each neighbouring cell of each
    scatterer is detected with probability 1/2, independently."""
    spec = _spread_spec(spread_loss_db=(6.0, 6.0, 6.0))
    n = 400
    pts = _cart(np.full(n, 10.0), np.zeros(n), np.zeros(n))
    out, _, f = _radar_call(spec, pts, noise=True, seed=5, scatterer=np.arange(n),
                            rcs_db=np.full(n, 16.0 - 40.0), fading=np.zeros(n))
    cells = np.round(_cells(out, 10.0, 0.0, 0.0), 3)
    for axis, step in ((0, 0.25), (1, 1.0), (2, 2.0)):
        for sign in (-1.0, 1.0):
            want = np.zeros(3)
            want[axis] = sign * step
            count = np.all(np.isclose(cells, want, atol=1e-3), axis=1).sum()
            assert abs(count - n / 2) < 5 * np.sqrt(n / 4)
    nb = f["gt_scatterer"][n:]
    assert len(np.unique(nb)) > 0.9 * n  # most scatterers have a neighbour
