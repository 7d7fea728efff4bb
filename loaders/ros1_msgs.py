"""Fast NumPy parsers of the ROS1 wire format (little-endian, u32-prefixed strings and arrays):
``std_msgs/Header``, ``sensor_msgs/PointCloud`` (Point32 + named channels) and
``sensor_msgs/PointCloud2`` (PointField layout -> NumPy dtype, big-endian aware). ``Cursor``
reads any other message field by field (the Campus radar message). A message too short for its
type is one ``DataError`` naming the message."""

from __future__ import annotations

import struct

import numpy as np

from loaders.errors import DataError


class Cursor:
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
    """``sensor_msgs/PointCloud`` -> (stamp, points (N,3) float32, {channel name: (N,)}; a
    name given twice: its first channel)."""
    c = Cursor(data, where)
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
        channels.setdefault(name, values)  # a repeated name: the first kept, as in ROS2
    return stamp, points, channels


_PF_TYPES = {1: "i1", 2: "u1", 3: "i2", 4: "u2", 5: "i4", 6: "u4", 7: "f4", 8: "f8"}


def parse_pointcloud2(data: bytes, where: str) -> tuple[float, np.ndarray, list[str]]:
    """``sensor_msgs/PointCloud2`` -> (stamp, structured array (N,) with one field per
    PointField of count 1, field names in message order)."""
    c = Cursor(data, where)
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
    arr, names = cloud2_array(fields, big, height, width, point_step, row_step, blob, where)
    return stamp, arr, names


def cloud2_array(fields: list[tuple[str, int, int, int]], big: bool, height: int, width: int,
                 point_step: int, row_step: int, blob, where: str
                 ) -> tuple[np.ndarray, list[str]]:
    """The points of a PointCloud2 layout (``fields``: (name, offset, datatype, count); the
    data bytes ``blob``) as a structured array with one field per PointField of count 1, and
    those field names in message order. Shared by the ROS1 parser above and the ROS2 (CDR)
    route of ``loaders.rosbag``."""
    nbytes = len(blob)
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
    return arr, names
