"""loaders.snail_radar on small extracted folders (``<sec>.<nsec>.pcd`` + ``times.txt``) and
TUM ground truth written here: the default name and date from the day folder, the sequence
folder of an input, the search for and preference among reference trajectories, the published
extrinsics (composition, mounting dates), the options, the folder reader's checks and what a
sequence states and returns."""

import warnings

import numpy as np
import pytest

from helpers_snail import radar_array, stamp_name, write_snail_folder
from loaders.errors import DataError
from loaders.se3 import inv_T, make_T
from loaders.snail_radar import (
    GT_SEARCH_LEVELS,
    P_BODY_ARS548,
    P_BODY_OCULII,
    R_BODY_X36D,
    R_BODY_XT32,
    T_BODY_XT32,
    Options,
    SnailRadarSequence,
    _pick,
    _rotation,
    _sequence_folder,
    body_T_ars548,
    body_T_oculii,
    date_from_path,
    find_gt_file,
    gt_candidates,
    sequence_name,
)

T0 = 1706000000.0


def rot_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0, 0, 1.0]])


def items(sensor="eagle", n=4, period=0.1, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        p = rng.uniform(-20, 20, (6, 3))
        d = rng.uniform(-3, 3, 6)
        out.append((T0 + period * k, radar_array(sensor, p, d, rng)))
    return out


def eagle_folder(seq, n=4, **kw):
    frames = items(n=n, **kw)
    write_snail_folder(seq / "eagleg7" / "enhanced", frames)
    return frames


def write_gt(path, stamps, positions):
    """TUM rows of identity rotations at ``positions``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(f"{t:.9f} {x:.9f} {y:.9f} {z:.9f} 0 0 0 1\n"
                            for t, (x, y, z) in zip(stamps, positions, strict=True)))
    return path


# --- names, dates, folders ---------------------------------------------------------------------


def test_sequence_name_carries_a_day_folder_only(tmp_path):
    for day in ("20231105_aft", "20231105_eve", "20240123"):
        (tmp_path / day / "data4" / "eagleg7" / "enhanced").mkdir(parents=True)
        (tmp_path / day / "data4.bag").write_bytes(b"")
        assert sequence_name(tmp_path / day / "data4.bag") == f"{day}_data4"
        assert sequence_name(tmp_path / day / "data4") == f"{day}_data4"
        assert sequence_name(tmp_path / day / "data4" / "eagleg7" / "enhanced") == \
            f"{day}_data4"
    for other in ("2023110_aft", "20231105_mor", "x20231105", "202311050"):
        (tmp_path / other).mkdir()
        (tmp_path / other / "data1.bag").write_bytes(b"")
        assert sequence_name(tmp_path / other / "data1.bag") == "data1"


def test_sequence_folder_of_each_input(tmp_path):
    seq = tmp_path / "20240123" / "data3"
    for sub in ("eagleg7/enhanced", "eagleg7/pcl", "ars548/points", "eagleg7/trk",
                "other/enhanced"):
        (seq / sub).mkdir(parents=True)
    assert _sequence_folder(tmp_path / "20240123" / "data3.bag") == seq
    assert _sequence_folder(seq) == seq
    for sub in ("eagleg7/enhanced", "eagleg7/pcl", "ars548/points"):
        assert _sequence_folder(seq / sub) == seq
    assert _sequence_folder(seq / "eagleg7" / "trk") == seq / "eagleg7" / "trk"
    assert _sequence_folder(seq / "other" / "enhanced") == seq / "other" / "enhanced"
    assert _sequence_folder(seq / "eagleg7") == seq / "eagleg7"


def test_date_from_the_nearest_group_folder(tmp_path):
    assert date_from_path(tmp_path / "20231105_aft" / "data4") == 20231105.5
    assert date_from_path(tmp_path / "20231105_eve" / "data4.bag") == 20231105.5
    assert date_from_path(tmp_path / "20240123" / "data1") == 20240123.0
    assert date_from_path(tmp_path / "20230101" / "x" / "20231208" / "data1") == 20231208.0
    assert date_from_path(tmp_path / "runs" / "data1") is None
    assert date_from_path(tmp_path / "2023110" / "data1") is None


# --- reference trajectories ----------------------------------------------------------------------


def test_pick_prefers_tls_then_csv_then_utm_and_refuses_both_tum(tmp_path):
    tls, csv, utm = (tmp_path / n for n in ("tls_T_xt32.txt", "ref_tls_T_xt32.csv",
                                            "utm50r_T_xt32.txt"))
    assert _pick([csv, tls], "w") == tls
    assert _pick([utm, csv], "w") == csv
    assert _pick([utm], "w") == utm
    assert _pick([], "w") is None
    assert _pick([tmp_path / "other.txt"], "w") is None
    with pytest.raises(DataError) as err:
        _pick([utm, tls], "here")
    assert str(err.value) == ("here: both tls_T_xt32.txt and utm50r_T_xt32.txt are present; "
                              "choose one with gt (--gt FILE)")


def test_gt_candidates_order(tmp_path):
    seq = tmp_path / "a" / "b" / "20240123" / "data3"
    seq.mkdir(parents=True)
    got = gt_candidates(seq)
    ups = list(seq.parents)[:GT_SEARCH_LEVELS]
    assert GT_SEARCH_LEVELS == 4
    assert got == [seq] + [up / tree / "20240123" / "data3" for up in ups
                           for tree in ("ref_trajs", "full_trajs")]
    assert got[1] == tmp_path / "a" / "b" / "20240123" / "ref_trajs" / "20240123" / "data3"
    assert got[4] == tmp_path / "a" / "b" / "full_trajs" / "20240123" / "data3"


def test_find_gt_file_in_the_folder_and_in_the_trees(tmp_path):
    day = tmp_path / "root" / "20240123"
    seq = day / "data3"
    seq.mkdir(parents=True)
    assert find_gt_file(seq) is None
    full = write_gt(tmp_path / "root" / "full_trajs" / "20240123" / "data3" /
                    "utm50r_T_xt32.txt", [0.0], [(0, 0, 0)])
    assert find_gt_file(seq) == full
    assert find_gt_file(day / "data3.bag") == full
    ref = write_gt(tmp_path / "root" / "ref_trajs" / "20240123" / "data3" /
                   "ref_tls_T_xt32.csv", [0.0], [(0, 0, 0)])
    assert find_gt_file(seq) == ref  # ref_trajs is searched before full_trajs
    own = write_gt(seq / "utm50r_T_xt32.txt", [0.0], [(0, 0, 0)])
    assert find_gt_file(seq) == own  # the sequence folder first
    # a tree five levels up is too far
    deep = tmp_path / "deep" / "a" / "b" / "c" / "20240123" / "data1"
    deep.mkdir(parents=True)
    write_gt(tmp_path / "deep" / "ref_trajs" / "20240123" / "data1" / "tls_T_xt32.txt", [0.0],
             [(0, 0, 0)])
    assert find_gt_file(deep) is None
    near = tmp_path / "deep" / "a" / "b" / "20240123" / "data1"
    near.mkdir(parents=True)
    assert find_gt_file(near) is not None


def test_without_a_day_folder_a_unique_run_is_found_and_two_are_refused(tmp_path):
    seq = tmp_path / "mine" / "data7"
    seq.mkdir(parents=True)
    assert find_gt_file(seq) is None
    one = write_gt(tmp_path / "mine" / "ref_trajs" / "20240123" / "data7" / "tls_T_xt32.txt",
                   [0.0], [(0, 0, 0)])
    assert find_gt_file(seq) == one
    two = write_gt(tmp_path / "full_trajs" / "20231105" / "data7" / "utm50r_T_xt32.txt",
                   [0.0], [(0, 0, 0)])
    with pytest.raises(DataError) as err:
        find_gt_file(seq)
    hits = sorted([one, two])
    assert str(err.value) == (f"{seq}: the sequence is in no day folder (like 20240123/) and 2 "
                              f"reference trajectories are named data7 ({hits[0]}, {hits[1]}); "
                              "choose one with gt (--gt FILE)")
    # inside a day folder, another day's run is never taken
    dayseq = tmp_path / "20240124" / "data7"
    dayseq.mkdir(parents=True)
    assert find_gt_file(dayseq) is None


# --- extrinsics ----------------------------------------------------------------------------------


def test_rotation_is_the_nearest_proper_rotation():
    R = rot_z(30.0)
    np.testing.assert_allclose(_rotation((2.0 * R).tolist()), R, atol=1e-12)
    np.testing.assert_allclose(_rotation(np.round(R, 6).tolist()), R, atol=1e-6)
    flipped = _rotation(np.diag([1.0, 1.0, -1.0]).tolist())
    assert np.linalg.det(flipped) == pytest.approx(1.0)
    np.testing.assert_allclose(flipped @ flipped.T, np.eye(3), atol=1e-12)


def test_body_frames_of_the_xt32_and_oculii():
    # the XT32's axes are left-back-up: its x axis is the body's +y
    np.testing.assert_allclose(R_BODY_XT32 @ [1, 0, 0], [0, 1, 0])
    np.testing.assert_allclose(T_BODY_XT32, make_T(R_BODY_XT32, [0, 0, 0]))
    np.testing.assert_allclose(R_BODY_X36D @ R_BODY_X36D.T, np.eye(3), atol=1e-12)
    manual = body_T_oculii("manual")
    np.testing.assert_allclose(manual, make_T(np.eye(3), [0.07, 0.0, -0.115]), atol=0)
    refined = body_T_oculii()
    np.testing.assert_allclose(refined[:3, 3], P_BODY_OCULII, atol=0)
    np.testing.assert_allclose(P_BODY_OCULII, [0.07, 0.0, -0.115])
    R = refined[:3, :3]
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    # the refined Eagle rotation is within 3 deg of the manual (identity) one
    angle = np.degrees(np.arccos((np.trace(R) - 1) / 2))
    assert 0.5 < angle < 3.0
    with pytest.raises(DataError) as err:
        body_T_oculii("measured")
    assert str(err.value) == "Eagle extrinsic must be 'refined' or 'manual', got 'measured'"


def test_ars548_mount_by_date():
    np.testing.assert_allclose(P_BODY_ARS548, [0.0, 0.0, 0.07])
    first = body_T_ars548(20231104)
    # the first mounting is pitched about 14 deg (R_x36d_ars548[0, 0] = 0.9694)
    assert np.degrees(np.arccos(np.clip((np.trace(first[:3, :3]) - 1) / 2, -1, 1))) > 10
    np.testing.assert_allclose(first[:3, 3], [0.0, 0.0, 0.07], atol=0)
    assert np.allclose(body_T_ars548(20231105.0), first)
    later = body_T_ars548(20231105.5)  # the afternoon of 2023-11-05: the next mounting
    assert not np.allclose(later, first)
    assert np.allclose(body_T_ars548(20231108.9), later)
    assert not np.allclose(body_T_ars548(20231109), later)
    mounts = [body_T_ars548(d) for d in (20231104, 20231105.5, 20231109, 20231201, 20231208,
                                         20231213, 20240113)]
    for a in range(len(mounts)):
        for b in range(a + 1, len(mounts)):
            assert not np.allclose(mounts[a], mounts[b])
    assert np.allclose(body_T_ars548(20250101), mounts[-1])
    assert np.allclose(body_T_ars548(20240112.5), mounts[-2])
    with pytest.raises(DataError) as err:
        body_T_ars548(20231103.5, "seq.bag")
    assert str(err.value) == ("seq.bag: no ARS548 before 2023-11-04 (date 2.02311e+07); the "
                              "sequences of that time carry only the Eagle (sensor='eagle')")


# --- options ----------------------------------------------------------------------------


def test_options_defaults_and_the_doppler_sign():
    o = Options()
    assert (o.sensor, o.cloud, o.gt, o.gt_frame, o.date, o.extrinsic, o.T_body_radar,
            o.remove_gt_origin, o.time_offset_s, o.max_gap_s, o.uncovered, o.doppler_sign,
            o.stamp) == ("eagle", "enhanced", None, "xt32", None, "refined", None, True, 0.0,
                         0.35, "keep", 1.0, "header")
    assert Options(doppler_sign=-1).doppler_sign == -1.0
    with pytest.raises(ValueError, match="doppler_sign must be \\+1 or -1, got 0.5"):
        Options(doppler_sign=0.5)


# --- the folder reader and the sequence --------------------------------------------------------


def test_folder_reader_errors(tmp_path):
    seq = tmp_path / "20240123" / "data1"
    folder = seq / "eagleg7" / "enhanced"
    frames = eagle_folder(seq, n=3)
    times = folder / "times.txt"
    times.unlink()
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq)
    assert str(err.value) == (f"{folder}: no times.txt; expected the extracted layout "
                              "<sec>.<nsec>.pcd + times.txt (snail-radar dataset_tools "
                              "bag_to_folder.py)")
    times.write_text("\n  \n")
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq)
    assert str(err.value) == f"{times}: no stamps; expected one <sec>.<nsec> per line"
    names = [stamp_name(t) for t, _ in frames]
    times.write_text(f"{names[0]}\nnan\n")
    with pytest.raises(DataError, match=r"times\.txt: a line is not a stamp <sec>\.<nsec> "
                                        r"\(a stamp is not finite\)"):
        SnailRadarSequence(seq)
    times.write_text(f"{names[0]}\nabc\n")
    with pytest.raises(DataError, match=r"times\.txt: a line is not a stamp"):
        SnailRadarSequence(seq)
    times.write_text(f"{names[0]}\n{T0 + 5:.9f}\n{T0 + 6:.9f}\n")
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq)
    assert str(err.value) == (f"{folder}: 2 of the 3 frames listed in times.txt have no .pcd "
                              f"file (first: {T0 + 5:.9f}.pcd); the folder is incompletely "
                              "extracted")
    times.write_text(f" {names[0]} \n\n{names[2]}\n")
    with pytest.warns(UserWarning) as got:
        s = SnailRadarSequence(seq)
    assert [str(w.message) for w in got] == [
        f"{folder}: 1 .pcd files not listed in times.txt are ignored"]
    assert len(s) == 2
    np.testing.assert_allclose(s.stamps, [T0, T0 + 0.2], rtol=0, atol=1e-6)


def test_input_errors(tmp_path):
    with pytest.raises(DataError) as err:
        SnailRadarSequence(tmp_path / "none")
    assert str(err.value) == (f"{tmp_path / 'none'}: not found; expected a Snail-Radar sequence "
                              "bag or folder")
    seq = tmp_path / "20240123" / "data1"
    eagle_folder(seq)
    (seq / "xt32").mkdir()
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq, sensor="ars548")
    assert str(err.value) == (f"{seq}: no ars548/points/ folder for sensor 'ars548'; the folder "
                              "has eagleg7, xt32 (an incompletely extracted sequence, or another "
                              "sensor?)")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(DataError, match="the folder has no subfolders"):
        SnailRadarSequence(empty)
    with pytest.raises(DataError, match="^snail-radar options: "):
        SnailRadarSequence(seq, doppler_sign=2.0)
    loose = tmp_path / "loose" / "data1"
    eagle_folder(loose)
    with pytest.raises(DataError) as err:
        SnailRadarSequence(loose, sensor="ars548")
    # (no ars548 folder: that is said before the date)
    assert "no ars548/points/ folder" in str(err.value)


def test_ars548_needs_a_date_without_a_day_folder(tmp_path):
    seq = tmp_path / "loose" / "data1"
    frames = items("ars548", n=3, period=0.05)
    write_snail_folder(seq / "ars548" / "points", frames)
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq, sensor="ars548")
    assert str(err.value) == (
        f"{seq}: the ARS548 extrinsic depends on the sequence date and no group folder like "
        "20231105 or 20231105_aft is in the path; give --date (e.g. --date 20231105.5)")
    s = SnailRadarSequence(seq, sensor="ars548", date=20231110)
    np.testing.assert_allclose(s.sensor.T_body_sensor, body_T_ars548(20231110), atol=0)
    assert s.date == 20231110 and s.provenance["extrinsic"] == "Body_T_Ars548.m"
    assert s.sensor.model == "radar-sparse" and s.sensor.period_s == pytest.approx(0.05)
    assert s.provenance["sensor"] == "Continental ARS548"
    assert s.provenance["stream"] == "ars548/points" and s.provenance["doppler_field"] == "doppler"
    # a given extrinsic needs no date
    given = SnailRadarSequence(seq, sensor="ars548", T_body_radar="1 2 3 0 0 0 1")
    np.testing.assert_allclose(given.sensor.T_body_sensor, make_T(np.eye(3), [1, 2, 3]))
    assert given.provenance["extrinsic"] == "1 2 3 0 0 0 1"


def test_what_a_folder_sequence_states_and_reads(tmp_path):
    seq = tmp_path / "20231105_aft" / "data4"
    frames = eagle_folder(seq, n=4)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = SnailRadarSequence(seq)
    assert s.name == "20231105_aft_data4" and s.date == 20231105.5
    assert SnailRadarSequence(seq, name="mine").name == "mine"
    assert SnailRadarSequence(seq, date=20240101).date == 20240101
    assert s.ground_truth is None and len(s) == 4
    np.testing.assert_allclose(s.stamps, [T0, T0 + 0.1, T0 + 0.2, T0 + 0.3], rtol=0, atol=1e-6)
    got = s.stamps
    got[:] = 0
    assert s.stamps[0] == pytest.approx(T0)
    sensor = s.sensor
    assert (sensor.kind, sensor.model, sensor.doppler_kind) == ("radar", "radar-semidense",
                                                                 "radial")
    assert sensor.period_s == pytest.approx(0.1)
    np.testing.assert_allclose(sensor.T_body_sensor, body_T_oculii(), atol=0)
    p = s.provenance
    assert (p["loader"], p["input"], p["sensor"], p["stream"], p["doppler_field"],
            p["doppler_sign"], p["date"], p["extrinsic"], p["gt_frame"], p["messages"],
            p["repeated_stamps_dropped"], p["nan_points_dropped"]) == (
        "snail-radar", str(seq), "Oculii Eagle G7", "eagleg7/enhanced", "Doppler", 1.0,
        20231105.5, "refined", "xt32", 4, 0, 0)
    np.testing.assert_allclose(p["T_body_radar"], body_T_oculii(), atol=0)
    np.testing.assert_allclose(p["T_gtbody_radar"], inv_T(T_BODY_XT32) @ body_T_oculii(),
                               atol=1e-15)
    body = SnailRadarSequence(seq, gt_frame="body", extrinsic="manual")
    np.testing.assert_allclose(body.provenance["T_gtbody_radar"], body_T_oculii("manual"))
    assert body.provenance["extrinsic"] == "manual"
    # a scan: x y z and Doppler by name, the other fields lower-cased, float32
    scan = s[2]
    arr = frames[2][1]
    np.testing.assert_array_equal(scan.points, np.column_stack([arr["x"], arr["y"], arr["z"]]))
    assert scan.points.dtype == np.float64 and scan.doppler.dtype == np.float64
    np.testing.assert_array_equal(scan.doppler, arr["Doppler"])
    assert scan.stamp == pytest.approx(T0 + 0.2, abs=1e-6)
    names = [n for n in arr.dtype.names if n not in ("x", "y", "z", "Doppler")]
    assert sorted(scan.fields) == sorted(n.lower() for n in names)
    assert all(v.dtype == np.float32 for v in scan.fields.values())
    np.testing.assert_array_equal(scan.fields["power"], arr["Power"])
    np.testing.assert_array_equal(scan.fields["dopplercorrectionflag"],
                                  arr["dopplerCorrectionFlag"])
    flipped = SnailRadarSequence(seq, doppler_sign=-1)
    np.testing.assert_array_equal(flipped[2].doppler, -arr["Doppler"].astype(np.float64))
    assert flipped.provenance["doppler_sign"] == -1.0
    # the sensor folder itself is an input too
    direct = SnailRadarSequence(seq / "eagleg7" / "enhanced")
    assert direct.name == "20231105_aft_data4" and len(direct) == 4


def test_a_frame_without_doppler_names_its_fields(tmp_path):
    seq = tmp_path / "20240123" / "data1"
    arr = np.zeros(3, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("Power", "<f4")])
    arr["x"] = [1, 2, 3]
    write_snail_folder(seq / "eagleg7" / "enhanced", [(T0, arr), (T0 + 0.1, arr)])
    s = SnailRadarSequence(seq)
    f = seq / "eagleg7" / "enhanced" / f"{stamp_name(T0 + 0.1)}.pcd"
    with pytest.raises(DataError) as err:
        s[1]
    assert str(err.value) == (f"{f} (frame 1): no field(s) Doppler; the frame has fields x y z "
                              "Power (expected the eagle layout: x y z Doppler ...)")


def test_ground_truth_in_the_radar_frame_with_and_without_the_origin(tmp_path):
    seq = tmp_path / "20240123" / "data2"
    eagle_folder(seq, n=4)
    stamps = T0 - 0.5 + 0.05 * np.arange(40)
    xyz = np.column_stack([2.0 * (stamps - T0) + 1000.0, np.full(40, 500.0), np.zeros(40)])
    gt = write_gt(seq / "tls_T_xt32.txt", stamps, xyz)
    s = SnailRadarSequence(seq)
    assert s.provenance["gt_file"] == f"{gt} (found in the sequence folder)"
    T_xt32_radar = inv_T(T_BODY_XT32) @ body_T_oculii()
    expect = np.stack([make_T(np.eye(3), [2.0 * (t - T0) + 0.5 * 2.0, 0.0, 0.0]) @ T_xt32_radar
                       for t in T0 + 0.1 * np.arange(4)])
    np.testing.assert_allclose(s.ground_truth.poses, expect, atol=1e-6)
    np.testing.assert_allclose(s.provenance["gt_origin_removed"], [1000.0 - 1.0, 500.0, 0.0],
                               atol=1e-6)
    assert s.provenance["gt_association"]["with_gt"] == 4
    assert s.provenance["gt_association"]["max_gap_s"] == 0.35
    assert "gt_format" not in s.provenance
    kept = SnailRadarSequence(seq, remove_gt_origin=False, gt=gt)
    assert kept.provenance["gt_file"] == str(gt) and "gt_origin_removed" not in kept.provenance
    np.testing.assert_allclose(kept.ground_truth.poses[:, :3, 3] - expect[:, :3, 3],
                               [[999.0, 500.0, 0.0]] * 4, atol=1e-6)
    # GT rows of the body frame: only the extrinsic is applied
    body = SnailRadarSequence(seq, gt_frame="body")
    np.testing.assert_allclose(
        body.ground_truth.poses,
        np.stack([make_T(np.eye(3), e[:3, 3] - T_xt32_radar[:3, 3]) for e in expect])
        @ body_T_oculii(), atol=1e-6)
    # an offset moves the GT clock: 1 s later, positions 2 m further back
    late = SnailRadarSequence(seq, time_offset_s=0.1, remove_gt_origin=False)
    np.testing.assert_allclose(late.ground_truth.poses[:, 0, 3] - kept.ground_truth.poses[:, 0, 3],
                               -0.2, atol=1e-6)
    # a GT found in the trees beside the sequence says so
    (seq / "tls_T_xt32.txt").unlink()
    tree = write_gt(tmp_path / "ref_trajs" / "20240123" / "data2" / "tls_T_xt32.txt", stamps,
                    xyz)
    assert SnailRadarSequence(seq).provenance["gt_file"] == (
        f"{tree} (found in the reference trajectories beside the sequence)")


def test_gt_gap_and_uncovered_policies(tmp_path):
    seq = tmp_path / "20240123" / "data5"
    eagle_folder(seq, n=6)
    stamps = np.concatenate([T0 - 0.2 + 0.05 * np.arange(7), T0 + 0.4 + 0.05 * np.arange(6)])
    write_gt(seq / "tls_T_xt32.txt", stamps, np.zeros((len(stamps), 3)))
    # rows 0.1 -> 0.4 s: a 0.3 s gap, bridged by the default 0.35 s, not by 0.25 s
    s = SnailRadarSequence(seq)
    assert len(s.ground_truth) == 6
    with pytest.warns(UserWarning, match="excluded from scoring"):
        short = SnailRadarSequence(seq, max_gap_s=0.25)
    assert len(short.ground_truth) == 4 and len(short) == 6
    with pytest.raises(DataError, match="not covered"):
        SnailRadarSequence(seq, max_gap_s=0.25, uncovered="error")
    with pytest.warns(UserWarning, match="trimmed"):
        trimmed = SnailRadarSequence(seq, max_gap_s=0.25, uncovered="trim",
                                     time_offset_s=-0.45)
    # GT moved 0.45 s earlier: its second block ends at 0.2 s; scans 0.3-0.5 s trimmed
    assert len(trimmed) == 3 and trimmed.provenance["gt_association"]["trimmed"] == 3


# --- survivors of the first mutation run -------------------------------------------------------


def test_a_repeated_stamp_is_dropped_with_a_warning_naming_the_folder(tmp_path):
    seq = tmp_path / "20240123" / "data6"
    frames = eagle_folder(seq, n=3)
    folder = seq / "eagleg7" / "enhanced"
    names = [stamp_name(t) for t, _ in frames]
    (folder / "times.txt").write_text(f"{names[0]}\n{names[1]}\n{names[1]}\n{names[2]}\n")
    with pytest.warns(UserWarning) as got:
        s = SnailRadarSequence(seq)
    assert [str(w.message) for w in got] == [
        f"{folder}: 1 scans with a repeated header stamp dropped"]
    assert len(s) == 3 and s.provenance["repeated_stamps_dropped"] == 1
    assert s.provenance["messages"] == 4


def test_bag_input_topic_stream_and_messages(tmp_path):
    from helpers_snail import write_snail_bag

    day = tmp_path / "20240123"
    day.mkdir()
    frames = items(n=3)
    bag = write_snail_bag(day / "data2.bag", {"/radar_enhanced_pcl2": frames,
                                              "/radar_pcl2": []})
    s = SnailRadarSequence(bag)
    assert s.name == "20240123_data2" and len(s) == 3
    assert s.provenance["stream"] == "/radar_enhanced_pcl2"
    np.testing.assert_allclose(s.stamps, [t for t, _ in frames], rtol=0, atol=1e-6)
    np.testing.assert_array_equal(s[1].doppler, frames[1][1]["Doppler"].astype(np.float64))
    with pytest.raises(DataError) as err:
        SnailRadarSequence(bag, cloud="pcl")  # the topic is in the bag, without messages
    assert str(err.value) == f"{bag}: topic /radar_pcl2 has no messages"
    # GT covering the first two scans only: the warning names the bag
    write_gt(day / "data2" / "tls_T_xt32.txt", T0 - 0.1 + 0.05 * np.arange(5),
             np.zeros((5, 3)))
    with pytest.warns(UserWarning, match=f"^{bag}: 1 of the 3 scans kept have no ground truth"):
        part = SnailRadarSequence(bag)
    assert len(part.ground_truth) == 2


def test_gt_choice_errors_name_the_folder_and_ars548_dates_name_the_input(tmp_path):
    seq = tmp_path / "20240123" / "data8"
    eagle_folder(seq, n=2)
    for name in ("tls_T_xt32.txt", "utm50r_T_xt32.txt"):
        write_gt(seq / name, [T0], [(0, 0, 0)])
    with pytest.raises(DataError) as err:
        SnailRadarSequence(seq)
    assert str(err.value) == (f"{seq}: both tls_T_xt32.txt and utm50r_T_xt32.txt are present; "
                              "choose one with gt (--gt FILE)")
    loose = tmp_path / "mine" / "data9"
    loose.mkdir(parents=True)
    tree = tmp_path / "mine" / "ref_trajs" / "20240123" / "data9"
    for name in ("tls_T_xt32.txt", "utm50r_T_xt32.txt"):
        write_gt(tree / name, [T0], [(0, 0, 0)])
    with pytest.raises(DataError) as err:
        find_gt_file(loose)
    assert str(err.value).startswith(f"{tree}: both tls_T_xt32.txt and utm50r_T_xt32.txt")
    ars = tmp_path / "20231101" / "data1"
    write_snail_folder(ars / "ars548" / "points", items("ars548", n=2, period=0.05))
    with pytest.raises(DataError) as err:
        SnailRadarSequence(ars, sensor="ars548")
    assert str(err.value).startswith(f"{ars}: no ARS548 before 2023-11-04 (date 2.02311e+07)")


def test_reference_csv_gt_format_and_two_missing_fields(tmp_path):
    seq = tmp_path / "20240123" / "data10"
    eagle_folder(seq, n=3)
    header = ("#time, M_p_L_x, M_p_L_y, M_p_L_z, M_q_L_x, M_q_L_y, M_q_L_z, M_q_L_w, W_v_L_x, "
              "W_v_L_y, W_v_L_z")
    rows = "".join(f"{T0 - 0.1 + 0.05 * k:.9f}, {k}, 0, 0, 0, 0, 0, 1, 0, 0, 0\n"
                   for k in range(10))
    (seq / "ref_tls_T_xt32.csv").write_text(header + "\n" + rows)
    s = SnailRadarSequence(seq)
    assert s.provenance["gt_format"] == ("reference CSV (time, M_p_L, M_q_L: the XT32 pose in "
                                         "the map; W_v_L not used)")
    assert len(s.ground_truth) == 3
    bare = tmp_path / "20240123" / "data11"
    arr = np.zeros(2, dtype=[("x", "<f4"), ("y", "<f4"), ("Power", "<f4")])
    write_snail_folder(bare / "eagleg7" / "enhanced", [(T0, arr), (T0 + 0.1, arr)])
    with pytest.raises(DataError, match=r"no field\(s\) z, Doppler; the frame has fields x y "
                                        r"Power"):
        SnailRadarSequence(bare)[0]


def test_third_run_survivors(tmp_path, monkeypatch):
    # body_T_ars548 without a place: the message starts with ": "
    with pytest.raises(DataError, match="^: no ARS548 before 2023-11-04"):
        body_T_ars548(20231101)
    # five runs of one name in the trees: four are listed
    loose = tmp_path / "mine" / "data3"
    loose.mkdir(parents=True)
    trees = [write_gt(tmp_path / "mine" / "ref_trajs" / f"2024010{k}" / "data3" /
                      "tls_T_xt32.txt", [T0], [(0, 0, 0)]) for k in range(1, 6)]
    with pytest.raises(DataError) as err:
        find_gt_file(loose)
    assert f"5 reference trajectories are named data3 ({', '.join(map(str, trees[:4]))}); " \
        "choose one" in str(err.value)
    # times.txt over the frame limit, and with bytes that are not UTF-8
    seq = tmp_path / "20240123" / "data12"
    frames = eagle_folder(seq, n=2)
    times = seq / "eagleg7" / "enhanced" / "times.txt"
    monkeypatch.setenv("BENCH_MAX_FRAME_MB", "0.00001")  # 10 bytes
    with pytest.raises(DataError, match=f"^{times}: the file .* above the per-frame limit"):
        SnailRadarSequence(seq)
    monkeypatch.delenv("BENCH_MAX_FRAME_MB")
    times.write_bytes(stamp_name(frames[0][0]).encode() + b"\n\xff\n")
    with pytest.raises(DataError, match=f"^{times}: a line is not a stamp"):
        SnailRadarSequence(seq)
    # a float64 field is stored as float32; a NaN point is named and counted
    pcd_seq = tmp_path / "20240123" / "data13"
    arr = np.zeros(3, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("Doppler", "<f4"),
                             ("Power", "<f8")])
    arr["x"] = [1.0, np.nan, 3.0]
    arr["Power"] = [0.1, 0.2, 0.3]
    write_snail_folder(pcd_seq / "eagleg7" / "enhanced", [(T0, arr), (T0 + 0.1, arr)])
    s = SnailRadarSequence(pcd_seq)
    f0 = pcd_seq / "eagleg7" / "enhanced" / f"{stamp_name(T0)}.pcd"
    with pytest.warns(UserWarning, match=f"^{f0} \\(frame 0\\): dropped 1 of 3 points"):
        scan = s[0]
    assert scan.fields["power"].dtype == np.float32
    np.testing.assert_allclose(scan.fields["power"], [0.1, 0.3], rtol=1e-7)
    assert s.provenance["nan_points_dropped"] == 1


def test_bag_topic_of_another_type_and_unset_header_stamps(tmp_path):
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    from helpers_snail import write_snail_bag

    day = tmp_path / "20240123"
    day.mkdir()
    store = get_typestore(Stores.ROS1_NOETIC)
    text = "std_msgs/msg/String"
    bag = day / "data1.bag"
    with Writer(bag) as w:
        conn = w.add_connection("/radar_enhanced_pcl2", text, typestore=store)
        for i in range(3):
            w.write(conn, int((T0 + 0.1 * i) * 1e9),
                    store.serialize_ros1(store.types[text](data="x"), text))
    with pytest.raises(DataError) as err:
        SnailRadarSequence(bag)
    assert str(err.value) == (f"{bag}: topic /radar_enhanced_pcl2 has message type {text}; "
                              "expected one of sensor_msgs/msg/PointCloud2")
    frames = items(n=3)
    same = [(frames[0][0], arr) for _, arr in frames]  # one header stamp for all three
    bag2 = write_snail_bag(day / "data2.bag", {"/radar_enhanced_pcl2": same})
    with pytest.raises(DataError, match=f"^{bag2}: /radar_enhanced_pcl2: only 1 distinct header "
                                        "stamps for 3 messages"):
        SnailRadarSequence(bag2)
