"""Mutation-driven tests for loaders.helipr, second round: the survivors the first round left
(the frame-size limit's message, the truncation and corruption hints, the default GT gap, the
scan folder named in association errors, GT that does not start at 0, points at or near the
sensor and per-point offsets outside one period in the GT reconstruction). Every sequence is
written in HeLiPR's byte layout (packed 25/29-byte Aeva records named by their ns stamp,
LiDAR_GT/Aeva_gt.txt); the expected values are worked out by hand in each test."""

import numpy as np
import pytest

from helpers_public import write_helipr
from loaders.errors import DataError
from loaders.helipr import INTENSITY_AFTER_NS, RECORD_25, RECORD_29, HeliprSequence, sensor_velocity
from loaders.se3 import make_T
from loaders.trajectory import Trajectory

T0_NS = INTENSITY_AFTER_NS - 100_000_000_000  # 100 s before the intensity stamp: 25 bytes
STEP_NS = 100_000_000  # scans 0.1 s apart


def straight(root, frames=3, n=8, gt_step_ns=50_000_000, speed=2.0, points=None, offsets=None):
    """``frames`` scans of ``n`` points (zero compensated velocity) and GT every ``gt_step_ns``
    moving at ``speed`` m/s along x, from 0.3 s before the first scan to 0.3 s after the last.
    Returns (root, scan stamps ns)."""
    stamps = T0_NS + STEP_NS * np.arange(frames, dtype=np.int64)
    rng = np.random.default_rng(8)
    pts = points or [rng.uniform([5, -10, -1], [30, 10, 1], (n, 3)).astype(np.float32)
                     for _ in range(frames)]
    vel = [np.zeros(len(p), np.float32) for p in pts]
    span = (frames - 1) * STEP_NS + 600_000_000
    gt_ns = stamps[0] - 300_000_000 + gt_step_ns * np.arange(span // gt_step_ns + 1,
                                                             dtype=np.int64)
    g = (gt_ns - gt_ns[0]) * 1e-9
    poses = np.stack([make_T(np.eye(3), [speed * s, 0.0, 0.0]) for s in g])
    write_helipr(root, stamps, pts, vel, gt_ns, poses, time_offset_ns=offsets)
    return root, stamps


def aeva_files(root):
    return sorted((root / "LiDAR" / "Aeva").iterdir())


# --- check_layouts ---------------------------------------------------------------------------

def test_a_frame_above_the_size_limit_is_named_with_its_index(tmp_path, monkeypatch):
    """check_layouts 12: the limit's message starts with the file and frame index."""
    root, _ = straight(tmp_path / "s", n=10)  # 250-byte files
    monkeypatch.setenv("BENCH_MAX_FRAME_MB", "0.0001")  # 100 bytes
    first = aeva_files(root)[0]
    with pytest.raises(DataError) as err:
        HeliprSequence(root)
    assert str(err.value).startswith(f"{first}, frame 0: the file (250 bytes) would take")


def test_a_size_of_neither_layout_says_truncated(tmp_path):
    """check_layouts 44: 26 bytes is neither 25- nor 29-byte records (26 % 25 = 1,
    26 % 29 = 26)."""
    root, _ = straight(tmp_path / "s")
    f = aeva_files(root)[1]
    f.write_bytes(bytes(26))
    with pytest.raises(DataError) as err:
        HeliprSequence(root)
    msg = str(err.value)
    assert msg.startswith(f"{f}, frame 1: 26 bytes is not a whole number of 25-byte records")
    assert msg.endswith(f"(intensity after {INTENSITY_AFTER_NS} ns); the file is truncated or "
                        "not this layout")


def test_a_25_byte_stamp_file_of_29_byte_records_says_the_layouts_are_mixed(tmp_path):
    """check_layouts 35: 58 bytes under a 25-byte stamp is two 29-byte records (58 % 25 = 8)."""
    root, _ = straight(tmp_path / "s")
    f = aeva_files(root)[0]
    f.write_bytes(bytes(58))
    with pytest.raises(DataError) as err:
        HeliprSequence(root)
    assert "; it is a whole number of 29-byte records (with intensity): the sequence mixes " \
        "the two layouts" in str(err.value)


# --- sensor_velocity -------------------------------------------------------------------------

def test_sensor_velocity_window_is_the_whole_span_for_gt_not_starting_at_zero():
    """sensor_velocity 11: h above half the span is cut to half the span (0.2 s here), so
    the difference is over the whole GT span [100, 100.4] s: x rises 1.2 m, 3 m/s. A window
    of the requested 5 s would reach outside the GT."""
    t = 100.0 + 0.1 * np.arange(5)
    poses = np.stack([make_T(np.eye(3), [3.0 * (s - 100.0), 0.0, 0.0]) for s in t])
    v = sensor_velocity(Trajectory(t, poses), np.array([100.1, 100.3]), 5.0)
    np.testing.assert_allclose(v, [[3.0, 0.0, 0.0], [3.0, 0.0, 0.0]], atol=1e-9)


# --- __init__ --------------------------------------------------------------------------------

def test_provenance_names_the_sequence_root(tmp_path):
    """__init__ 93-95: the provenance's "root" is the sequence folder, also when opened from
    its LiDAR/Aeva folder."""
    root, _ = straight(tmp_path / "Seq01")
    assert HeliprSequence(root).provenance["root"] == str(root)
    assert HeliprSequence(root / "LiDAR" / "Aeva").provenance["root"] == str(root)


@pytest.mark.parametrize(("gt_step_ns", "max_gap"), [(200_000_000, 0.6), (50_000_000, 0.3)])
def test_default_max_gap_is_three_gt_steps_at_least_0_3_s(tmp_path, gt_step_ns, max_gap):
    """__init__ 147/160: the option's documented default, 3 median GT steps (0.2 s -> 0.6 s),
    at least 0.3 s (0.05 s -> 0.3 s)."""
    root, _ = straight(tmp_path / "s", gt_step_ns=gt_step_ns)
    seq = HeliprSequence(root)
    assert seq.provenance["gt_association"]["max_gap_s"] == pytest.approx(max_gap)


@pytest.mark.parametrize(("dropped", "hole"), [(1, (0.1, 0.5)), (3, (0.1, 0.9))])
def test_gt_holes_in_0_2_s_steps_are_bridged_up_to_0_6_s(tmp_path, dropped, hole):
    """__init__ 147 by behaviour: GT every 0.2 s (default max gap 0.6 s); a 0.4 s hole is
    interpolated across, a 0.8 s one is not: the scans inside it have no GT."""
    root, stamps = straight(tmp_path / "s", frames=9, gt_step_ns=200_000_000)
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    # GT rows at -0.3, -0.1, 0.1, 0.3, 0.5, 0.7, ... s from scan 0; drop from 0.3 s on
    gt.write_text("".join(rows[:3] + rows[3 + dropped:]))
    t = (stamps - stamps[0]) * 1e-9
    inside = (t > hole[0] + 1e-6) & (t < hole[1] - 1e-6)
    if hole[1] - hole[0] > 0.6:
        with pytest.warns(UserWarning, match="have no ground truth"):
            seq = HeliprSequence(root)
    else:
        inside[:] = False
        seq = HeliprSequence(root)
    np.testing.assert_allclose(seq.ground_truth.stamps, stamps[~inside] * 1e-9, atol=1e-6)


def test_a_gt_file_going_backwards_is_named(tmp_path):
    """__init__ 139/141/143: the GT checks name the GT file and the pose row."""
    root, _ = straight(tmp_path / "s")
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    rows[3], rows[4] = rows[4], rows[3]
    gt.write_text("".join(rows))
    with pytest.raises(DataError) as err:
        HeliprSequence(root)
    assert str(err.value).startswith(f"{gt}, pose row 4: stamp ")


def test_a_single_gt_row_has_the_nominal_step(tmp_path):
    """__init__ 148: one GT row has no step: the default max gap is 3 x 0.1 s (the nominal
    period), 0.3 s; the scan at the row's stamp is covered, the next one is not."""
    root, stamps = straight(tmp_path / "s", frames=2)
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    gt.write_text(rows[6])  # 0.3 s after the first row (0.3 s before scan 0): scan 0's stamp
    assert rows[6].startswith(f"{stamps[0]} ")
    with pytest.warns(UserWarning, match="have no ground truth"):
        seq = HeliprSequence(root)
    assert seq.provenance["gt_association"]["max_gap_s"] == pytest.approx(0.3)
    np.testing.assert_allclose(seq.ground_truth.stamps, [stamps[0] * 1e-9], atol=1e-6)


def test_provenance_says_where_the_calibration_and_the_velocity_come_from(tmp_path):
    """__init__ 114/115/122/124-126: the identity extrinsic and the ego-compensated velocity,
    with the maintainers' statement cited."""
    root, _ = straight(tmp_path / "s")
    prov = HeliprSequence(root).provenance
    assert prov["calibration_source"].startswith("identity: ")
    assert "the GT file is the Aeva frame's pose" in prov["calibration_source"]
    assert prov["doppler_source"].startswith("velocity field, ego-motion compensated by the "
                                             "sensor ")
    assert prov["doppler_source"].endswith("(HeLiPR-File-Player issue #4)")


def test_association_errors_name_the_scan_folder(tmp_path):
    """__init__ 175/183: uncovered='error' names the Aeva folder and the first uncovered
    frame."""
    root, _ = straight(tmp_path / "s", frames=3)
    gt = root / "LiDAR_GT" / "Aeva_gt.txt"
    rows = gt.read_text().splitlines(keepends=True)
    gt.write_text("".join(rows[:8]))  # GT up to 0.05 s after scan 0: scans 1, 2 uncovered
    with pytest.raises(DataError) as err:
        HeliprSequence(root, uncovered="error")
    assert str(err.value).startswith(f"{root / 'LiDAR' / 'Aeva'}, frame 1: scan stamp")


# --- scan: the GT reconstruction -------------------------------------------------------------

def test_reconstruction_of_points_at_and_near_the_sensor(tmp_path):
    """scan 82/83: at 2 m/s along x (compensated velocity 0), raw = -d_x * 2 with d the unit
    direction: -2 for (0.5, 0, 0) and (3, 0, 0), +2 for (-0.25, 0, 0), 0 for (0, 0.5, 0);
    a point at the origin has no direction and keeps its compensated 0 (not NaN, not
    dropped)."""
    p = np.array([[0.5, 0, 0], [3, 0, 0], [-0.25, 0, 0], [0, 0.5, 0], [0, 0, 0]], np.float32)
    root, _ = straight(tmp_path / "s", points=[p, p, p])
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    s = seq[1]
    assert len(s.points) == 5
    np.testing.assert_allclose(s.doppler, [-2.0, -2.0, 2.0, 0.0, 0.0], atol=1e-5)


def accelerating(root, offsets_s, frames=3):
    """``frames`` scans 0.1 s apart of one point (10, 0, 0) per offset (compensated velocity 0);
    GT every 0.05 s with x = g^2 (g seconds from the first GT row, 0.3 s before scan 0), so the
    sensor speed at g is 2 g along +x. Returns (root, scan stamps ns, GT stamps ns)."""
    offsets = [np.round(np.asarray(offsets_s) * 1e9).astype(np.int32)] * frames
    p = np.tile(np.array([[10.0, 0.0, 0.0]], np.float32), (len(offsets_s), 1))
    stamps = T0_NS + STEP_NS * np.arange(frames, dtype=np.int64)
    gt_ns = stamps[0] - 300_000_000 + 50_000_000 * np.arange(20, dtype=np.int64)
    g = (gt_ns - gt_ns[0]) * 1e-9
    poses = np.stack([make_T(np.eye(3), [s * s, 0.0, 0.0]) for s in g])
    zeros = [np.zeros(len(offsets_s), np.float32)] * frames
    write_helipr(root, stamps, [p] * frames, zeros, gt_ns, poses, time_offset_ns=offsets)
    return root, stamps, gt_ns


def test_reconstruction_holds_the_velocity_outside_one_period(tmp_path):
    """scan 88/89/99: points take the sensor speed 2 g at their own time, clipped to
    [stamp, stamp + period]: offsets -0.05 and 0 s take 2 g_scan, 0.05 s 2 (g_scan + 0.05),
    0.15 and 0.25 s 2 (g_scan + 0.1); every point is on +x, so raw = -speed."""
    offsets_s = np.array([-0.05, 0.0, 0.05, 0.15, 0.25])
    root, stamps, gt_ns = accelerating(tmp_path / "acc", offsets_s)
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    g_scan = (stamps[1] - gt_ns[0]) * 1e-9  # 0.4 s
    taken = g_scan + np.clip(offsets_s, 0.0, 0.1)
    np.testing.assert_allclose(seq[1].doppler, -2.0 * taken, atol=1e-4)


def test_reconstruction_of_a_single_scan_takes_the_nominal_period(tmp_path):
    """__init__ 212: one scan has no period of its own: the nominal 0.1 s is the span its
    points' times are clipped to (offsets 0.05, 0.1 and 0.2 s take 2 (g_scan + 0.05),
    2 (g_scan + 0.1) twice)."""
    offsets_s = np.array([0.0, 0.05, 0.1, 0.2])
    root, stamps, gt_ns = accelerating(tmp_path / "one", offsets_s, frames=1)
    seq = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    assert len(seq) == 1
    g_scan = (stamps[0] - gt_ns[0]) * 1e-9  # 0.3 s
    taken = g_scan + np.clip(offsets_s, 0.0, 0.1)
    np.testing.assert_allclose(seq[0].doppler, -2.0 * taken, atol=1e-4)


# --- scan: fields ----------------------------------------------------------------------------

def test_line_index_is_float32_like_the_other_fields(tmp_path):
    """scan 128: the line index is stored as float32 (exact for 0..255)."""
    root, _ = straight(tmp_path / "s")
    s = HeliprSequence(root)[0]
    assert s.fields["line_index"].dtype == np.float32
    np.testing.assert_array_equal(s.fields["line_index"], np.arange(8, dtype=np.float32))


# --- _refuse_layout --------------------------------------------------------------------------

def test_the_share_of_impossible_points_and_the_corrupt_hint(tmp_path):
    """_refuse_layout 8/33/34: 3 of 4 records beyond 10 km: 75 %; 100 bytes is no whole
    number of 29-byte records, so the hint is the corrupt one, ending the message."""
    root, _ = straight(tmp_path / "s")
    f = aeva_files(root)[0]
    rec = np.zeros(4, RECORD_25)
    rec["x"] = [5.0, 2e4, -3e4, 1e6]
    rec.tofile(f)
    seq = HeliprSequence(root)
    with pytest.raises(DataError) as err:
        seq[0]
    msg = str(err.value)
    assert "(the layout of its stamp), 75 % of the points are impossible" in msg
    assert msg.endswith("or a time offset beyond 1 s); the file is corrupt or not an Aeva scan")


def test_the_other_layout_with_exactly_one_percent_impossible_is_plausible(tmp_path):
    """_refuse_layout 23/27-30: 100 records of 29 bytes (2900 bytes, also 116 of 25) under a
    25-byte stamp, one of them beyond 10 km: read as 29-byte records 1 % is impossible, which
    is still plausible (MAX_FAR_SHARE is 1 %, refused only above it)."""
    root, _ = straight(tmp_path / "s")
    f = aeva_files(root)[2]
    rec = np.zeros(100, RECORD_29)
    rec["x"] = 10.0
    rec["x"][37] = 5e4
    rec["time_offset_ns"] = 50_000_000
    rec["intensity"] = 1e30
    rec.tofile(f)
    seq = HeliprSequence(root)
    with pytest.raises(DataError) as err:
        seq[2]
    msg = str(err.value)
    assert msg.startswith(f"{f}, frame 2: read as 25-byte records (without intensity)")
    assert msg.endswith("; read as 29-byte records (with intensity) they are plausible: this "
                        "frame has the other layout than its stamp says (set --intensity yes/no "
                        "for the whole sequence, or remove the frame)")
