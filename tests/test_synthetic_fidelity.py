"""Fidelity of the synthetic suite: the LiDAR sweep (per-point time offsets, motion distortion,
Doppler at each point's own time), the real-sample statistics of the semi-dense radar, and the
fidelity table's arithmetic and orderings."""

from __future__ import annotations

import numpy as np
import pytest

from bench.studies import fidelity as F
from bench.studies import realism as R
from loaders.se3 import transform_points
from loaders.synthetic import SyntheticSequence
from loaders.synthetic.sensors import SENSORS, SWEEP_STEPS


def _fd_velocity(motion, t: float, h: float = 1e-4) -> np.ndarray:
    """Sensor velocity in the sensor frame at motion time t by central differences of the GT
    sensor poses (independent of the model's analytic twist)."""
    Tp, T0, Tm = (motion.sensor_pose(np.array([t + d]))[0] for d in (h, 0.0, -h))
    return T0[:3, :3].T @ (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)


# LiDAR sweep ---------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def wall_sweep():
    return SyntheticSequence("straight-wall", "lidar-dense", 12, seed=7, noise=False,
                             points=6000, sweep=True)


def test_sweep_offsets_span_one_period_in_azimuth_order(wall_sweep):
    period = SENSORS["lidar-dense"].period_s
    scan = wall_sweep.scan(5)
    tau = scan.fields["time_offset_s"]
    assert len(tau) == len(scan)
    steps = np.round(tau / (period / SWEEP_STEPS))
    np.testing.assert_allclose(tau, steps * period / SWEEP_STEPS, atol=1e-12)
    assert tau.min() == 0.0 and period - period / SWEEP_STEPS - 1e-12 <= tau.max() < period
    # columns are swept right (-az) to left (+az): the offset never decreases with azimuth
    az = np.arctan2(scan.points[:, 1], scan.points[:, 0])
    assert np.all(np.diff(tau[np.argsort(az, kind="stable")]) >= 0)


def test_sweep_points_lie_on_the_scene_at_their_own_time(wall_sweep):
    """Known answer: the straight-wall scene is the road z = 0 and the walls' inner faces
    y = left and y = -right (world frame). Each point mapped with the sensor pose at its own
    time lies on one of them; mapped with the stamp's pose (ignoring the offset) it does not."""
    p = wall_sweep.scene_model.params
    faces_y = np.array([p["wall_left_m"], -p["wall_right_m"]])
    i = 6
    scan = wall_sweep.scan(i)
    tau = scan.fields["time_offset_s"]
    t = wall_sweep.stamps[i] + tau
    T = wall_sweep.motion.sensor_pose(t)
    world = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points) + T[:, :3, 3]

    def off_surface(w):
        return np.minimum(np.abs(w[:, 2]), np.abs(w[:, 1:2] - faces_y).min(axis=1))

    assert off_surface(world).max() < 1e-6
    at_stamp = transform_points(wall_sweep.ground_truth.poses[i], scan.points)
    late = tau > 0.05
    # late points were cast >= 0.05 s after the stamp (~0.7 m of travel at 12-16.5 m/s)
    assert np.median(off_surface(at_stamp[late])) > 1e-3


def test_sweep_doppler_is_the_radial_velocity_at_each_points_time(wall_sweep):
    i = 9
    scan = wall_sweep.scan(i)
    tau = scan.fields["time_offset_s"]
    d = scan.points / np.linalg.norm(scan.points, axis=1, keepdims=True)
    expected = np.empty(len(scan))
    for step in np.unique(tau):
        rows = tau == step
        v = _fd_velocity(wall_sweep.motion, wall_sweep.stamps[i] + step)
        expected[rows] = -(d[rows] @ v)
    np.testing.assert_allclose(scan.doppler, expected, atol=1e-6)
    # the sensor-frame velocity changes over the sweep (attitude oscillation), so the Doppler
    # at the stamp's velocity would differ: the test can tell the two apart
    v0 = _fd_velocity(wall_sweep.motion, wall_sweep.stamps[i])
    assert np.abs(scan.doppler - (-(d @ v0))).max() > 1e-4


def test_no_sweep_no_time_offsets():
    seq = SyntheticSequence("tunnel", "lidar-dense", 3, seed=1, points=3000)
    assert "time_offset_s" not in seq.scan(1).fields


def test_sweep_with_movers_gives_their_doppler_at_the_points_time():
    """Tunnel with traffic: a moving point's Doppler includes the mover's velocity at its own
    time; static points still obey -d . v_sensor(t + tau)."""
    seq = SyntheticSequence("tunnel-vehicles", "lidar-dense", 6, seed=5, noise=False,
                            points=4000, sweep=True)
    scan = seq.scan(3)
    tau = scan.fields["time_offset_s"]
    static = scan.fields["gt_label"] == 0
    assert (~static).sum() > 20
    d = scan.points / np.linalg.norm(scan.points, axis=1, keepdims=True)
    own = np.array([seq.motion.sensor_twist(np.array([seq.stamps[3] + s]))[0][0]
                    for s in tau[static]])
    np.testing.assert_allclose(scan.doppler[static], -np.einsum("ij,ij->i", d[static], own),
                               atol=1e-9)
    assert np.abs(scan.doppler[~static] + np.einsum(
        "ij,j->i", d[~static], seq.sensor_twist(3)[0])).max() > 1.0


# real-sample statistics ------------------------------------------------------------------------

def test_sequence_stats_known_answer():
    """Exact static radar scans: the ego-velocity residual vanishes, every point is an inlier."""
    seq = SyntheticSequence("straight-wall", "lidar-dense", 4, seed=2, noise=False, points=2000)
    st = R.sequence_stats(seq)
    assert st["doppler_resid_mps"] < 1e-9 and st["inlier_frac"] == 1.0
    counts = [len(seq.scan(i)) for i in range(4)]
    assert st["points"] == np.median(counts)
    r = np.concatenate([np.linalg.norm(seq.scan(i).points, axis=1) for i in range(4)])
    assert st["range_p50_m"] == pytest.approx(np.median(r))


def test_noise_split_recovers_known_doppler_and_azimuth_noise():
    """Static points seen from a known velocity, Doppler noise 0.04 m/s and azimuth noise 0.8
    deg added: the fit of e^2 on the squared azimuth sensitivity returns both."""
    rng = np.random.default_rng(3)
    n, v = 200_000, np.array([8.0, 0.5, 0.1])
    az, el = rng.uniform(-1.0, 1.0, n), rng.uniform(-0.2, 0.2, n)
    r = rng.uniform(5.0, 150.0, n)
    d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    doppler = -(d @ v) + rng.normal(0.0, 0.04, n)
    az_meas = az + rng.normal(0.0, np.radians(0.8), n)  # the point is reported off its ray
    d_meas = np.column_stack([np.cos(el) * np.cos(az_meas), np.cos(el) * np.sin(az_meas),
                              np.sin(el)])
    e2, s2 = R.noise_split(r[:, None] * d_meas, doppler, v, np.ones(n, bool))
    sd, saz = R._fit_noise(e2, s2)
    assert sd == pytest.approx(0.04, rel=0.05) and saz == pytest.approx(0.8, rel=0.05)


def test_feature_residuals_known_answer():
    """Exact static pair: |f - g| ~ 0 (second order in the motion); a range error dr of the
    target point adds 2 r dr."""
    from methods.doppler import DopplerScan

    p = np.array([[30.0, 4.0, 1.0], [80.0, -10.0, 3.0]])
    v, dt = np.array([9.0, 0.0, 0.0]), 0.1
    q = p - v * dt  # the sensor moved forward: the same static points in the later frame
    dop = lambda x: -(x / np.linalg.norm(x, axis=1, keepdims=True)) @ v  # noqa: E731
    src = DopplerScan(0.0, np.ascontiguousarray(p.T, np.float32), dop(p).astype(np.float32))
    idx = np.arange(2)
    exact = R.feature_residuals(src, DopplerScan(dt, np.ascontiguousarray(q.T, np.float32),
                                                 dop(q).astype(np.float32)), idx, idx)
    assert exact.max() < 0.02
    rq = np.linalg.norm(q, axis=1)
    q_off = q * ((rq + 0.05) / rq)[:, None]  # 5 cm farther
    off = R.feature_residuals(src, DopplerScan(dt, np.ascontiguousarray(q_off.T, np.float32),
                                               dop(q).astype(np.float32)), idx, idx)
    np.testing.assert_allclose(off, 2 * rq * 0.05, rtol=0.05)


@pytest.fixture(scope="module")
def real_vs_synth():
    assert R.REAL_SAMPLE.exists(), f"the vendored real sample {R.REAL_SAMPLE} is missing"
    real = R.sequence_stats(R.real_sample())
    synth = R.sequence_stats(R.synthetic_semidense(60))
    return {row[0]: row for row in R.compare(real, synth)}


#: not reached yet (issue 11, see loaders/synthetic/README.md): the loop scene lacks the real
#: sample's far content (median range 71 m, elevations 2-6 deg) and its spatially clustered
#: detections; strict, so reaching one fails here until it is moved back to the asserted set
NOT_REACHED = {"range_p50_m", "range_p90_m", "elev_iqr_deg", "kept_frac"}


@pytest.mark.parametrize("name", [
    pytest.param(n, marks=pytest.mark.xfail(strict=True, reason="scene texture not calibrated"))
    if n in NOT_REACHED else n for n in R.STAT_NAMES])
def test_semidense_radar_matches_the_real_sample(real_vs_synth, name):
    _, real, synth, ratio, ok = real_vs_synth[name]
    assert ok, f"{name}: real {real:.3f}, synthetic {synth:.3f} (ratio {ratio:.2f})"


# fidelity table ------------------------------------------------------------------------------

def test_paper_table_and_ratios():
    paper = F.paper_table()
    row = paper[("Loop1_4", "doppler", None)]
    assert row["rot_48"] == pytest.approx(15.604)
    assert ("Campus1", "icp-p2p", False) in paper and ("Tunnel_Vehicles", "dicp", True) in paper
    r = F.Row("Loop1_4", "Semi-Dense 4D Radar", "doppler", None, row,
              {"rot_8": 6.246, "trans_8": 0.44, "rot_48": 15.604, "trans_48": np.nan}, False)
    assert r.ratio("rot_8") == pytest.approx(2.0, rel=1e-3)
    assert r.ratio("trans_8") == pytest.approx(0.5, rel=1e-2)
    assert r.ratio("rot_48") == pytest.approx(1.0)
    assert np.isnan(r.ratio("trans_48"))
    csv_text = F.format_csv([r])
    assert "Loop1_4" in csv_text.splitlines()[1] and ",2.0" in csv_text


def _row(seq, method, seed, rot8, rot48):
    v = {"rot_8": rot8, "trans_8": 1.0, "rot_48": rot48, "trans_48": 1.0}
    return F.Row(seq, "", method, seed, v, v, False)


def test_orderings_hold_and_fail():
    rows = [_row("Campus1", "doppler", None, 1.0, 2.0), _row("Campus1", "icp-p2p", True, 2.0, 3.0),
            _row("Loop1_0", "doppler", None, 1.0, 2.0), _row("Loop1_0", "dicp", True, 0.5, 3.0),
            _row("Loop1_4", "doppler", None, 1.0, 5.0),
            _row("Tunnel_Empty", "doppler", None, 1.0, 2.0),
            _row("Tunnel_Empty", "dicp", True, 0.5, 1.0)]
    checks = {c[0].split(":")[0]: c[2] for c in F.orderings(rows)}
    assert checks["Campus1"] is True
    assert checks["Loop1_0"] is False  # dicp's 48 m rotation 3.0 > doppler's 2.0
    assert checks["Loop1_4 (U-turn)"] is False  # 5.0 < 3 x 2.0
    assert checks["Tunnel_Empty"] is True


def test_bench_synth_realism_prints_every_statistic_and_exits_by_the_check():
    """`bench synth --realism`: one line per statistic; exit 0 only when all are within 20 %."""
    from typer.testing import CliRunner

    from bench.cli import app

    assert R.REAL_SAMPLE.exists(), f"the vendored real sample {R.REAL_SAMPLE} is missing"
    res = CliRunner().invoke(app, ["synth", "--realism"])
    lines = {ln.split()[0]: ln for ln in res.output.splitlines() if ln.strip()}
    assert all(name in lines for name in R.STAT_NAMES + R.EXTRA_NAMES), res.output
    all_within = all(lines[name].rstrip().endswith("yes") for name in R.STAT_NAMES)
    assert res.exit_code == (0 if all_within else 1), res.output
