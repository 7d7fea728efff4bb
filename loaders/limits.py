"""What one frame may cost, checked from file sizes and headers before anything is read.

A corrupt or hostile input (a 2 GB frame file, a PCD header claiming two billion values a
point, a bag message whose length field is garbage) must end in one ``DataError``, not in an
allocation that exhausts the machine. Every loader checks the bytes a frame would occupy
against ``max_frame_bytes()`` before reading it:

- the limit is ``DEFAULT_MAX_FRAME_MB`` = 256 MB a frame (the largest real frames the loaders
  read hold a few MB: a dense FMCW LiDAR frame of 120,000 points x 29 bytes is 3.5 MB), so a
  conversion's memory stays within a few times that;
- raise it for a genuine larger frame with the environment variable ``BENCH_MAX_FRAME_MB``
  in MB = 10^6 bytes, not MiB (e.g. ``BENCH_MAX_FRAME_MB=2048 bench convert ...``);
  ``BENCH_MAX_FRAME_MB=inf`` lifts the limit (``NO_LIMIT``); zero, a negative number or NaN is
  one ``DataError``.

Numbers in file names (frame indices, nanosecond stamps) are parsed by ``file_number``: at most
19 digits (below 2^63, what an int64 stamp holds), so a stray file named with 30 digits is one
``DataError`` naming it, not an ``OverflowError``.
"""

from __future__ import annotations

import os
from pathlib import Path

from loaders.errors import DataError

DEFAULT_MAX_FRAME_MB = 256
ENV_VAR = "BENCH_MAX_FRAME_MB"
#: the largest number a frame file's name may carry (int64)
MAX_FILE_NUMBER = 2**63 - 1
#: the limit [bytes] when ``BENCH_MAX_FRAME_MB=inf``: none (no file or frame is larger)
NO_LIMIT = 2**63 - 1


def max_frame_bytes() -> int:
    """The per-frame limit [bytes]: ``BENCH_MAX_FRAME_MB`` (MB = 10^6 bytes; ``inf``: no limit,
    ``NO_LIMIT``) or 256 MB."""
    text = os.environ.get(ENV_VAR, "").strip()
    if not text:
        return DEFAULT_MAX_FRAME_MB * 1_000_000
    try:
        mb = float(text)
    except ValueError:
        raise DataError(f"{ENV_VAR}={text!r}: expected a number of megabytes") from None
    if not mb > 0:
        raise DataError(f"{ENV_VAR}={text!r}: expected a positive number of megabytes (or inf: "
                        "no limit)")
    if mb * 1_000_000 >= NO_LIMIT:  # inf, or more than any file can hold
        return NO_LIMIT
    return int(mb * 1_000_000)


def check_frame_bytes(nbytes: int, where: str, what: str = "the frame") -> None:
    """``DataError`` when ``nbytes`` (what reading the frame would hold) exceeds the limit."""
    limit = max_frame_bytes()
    if limit < NO_LIMIT and nbytes > limit:
        raise DataError(
            f"{where}: {what} would take {nbytes / 1e6:,.0f} MB, above the per-frame limit of "
            f"{limit / 1e6:,.0f} MB (real frames hold a few MB: a corrupt or foreign file?); "
            f"if the frame is genuine, raise the limit with {ENV_VAR}=<MB>")


def check_file_size(path: Path, where: str) -> int:
    """The size of ``path`` [bytes], checked against the per-frame limit (from ``stat``, before
    anything is read)."""
    try:
        size = Path(path).stat().st_size
    except OSError as err:
        raise DataError(f"{where}: cannot read the file ({err.strerror or err})") from None
    check_frame_bytes(size, where, f"the file ({size:,} bytes)")
    return size


def file_number(text: str, path: Path | str) -> int:
    """The number in a frame file's name (``text``: its digits), at most ``MAX_FILE_NUMBER``."""
    if not text.isdigit():
        raise DataError(f"{path}: expected a number in the file name, got {text!r}")
    if len(text) > 19 or int(text) > MAX_FILE_NUMBER:
        raise DataError(f"{path}: the number in the file name has {len(text)} digits; expected "
                        "a frame index or a stamp of at most 19 digits (below 2^63): a stray "
                        "file? move it out of the folder")
    return int(text)
