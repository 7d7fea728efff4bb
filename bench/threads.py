"""Thread counts of the numerical libraries, pinned the same way in every executor mode.

BLAS (OpenBLAS / MKL), OpenMP and numba read their thread counts from these variables when they
load, so ``pin_threads`` must run before NumPy & co. are imported (``bench.cli`` calls it first)
and worker processes inherit the values. A value the user set is kept. Each method's own
``num_threads`` parameter (small_gicp, kiss-icp, kd-trees) is separate and recorded with its
parameters.
"""

from __future__ import annotations

import os

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def pin_threads() -> dict[str, str]:
    """Set every variable of ``THREAD_VARS`` to 1 unless already set; return the values."""
    for var in THREAD_VARS:
        os.environ.setdefault(var, "1")
    return {var: os.environ[var] for var in THREAD_VARS}


def thread_settings() -> dict[str, str | None]:
    """The current values (recorded in each run's meta.json)."""
    return {var: os.environ.get(var) for var in THREAD_VARS}
