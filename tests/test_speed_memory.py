"""`bench speed --memory`: the probe measures a finished `bench run`, not a failed one."""

from __future__ import annotations

import pytest

from bench.studies.speed import peak_memory_of_run
from conftest import constant_twist_sequence
from loaders.store import write_store


def test_memory_probe_measures_a_finished_run_and_fails_loudly(tmp_path):
    store = tmp_path / "twist.h5"
    write_store(constant_twist_sequence(n_frames=12, n_points=2000), store)  # an 8.8 m path
    # icp-p2p takes num_threads: the probe once passed it as `-p=num_threads=1`, which every
    # run rejected (exit 2), and reported the imports' footprint as the method's peak
    peak_mb, imports_mb = peak_memory_of_run("icp-p2p", store)
    assert peak_mb > imports_mb > 50
    with pytest.raises(RuntimeError, match="bench run` failed"):
        peak_memory_of_run("icp-p2p", tmp_path / "missing.h5")
