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


# fidelity report -------------------------------------------------------------------------------

def test_paper_tables_are_read():
    paper = F.paper_table3()
    row = paper[("Loop1_4", "doppler", None)]
    assert row["rel"]["48"] == pytest.approx((15.604, 6.883))
    assert row["time_ms"] == pytest.approx(2.2) and row["class"] == "Semi-Dense 4D Radar"
    assert ("Campus1", "icp-p2p", False) in paper and ("Tunnel_Vehicles", "dicp", True) in paper
    ape = F.paper_ape()
    assert ape[("Loop1_3", "doppler")] == pytest.approx(101.74)
    assert ape[("Tunnel_Empty", "gicp")] == float("inf")


def _run(seq, method, seed, rot=1.0, trans=1.0, time_ms=1.0, ape=1.0, diverged=False):
    rel = {n: (rot, trans) for n in F.LENGTHS}
    return F.Run(seq, "", method, seed, rel, time_ms, ape, diverged)


def test_cells_ratios_and_checks():
    paper = F.paper_table3()
    p = paper[("Loop1_2", "doppler", None)]["rel"]
    runs = {("Loop1_2", "doppler", None): F.Run(
        "Loop1_2", "", "doppler", None, {n: (2 * p[n][0], 0.5 * p[n][1]) for n in F.LENGTHS},
        0.4, 1.0, False),
        ("Loop1_2", "dicp", True): _run("Loop1_2", "dicp", True, rot=10.0, trans=0.7)}
    cells = F.table3_cells(runs, paper)
    ours = [c for c in cells if c.method == "doppler" and c.quantity != "time_ms"]
    assert len(ours) == 12 and all(c.role == "calibration target" for c in ours)
    assert {round(c.ratio, 9) for c in ours} == {2.0, 0.5} and all(c.within for c in ours)
    (seq, worst, ok), = F.target_check(cells)
    assert seq == "Loop1_2" and worst == pytest.approx(2.0) and ok
    # dicp (with seed) on Loop1_2: rotation 10 deg is outside 2x at every length (paper
    # 0.63-1.86 deg); 0.7 m is inside only at 8 and 16 m (paper 0.62 and 1.12 m, then 1.63-3.21)
    (method, k, n), = F.prediction_shares(cells)
    assert method == "dicp" and (k, n) == (2, 12)
    csv_text = F.format_csv(cells)
    assert csv_text.splitlines()[0].startswith("data,sequence")
    assert all(line.startswith("synthetic,") for line in csv_text.splitlines()[1:])


def _tunnel_and_loop_runs(icp_div=True, dicp_ape=30.0):
    runs = {}
    for seq in F.TUNNELS:
        for m in F.ICP_FAMILY:
            runs[(seq, m, True)] = _run(seq, m, True, ape=None if icp_div else 5.0,
                                        diverged=icp_div)
        runs[(seq, "dicp", True)] = _run(seq, "dicp", True, ape=dicp_ape, time_ms=50.0)
        runs[(seq, "doppler", None)] = _run(seq, "doppler", None, ape=20.0, time_ms=5.0)
        runs[(seq, "doppler-icp", True)] = _run(seq, "doppler-icp", True, ape=10.0)
    for seq in ("Loop1_0", "Loop1_1", "Loop1_3", "Loop1_4"):
        for m in F.PAPER_METHODS:
            ours = m == "doppler"
            runs[(seq, m, None if ours else True)] = _run(
                seq, m, None if ours else True, ape=3.0 if ours else 5.0,
                time_ms=1.0 if ours else 50.0)
    runs[("Loop1_2", "doppler", None)] = _run("Loop1_2", "doppler", None, rot=1.05, trans=0.95)
    runs[("Loop1_2", "dicp", True)] = _run("Loop1_2", "dicp", True, rot=1.0, trans=1.0,
                                            time_ms=50.0)
    return runs


def test_findings_hold_on_paper_like_runs_and_fail_otherwise():
    paper = F.paper_table3()
    holds = [f.holds for f in F.findings(_tunnel_and_loop_runs(), paper)]
    assert holds == [True, True, True, True, True]
    # ICP that does not diverge, DICP best in the tunnels, doppler slower than DICP somewhere,
    # doppler 20 % off DICP on Loop1_2
    runs = _tunnel_and_loop_runs(icp_div=False, dicp_ape=1.0)
    runs[("Tunnel_Empty", "doppler", None)] = _run("Tunnel_Empty", "doppler", None,
                                                    time_ms=80.0)
    runs[("Loop1_2", "doppler", None)] = _run("Loop1_2", "doppler", None, rot=1.2)
    runs[("Loop1_3", "vgicp", True)] = _run("Loop1_3", "vgicp", True, ape=1.0)
    found = F.findings(runs, paper)
    assert [f.holds for f in found] == [False, False, False, False, False]
    assert any("NOT fastest" in m for m in found[0].measured)
    assert any("lowest vgicp" in m and "Loop1_3" in m for m in found[3].measured)


def test_report_is_titled_synthetic_and_written_from_run_folders(tmp_path):
    import json

    import yaml

    for seq, method, seed, rot in (("Loop1_0", "doppler", None, 1.2),
                                   ("Loop1_0", "dicp", True, 0.8)):
        d = tmp_path / seq / (method if seed is None else f"{method}_seed")
        d.mkdir(parents=True)
        rel = {n: {"rot_deg_mean": rot, "trans_m_mean": 0.7, "rot_deg_median": rot,
                   "trans_m_median": 0.7, "n": 10} for n in F.LENGTHS}
        (d / "metrics.json").write_text(json.dumps({
            "sequence": seq, "method": method, "seed": seed, "diverged": False,
            "relative_error": rel, "ape": {"trans_rmse_m": 2.0}, "time_ms": {"mean": 3.0}}))
        (d / "config.yaml").write_text(yaml.safe_dump(
            {"sequence": {"sensor_class": "Semi-Dense 4D Radar"}}))
    path = F.write_report(tmp_path)
    text = path.read_text()
    assert text.startswith("# Fidelity report - SYNTHETIC data")
    assert "not the paper's data" in text.splitlines()[0]
    assert "| Loop1_0 | doppler | calibration target | 8 m | 1.172 / 1.200 (1.02) |" in text
    assert "angle_accuracy_deg" in text  # the calibration is stated
    rows = (tmp_path / "fidelity.csv").read_text().splitlines()
    assert len(rows) == 1 + 2 * 13


def test_bench_synth_realism_prints_every_statistic_and_exits_by_the_check(real_vs_synth):
    """`bench synth --realism`: one line per statistic with the real and synthetic values and
    whether they are within 20 %; exit 0 only when all are. The verdict is recomputed here from
    the statistics computed in this process (``sequence_stats`` of both sequences, the
    ``real_vs_synth`` fixture; only its raw values, not its flags) with the issue's rule,
    |synthetic / real - 1| <= 0.2, so a command that prints a wrong flag or exits by another
    rule fails."""
    from typer.testing import CliRunner

    from bench.cli import app

    assert R.REAL_SAMPLE.exists(), f"the vendored real sample {R.REAL_SAMPLE} is missing"
    res = CliRunner().invoke(app, ["synth", "--realism"])
    lines = {ln.split()[0]: ln.split() for ln in res.output.splitlines() if ln.strip()}
    assert all(name in lines for name in R.STAT_NAMES + R.EXTRA_NAMES), res.output
    verdicts = {}
    for name in R.STAT_NAMES:
        _, real, synth, _, _ = real_vs_synth[name]
        printed_real, printed_synth = float(lines[name][1]), float(lines[name][2])
        assert printed_real == pytest.approx(real, abs=1e-3), name
        assert printed_synth == pytest.approx(synth, abs=1e-3), name
        verdicts[name] = abs(synth / real - 1.0) <= 0.20
        assert lines[name][-1] == ("yes" if verdicts[name] else "NO"), (name, lines[name])
    assert res.exit_code == (0 if all(verdicts.values()) else 1), res.output
    # today's known gaps (NOT_REACHED, strict xfails above) are the statistics outside
    assert {n for n, ok in verdicts.items() if not ok} == NOT_REACHED
