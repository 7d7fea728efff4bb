"""Doppler Correspondence's reused sort arrays (methods/doppler_kernel.SortWorkspace): five
disjoint views of the asked length and dtype, kept while a scan fits and grown when one does
not, so that ``sorted_scan_into`` through them equals ``sorted_scan`` scan after scan; and the
warm-up leaves no compilation to a timed call."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from methods import doppler_kernel as kernel


def _disjoint(arrays) -> bool:
    return not any(np.shares_memory(a, b) for a, b in itertools.combinations(arrays, 2))


def test_the_views_are_disjoint_and_of_the_asked_shape_and_dtype():
    ws = kernel.SortWorkspace()
    for n in (0, 1, 5, 4, 100, 7, 126, 300):
        values, keys, spare, pts, vals = arrays = ws.arrays(n)
        assert values.shape == (n,) and values.dtype == np.float32
        assert keys.shape == spare.shape == (n,) and keys.dtype == spare.dtype == np.uint64
        assert pts.shape == (3, n) and pts.dtype == np.float32
        assert vals.shape == (n,) and vals.dtype == np.float32
        if n:
            assert _disjoint(arrays)


def test_a_scan_that_fits_reuses_the_arrays_and_a_larger_one_grows_them():
    ws = kernel.SortWorkspace()
    first = ws.arrays(100)
    again = ws.arrays(60)
    assert all(np.shares_memory(a[:1], b[:1]) for a, b in zip(first, again, strict=True))
    grown = ws.arrays(101)  # a little larger: grown by a quarter at least
    assert not np.shares_memory(grown[0], first[0])
    bigger = ws.arrays(125)  # still within the grown capacity
    assert np.shares_memory(bigger[0][:1], grown[0][:1])
    assert not np.shares_memory(ws.arrays(126)[0], grown[0])


def test_sorting_through_one_workspace_equals_sorting_each_scan_afresh():
    rng = np.random.default_rng(7)
    ws = kernel.SortWorkspace()
    for n in (50, 400, 30, 401, 1000, 999):
        pts = rng.uniform(-50, 50, (3, n)).astype(np.float32)
        dop = rng.uniform(-10, 10, n).astype(np.float32)
        ref_pts, ref_vals = kernel.sorted_scan(pts, dop, 0.1, 1.0)
        arrays = ws.arrays(n)
        kernel.sorted_scan_into(pts, dop, 0.1, 1.0, *arrays)
        np.testing.assert_array_equal(arrays[3], ref_pts)
        np.testing.assert_array_equal(arrays[4], ref_vals)
        np.testing.assert_array_equal(ref_vals, np.sort(ref_vals))


_AFTER_WARM_UP = """
import numpy as np
from methods import doppler_kernel as kernel
from methods import timing

kernel.warm_up()
rng = np.random.default_rng(8)
pts = rng.uniform(-50, 50, (3, 200)).astype(np.float32)
dop = rng.uniform(-10, 10, 200).astype(np.float32)
ws = kernel.SortWorkspace()
with timing.stopwatch() as watch:
    f = kernel.features(pts, dop, 0.1, 1.0)
    keys = kernel.sorted_keys(f)
    kernel.match_and_accumulate(pts, f, keys, pts, f, keys, 9.0, 5.0)
    ps, fs = kernel.sorted_scan(pts, dop, 0.1, 1.0)
    arrays = ws.arrays(200)
    kernel.sorted_scan_into(pts, dop, 0.1, 1.0, *arrays)
    kernel.match_sorted(arrays[3], arrays[4], ps, fs, 9.0, 5.0)
    kernel.pairs(pts, dop, pts, dop, 0.1, 9.0, 5.0)
    kernel.match_sorted_into(arrays[3], arrays[4], ps, fs, 9.0, 5.0, arrays[0].view(np.int32))
    kernel.match_fit_into(arrays[3], arrays[4], ps, fs, 9.0, 5.0, arrays[0].view(np.int32))
print("compiles", watch.compiles)
"""


def test_after_the_warm_up_no_kernel_call_compiles():
    """In a fresh process (nothing compiled or loaded yet): the warm-up compiles or loads every
    path a float32 scan takes, so none of the kernel's calls compiles (or loads) afterwards."""
    root = Path(__file__).resolve().parents[1]
    out = subprocess.run([sys.executable, "-c", _AFTER_WARM_UP], cwd=root, timeout=600,
                         capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(root)})
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-2:] == ["compiles", "0"], out.stdout
