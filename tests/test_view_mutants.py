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
