"""Thread counts of the numerical libraries: pinned to 1, from this one place, on every path that
times a method (the CLI, the executors' workers, ``bench.api``, ``bench speed``, the tests).

Two layers, because neither alone is enough:
- ``pin_threads`` sets ``THREAD_VARS`` to 1 in the environment. BLAS (OpenBLAS / MKL), OpenMP
  and numba read them when they load, so it should run before NumPy & co. are imported:
  ``bench/__init__.py`` calls it, so importing anything of ``bench`` first pins them, and
  worker processes inherit the values. A different value the user set (e.g.
  ``OPENBLAS_NUM_THREADS=4``) is overridden: a timed run is a one-thread run; the user's value
  is kept in ``overridden_settings`` and recorded in each run's meta.json.
- ``limit_threads`` sets the thread count of the libraries already loaded in this process
  (OpenBLAS, libgomp, numba) to 1 at the start of every timed run, so a process that loaded
  NumPy, numba or kiss-icp before ``bench`` (a notebook, a script) cannot leak either: numba
  through its run-time ``numba.set_num_threads``, never by changing ``NUMBA_NUM_THREADS`` under
  a pool already running (numba refuses that at its next compilation). It uses threadpoolctl when
  installed, else the libraries' own ``*_set_num_threads`` entry points found in the process's
  memory map (the symbol names are threadpoolctl's, threadpoolctl/threadpoolctl.py).

Each method's own ``num_threads`` parameter (small_gicp, kiss-icp, kd-trees) is separate and
recorded with its parameters. Whatever leaks anyway is caught by the process-CPU check of every
run (``methods.timing.cpu_leak``).
"""

from __future__ import annotations

import ctypes
import os
import sys

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
PINNED = "1"
#: the values the user had set before ``pin_threads`` overrode them (recorded in meta.json)
overridden_settings: dict[str, str] = {}
#: [True] once numba's pool was found running before ``pin_threads`` (limited at run time)
_numba_limited_at_run_time: list[bool] = []

# (library file name contains, setter symbols): OpenBLAS under its plain and SciPy-wheel names
# (NumPy's 64-bit-integer build adds a 64_ suffix), OpenMP (libgomp, libomp, libiomp), MKL
_SETTERS = (
    ("openblas", ("openblas_set_num_threads", "openblas_set_num_threads64_",
                  "scipy_openblas_set_num_threads", "scipy_openblas_set_num_threads64_")),
    ("omp", ("omp_set_num_threads",)),
    ("mkl_rt", ("MKL_Set_Num_Threads",)),
)


def numba_pool_launched() -> bool:
    """numba is loaded and its thread pool already started (its size is then fixed)."""
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return bool(getattr(parallel, "_is_initialized", False))


def pin_threads() -> dict[str, str]:
    """Set every variable of ``THREAD_VARS`` to 1 (a user's other value is overridden and
    remembered in ``overridden_settings``); return the values.

    numba reads ``NUMBA_NUM_THREADS`` again at every compilation and refuses a value other than
    its pool's once the pool is running ("Cannot set NUMBA_NUM_THREADS to a different value
    once the threads have been launched"): in a process that ran parallel numba code before
    importing ``bench`` (a notebook) the variable is left alone, and every timed run limits
    numba at run time instead (``numba.set_num_threads(1)`` in ``limit_threads``). numba
    loaded but its pool not started: its configuration is read again, so the pool starts with
    one thread."""
    launched = numba_pool_launched()
    for var in THREAD_VARS:
        if var == "NUMBA_NUM_THREADS" and launched:
            _numba_limited_at_run_time[:] = [True]
            continue
        value = os.environ.get(var)
        if value is not None and value != PINNED:
            overridden_settings.setdefault(var, value)
        os.environ[var] = PINNED
    numba = sys.modules.get("numba")
    if numba is not None and not launched:
        numba.core.config.reload_config()
    return thread_settings()


def thread_settings() -> dict[str, str | None]:
    """The thread count of each library in a timed run (recorded in each run's meta.json and
    in its host identity): the variables' values, and "1" for numba when its pool was started
    before ``bench`` and is limited at run time instead."""
    settings = {var: os.environ.get(var) for var in THREAD_VARS}
    if _numba_limited_at_run_time:
        settings["NUMBA_NUM_THREADS"] = PINNED
    return settings


def _loaded_libraries() -> list[str]:
    try:
        with open("/proc/self/maps") as f:
            paths = {line.split()[-1] for line in f if ".so" in line}
    except OSError:
        return []
    return sorted(p for p in paths if p.startswith("/"))


def _limit_native(threads: int) -> list[str]:
    limited = []
    for path in _loaded_libraries():
        name = os.path.basename(path).lower()
        for marker, symbols in _SETTERS:
            if marker not in name:
                continue
            try:
                lib = ctypes.CDLL(path, mode=os.RTLD_NOLOAD | os.RTLD_LOCAL)
            except OSError:
                continue
            for symbol in symbols:
                setter = getattr(lib, symbol, None)
                if setter is not None:
                    setter(ctypes.c_int(threads))
                    limited.append(f"{os.path.basename(path)}:{symbol}")
                    break
    return limited


def limit_threads(threads: int = 1) -> list[str]:
    """Set the thread count of every numerical library loaded in this process (BLAS, OpenMP,
    numba) to ``threads``; returns what was limited. Called at the start of every timed run."""
    pin_threads()
    limited = []
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(threads)
        limited.append("threadpoolctl")
    except ImportError:
        limited += _limit_native(threads)
    numba = sys.modules.get("numba")
    if numba is not None:
        try:  # at run time: works whenever numba was loaded, its pool started or not
            numba.set_num_threads(threads)
            limited.append("numba")
        except (ValueError, RuntimeError):  # numba's own limit is below ``threads``
            pass
    return limited


def leak_hint() -> str:
    """What to check when work left the timed thread (for the process-CPU check's message)."""
    user = ", ".join(f"{k}={v}" for k, v in overridden_settings.items())
    now = ", ".join(f"{k}={v}" for k, v in thread_settings().items())
    return (f"thread settings now {now}" + (f" (the user had set {user})" if user else "")
            + "; a library with its own threads (TBB, OpenMP, a method's num_threads) or "
            "another thread of this process (a progress display) also counts")
