"""ROS1 bag indexing for the real-dataset loaders (rosbags, pure Python).

- ``BagTopic``: opens one or more bags, finds a topic (a ``DataError`` lists the topics a bag
  has when it is missing), checks the message type, and keeps a small per-message index
  (bag, chunk, offset). Messages are read lazily one at a time with plain file seeks (at most
  one decompressed chunk is cached per bag), so memory stays bounded by a few frames whatever
  the bag size. After indexing no rosbags reader stays open: instances pickle to workers.
- ``topic_stamps`` / ``sort_unique_stamps``: scan stamps of a topic, in order.
- ``make_typestore``: the ROS1 Noetic type store plus custom .msg definitions registered from
  text (and, when a bag carries its own definition, from the bag).
Message parsers are ``loaders.ros1_msgs``; every loader's last step is ``loaders.assemble``.

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
from loaders.limits import check_frame_bytes

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
                check_frame_bytes(int(chunk.datasize), self.where(i), "its compressed chunk")
                data = f.read(chunk.datasize)
                if len(data) != chunk.datasize:
                    raise EOFError("chunk shorter than its header says")
                cached = (cp, _DECOMPRESSORS[chunk.compression](data))
                self._cache[b] = cached
            import io

            bio = io.BytesIO(cached[1])
            bio.seek(int(self.offset[i]))
            return _read_record(bio, prefix)
        except DataError as err:  # the size limit (a DataError is also a ValueError)
            raise DataError(f"{self.where(i)}{err}") from None
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
        if prefix is None:  # a garbage length must not become a 4 GB read
            check_frame_bytes(size, "", "the message")
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
            f"{len(stamps)} messages (unset header.stamp?); use --stamp record (option "
            "stamp='record') to take the bag's record time"
        )
    return stamps
