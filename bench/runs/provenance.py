"""Where and how a run was made (``meta.json``): git commit and dirty flag, package versions,
CPU, thread settings, the timing lock, host and date. Descriptive only: what determines the
result is ``bench.runs.identity``."""

from __future__ import annotations

import functools
import hashlib
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


def _cpuinfo(text: str | None = None) -> dict[str, str]:
    """The first processor's fields of /proc/cpuinfo (or of ``text``); empty elsewhere."""
    if text is None:
        try:
            text = Path("/proc/cpuinfo").read_text()
        except OSError:
            return {}
    fields: dict[str, str] = {}
    for line in text.splitlines():
        if not line.strip():
            if fields:
                break  # the first processor's block is enough
            continue
        key, sep, value = line.partition(":")
        if sep:
            fields.setdefault(key.strip(), value.strip())
    return fields


def cpu_model(cpuinfo: str | None = None) -> str:
    """The CPU's full description: /proc/cpuinfo's model name with the vendor, family, model
    and stepping numbers, e.g. "AMD EPYC (AuthenticAMD family 25 model 1 stepping 1)". A virtual
    machine may name only "AMD EPYC" for every generation; the numbers still tell them apart.
    Elsewhere macOS's brand string, else what ``platform`` knows (on Windows it holds the
    family, model and stepping too)."""
    info = _cpuinfo(cpuinfo)
    name = info.get("model name") or info.get("Model Name") or info.get("Hardware")
    numbers = [f"{label} {info[key]}" for key, label in (
        ("cpu family", "family"), ("model", "model"), ("stepping", "stepping"),
        ("CPU implementer", "implementer"), ("CPU part", "part"), ("CPU variant", "variant"),
        ("CPU revision", "revision")) if key in info]
    vendor = info.get("vendor_id")
    detail = " ".join(([vendor] if vendor else []) + numbers)
    if name or detail:
        return f"{name or 'unknown CPU'} ({detail})" if detail else name
    if platform.system() == "Darwin":
        try:
            brand = subprocess.run(["sysctl", "-n", "machdep.cpu.brand_string"],
                                   capture_output=True, text=True, timeout=5).stdout.strip()
            if brand:
                return brand
        except (OSError, subprocess.SubprocessError):
            pass
    return platform.processor() or platform.machine()


def cpu_flags_digest(cpuinfo: str | None = None) -> str | None:
    """SHA-256 (12 hex digits) of the CPU's instruction-set flags (/proc/cpuinfo ``flags``, or
    ``Features`` on ARM; None elsewhere): two hosts of one model name may expose different
    instruction sets (a virtual machine's configuration), and numba compiles for them."""
    info = _cpuinfo(cpuinfo)
    flags = info.get("flags") or info.get("Features")
    if not flags:
        return None
    return hashlib.sha256(" ".join(sorted(flags.split())).encode()).hexdigest()[:12]


@functools.cache
def installed_version(name: str) -> str | None:
    """The installed version of distribution ``name`` (None: not installed); read once per
    process (every skip decision of a command asks for the same few)."""
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def installed_versions(names) -> dict[str, str | None]:
    """The installed version of each distribution in ``names`` (None when absent), read once
    per process (``installed_version``)."""
    return {name: installed_version(name) for name in names}


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
