"""bench view's recording in-process (write_recording, _log_pair, _log_sequence): what it
logs, where, in which colours and on which timelines, against values worked out from the
sequence's own poses (a stand-in for rerun records the calls; one test uses rerun itself).
Written for a mutation run of bench/report/view.py: besides these, only the 13 s CLI test
(tests/test_view.py) reaches this code."""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench import guard
from bench.report import view
from conftest import constant_twist_sequence, dev_dependency
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import write_store
from loaders.trajectory import Trajectory

N_FRAMES = 6


class _Stream:
    """A stand-in for rerun's RecordingStream: records what is logged, and saves a file that
    starts as a rerun recording does (so the guard takes it for one)."""

    made: list = []

    def __init__(self, application_id, recording_id=None):
        self.application_id, self.recording_id = application_id, recording_id
        self.logged, self.times, self.calls = [], [], []
        _Stream.made.append(self)

    def save(self, path):
        self.calls.append("save")
        with open(path, "wb") as f:
            f.write(guard.RRD_MAGIC + b"\0" * 8)

    def log(self, path, item, static=False):
        self.logged.append((path, item, static))

    def set_time(self, name, **value):
        self.times.append((name, value))

    def flush(self):
        self.calls.append("flush")

    def disconnect(self):
        self.calls.append("disconnect")


def _fake_rr():
    return SimpleNamespace(RecordingStream=_Stream,
                           LineStrips3D=lambda strips, **kw: ("lines", np.asarray(strips), kw),
                           Points3D=lambda pts, **kw: ("points", np.asarray(pts), kw))


@pytest.fixture
def fake_rr(monkeypatch):
    _Stream.made = []
    monkeypatch.setattr(view, "_rerun", _fake_rr)
    return _Stream.made


def _world(T, p):
    """Points p (N, 3) of a frame placed by the pose T (4 x 4): R p + t."""
    return p @ T[:3, :3].T + T[:3, 3]


def _shifted(T, k):
    """The pose T moved by (0, 0.5 k, 0) in the world: an estimate that drifts sideways."""
    out = T.copy()
    out[1, 3] += 0.5 * k
    return out


def _tum(stamps, poses) -> str:
    quats = Rotation.from_matrix(poses[:, :3, :3]).as_quat()  # x y z w
    return "".join(f"{t:.9f} {T[0, 3]:.9f} {T[1, 3]:.9f} {T[2, 3]:.9f} "
                   f"{q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}\n"
                   for t, T, q in zip(stamps, poses, quats, strict=True))


@pytest.fixture(scope="module")
def memory():
    return constant_twist_sequence(n_frames=N_FRAMES, n_points=600)


@pytest.fixture(scope="module")
def store(memory, tmp_path_factory):
    return write_store(memory, tmp_path_factory.mktemp("view") / "t.h5")


def _run_dir(tmp_path, memory, all_frames=True):
    """A run folder's estimate: est_tum.txt of the first four frames, est_all_tum.txt of every
    frame (both the GT drifting sideways by 0.5 m a frame)."""
    run = tmp_path / "run"
    run.mkdir()
    gt = memory.ground_truth
    est = np.array([_shifted(T, k) for k, T in enumerate(gt.poses)])
    (run / "est_tum.txt").write_text(_tum(gt.stamps[:4], est[:4]))
    if all_frames:
        (run / "est_all_tum.txt").write_text(_tum(gt.stamps, est))
    return run, est


def _by_path(stream, path):
    return [item for p, item, _ in stream.logged if p == path]


def test_a_recording_with_a_run_and_a_pair(fake_rr, store, memory, tmp_path):
    run, est = _run_dir(tmp_path, memory)
    out = tmp_path / "out" / "v.rrd"
    assert view.write_recording(store, out, run, pair=2) == out
    assert guard.is_recording(out)
    (rec,) = fake_rr
    assert (rec.application_id, rec.recording_id) == ("doppler-bench", "view-t")
    assert rec.calls == ["save", "flush", "disconnect"]
    # the estimate: every frame (est_all_tum.txt), aligned at the first pose (the GT's)
    (line,) = _by_path(rec, "world/estimate")
    np.testing.assert_allclose(line[1][0], est[:, :3, 3], atol=1e-6)
    (line,) = _by_path(rec, "world/ground_truth")
    np.testing.assert_allclose(line[1][0], memory.ground_truth.poses[:, :3, 3], atol=1e-9)
    # every scan (stride 1 by default) placed by the GT, not by the drifting estimate
    scans = _by_path(rec, "world/scan")
    assert len(scans) == N_FRAMES
    for k, (_, pts, _) in enumerate(scans):
        np.testing.assert_allclose(pts, _world(memory.ground_truth.poses[k], memory[k].points),
                                   atol=1e-6)
    frames = [v["sequence"] for n, v in rec.times if n == "frame"]
    assert frames == [*range(N_FRAMES), 2]  # the scans, then the pair's frame


def test_the_pair_joins_its_points_where_the_gt_puts_them(fake_rr, store, memory, tmp_path):
    from bench.report.figures.pair import pair_correspondences

    view.write_recording(store, tmp_path / "v.rrd", pair=2)
    (rec,) = fake_rr
    data = pair_correspondences(store, 2)  # which points pair up (not what is checked here)
    Ts, Tt = memory.ground_truth.poses[2], memory.ground_truth.poses[3]
    src, tgt = _world(Ts, memory[2].points), _world(Tt, memory[3].points)
    assert rec.logged[-2][0] == "world/pair/closest_correspondences"
    assert rec.logged[-1][0] == "world/pair/doppler_correspondences"
    for (_, (kind, strips, kw), static), key, rgb in zip(
            rec.logged[-2:], ("closest", "doppler"), ([220, 40, 40], [40, 160, 40]),
            strict=True):
        s_idx, t_idx = data[key]
        assert kind == "lines" and not static and len(s_idx) > 10
        assert strips.shape == (len(s_idx), 2, 3)
        np.testing.assert_allclose(strips[:, 0], src[s_idx], atol=1e-6)
        np.testing.assert_allclose(strips[:, 1], tgt[t_idx], atol=1e-6)
        assert kw == {"colors": [rgb]}
    # static world points, exact poses: a Doppler pair's two ends lie close in the world
    s_idx, t_idx = data["doppler"]
    gap = np.linalg.norm(src[s_idx] - tgt[t_idx], axis=1)
    assert np.median(gap) < 1.0


def test_the_pair_of_a_store_without_gt_stays_in_the_sensor_frame(fake_rr, memory, tmp_path):
    bare = MemorySequence("bare", memory.sensor, [memory[k] for k in range(3)])
    store = write_store(bare, tmp_path / "bare.h5")
    from bench.report.figures.pair import pair_correspondences

    view.write_recording(store, tmp_path / "v.rrd", pair=1)
    (rec,) = fake_rr
    assert _by_path(rec, "world/ground_truth") == [] and _by_path(rec, "world/estimate") == []
    for k, (_, pts, _) in enumerate(_by_path(rec, "world/scan")):
        np.testing.assert_allclose(pts, memory[k].points, atol=1e-6)  # as measured
    data = pair_correspondences(store, 1)
    for (_, (_, strips, _), _), key in zip(rec.logged[-2:], ("closest", "doppler"),
                                           strict=True):
        s_idx, t_idx = data[key]
        np.testing.assert_allclose(strips[:, 0], memory[1].points[s_idx], atol=1e-6)
        np.testing.assert_allclose(strips[:, 1], memory[2].points[t_idx], atol=1e-6)


def test_without_est_all_the_run_s_est_tum_is_read(fake_rr, store, memory, tmp_path):
    run, est = _run_dir(tmp_path, memory, all_frames=False)
    view.write_recording(store, tmp_path / "v.rrd", run, stride=2)
    (rec,) = fake_rr
    (line,) = _by_path(rec, "world/estimate")
    np.testing.assert_allclose(line[1][0], est[:4, :3, 3], atol=1e-6)
    assert [v["sequence"] for n, v in rec.times if n == "frame"] == [0, 2, 4]


def test_a_folder_without_est_tum_is_no_finished_run(fake_rr, store, tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    with pytest.raises(DataError, match=r"^(.*): no est_tum\.txt \(not a finished run folder\)$"
                       ) as err:
        view.write_recording(store, tmp_path / "v.rrd", run)
    assert str(err.value).startswith(str(run))


@pytest.mark.parametrize("name", ["est_tum.txt", "est_all_tum.txt"])
def test_the_run_s_estimate_is_never_overwritten(fake_rr, store, memory, tmp_path, name):
    run, _ = _run_dir(tmp_path, memory)
    before = (run / name).read_bytes()
    with pytest.raises(DataError, match=r"is an input of this command"):
        view.write_recording(store, run / name, run)
    assert (run / name).read_bytes() == before and fake_rr == []


def test_a_recording_is_replaced_another_file_is_not(fake_rr, store, tmp_path):
    out = tmp_path / "v.rrd"
    view.write_recording(store, out)
    view.write_recording(store, out)  # its own recording: made again
    assert len(fake_rr) == 2 and guard.is_recording(out)
    other = tmp_path / "notes.rrd"
    other.write_text("mine")
    with pytest.raises(DataError, match=r"exists and is not a rerun recording this command "
                                        r"wrote"):
        view.write_recording(store, other)
    assert other.read_text() == "mine"


def test_scans_without_gt_are_placed_by_the_drifting_estimate():
    # GT for the first two scans only, an estimate that drifts away from it: scans 0 and 1
    # where the GT puts them, scan 2 where the (aligned) estimate does
    def at(x, y=0.0):
        T = np.eye(4)
        T[:3, 3] = [x, y, 0.0]
        return T

    t = np.array([0.0, 0.1, 0.2])
    pts = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    scans = [Scan(s, pts, np.array([0.0, 0.0])) for s in t]
    gt = Trajectory(t[:2], np.array([at(10), at(11)]))
    est = Trajectory(t, np.array([at(0), at(1, 3), at(2, 6)]))
    rec = _Stream("x")
    view._log_sequence(_fake_rr(), rec, MemorySequence("m", SensorInfo("radar", 0.1), scans, gt),
                       gt, est, 1)
    placed = [item[1] for p, item, _ in rec.logged if p == "world/scan"]
    for got, shift in zip(placed, ([10, 0, 0], [11, 0, 0], [12, 6, 0]), strict=True):
        np.testing.assert_allclose(got, pts + shift)


def test_the_colour_limit_is_the_first_scan_s_95th_percentile():
    # |d| of the first scan: 95 values of 1 m/s and 5 of 10 m/s: its 95th percentile
    # (linear, numpy's default) is 1 + 0.05 * 9 = 1.45 m/s (the 96th would be 10 m/s)
    d0 = np.r_[np.ones(95), np.full(5, 10.0)]
    pts = np.zeros((100, 3)) + [1.0, 0.0, 0.0]
    scans = [Scan(0.0, pts, d0), Scan(0.1, pts[:2], np.array([2.0, -0.725]))]
    rec = _Stream("x")
    view._log_sequence(_fake_rr(), rec, MemorySequence("m", SensorInfo("radar", 0.1), scans),
                       None, None, 1)
    first, second = (item[2]["colors"] for p, item, _ in rec.logged if p == "world/scan")
    # d = 1 m/s: x = 1 / 1.45; red 0.55 + 0.45 x, green 0.55 (1 - x), blue 0.55 (1 - x)
    x = 1 / 1.45
    np.testing.assert_array_equal(first[0], np.floor(255 * np.array(
        [0.55 + 0.45 * x, 0.55 * (1 - x), 0.55 * (1 - x)])))
    # the second scan keeps the first's limit: 2 m/s saturates red, -0.725 is half blue
    np.testing.assert_array_equal(second, [[255, 0, 0], [70, 70, 197]])


def test_an_all_zero_first_scan_sets_the_limit_to_1_mps():
    pts = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    scans = [Scan(0.0, pts, np.zeros(2)), Scan(0.1, pts, np.array([0.5, -1.0]))]
    rec = _Stream("x")
    view._log_sequence(_fake_rr(), rec, MemorySequence("m", SensorInfo("radar", 0.1), scans),
                       None, None, 1)
    first, second = (item[2]["colors"] for p, item, _ in rec.logged if p == "world/scan")
    np.testing.assert_array_equal(first, [[140, 140, 140]] * 2)
    # limit 1 m/s: 0.5 -> x = 0.5: red 0.775, green 0.275, blue 0.275; -1 -> full blue
    np.testing.assert_array_equal(second, [[197, 70, 70], [0, 0, 255]])


def test_rerun_itself_reads_the_recording_back(store, tmp_path):
    chunk = dev_dependency("rerun.chunk")
    out = tmp_path / "v.rrd"
    view.write_recording(store, out, pair=1, stride=3)
    reader = chunk.RrdReader(out)
    assert [r.application_id for r in reader.recordings()] == ["doppler-bench"]
    assert [str(r.recording_id) for r in reader.recordings()] == ["view-t"]
    paths = {str(c.entity_path) for c in reader.stream()}
    assert {"/world/scan", "/world/sensor", "/world/ground_truth",
            "/world/pair/closest_correspondences",
            "/world/pair/doppler_correspondences"} <= paths
    assert "/world/estimate" not in paths
