"""Where and how a run was made (``meta.json``): git commit and dirty flag, package versions,
CPU, thread settings, the timing lock, host and date. Descriptive only: what determines the
result is ``bench.runs.identity``."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from datetime import UTC, datetime
from importlib import metadata
from pathlib import Path

from bench.paths import ROOT
from bench.threads import thread_settings
from methods.timing import TIMING_LOCK_ENV

_PACKAGES = ["doppler-bench", "numpy", "scipy", "h5py", "rosbags", "evo", "kiss-icp",
             "small_gicp", "open3d-cpu", "numba", "pandas", "pydantic"]


def _git_state() -> dict:
    root = ROOT
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True,
                              timeout=10).stdout.strip()
    try:
        return {"commit": git("rev-parse", "HEAD") or None,
                "dirty": bool(git("status", "--porcelain", "--untracked-files=no"))}
    except (OSError, subprocess.SubprocessError):
        return {"commit": None, "dirty": None}


def cpu_model() -> str:
    """The CPU model name (/proc/cpuinfo), else what platform knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def installed_versions(names) -> dict[str, str | None]:
    """The installed version of each distribution in ``names`` (None when absent)."""
    versions = {}
    for name in names:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def run_meta() -> dict:
    """Provenance of a run: git commit and dirty flag, package versions, CPU, threads, date."""
    return {
        "git": _git_state(),
        "python": platform.python_version(),
        "packages": installed_versions(_PACKAGES),
        "cpu": cpu_model(),
        "cpu_count": os.cpu_count(),
        "threads": thread_settings(),
        # what numba actually uses (read when it was imported, which may precede the pinning)
        "numba_threads": (sys.modules["numba"].config.NUMBA_NUM_THREADS
                          if "numba" in sys.modules else None),
        "timing_lock": os.environ.get(TIMING_LOCK_ENV),
        "host": platform.node(),
        "date": datetime.now(UTC).isoformat(timespec="seconds"),
    }
