"""How the store is read: only the per-point arrays asked for, from blocks of whole chunks, in
any order, with the same values as the arrays written; version 1 stores read the same."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import loaders.store as store_module
from conftest import SAMPLE_STORE as SAMPLE
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import FORMAT_VERSION, StoreSequence, write_store
from methods.registry import METHODS


def _ragged_sequence(n_frames: int = 40, seed: int = 0) -> MemorySequence:
    """Scans of 1 to 2,500 points with Doppler and two fields (one of them deskew times)."""
    rng = np.random.default_rng(seed)
    scans = []
    for k in range(n_frames):
        n = int(rng.integers(1, 2500))
        scans.append(Scan(k * 0.1, rng.normal(size=(n, 3)) * 30, rng.normal(size=n),
                          {"power": rng.random(n), "time_offset_s": rng.random(n) * 0.1}))
    return MemorySequence("ragged", SensorInfo("radar", 0.1), scans)


def _same(scan: Scan, ref: Scan, fields: set[str] | None) -> None:
    np.testing.assert_array_equal(scan.points, ref.points.astype(np.float32))
    if fields is None or "doppler" in fields:
        np.testing.assert_array_equal(scan.doppler, ref.doppler.astype(np.float32))
    else:
        assert scan.doppler is None
    wanted = set(ref.fields) if fields is None else set(ref.fields) & fields
    assert set(scan.fields) == wanted
    for name in wanted:
        np.testing.assert_array_equal(scan.fields[name], ref.fields[name].astype(np.float32))


@pytest.mark.parametrize("fields", [None, {"doppler"}, set(), {"time_offset_s", "unknown"}])
def test_blocks_of_small_chunks_give_every_scan_in_any_order(tmp_path, monkeypatch, fields):
    # chunks of 1,000 points and blocks of 3,000: scans cross chunk and block boundaries, and
    # some scans are larger than a block
    monkeypatch.setattr(store_module, "CHUNK_POINTS", 1000)
    monkeypatch.setattr(store_module, "BLOCK_POINTS", 3000)
    seq = _ragged_sequence()
    store = StoreSequence(write_store(seq, tmp_path / "r.h5"), fields=fields)
    with h5py.File(store.path) as h5:
        assert h5["points/xyz"].chunks == (1000, 3)
    n = len(seq)
    order = [*range(n), *reversed(range(n)), *np.random.default_rng(1).permutation(n)]
    for i in order:
        _same(store[i], seq[i], fields)
    store.close()


def test_a_scan_does_not_share_memory_with_the_block(tmp_path, monkeypatch):
    monkeypatch.setattr(store_module, "BLOCK_POINTS", 1)
    seq = _ragged_sequence(6)
    store = StoreSequence(write_store(seq, tmp_path / "r.h5"))
    first = store[0]
    for i in range(1, 6):  # reading on replaces the block; the scan read first keeps its values
        store[i]
    _same(first, seq[0], None)


def test_version_2_layout_raw_inputs_compressed_annotations(tmp_path):
    seq = _ragged_sequence(5)
    with h5py.File(write_store(seq, tmp_path / "fast.h5")) as h5:
        assert h5.attrs["format_version"] == FORMAT_VERSION == 2
        for name in ("xyz", "doppler", "time_offset_s"):
            assert h5[f"points/{name}"].compression is None
            assert h5[f"points/{name}"].chunks[0] == 65536
        assert h5["points/power"].compression == "lzf"
    with h5py.File(write_store(seq, tmp_path / "small.h5", compression="gzip")) as h5:
        assert {h5[f"points/{k}"].compression for k in h5["points"]} == {"gzip"}


def test_a_version_1_store_reads_the_same(tmp_path, monkeypatch):
    # version 1: every array shuffle + LZF in 32,768-point chunks
    monkeypatch.setattr(store_module, "CHUNK_POINTS", 32768)
    seq = _ragged_sequence(60)
    path = write_store(seq, tmp_path / "v1.h5", compression="lzf")
    with h5py.File(path, "r+") as h5:
        h5.attrs["format_version"] = 1
    for fields in (None, {"doppler"}):
        store = StoreSequence(path, fields=fields)
        for i in range(len(seq)):
            _same(store[i], seq[i], fields)
        store.close()


def test_the_vendored_version_1_sample_reads_with_selected_arrays():
    assert SAMPLE.exists(), f"the vendored real sample {SAMPLE} is missing"
    with h5py.File(SAMPLE) as h5:
        assert h5.attrs["format_version"] == 1 and h5["points/xyz"].compression == "gzip"
    full, doppler_only, points_only = (StoreSequence(SAMPLE, fields=f)
                                       for f in (None, {"doppler"}, frozenset()))
    for i in (0, 1, 137, 249, 3):
        a, b, c = full[i], doppler_only[i], points_only[i]
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.points, c.points)
        np.testing.assert_array_equal(a.doppler, b.doppler)
        assert c.doppler is None and a.stamp == b.stamp == c.stamp


def test_every_registered_method_declares_what_it_reads():
    # a method that declares nothing reads everything (plugins); the registered ones say
    for cls in METHODS.values():
        if cls.__module__.startswith("methods."):
            assert cls.reads_fields is not None, cls.name
            assert cls.reads_fields <= {"doppler", "time_offset_s"}, cls.name
    assert METHODS["doppler"].reads_fields == {"doppler"}
    assert METHODS["gicp"].reads_fields == frozenset()
