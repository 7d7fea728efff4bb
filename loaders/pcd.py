"""A small reader of PCD point-cloud files (``DATA ascii`` and ``DATA binary``), header checked
against the bytes before anything is allocated.

Format (PCL's "PCD v0.7": pointclouds.org/documentation/tutorials/pcd_file_format.html): text
header lines ``VERSION``, ``FIELDS``, ``SIZE``, ``TYPE`` (F float, I signed, U unsigned),
``COUNT`` (values per field, default 1), ``WIDTH``, ``HEIGHT``, ``VIEWPOINT``, ``POINTS``, then
``DATA ascii|binary|binary_compressed`` and the data. Binary data are packed little-endian
records of ``sum(SIZE * COUNT)`` bytes, one per point, in FIELDS order.

Snail-Radar writes its radar frames with these two variants (snail-radar/dataset_tools,
``python/bag_to_folder.py``: ``extract_and_save_bin`` writes ``DATA binary``,
``extract_and_save_ascii`` ``DATA ascii``; every radar value is packed as float32, ``SIZE 4``,
``TYPE F``, ``HEIGHT 1``, ``POINTS = WIDTH``). ``binary_compressed`` (LZF) is not used by
the dataset and is refused with a message.

Every inconsistency is one ``DataError`` naming the file and what was expected: a data size that
is not a whole number of records, a point count that disagrees with the bytes, a field list
whose SIZE / TYPE / COUNT lists have another length, an unknown type or size, a missing header
line. The point count of the header is compared with the file size before any array is made, and
the file size and one record (``SIZE`` x ``COUNT`` summed over the fields) with the per-frame
limit of ``loaders.limits`` before a ``COUNT`` is expanded, so a corrupt header never causes a
large allocation.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.fileio import atomic_write_bytes
from loaders.limits import check_file_size, check_frame_bytes

#: the longest header read before giving up (a PCD header is a few hundred bytes)
MAX_HEADER_BYTES = 64 * 1024
_KINDS = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4",
          ("I", 8): "i8", ("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("U", 8): "u8"}


@dataclass(frozen=True)
class PcdHeader:
    """The parsed header: field names (a field with COUNT k > 1 becomes ``name_0..name_k-1``),
    the record dtype, the point count, the data kind and where the data start."""

    fields: list[str]
    dtype: np.dtype
    points: int
    data: str
    data_offset: int


def read_pcd_header(path: Path, head: bytes | None = None) -> PcdHeader:
    """Parse and check the header of ``path`` (``head``: its first bytes, when already read)."""
    if head is None:
        with open(path, "rb") as f:
            head = f.read(MAX_HEADER_BYTES)
    entries: dict[str, list[str]] = {}
    pos = 0
    data_kind = None
    while pos < len(head):
        end = head.find(b"\n", pos)
        if end < 0:
            break
        line = head[pos:end].decode("ascii", errors="replace").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *values = line.split()
        key = key.upper()
        if key == "DATA":
            data_kind = values[0].lower() if values else ""
            break
        entries[key] = values
    if data_kind is None:
        raise DataError(f"{path}: not a PCD file: no DATA line in its first {len(head)} bytes "
                        "(expected a header VERSION / FIELDS / SIZE / TYPE / COUNT / WIDTH / "
                        "HEIGHT / POINTS / DATA)")
    for key in ("FIELDS", "SIZE", "TYPE"):
        if not entries.get(key):
            raise DataError(f"{path}: PCD header has no {key} line; expected FIELDS, SIZE and "
                            "TYPE lists of one entry per field")
    names = entries["FIELDS"]
    sizes, types = entries["SIZE"], entries["TYPE"]
    counts = entries.get("COUNT", ["1"] * len(names))
    if not (len(sizes) == len(types) == len(counts) == len(names)):
        raise DataError(
            f"{path}: PCD header lists {len(names)} FIELDS ({' '.join(names)}) but "
            f"{len(sizes)} SIZE, {len(types)} TYPE and {len(counts)} COUNT entries; expected one "
            "of each per field"
        )
    try:
        ints = [(int(size), int(count)) for size, count in zip(sizes, counts, strict=True)]
        width = int(entries.get("WIDTH", ["-1"])[0])
        height = int(entries.get("HEIGHT", ["1"])[0])
        points = int(entries["POINTS"][0]) if "POINTS" in entries else width * height
    except ValueError as err:
        raise DataError(f"{path}: PCD header has a non-integer SIZE / COUNT / WIDTH / HEIGHT / "
                        f"POINTS ({err})") from None
    # the sizes come first: COUNT 2000000000 must not be expanded into names before refusing
    record = sum(size * count for size, count in ints)
    # (POINTS is compared with the data bytes, which the file-size limit bounds, by read_pcd)
    check_frame_bytes(record, str(path), f"one point record of the PCD header ({record:,} "
                      "bytes: SIZE x COUNT summed over FIELDS)")
    out_names, formats = [], []
    for name, kind, (size, k) in zip(names, types, ints, strict=True):
        fmt = _KINDS.get((kind.upper(), size))
        if fmt is None or k < 1:
            raise DataError(f"{path}: PCD field {name!r} has TYPE {kind} SIZE {size} COUNT "
                            f"{k}; expected TYPE F (4/8), I or U (1/2/4/8), COUNT >= 1")
        for j in range(k):
            out_names.append(name if k == 1 else f"{name}_{j}")
            formats.append("<" + fmt)
    if width < 0 or height < 1 or points != width * height:
        raise DataError(f"{path}: PCD header says POINTS {points} but WIDTH {width} x HEIGHT "
                        f"{height}; expected POINTS = WIDTH * HEIGHT")
    if len(set(out_names)) != len(out_names):
        raise DataError(f"{path}: PCD header repeats a field name ({' '.join(names)})")
    dtype = np.dtype({"names": out_names, "formats": formats})
    return PcdHeader(out_names, dtype, points, data_kind, pos)


def read_pcd(path: str | Path) -> tuple[np.ndarray, list[str]]:
    """The points of a PCD file as a structured array (one field per FIELDS entry, native
    little-endian values) and the field names, after checking the header against the data."""
    path = Path(path)
    try:
        size = check_file_size(path, str(path))
        with open(path, "rb") as f:
            head = f.read(MAX_HEADER_BYTES)
            h = read_pcd_header(path, head)
            if h.data == "binary":
                nbytes = size - h.data_offset
                rec = h.dtype.itemsize
                if nbytes % rec:
                    raise DataError(
                        f"{path}: {nbytes} data bytes are not a whole number of {rec}-byte "
                        f"records (fields {' '.join(h.fields)}); the file is truncated or its "
                        "SIZE / FIELDS header is wrong"
                    )
                if nbytes // rec != h.points:
                    raise DataError(
                        f"{path}: the header says POINTS {h.points} but the data hold "
                        f"{nbytes // rec} records of {rec} bytes (fields {' '.join(h.fields)})"
                    )
                f.seek(h.data_offset)
                arr = np.fromfile(f, dtype=h.dtype, count=h.points)
                return arr, h.fields
            if h.data == "ascii":
                f.seek(h.data_offset)
                return _read_ascii(path, f, h), h.fields
    except OSError as err:
        raise DataError(f"{path}: cannot read the PCD file ({err})") from None
    if h.data == "binary_compressed":
        raise DataError(f"{path}: DATA binary_compressed is not supported (the Snail-Radar "
                        "tools write binary or ascii PCD); re-save it uncompressed, e.g. with "
                        "pcl_convert_pcd_ascii_binary")
    raise DataError(f"{path}: unknown PCD DATA kind {h.data!r}; expected ascii or binary")


def _read_ascii(path: Path, f, h: PcdHeader) -> np.ndarray:
    rows = []
    n_values = len(h.fields)
    for lineno, line in enumerate(f, start=1):
        text = line.strip()
        if not text:
            continue
        parts = text.split()
        if len(parts) != n_values:
            raise DataError(f"{path}: data line {lineno} has {len(parts)} values; expected "
                            f"{n_values} (fields {' '.join(h.fields)})")
        if len(rows) == h.points:
            raise DataError(f"{path}: more data lines than the header's POINTS {h.points}")
        rows.append(parts)
    if len(rows) != h.points:
        raise DataError(f"{path}: the header says POINTS {h.points} but the file has "
                        f"{len(rows)} data lines")
    arr = np.empty(h.points, dtype=h.dtype)
    if h.points:
        try:
            table = np.array(rows, dtype=np.float64)
        except ValueError as err:
            raise DataError(f"{path}: a data value is not a number ({err})") from None
        for j, name in enumerate(h.fields):
            arr[name] = table[:, j]
    return arr


def write_pcd(path: str | Path, arr: np.ndarray, data: str = "binary") -> Path:
    """Write a structured array as PCD (``ascii`` or ``binary``), fields in array order (tests
    and tools; the header matches the arrays exactly)."""
    path = Path(path)
    names = list(arr.dtype.names)
    kinds, sizes = [], []
    for name in names:
        dt = arr.dtype[name]
        kinds.append({"f": "F", "i": "I", "u": "U"}[dt.kind])
        sizes.append(str(dt.itemsize))
    n = len(arr)
    header = ("# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
              f"FIELDS {' '.join(names)}\nSIZE {' '.join(sizes)}\nTYPE {' '.join(kinds)}\n"
              f"COUNT {' '.join('1' for _ in names)}\nWIDTH {n}\nHEIGHT 1\n"
              f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA {data}\n")
    body = [header.encode("ascii")]
    if data == "binary":
        packed = np.dtype({"names": names,
                           "formats": ["<" + arr.dtype[k].str[1:] for k in names]})
        body.append(arr.astype(packed).tobytes())
    else:
        body += [(" ".join(repr(v.item()) for v in row) + "\n").encode("ascii") for row in arr]
    atomic_write_bytes(path, b"".join(body))
    return path
