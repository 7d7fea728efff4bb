"""Shared ROS1 bag reading for the real-dataset loaders (rosbags, pure Python).

- ``BagTopic``: opens one or more bags, finds a topic (a ``DataError`` lists the topics a bag
  has when it is missing), checks the message type, and keeps a small per-message index
  (bag, chunk, offset). Messages are read lazily one at a time with plain file seeks (at most
  one decompressed chunk is cached per bag), so memory stays bounded by a few frames whatever
  the bag size. After indexing no rosbags reader stays open: instances pickle to workers.
- Fast numpy parsers for the ROS1 wire format of ``std_msgs/Header``,
  ``sensor_msgs/PointCloud`` (Point32 + named channels) and ``sensor_msgs/PointCloud2``
  (PointField layout -> numpy dtype, big-endian aware).
- ``make_typestore``: the ROS1 Noetic type store plus custom .msg definitions registered from
  text (and, when a bag carries its own definition, from the bag).
- ``finish_scan``: the common last step of every loader (drop non-finite points with a
  ``warnings.warn`` and a count, refuse empty scans with a ``DataError``).

Truncated or unindexed bags give one ``DataError`` naming the file.
"""

from __future__ import annotations

import struct
import warnings
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.scan import Scan

try:  # rosbags internals used for the record layout; pinned in pyproject (>= 0.10)
    from rosbags.rosbag1.reader import Header as _RecordHeader
    from rosbags.rosbag1.reader import decompressors as _DECOMPRESSORS
except ImportError:  # pragma: no cover
    _RecordHeader = None
    _DECOMPRESSORS = {}

_OP_MSGDATA = 0x02
_OP_CONNECTION = 0x07

_READ_ERRORS = (OSError, EOFError, struct.error, AssertionError, ValueError, KeyError, IndexError)


def _reader_errors() -> tuple[type[BaseException], ...]:
    from rosbags.rosbag1 import ReaderError

    return (ReaderError, *_READ_ERRORS)


# -- type store --------------------------------------------------------------------------------

def make_typestore(extra: dict[str, str] | None = None):
    """The ROS1 Noetic type store with extra message types registered from .msg text
    (``{"pkg/msg/Name": text}``)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    if extra:
        types = {}
        for name, text in extra.items():
            types.update(get_types_from_msg(text, name))
        store.register(types)
    return store


def register_bag_definition(store, msgtype: str, msgdef: str) -> bool:
    """Register a type from the full definition text a bag stores with its connection (with
    its dependencies). Returns False when the store already has a different definition."""
    from rosbags.typesys import get_types_from_msg
    from rosbags.typesys.base import TypesysError

    if not msgdef.strip():
        return False
    try:
        store.register(get_types_from_msg(msgdef, msgtype))
    except TypesysError:
        return False
    return True


# -- bag index ---------------------------------------------------------------------------------

@dataclass
class _Chunk:
    datapos: int
    datasize: int
    compression: str


class BagTopic:
    """Lazy access to the messages of one topic across several bags.

    accept: message types (ROS2-style names as rosbags reports them, e.g.
    ``sensor_msgs/msg/PointCloud``) the caller can parse; another type raises ``DataError``.
    Messages are ordered by bag, then record time. ``msgtype`` / ``msgdef`` describe the
    topic's type (one type across all bags).
    """

    def __init__(self, bags: list[Path] | list[str], topic: str,
                 accept: tuple[str, ...] | None = None) -> None:
        if _RecordHeader is None:  # pragma: no cover
            raise DataError("rosbags >= 0.10 is required to read ROS1 bags")
        self.paths = [Path(b) for b in bags]
        if not self.paths:
            raise DataError(f"no bag files given for topic {topic}")
        self.topic = topic
        self.msgtype: str | None = None
        self.msgdef = ""
        self.chunks: list[dict[int, _Chunk]] = []
        bag_idx, chunk_pos, offset, rtime = [], [], [], []
        for b, path in enumerate(self.paths):
            entries, chunks, msgtype, msgdef = _index_bag(path, topic)
            if accept is not None and msgtype not in accept:
                raise DataError(
                    f"{path}: topic {topic} has message type {msgtype}; expected one of "
                    f"{', '.join(accept)}"
                )
            if self.msgtype is not None and msgtype != self.msgtype:
                raise DataError(
                    f"{path}: topic {topic} has message type {msgtype} but {self.paths[0]} has "
                    f"{self.msgtype}; all bags must use one type"
                )
            self.msgtype, self.msgdef = msgtype, msgdef or self.msgdef
            self.chunks.append(chunks)
            bag_idx.extend([b] * len(entries))
            for t, cp, off in entries:
                rtime.append(t)
                chunk_pos.append(cp)
                offset.append(off)
        self.bag = np.asarray(bag_idx, dtype=np.int32)
        self.chunk_pos = np.asarray(chunk_pos, dtype=np.int64)
        self.offset = np.asarray(offset, dtype=np.int64)
        self.record_time_ns = np.asarray(rtime, dtype=np.int64)
        self._files: dict[int, object] = {}
        self._cache: dict[int, tuple[int, bytes]] = {}

    def __len__(self) -> int:
        return len(self.bag)

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_files"] = {}
        state["_cache"] = {}
        return state

    def close(self) -> None:
        for f in self._files.values():
            f.close()
        self._files.clear()
        self._cache.clear()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass

    def where(self, i: int) -> str:
        """"bag, message k of topic" for messages."""
        b = int(self.bag[i])
        k = i - int(np.searchsorted(self.bag, b))
        return f"{self.paths[b]}, {self.topic} message {k}"

    def _file(self, b: int):
        f = self._files.get(b)
        if f is None:
            f = self._files[b] = open(self.paths[b], "rb")  # noqa: SIM115
        return f

    def raw(self, i: int, prefix: int | None = None) -> bytes:
        """The serialized message ``i`` (or only its first ``prefix`` bytes)."""
        b = int(self.bag[i])
        cp = int(self.chunk_pos[i])
        chunk = self.chunks[b][cp]
        try:
            if chunk.compression == "none":
                f = self._file(b)
                f.seek(chunk.datapos + int(self.offset[i]))
                return _read_record(f, prefix)
            cached = self._cache.get(b)
            if cached is None or cached[0] != cp:
                f = self._file(b)
                f.seek(chunk.datapos)
                data = f.read(chunk.datasize)
                if len(data) != chunk.datasize:
                    raise EOFError("chunk shorter than its header says")
                cached = (cp, _DECOMPRESSORS[chunk.compression](data))
                self._cache[b] = cached
            import io

            bio = io.BytesIO(cached[1])
            bio.seek(int(self.offset[i]))
            return _read_record(bio, prefix)
        except _reader_errors() as err:
            raise DataError(
                f"{self.where(i)}: cannot read the message ({type(err).__name__}: {err}); the "
                "bag looks truncated or damaged"
            ) from None

    def header_stamps(self) -> np.ndarray:
        """``header.stamp`` [s] of every message (reads only the first bytes of each)."""
        out = np.empty(len(self), dtype=np.float64)
        for i in range(len(self)):
            data = self.raw(i, prefix=12)
            if len(data) < 12:
                raise DataError(f"{self.where(i)}: message too short for a std_msgs/Header")
            sec, nsec = struct.unpack_from("<II", data, 4)
            out[i] = sec + nsec * 1e-9
        return out


def _read_record(bio, prefix: int | None) -> bytes:
    while True:
        header = _RecordHeader.read(bio)
        op = header.get_uint8("op")
        (size,) = struct.unpack("<I", _read_exact(bio, 4))
        if op == _OP_CONNECTION:
            bio.seek(size, 1)
            continue
        if op != _OP_MSGDATA:
            raise ValueError(f"expected a message record, found op {op}")
        return _read_exact(bio, size if prefix is None else min(size, prefix))


def _read_exact(bio, n: int) -> bytes:
    data = bio.read(n)
    if len(data) != n:
        raise EOFError(f"expected {n} bytes, got {len(data)}")
    return data


def _index_bag(path: Path, topic: str):
    """Open one bag with rosbags, return (entries [(time_ns, chunk_pos, offset)], chunks,
    msgtype, msgdef) for ``topic``; the reader is closed before returning."""
    from rosbags.rosbag1 import Reader

    if not path.exists():
        raise DataError(f"{path}: bag file not found")
    try:
        reader = Reader(path)
        reader.open()
    except _reader_errors() as err:
        raise DataError(
            f"{path}: cannot open the ROS1 bag ({type(err).__name__}: {err}); the file is "
            "truncated, damaged, unindexed (try `rosbag reindex`) or not a ROS1 bag"
        ) from None
    try:
        conns = [c for c in reader.connections if c.topic == topic]
        if not conns:
            have = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
            raise DataError(
                f"{path}: no topic {topic}; the bag has "
                + (", ".join(have) if have else "no topics")
            )
        types = {c.msgtype for c in conns}
        if len(types) > 1:
            raise DataError(f"{path}: topic {topic} has several message types {sorted(types)}")
        entries = []
        for c in conns:
            entries.extend((e.time, e.chunk_pos, e.offset) for e in reader.indexes[c.id])
        entries.sort()
        chunks = {}
        for pos, ch in reader.chunks.items():
            comp = next((k for k, v in _DECOMPRESSORS.items() if v is ch.decompressor), None)
            if comp is None:
                raise DataError(f"{path}: unsupported chunk compression")
            chunks[pos] = _Chunk(ch.datapos, ch.datasize, comp)
        return entries, chunks, conns[0].msgtype, conns[0].msgdef.data
    finally:
        reader.close()


def iter_topic_messages(bags: list[Path], topic: str, typestore,
                        accept: tuple[str, ...] | None = None) -> Iterator[tuple[object, str]]:
    """Deserialize every message of ``topic`` across ``bags`` (for small topics such as
    odometry); yields (message, location)."""
    index = BagTopic(bags, topic, accept)
    try:
        if index.msgtype not in typestore.types:
            register_bag_definition(typestore, index.msgtype, index.msgdef)
        for i in range(len(index)):
            raw = index.raw(i)
            try:
                msg = typestore.deserialize_ros1(raw, index.msgtype)
            except Exception as err:  # rosbags raises assorted errors on bad bytes
                raise DataError(
                    f"{index.where(i)}: cannot deserialize {index.msgtype} ({err})"
                ) from None
            yield msg, index.where(i)
    finally:
        index.close()


# -- ROS1 wire format parsers ------------------------------------------------------------------

class _Cursor:
    """Reads the ROS1 serialization (little-endian, u32-prefixed strings and arrays)."""

    __slots__ = ("buf", "pos", "where")

    def __init__(self, buf: bytes, where: str) -> None:
        self.buf = buf
        self.pos = 0
        self.where = where

    def need(self, n: int) -> None:
        if self.pos + n > len(self.buf):
            raise DataError(
                f"{self.where}: message ends after {len(self.buf)} bytes, needed "
                f"{self.pos + n}; wrong message type or damaged data"
            )

    def u8(self) -> int:
        self.need(1)
        self.pos += 1
        return self.buf[self.pos - 1]

    def u32(self) -> int:
        self.need(4)
        (v,) = struct.unpack_from("<I", self.buf, self.pos)
        self.pos += 4
        return v

    def string(self) -> str:
        n = self.u32()
        self.need(n)
        s = self.buf[self.pos:self.pos + n].decode("utf-8", errors="replace")
        self.pos += n
        return s

    def array(self, dtype: str | np.dtype, count: int) -> np.ndarray:
        dt = np.dtype(dtype)
        self.need(count * dt.itemsize)
        a = np.frombuffer(self.buf, dtype=dt, count=count, offset=self.pos)
        self.pos += count * dt.itemsize
        return a

    def header(self) -> tuple[float, str]:
        self.u32()  # seq
        self.need(8)
        sec, nsec = struct.unpack_from("<II", self.buf, self.pos)
        self.pos += 8
        return sec + nsec * 1e-9, self.string()


def parse_pointcloud(data: bytes, where: str) -> tuple[float, np.ndarray, dict[str, np.ndarray]]:
    """``sensor_msgs/PointCloud`` -> (stamp, points (N,3) float32, {channel name: (N,)})."""
    c = _Cursor(data, where)
    stamp, _ = c.header()
    n = c.u32()
    points = c.array("<f4", 3 * n).reshape(n, 3)
    channels = {}
    for _ in range(c.u32()):
        name = c.string()
        m = c.u32()
        values = c.array("<f4", m)
        if m != n:
            raise DataError(
                f"{where}: channel {name!r} has {m} values for {n} points; expected one per point"
            )
        channels[name] = values
    return stamp, points, channels


_PF_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def parse_pointcloud2(data: bytes, where: str) -> tuple[float, np.ndarray, list[str]]:
    """``sensor_msgs/PointCloud2`` -> (stamp, structured array (N,) with one field per
    PointField of count 1, field names in message order)."""
    c = _Cursor(data, where)
    stamp, _ = c.header()
    height, width = c.u32(), c.u32()
    fields = []
    for _ in range(c.u32()):
        name = c.string()
        offset = c.u32()
        datatype = c.u8()
        count = c.u32()
        fields.append((name, offset, datatype, count))
    big = bool(c.u8())
    point_step, row_step = c.u32(), c.u32()
    nbytes = c.u32()
    c.need(nbytes)
    blob = c.buf[c.pos:c.pos + nbytes]
    endian = ">" if big else "<"
    names, formats, offsets = [], [], []
    for name, offset, datatype, count in fields:
        if datatype not in _PF_TYPES:
            raise DataError(f"{where}: PointField {name!r} has unknown datatype {datatype}")
        if count != 1:
            continue  # arrays per point are not per-point scalars; skipped
        if offset + np.dtype(_PF_TYPES[datatype]).itemsize > point_step:
            raise DataError(
                f"{where}: PointField {name!r} at offset {offset} overruns point_step {point_step}"
            )
        names.append(name)
        formats.append(endian + _PF_TYPES[datatype])
        offsets.append(offset)
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                      "itemsize": point_step})
    n = height * width
    if point_step == 0 or row_step < width * point_step or nbytes < height * row_step:
        raise DataError(
            f"{where}: PointCloud2 layout inconsistent: {height}x{width} points, point_step "
            f"{point_step}, row_step {row_step}, {nbytes} data bytes"
        )
    if row_step == width * point_step:
        arr = np.frombuffer(blob, dtype=dtype, count=n)
    else:
        rows = np.frombuffer(blob, dtype=np.uint8, count=height * row_step).reshape(height, -1)
        packed = np.ascontiguousarray(rows[:, :width * point_step]).tobytes()
        arr = np.frombuffer(packed, dtype=dtype, count=n)
    return stamp, arr, names


# -- common scan assembly ----------------------------------------------------------------------

def finish_scan(
    stamp: float,
    points: np.ndarray,
    doppler: np.ndarray | None,
    fields: dict[str, np.ndarray],
    source: str,
    counters: dict | None = None,
) -> Scan:
    """Drop points with a non-finite coordinate or Doppler (``warnings.warn`` with the count,
    added to ``counters["nan_points_dropped"]``) and build the Scan; an empty scan (0 points
    before or after dropping) raises ``DataError`` naming the file and frame."""
    points = np.asarray(points)
    n = len(points)
    if n == 0:
        raise DataError(f"{source}: empty scan (0 points); expected at least one point")
    good = np.isfinite(points).all(axis=1)
    if doppler is not None:
        good &= np.isfinite(doppler)
    bad = int(n - good.sum())
    if bad:
        warnings.warn(f"{source}: dropped {bad} of {n} points with NaN/inf coordinates or "
                      "Doppler", stacklevel=3)
        if counters is not None:
            counters["nan_points_dropped"] = counters.get("nan_points_dropped", 0) + bad
            counters["frames_with_nan"] = counters.get("frames_with_nan", 0) + 1
        if bad == n:
            raise DataError(f"{source}: empty scan (all {n} points are NaN/inf)")
        points = points[good]
        doppler = None if doppler is None else doppler[good]
        fields = {k: v[good] for k, v in fields.items()}
    return Scan(stamp=stamp, points=points, doppler=doppler, fields=fields, source=source)


def sort_unique_stamps(stamps: np.ndarray, where: str) -> tuple[np.ndarray, int]:
    """Order of the frames by stamp with repeated stamps removed (first kept); warns with the
    count of repeats. Returns (indices into ``stamps``, repeats dropped)."""
    order = np.argsort(stamps, kind="stable")
    s = stamps[order]
    keep = np.ones(len(s), dtype=bool)
    keep[1:] = np.diff(s) > 0
    dup = int((~keep).sum())
    if dup:
        warnings.warn(f"{where}: {dup} scans with a repeated header stamp dropped", stacklevel=3)
    return order[keep], dup


def topic_stamps(index: BagTopic, stamp: str, where: str) -> np.ndarray:
    """Scan stamps of every message: ``stamp`` "header" (header.stamp, the sensor clock) or
    "record" (the bag's record time, for drivers that leave the header stamp unset). Raises
    when header stamps are mostly repeated (e.g. all zero)."""
    if stamp == "record":
        return index.record_time_ns.astype(np.float64) * 1e-9
    if stamp != "header":
        raise DataError(f"stamp must be 'header' or 'record', got {stamp!r}")
    stamps = index.header_stamps()
    if len(stamps) > 2 and len(np.unique(stamps)) < len(stamps) / 2:
        raise DataError(
            f"{where}: {index.topic}: only {len(np.unique(stamps))} distinct header stamps for "
            f"{len(stamps)} messages (unset header.stamp?); use stamp='record' to take the bag's "
            "record time"
        )
    return stamps


def median_period(stamps: np.ndarray, default: float) -> float:
    d = np.diff(np.asarray(stamps, dtype=np.float64))
    d = d[d > 0]
    return float(np.median(d)) if len(d) else default
