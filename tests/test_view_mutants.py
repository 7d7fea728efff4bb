"""bench.report.view's colours and pose look-up against values worked out from their
definitions (written for a mutation run of the module)."""

import sys

import numpy as np
import pytest

from bench.report.view import _pose_at, _rerun, doppler_colors
from loaders.errors import DataError
from loaders.se3 import make_T
from loaders.trajectory import Trajectory


def test_doppler_colours_by_hand():
    # x = clip(d / limit, -1, 1); red 0.55 + 0.45 x (x > 0) else 0.55 (1 + x); blue mirrored;
    # green 0.55 (1 - |x|); times 255, truncated to uint8 (exact: an overflow wraps by 256,
    # and 255 too much looks like 1 too little)
    c = doppler_colors(np.array([-5.0, -2.5, 0.0, 2.5, 5.0, 10.0, -10.0]), 5.0)
    assert c.dtype == np.uint8 and c.shape == (7, 3)
    np.testing.assert_array_equal(c, [[0, 0, 255], [70, 70, 197], [140, 140, 140],
                                      [197, 70, 70], [255, 0, 0], [255, 0, 0], [0, 0, 255]])


def test_doppler_colours_with_a_zero_limit():
    # the limit is floored at 1e-6 m/s: any non-zero Doppler saturates, 0 stays grey
    c = doppler_colors(np.array([-1e-3, 0.0, 1e-3]), 0.0)
    np.testing.assert_array_equal(c, [[0, 0, 255], [140, 140, 140], [255, 0, 0]])


def test_the_pose_at_a_stamp():
    poses = np.array([make_T(np.eye(3), np.array([k, 0.0, 0.0])) for k in range(3)])
    traj = Trajectory(np.array([0.0, 0.1, 0.2]), poses)
    np.testing.assert_array_equal(_pose_at(traj, 0.1 + 5e-7), poses[1])
    np.testing.assert_array_equal(_pose_at(traj, 0.2), poses[2])
    assert _pose_at(traj, 0.1 + 2e-6) is None
    assert _pose_at(traj, 0.15) is None
    assert _pose_at(None, 0.1) is None


def test_the_pose_of_a_single_pose_trajectory():
    T = make_T(np.eye(3), np.array([1.0, 2.0, 3.0]))
    np.testing.assert_array_equal(_pose_at(Trajectory(np.array([4.0]), T[None]), 4.0), T)


def test_without_rerun_the_message_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    with pytest.raises(DataError, match=r"^bench view needs rerun-sdk: pip install "
                                        r"'doppler-bench\[viewer\]'$"):
        _rerun()


class _Rec:
    """Records what _log_sequence logs (a stand-in for rerun's RecordingStream)."""

    def __init__(self):
        self.logged, self.times = [], []

    def log(self, path, item, static=False):
        self.logged.append((path, item, static))

    def set_time(self, name, **value):
        self.times.append((name, value))


def _fake_rr():
    from types import SimpleNamespace

    return SimpleNamespace(LineStrips3D=lambda strips, **kw: ("lines", strips, kw),
                           Points3D=lambda pts, **kw: ("points", pts, kw))


def test_what_the_sequence_logs():
    from bench.report.view import _log_sequence
    from loaders.scan import MemorySequence, Scan, SensorInfo

    def at(x):
        return make_T(np.eye(3), np.array([x, 0.0, 0.0]))

    t = np.array([5.0, 5.1, 5.2])
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [1.0, 1.0, 1.0]])
    dop = np.array([-4.0, 0.0, 4.0, 2.0])  # 95th percentile of |d|: 4 m/s
    scans = [Scan(s, pts, dop) for s in t]
    gt = Trajectory(t[:2], np.array([at(10), at(11)]))  # the last scan has no GT
    est = Trajectory(t, np.array([at(0), at(1), at(2)]))
    rec = _Rec()
    _log_sequence(_fake_rr(), rec, MemorySequence("m", SensorInfo("radar", 0.1), scans, gt),
                  gt, est, 1)
    (p0, e, s0), (p1, g, s1) = rec.logged[:2]
    assert (p0, s0, p1, s1) == ("world/estimate", True, "world/ground_truth", True)
    np.testing.assert_allclose(e[1][0], [[10, 0, 0], [11, 0, 0], [12, 0, 0]])  # aligned
    assert e[2] == {"colors": [[255, 140, 0]]}
    np.testing.assert_allclose(g[1][0], [[10, 0, 0], [11, 0, 0]])
    assert g[2] == {"colors": [[20, 20, 20]]}
    assert [n for n, _ in rec.times] == ["frame", "time"] * 3
    assert [v["sequence"] for n, v in rec.times if n == "frame"] == [0, 1, 2]
    np.testing.assert_allclose([v["duration"] for n, v in rec.times if n == "time"],
                               [0.0, 0.1, 0.2], atol=1e-12)
    rest = rec.logged[2:]
    assert [p for p, _, _ in rest] == ["world/scan", "world/sensor"] * 3
    for k, x in enumerate([10.0, 11.0, 12.0]):  # placed by the GT, the last by the estimate
        (_, (kind, p, kw), static), (_, (kind2, c, kw2), _) = rest[2 * k], rest[2 * k + 1]
        assert kind == kind2 == "points" and not static
        np.testing.assert_allclose(p, pts + [x, 0, 0])
        assert kw["radii"] == 0.05
        np.testing.assert_array_equal(kw["colors"], doppler_colors(dop, 4.0))
        np.testing.assert_allclose(c, [[x, 0, 0]])
        assert kw2 == {"radii": 0.4, "colors": [[0, 160, 0]]}


def test_what_the_sequence_logs_without_gt_with_a_stride():
    from bench.report.view import _log_sequence
    from loaders.scan import MemorySequence, Scan, SensorInfo

    t = np.array([1.0, 1.1, 1.2])
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0]])
    scans = [Scan(t[0], pts, np.array([1.0, -1.0])), Scan(t[1], pts), Scan(t[2], pts)]
    est = Trajectory(t[:2], np.array([make_T(np.eye(3), np.array([x, 0.0, 0.0]))
                                      for x in (3.0, 4.0)]))
    rec = _Rec()
    _log_sequence(_fake_rr(), rec, MemorySequence("m", SensorInfo("radar", 0.1), scans), None,
                  est, 2)
    (p0, e, _), *rest = rec.logged
    assert p0 == "world/estimate"
    np.testing.assert_allclose(e[1][0], [[0, 0, 0], [1, 0, 0]])  # aligned at the identity
    assert [p for p, _, _ in rest] == ["world/scan", "world/sensor", "world/scan"]
    np.testing.assert_allclose(rest[0][1][1], pts)  # frame 0: the estimate's first pose
    np.testing.assert_allclose(rest[2][1][1], pts)  # frame 2: no pose, as measured
    assert rest[2][1][2]["colors"] is None  # no Doppler
    assert [v["sequence"] for n, v in rec.times if n == "frame"] == [0, 2]
