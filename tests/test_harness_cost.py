"""``bench.studies.harness``: the harness's own per-frame cost, phase by phase."""

from __future__ import annotations

import numpy as np

from bench.studies.harness import phases, tiled_store
from conftest import constant_twist_sequence
from loaders.store import StoreSequence


def test_tiled_store_cycles_the_scans_on_a_straight_ground_truth(tmp_path):
    base = constant_twist_sequence(n_frames=4, n_points=500)
    store = StoreSequence(tiled_store(base, 10, tmp_path / "t.h5"))
    assert len(store) == 10
    np.testing.assert_allclose(store.stamps, np.arange(10) * base.sensor.period_s)
    np.testing.assert_array_equal(store[6].points, base[2].points.astype(np.float32))
    np.testing.assert_allclose(store.ground_truth.poses[:, 0, 3], 10.0 * store.stamps)


def test_phases_add_up_to_the_harness_cost(tmp_path):
    base = constant_twist_sequence(n_frames=6, n_points=1500)
    r = phases(tiled_store(base, 60, tmp_path / "t.h5"), "doppler")
    assert r["frames"] == 60 and r["method"] == "doppler"
    assert r["method_ms"] > 0 and r["read_ms"] > 0 and r["startup_s"] > 0
    for suffix in ("", "_wall"):
        parts = sum(r[f"{k}{suffix}_ms"] for k in ("read", "driver", "evaluate", "write"))
        assert abs(r[f"harness{suffix}_ms"] - parts) < 1e-9
        # the loop holds the method's timed frames (59 of 60) and the reads
        assert r[f"loop{suffix}_ms"] > r["method_ms"] * 59 / 60
