"""Headerless binary point files: fixed-size little-endian records, one per point.

View-of-Delft, ColoRadar and HeLiPR store each scan as such a file with no header: the point
count is the file size divided by the record size. ``read_records`` checks that the size is a
whole number of records before reading (a truncated file, or a file of another layout, is one
``DataError`` naming the file, the frame and the layout expected, never a huge allocation: the
array read is never larger than the file, and a file above the per-frame limit of
``loaders.limits`` is refused from its size), and names the layout the size does fit when one of
the ``alternatives`` (e.g. the same sensor without its Doppler field) matches.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.limits import check_file_size


def record_dtype(fields: list[tuple[str, str]]) -> np.dtype:
    """A packed (unaligned) record of ``(name, numpy type)`` fields, e.g. ``("x", "<f4")``."""
    return np.dtype(fields, align=False)


def describe(dtype: np.dtype) -> str:
    """ "x y z (float32), time_offset_ns (int32)"-style description of a record."""
    parts: list[tuple[str, list[str]]] = []
    for name in dtype.names:
        kind = {"f": "float", "i": "int", "u": "uint"}[dtype[name].kind] + str(
            8 * dtype[name].itemsize)
        if parts and parts[-1][0] == kind:
            parts[-1][1].append(name)
        else:
            parts.append((kind, [name]))
    return ", ".join(f"{' '.join(names)} ({kind})" for kind, names in parts)


def read_records(path: Path, dtype: np.dtype, where: str, layout: str,
                 alternatives: dict[str, int] | None = None) -> np.ndarray:
    """The records of ``path`` as a structured array (one row a point).

    where: "file, frame i" for messages. layout: what the loader expects ("View-of-Delft radar
    N x 7"). alternatives: other record sizes [bytes] by what they would mean ("ColoRadar lidar
    x y z intensity, no Doppler"), named in the error when the size fits one of them."""
    size = check_file_size(path, where)
    rec = dtype.itemsize
    if size == 0:
        raise DataError(f"{where}: empty file (0 bytes); expected {layout}: {rec}-byte records "
                        f"of {describe(dtype)}")
    if size % rec:
        fits = [f"{what} ({n} bytes a point)" for what, n in (alternatives or {}).items()
                if n and size % n == 0]
        hint = (f"; its size is a whole number of records of {' or '.join(fits)}: a file of "
                "another layout?" if fits else "; the file is truncated or not this layout")
        raise DataError(
            f"{where}: {size} bytes is not a whole number of {rec}-byte records ({layout}: "
            f"{describe(dtype)}){hint}")
    return np.fromfile(path, dtype=dtype, count=size // rec)
