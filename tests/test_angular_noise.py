"""methods/angular_noise.py: the angular noise recovered from Doppler residuals (known
answer), and its compiled normal equations against the plain numpy form."""

from __future__ import annotations

import numpy as np

from methods.angular_noise import AngularNoise, _normal_equations, sensitivities
from methods.ego_velocity import estimate_ego_velocity


def noisy_scan(rng, n, v, saz_deg, sel_deg, sd):
    az = rng.uniform(-np.radians(60), np.radians(60), n)
    el = rng.uniform(-np.radians(20), np.radians(20), n)
    r = rng.uniform(3, 100, n)
    d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    doppler = -d @ v + rng.normal(0, sd, n)  # measured along the true direction
    az_m = az + rng.normal(0, np.radians(saz_deg), n)  # ... the point reported off it
    el_m = el + rng.normal(0, np.radians(sel_deg), n)
    pts = r[:, None] * np.column_stack([np.cos(el_m) * np.cos(az_m),
                                        np.cos(el_m) * np.sin(az_m), np.sin(el_m)])
    return pts, doppler


def estimated(saz_deg, sel_deg, sd, scans=10):
    rng = np.random.default_rng(11)
    v = np.array([8.0, 0.5, 0.3])
    noise = AngularNoise()
    for _ in range(scans):
        pts, dop = noisy_scan(rng, 4000, v, saz_deg, sel_deg, sd)
        ego = estimate_ego_velocity(pts, dop, threshold_mps=1.0)
        noise.add(pts[ego.inliers], dop[ego.inliers], ego.velocity)
    return noise.estimate()


def test_recovers_known_angular_and_doppler_noise():
    sd, saz, sel = estimated(0.5, 1.0, 0.03)
    assert abs(sd - 0.03) < 0.003 and abs(saz - 0.5) < 0.05 and abs(sel - 1.0) < 0.1
    # a radar's large elevation noise (the real Eagle's) is recovered too; the first-order
    # model then gives part of the Doppler variance to the angles, which is not used
    _, saz, sel = estimated(0.4, 2.5, 0.03)
    assert abs(saz - 0.4) < 0.06 and abs(sel - 2.5) < 0.25


def test_compiled_normal_equations_equal_numpy():
    rng = np.random.default_rng(2)
    v = np.array([6.0, -0.4, 0.2])
    pts, dop = noisy_scan(rng, 500, v, 0.5, 1.0, 0.05)
    XtX, Xty = _normal_equations(pts, dop, v)
    s_az, s_el = sensitivities(pts, v)
    e2 = (dop + (pts / np.linalg.norm(pts, axis=1, keepdims=True)) @ v) ** 2
    X = np.column_stack([np.ones(len(pts)), s_az**2, s_el**2])
    np.testing.assert_allclose(XtX, X.T @ X, rtol=1e-10)
    np.testing.assert_allclose(Xty, X.T @ e2, rtol=1e-10)


def test_sensitivities_are_the_derivatives_of_the_predicted_doppler():
    rng = np.random.default_rng(4)
    v = np.array([5.0, 1.0, -0.5])
    az, el, r = rng.uniform(-1, 1, 50), rng.uniform(-0.3, 0.3, 50), rng.uniform(2, 50, 50)

    def doppler(az, el):
        return -(np.cos(el) * np.cos(az) * v[0] + np.cos(el) * np.sin(az) * v[1]
                 + np.sin(el) * v[2])

    pts = r[:, None] * np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az),
                                        np.sin(el)])
    s_az, s_el = sensitivities(pts, v)
    h = 1e-6
    np.testing.assert_allclose(s_az, (doppler(az + h, el) - doppler(az - h, el)) / (2 * h),
                               atol=1e-6)
    np.testing.assert_allclose(s_el, (doppler(az, el + h) - doppler(az, el - h)) / (2 * h),
                               atol=1e-6)


def test_nothing_to_estimate_without_points():
    assert AngularNoise().estimate() is None
