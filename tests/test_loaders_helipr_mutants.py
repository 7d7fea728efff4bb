"""Mutation-driven tests for loaders.helipr: tiny sequences in HeLiPR's byte layout (packed
25/29-byte Aeva records named by their ns stamp, LiDAR_GT/Aeva_gt.txt) and the helpers, each
checked against values written or worked out by hand."""

import numpy as np
import pytest

from helpers_public import write_helipr
from loaders.assemble import MAX_POINT_RANGE_M
from loaders.errors import DataError
from loaders.helipr import (
    INTENSITY_AFTER_NS,
    RECORD_25,
    RECORD_29,
    HeliprSequence,
    find_aeva_dir,
    implausible_share,
    read_gt,
    sensor_velocity,
)
from loaders.se3 import make_T
from loaders.sensor_classes import DENSE_LIDAR, sensor_class
from loaders.trajectory import Trajectory

T0_NS = INTENSITY_AFTER_NS - 100_000_000_000  # 100 s before the intensity stamp: 25 bytes
SPEED = 2.0  # m/s along x_world


def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def small_sequence(root, t0_ns=T0_NS, frames=4, n=20, velocity=None, gt_scale=1.0):
    """``frames`` scans 0.1 s apart of ``n`` points each; GT every 0.05 s moving at SPEED
    along x, from 0.2 s before the first scan to 0.2 s after the last. Returns (root, points,
    velocities, scan stamps ns)."""
    rng = np.random.default_rng(11)
    stamps = t0_ns + 100_000_000 * np.arange(frames, dtype=np.int64)
    pts = [rng.uniform([5, -10, -1], [30, 10, 1], (n, 3)).astype(np.float32)
           for _ in range(frames)]
    vel = velocity if velocity is not None else [rng.uniform(-3, 3, n).astype(np.float32)
                                                 for _ in range(frames)]
    gt_ns = stamps[0] - 200_000_000 + 50_000_000 * np.arange(2 * frames + 8, dtype=np.int64)
    gt_t = (gt_ns - gt_ns[0]) * 1e-9
    poses = np.stack([make_T(np.eye(3), [SPEED * s, 0.0, 0.0]) for s in gt_t])
    write_helipr(root, stamps, pts, vel, gt_ns, poses)
    if gt_scale != 1.0:  # rewrite the GT stamps in seconds
        gt = root / "LiDAR_GT" / "Aeva_gt.txt"
        rows = [r.split(" ", 1) for r in gt.read_text().splitlines()]
        gt.write_text("".join(f"{int(t) * gt_scale:.9f} {rest}\n" for t, rest in rows))
    return root, pts, vel, stamps


# --- sensor declaration (the model string changed since 942ccd0) ---------------------------

def test_sensor_is_a_dense_fmcw_lidar_at_the_scan_period(tmp_path):
    root, *_ = small_sequence(tmp_path / "s")
    seq = HeliprSequence(root)
    assert seq.sensor.model.startswith("lidar-fmcw")
    assert "Aeva Aeries II" in seq.sensor.model
    assert sensor_class(seq.sensor) == DENSE_LIDAR
    assert seq.sensor.period_s == pytest.approx(0.1, abs=1e-6)


# --- the records read against the records written -----------------------------------------

def test_every_field_read_back_and_the_provenance(tmp_path):
    root, pts, vel, stamps = small_sequence(tmp_path / "Seq07")
    seq = HeliprSequence(root)
    assert seq.name == "Seq07" and len(seq) == 4
    np.testing.assert_allclose(seq.stamps, stamps * 1e-9, rtol=0, atol=1e-6)
    s = seq[2]
    np.testing.assert_array_equal(s.points.astype(np.float32), pts[2])
    np.testing.assert_allclose(s.doppler, vel[2].astype(np.float64), rtol=0, atol=0)
    np.testing.assert_allclose(s.fields["reflectivity"], 0.5)
    np.testing.assert_allclose(s.fields["line_index"], np.arange(20) % 64)
    np.testing.assert_allclose(s.fields["time_offset_s"],
                               np.linspace(0, 99_000_000, 20).astype(np.int32) * 1e-9,
                               atol=1e-9)
    assert s.stamp == pytest.approx(stamps[2] * 1e-9, abs=1e-6)
    p = seq.provenance
    assert p["loader"] == "helipr" and p["frames_found"] == 4
    assert p["doppler_sign"] == 1.0 and p["nan_points_dropped"] == 0
    assert p["record_layout"] == "intensity auto: 0 files of 29 bytes a point, 4 of 25"
    assert p["stamp_source"].endswith("<t_ns>.bin file names")
    assert "ego-motion compensated" in p["doppler_source"]
    np.testing.assert_allclose(np.array(p["T_gt_sensor"]), np.eye(4))


def test_doppler_sign_minus_one_flips_and_other_signs_are_refused(tmp_path):
    root, pts, vel, _ = small_sequence(tmp_path / "s")
    seq = HeliprSequence(root, doppler_sign=-1)
    assert seq.doppler_sign == -1.0 and seq.provenance["doppler_sign"] == -1.0
    assert seq.options.doppler_sign == -1.0
    np.testing.assert_allclose(seq[1].doppler, -vel[1].astype(np.float64), atol=0)
    with pytest.raises(DataError, match="doppler_sign must be"):
        HeliprSequence(root, doppler_sign=0.5)


def test_intensity_option_overrides_the_stamp_rule(tmp_path):
    # files stamped before the rule's stamp but written with 29-byte records
    root = tmp_path / "s"
    aeva = root / "LiDAR" / "Aeva"
    aeva.mkdir(parents=True)
    stamps = T0_NS + 100_000_000 * np.arange(3, dtype=np.int64)
    for k, t in enumerate(stamps):
        rec = np.zeros(5, RECORD_29)
        rec["x"] = 10.0 + k
        rec["intensity"] = 3.0 + k
        rec.tofile(aeva / f"{t}.bin")
    # auto: 145 bytes is a whole number of 29-byte records, not of 25: the mixed-layout hint
    with pytest.raises(DataError, match=r"145 bytes is not a whole number of 25-byte records "
                                        r"\(without intensity\).*mixes the two layouts"):
        HeliprSequence(root)
    seq = HeliprSequence(root, intensity="yes")
    assert seq.provenance["record_layout"] == "intensity yes: 3 files of 29 bytes a point, 0 of 25"
    s = seq[1]
    np.testing.assert_allclose(s.points[:, 0], 11.0)
    np.testing.assert_allclose(s.fields["intensity"], 4.0)
    # "no" on 29-byte files stamped after the rule is refused the same way
    with pytest.raises(DataError, match="mixes the two layouts"):
        HeliprSequence(root, intensity="no")


def test_a_truncated_file_is_refused_when_opened(tmp_path):
    root, *_ = small_sequence(tmp_path / "s")
    f = sorted((root / "LiDAR" / "Aeva").iterdir())[1]
    f.write_bytes(f.read_bytes()[:-3])  # 497 bytes: neither 25 nor 29 divides it
    with pytest.raises(DataError, match=rf"{f.name}, frame 1: 497 bytes.*truncated or not this"):
        HeliprSequence(root)
    f.write_bytes(b"x")  # one byte: not empty, not a record
    with pytest.raises(DataError, match=rf"{f.name}, frame 1: 1 bytes.*truncated or not this"):
        HeliprSequence(root)


def test_an_empty_file_passes_the_layout_check(tmp_path):
    root, *_ = small_sequence(tmp_path / "s")
    f = sorted((root / "LiDAR" / "Aeva").iterdir())[2]
    f.write_bytes(b"")
    seq = HeliprSequence(root)  # the empty frame is refused only when read
    assert len(seq) == 4
    np.testing.assert_allclose(seq[0].fields["reflectivity"], 0.5)


def test_a_mixed_sequence_drops_intensity_from_every_frame(tmp_path):
    b = INTENSITY_AFTER_NS
    stamps = np.array([b - 50_000_000, b + 50_000_000], dtype=np.int64)
    pts = [np.full((4, 3), 5.0, np.float32)] * 2
    vel = [np.zeros(4, np.float32)] * 2
    gt_ns = b - 300_000_000 + 100_000_000 * np.arange(7, dtype=np.int64)
    poses = np.stack([np.eye(4)] * 7)
    root = write_helipr(tmp_path / "m", stamps, pts, vel, gt_ns, poses)
    seq = HeliprSequence(root)
    assert "intensity" not in seq[1].fields and "intensity" not in seq[0].fields
    np.testing.assert_allclose(seq[1].points, 5.0)


# --- stamps, folders, GT -------------------------------------------------------------------

def test_folder_and_stamp_errors(tmp_path):
    with pytest.raises(DataError, match=r"missing: not found; expected a HeLiPR/HeRCULES "
                                        r"sequence folder with LiDAR/Aeva/<t_ns>\.bin and "
                                        r"LiDAR_GT/Aeva_gt\.txt$"):
        find_aeva_dir(tmp_path / "missing")
    (tmp_path / "other" / "Aeva").mkdir(parents=True)  # an Aeva folder not under LiDAR
    with pytest.raises(DataError, match=r"Aeva: no LiDAR/Aeva folder; expected a HeLiPR/HeRCULES "
                                        r"sequence folder with LiDAR/Aeva/<t_ns>\.bin and "
                                        r"LiDAR_GT/Aeva_gt\.txt \(or global_Aeva_gt\.txt\)"):
        find_aeva_dir(tmp_path / "other" / "Aeva")
    (tmp_path / "x" / "LiDAR" / "Aeva").mkdir(parents=True)
    root, aeva = find_aeva_dir(tmp_path / "x" / "LiDAR" / "Aeva")
    assert root == tmp_path / "x" and aeva == tmp_path / "x" / "LiDAR" / "Aeva"
    assert find_aeva_dir(tmp_path / "x") == (tmp_path / "x", aeva)
    (aeva / "notes.txt").write_text("x")
    with pytest.raises(DataError, match="no <t_ns>.bin Aeva scans"):
        HeliprSequence(tmp_path / "x")
    np.zeros(2, RECORD_25).tofile(aeva / "100.bin")
    np.zeros(2, RECORD_25).tofile(aeva / "0100.bin")
    with pytest.raises(DataError, match="two scans share a stamp"):
        HeliprSequence(tmp_path / "x")
    (aeva / "0100.bin").unlink()
    (aeva / "99999999999999999999.bin").write_bytes(b"")  # 20 digits: beyond a ns stamp
    with pytest.raises(DataError, match=r"99999999999999999999\.bin: the number in the file"):
        HeliprSequence(tmp_path / "x")


def test_gt_stamps_in_seconds_or_nanoseconds(tmp_path):
    root_ns, *_ = small_sequence(tmp_path / "ns")
    root_s, *_ = small_sequence(tmp_path / "s", gt_scale=1e-9)
    a = read_gt(root_ns / "LiDAR_GT" / "Aeva_gt.txt")
    b = read_gt(root_s / "LiDAR_GT" / "Aeva_gt.txt")
    expected = (T0_NS - 200_000_000) * 1e-9 + 0.05 * np.arange(16)
    np.testing.assert_allclose(a.stamps, expected, atol=1e-6, rtol=0)
    np.testing.assert_allclose(b.stamps, expected, atol=1e-6, rtol=0)
    seq = HeliprSequence(root_s)
    assert len(seq.ground_truth) == 4


def test_gt_option_extrinsic_and_uncovered(tmp_path):
    root, _, _, stamps = small_sequence(tmp_path / "s")
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    moved = gt.rename(tmp_path / "elsewhere.txt")
    plain = HeliprSequence(root)
    assert plain.ground_truth is None and len(plain) == 4
    with pytest.raises(DataError, match=r"neither LiDAR_GT/Aeva_gt\.txt nor "
                                        r"LiDAR_GT/global_Aeva_gt\.txt exists \(or give gt=FILE\)"):
        HeliprSequence(root, reconstruct_doppler_from_gt=True)
    seq = HeliprSequence(root, gt=moved, extrinsic="1 2 3 0 0 0 1")
    assert seq.provenance["calibration_source"] == "option extrinsic"
    np.testing.assert_allclose(seq.sensor.T_body_sensor[:3, 3], [1, 2, 3])
    # pose of the sensor = GT pose @ T: x = SPEED * (t - t_gt0) + 1
    t_rel = (stamps - (stamps[0] - 200_000_000)) * 1e-9
    np.testing.assert_allclose(seq.ground_truth.poses[:, :3, 3],
                               np.column_stack([SPEED * t_rel + 1, np.full(4, 2.0),
                                                np.full(4, 3.0)]), atol=1e-6)
    with pytest.raises(DataError, match="ground-truth file not found"):
        HeliprSequence(root, gt=tmp_path / "nope.txt")
    # a GT clock 1 s late leaves every scan uncovered: trim keeps none, error refuses
    with pytest.raises(DataError):
        HeliprSequence(root, gt=moved, time_offset=5.0, uncovered="error")


# --- plausibility of the records -----------------------------------------------------------

def test_implausible_share_by_hand():
    rec = np.zeros(8, RECORD_25)
    rec["x"][1] = MAX_POINT_RANGE_M          # on the limit: plausible
    rec["y"][2] = -MAX_POINT_RANGE_M * 1.01  # beyond
    rec["z"][3] = np.nan
    rec["x"][4] = np.inf
    rec["time_offset_ns"][5] = 1_000_000_000   # 1 s: plausible
    rec["time_offset_ns"][6] = -1_000_000_001  # beyond 1 s
    assert implausible_share(rec) == pytest.approx(4 / 8)
    assert implausible_share(np.zeros(0, RECORD_25)) == 0.0


def test_impossible_points_name_the_other_layout_when_it_fits(tmp_path):
    root, *_ = small_sequence(tmp_path / "s", n=29)
    f = sorted((root / "LiDAR" / "Aeva").iterdir())[1]
    # 25 plausible 29-byte records = 725 bytes = 29 25-byte records: both sizes fit
    rec = np.zeros(25, RECORD_29)
    rec["x"] = 10.0
    rec["time_offset_ns"] = 50_000_000
    rec["intensity"] = 1e30
    rec.tofile(f)
    seq = HeliprSequence(root)
    with pytest.raises(DataError, match=r"read as 25-byte records \(without intensity\) \(the "
                                        r"layout of its stamp\), \d+ % of the points are "
                                        r"impossible.*read as 29-byte records \(with "
                                        r"intensity\) they are plausible"):
        seq[1]
    junk = np.full(29 * 25, 0x7F, np.uint8)  # every float ~3.4e38 in either layout
    junk.tofile(f)
    with pytest.raises(DataError, match="corrupt or not an Aeva scan"):
        seq[1]


# --- the sensor velocity from the GT -------------------------------------------------------

def test_sensor_velocity_is_in_the_sensor_frame_and_held_at_the_ends():
    t = 0.1 * np.arange(21)
    yaw = np.pi / 2  # sensor x along world y
    poses = np.stack([make_T(rot_z(yaw), [0.0, 3.0 * s, 0.0]) for s in t])
    gt = Trajectory(t, poses)
    v = sensor_velocity(gt, np.array([0.0, 1.0, 2.0, 5.0]), 0.1)
    np.testing.assert_allclose(v, np.tile([3.0, 0.0, 0.0], (4, 1)), atol=1e-9)
    # accelerating x = s^2: central difference is exact for a quadratic (v = 2 t)
    poses = np.stack([make_T(np.eye(3), [s * s, 0.0, 0.0]) for s in t])
    gt = Trajectory(t, poses)
    v = sensor_velocity(gt, np.array([1.0, 0.0, 2.0]), 0.1)
    np.testing.assert_allclose(v[:, 0], [2.0, 2 * 0.1, 2 * 1.9], atol=0.02)
    # h larger than half the span: the whole span, centred
    v = sensor_velocity(gt, np.array([0.3]), 5.0)
    np.testing.assert_allclose(v[0, 0], 4.0 / 2.0, atol=1e-9)


def test_reconstruction_clips_offsets_beyond_the_period(tmp_path):
    """Straight at SPEED along x: raw = comp - d . (SPEED, 0, 0) whatever the offset, and an
    offset beyond one period is taken at the period's end (same velocity here)."""
    root, pts, vel, _ = small_sequence(tmp_path / "s", frames=4, n=6)
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    assert seq.sensor.doppler_kind == "gt-reconstructed"
    for i in range(len(seq)):
        p = pts[seq._keep[i]].astype(np.float64)
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        np.testing.assert_allclose(seq[i].doppler,
                                   vel[seq._keep[i]] - d[:, 0] * SPEED, atol=1e-4)


def test_read_errors_name_the_stamp_layout_and_the_other_one(tmp_path):
    b = INTENSITY_AFTER_NS
    stamps = np.array([b - 50_000_000, b + 50_000_000, b + 150_000_000], dtype=np.int64)
    pts = [np.full((4, 3), 5.0, np.float32)] * 3
    vel = [np.zeros(4, np.float32)] * 3
    gt_ns = b - 300_000_000 + 100_000_000 * np.arange(8, dtype=np.int64)
    root = write_helipr(tmp_path / "r", stamps, pts, vel, gt_ns, np.stack([np.eye(4)] * 8))
    files = [root / "LiDAR" / "Aeva" / f"{t}.bin" for t in stamps]
    seq = HeliprSequence(root)
    files[0].write_bytes(b"")
    with pytest.raises(DataError, match=rf"frame 0: empty file \(0 bytes\); expected HeLiPR Aeva "
                                        rf"25-byte records \(without intensity: stamp at or "
                                        rf"before {b} ns\)"):
        seq[0]
    np.zeros(2, RECORD_25).tofile(files[1])  # 50 bytes: two 25-byte records, not 29-byte ones
    with pytest.raises(DataError, match=rf"frame 1: 50 bytes is not a whole number of 29-byte "
                                        rf"records \(HeLiPR Aeva 29-byte records \(with "
                                        rf"intensity: stamp after {b} ns\).*the 25-byte layout "
                                        r"\(without intensity\) \(25 bytes a point\)"):
        seq[1]
    # 29 plausible 25-byte records (725 bytes, also 25 29-byte ones) under an intensity stamp
    rec = np.zeros(29, RECORD_25)
    rec["x"] = 10.0
    rec["reflectivity"] = 1e30
    rec["velocity"] = 1e30
    rec.tofile(files[2])
    with pytest.raises(DataError, match=r"frame 2: read as 29-byte records \(with intensity\) "
                                        r"\(the layout of its stamp\).*read as 25-byte records "
                                        r"\(without intensity\) they are plausible"):
        seq[2]


def test_one_impossible_point_in_a_hundred_is_tolerated(tmp_path):
    """MAX_FAR_SHARE is 1 %: a share of exactly 1 % is still read (the NaN point dropped)."""
    rng = np.random.default_rng(3)
    p = rng.uniform(5, 20, (100, 3)).astype(np.float32)
    p[7, 1] = np.nan
    root, *_ = small_sequence(tmp_path / "s", n=100)
    f = sorted((root / "LiDAR" / "Aeva").iterdir())[0]
    rec = np.zeros(100, RECORD_25)
    rec["x"], rec["y"], rec["z"] = p[:, 0], p[:, 1], p[:, 2]
    rec.tofile(f)
    seq = HeliprSequence(root)
    with pytest.warns(UserWarning, match=rf"{f.name}, frame 0: dropped 1 of 100 points"):
        s = seq[0]
    assert seq.provenance["nan_points_dropped"] == 1
    assert len(s.points) == 99
    np.testing.assert_array_equal(s.points.astype(np.float32), np.delete(p, 7, axis=0))


def test_a_single_scan_has_the_nominal_period(tmp_path):
    root, *_ = small_sequence(tmp_path / "one", frames=1)
    seq = HeliprSequence(root)
    assert len(seq) == 1 and seq.sensor.period_s == pytest.approx(0.1)


def test_max_gap_option_decides_what_gt_hole_is_interpolated(tmp_path):
    root, *_ = small_sequence(tmp_path / "s", frames=4)
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    # GT every 0.05 s from 0.2 s before scan 0; drop rows 5..8: a 0.25 s hole around scan 1
    gt.write_text("".join(rows[:5] + rows[9:]))
    assert len(HeliprSequence(root, uncovered="error").ground_truth) == 4  # default 0.3 s
    with pytest.raises(DataError):
        HeliprSequence(root, uncovered="error", max_gap=0.2)


def test_reconstruction_shifts_the_gt_by_the_time_offset(tmp_path):
    """GT x = (s - g0)^2 on the GT clock; the sensor clock is GT + tau, so the sensor speed at
    sensor time t is 2 (t - tau - g0), and a point's raw radial velocity -d_x times that."""
    tau = 0.05
    stamps = T0_NS + 100_000_000 * np.arange(3, dtype=np.int64)
    rng = np.random.default_rng(4)
    pts = [rng.uniform([5, -10, -1], [30, 10, 1], (10, 3)).astype(np.float32) for _ in stamps]
    vel = [np.zeros(10, np.float32)] * 3
    gt_ns = stamps[0] - 300_000_000 + 50_000_000 * np.arange(20, dtype=np.int64)
    g = (gt_ns - gt_ns[0]) * 1e-9
    poses = np.stack([make_T(np.eye(3), [s * s, 0.0, 0.0]) for s in g])
    root = write_helipr(tmp_path / "acc", stamps, pts, vel, gt_ns, poses)
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True, time_offset=tau)
    assert len(seq) == 3
    offsets = np.linspace(0, 99_000_000, 10).astype(np.int32) * 1e-9
    for i in range(3):
        p = pts[i].astype(np.float64)
        d = p / np.linalg.norm(p, axis=1, keepdims=True)
        t_rel = (stamps[i] - gt_ns[0]) * 1e-9 + offsets
        np.testing.assert_allclose(seq[i].doppler, -d[:, 0] * 2 * (t_rel - tau), atol=1e-3)


def test_a_gt_gap_names_the_first_scan_inside_it(tmp_path):
    root, *_ = small_sequence(tmp_path / "s", frames=5)
    files = sorted((root / "LiDAR" / "Aeva").iterdir())
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    gt.write_text("".join(rows[:5] + rows[11:]))  # no GT from 0.05 to 0.3 s: scans 1..3
    with pytest.raises(DataError, match=rf"{files[1].name}, frame 1: inside a gap of .* "
                                        r"cannot be reconstructed from the GT; cut the sequence"), \
            pytest.warns(UserWarning):
        HeliprSequence(root, reconstruct_doppler_from_gt=True)


def test_a_25_byte_file_under_an_intensity_stamp_is_refused_when_opened(tmp_path):
    root, *_ = small_sequence(tmp_path / "s", t0_ns=INTENSITY_AFTER_NS + 1_000_000_000)
    f = sorted((root / "LiDAR" / "Aeva").iterdir())[1]
    np.zeros(2, RECORD_25).tofile(f)  # 50 bytes: two 25-byte records, not 29-byte ones
    with pytest.raises(DataError, match=rf"{f.name}, frame 1: 50 bytes is not a whole number of "
                                        r"29-byte records \(with intensity\), the layout of its "
                                        r"stamp.*; it is a whole number of 25-byte records "
                                        r"\(without intensity\): the sequence mixes the two "
                                        r"layouts \(set --intensity yes/no for the whole "
                                        r"sequence, or remove the frame\)"):
        HeliprSequence(root)
