"""loaders.ros1_msgs on messages serialised here by hand from the ROS1 wire format (ros.org
wiki "roscpp/Overview/MessagesSerializationAndAdaptingTypes": little-endian, strings and
arrays prefixed by a u32 length; std_msgs/Header = seq u32, stamp sec u32 + nsec u32,
frame_id string): every value read is the one written, and every short or inconsistent
message is one DataError naming it."""

import struct

import numpy as np
import pytest

from loaders.errors import DataError
from loaders.ros1_msgs import Cursor, cloud2_array, parse_pointcloud, parse_pointcloud2

WHERE = "bag.bag, /radar message 3"


def ros_string(text: str) -> bytes:
    raw = text.encode("utf-8")
    return struct.pack("<I", len(raw)) + raw


def ros_header(sec: int, nsec: int, frame: str = "radar", seq: int = 7) -> bytes:
    return struct.pack("<III", seq, sec, nsec) + ros_string(frame)


def pointcloud_msg(points: np.ndarray, channels: list[tuple[str, np.ndarray]],
                   sec: int = 1700000000, nsec: int = 250000000) -> bytes:
    """sensor_msgs/PointCloud: header, Point32[] points, ChannelFloat32[] channels."""
    out = ros_header(sec, nsec) + struct.pack("<I", len(points))
    out += b"".join(struct.pack("<fff", *p) for p in points)
    out += struct.pack("<I", len(channels))
    for name, values in channels:
        out += ros_string(name) + struct.pack("<I", len(values))
        out += b"".join(struct.pack("<f", v) for v in values)
    return out


def pointcloud2_msg(fields: list[tuple[str, int, int, int]], height: int, width: int,
                    point_step: int, row_step: int, data: bytes, big: bool = False,
                    sec: int = 1600000000, nsec: int = 5) -> bytes:
    """sensor_msgs/PointCloud2: header, height, width, PointField[] (name, offset u32,
    datatype u8, count u32), is_bigendian u8, point_step, row_step, uint8[] data,
    is_dense u8."""
    out = ros_header(sec, nsec) + struct.pack("<II", height, width)
    out += struct.pack("<I", len(fields))
    for name, offset, datatype, count in fields:
        out += ros_string(name) + struct.pack("<IBI", offset, datatype, count)
    out += struct.pack("<BII", int(big), point_step, row_step)
    out += struct.pack("<I", len(data)) + data + b"\x01"
    return out


# --- Cursor -------------------------------------------------------------------------------


def test_cursor_reads_each_primitive_in_order():
    buf = b"\x05" + struct.pack("<I", 4000000000) + ros_string("héllo") + struct.pack(
        "<3f", 1.5, -2.25, 8.0)
    c = Cursor(buf, WHERE)
    assert c.u8() == 5 and c.pos == 1
    assert c.u32() == 4000000000 and c.pos == 5
    assert c.string() == "héllo" and c.pos == 5 + 4 + 6
    a = c.array("<f4", 3)
    np.testing.assert_array_equal(a, [1.5, -2.25, 8.0])
    assert c.pos == len(buf)


def test_cursor_header_stamp_and_frame():
    c = Cursor(ros_header(1700000123, 999999999, "base_link") + b"rest", WHERE)
    stamp, frame = c.header()
    assert frame == "base_link"
    assert stamp == pytest.approx(1700000123.999999999, abs=1e-6)
    assert c.buf[c.pos:] == b"rest"


def test_cursor_string_with_bad_utf8_is_replaced_not_an_error():
    c = Cursor(struct.pack("<I", 3) + b"a\xffb", WHERE)
    assert c.string() == "a\ufffdb"


def test_need_accepts_the_exact_end_and_refuses_one_more_byte():
    c = Cursor(b"\x00\x01\x02\x03", WHERE)
    c.need(4)  # the whole buffer: fine
    c.pos = 2
    c.need(2)
    with pytest.raises(DataError) as err:
        c.need(3)
    assert str(err.value) == (f"{WHERE}: message ends after 4 bytes, needed 5; wrong message "
                              "type or damaged data")


@pytest.mark.parametrize("read", [
    lambda c: c.u8(),
    lambda c: c.u32(),
    lambda c: c.string(),
    lambda c: c.array("<f4", 2),
    lambda c: c.header(),
])
def test_every_read_past_the_end_is_a_data_error(read):
    c = Cursor(b"", WHERE)
    with pytest.raises(DataError, match="message ends after 0 bytes"):
        read(c)


def test_a_string_longer_than_its_message_is_refused():
    c = Cursor(struct.pack("<I", 10) + b"abc", WHERE)
    with pytest.raises(DataError, match=r"ends after 7 bytes, needed 14"):
        c.string()


def test_header_too_short_for_its_stamp():
    c = Cursor(struct.pack("<II", 1, 2), WHERE)
    with pytest.raises(DataError, match=r"ends after 8 bytes, needed 12"):
        c.header()


# --- sensor_msgs/PointCloud ----------------------------------------------------------------


def test_pointcloud_points_channels_and_stamp():
    points = np.array([[1.0, 2.0, 3.0], [-4.5, 0.25, 7.0]], dtype=np.float32)
    msg = pointcloud_msg(points, [("doppler", np.array([0.5, -1.5])),
                                  ("intensity", np.array([10.0, 20.0]))])
    stamp, pts, channels = parse_pointcloud(msg, WHERE)
    assert stamp == pytest.approx(1700000000.25, abs=1e-6)
    assert pts.shape == (2, 3) and pts.dtype == np.float32
    np.testing.assert_array_equal(pts, points)
    assert list(channels) == ["doppler", "intensity"]
    np.testing.assert_array_equal(channels["doppler"], [0.5, -1.5])
    np.testing.assert_array_equal(channels["intensity"], [10.0, 20.0])


def test_pointcloud_repeated_channel_name_keeps_the_first():
    points = np.zeros((1, 3), np.float32)
    msg = pointcloud_msg(points, [("v", np.array([1.0])), ("v", np.array([2.0]))])
    _, _, channels = parse_pointcloud(msg, WHERE)
    np.testing.assert_array_equal(channels["v"], [1.0])


def test_pointcloud_channel_of_another_length_is_refused():
    msg = pointcloud_msg(np.zeros((3, 3), np.float32), [("doppler", np.array([1.0, 2.0]))])
    with pytest.raises(DataError) as err:
        parse_pointcloud(msg, WHERE)
    assert str(err.value) == (f"{WHERE}: channel 'doppler' has 2 values for 3 points; "
                              "expected one per point")


def test_pointcloud_truncated_points_are_refused():
    msg = pointcloud_msg(np.zeros((3, 3), np.float32), [])
    with pytest.raises(DataError, match="message ends after"):
        parse_pointcloud(msg[:-10], WHERE)


# --- sensor_msgs/PointCloud2 ---------------------------------------------------------------

#: datatype -> (NumPy type, size), from sensor_msgs/PointField's constants
PF = {1: ("i1", 1), 2: ("u1", 1), 3: ("i2", 2), 4: ("u2", 2), 5: ("i4", 4), 6: ("u4", 4),
      7: ("f4", 4), 8: ("f8", 8)}


def xyz_fields() -> list[tuple[str, int, int, int]]:
    return [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1)]


def test_pointcloud2_xyz_and_stamp():
    xyz = np.array([[1, 2, 3], [4, 5, 6], [-7, 8.5, 9]], dtype="<f4")
    msg = pointcloud2_msg(xyz_fields(), 1, 3, 12, 36, xyz.tobytes())
    stamp, arr, names = parse_pointcloud2(msg, WHERE)
    assert stamp == pytest.approx(1600000000.000000005, abs=1e-6)
    assert names == ["x", "y", "z"] and len(arr) == 3
    np.testing.assert_array_equal(np.column_stack([arr["x"], arr["y"], arr["z"]]), xyz)


@pytest.mark.parametrize("big", [False, True])
def test_every_point_field_datatype_both_byte_orders(big):
    """One field of each of the eight datatypes, packed one after another; the values read
    are the ones packed with struct in the message's byte order."""
    codes = {1: "b", 2: "B", 3: "h", 4: "H", 5: "i", 6: "I", 7: "f", 8: "d"}
    values = {1: -100, 2: 200, 3: -30000, 4: 60000, 5: -2000000000, 6: 4000000000, 7: 1.5,
              8: -2.0 ** 0.5}
    fields, offset = [], 0
    for dt in range(1, 9):
        fields.append((f"f{dt}", offset, dt, 1))
        offset += PF[dt][1]
    order = ">" if big else "<"
    point = b"".join(struct.pack(order + codes[dt], values[dt]) for dt in range(1, 9))
    msg = pointcloud2_msg(fields, 1, 2, offset, 2 * offset, point * 2, big=big)
    _, arr, names = parse_pointcloud2(msg, WHERE)
    assert names == [f"f{dt}" for dt in range(1, 9)]
    for dt in range(1, 9):
        assert arr.dtype[f"f{dt}"] == np.dtype(order + PF[dt][0])
        np.testing.assert_array_equal(arr[f"f{dt}"], [values[dt]] * 2)


def test_fields_with_count_other_than_one_are_skipped():
    fields = [("x", 0, 7, 1), ("rgb", 4, 2, 3), ("v", 8, 7, 1)]
    data = struct.pack("<f3Bxf", 1.0, 1, 2, 3, -0.5)
    _, arr, names = parse_pointcloud2(pointcloud2_msg(fields, 1, 1, 12, 12, data), WHERE)
    assert names == ["x", "v"] and arr.dtype.names == ("x", "v")
    assert arr["x"][0] == 1.0 and arr["v"][0] == -0.5


def test_padded_rows_are_read_without_their_padding():
    """2 rows of 2 points, 8-byte points, 4 bytes of padding after each row."""
    fields = [("a", 0, 6, 1), ("b", 4, 6, 1)]
    rows = [struct.pack("<4I", 1, 2, 3, 4) + b"\xee" * 4, struct.pack("<4I", 5, 6, 7, 8)
            + b"\xee" * 4]
    msg = pointcloud2_msg(fields, 2, 2, 8, 20, b"".join(rows))
    _, arr, _ = parse_pointcloud2(msg, WHERE)
    np.testing.assert_array_equal(arr["a"], [1, 3, 5, 7])
    np.testing.assert_array_equal(arr["b"], [2, 4, 6, 8])


def test_unpadded_layout_reads_only_the_points_of_the_header():
    """More data bytes than height x row_step: only the header's points are read."""
    data = np.arange(4, dtype="<u4").tobytes()
    arr, names = cloud2_array([("a", 0, 6, 1)], False, 1, 3, 4, 12, data, WHERE)
    assert names == ["a"]
    np.testing.assert_array_equal(arr["a"], [0, 1, 2])


def test_a_field_ending_exactly_at_point_step_is_fine_one_byte_more_is_not():
    arr, _ = cloud2_array([("a", 4, 6, 1)], False, 1, 1, 8, 8, bytes(range(8)), WHERE)
    assert arr["a"][0] == int.from_bytes(bytes([4, 5, 6, 7]), "little")
    with pytest.raises(DataError) as err:
        cloud2_array([("a", 5, 6, 1)], False, 1, 1, 8, 8, bytes(8), WHERE)
    assert str(err.value) == f"{WHERE}: PointField 'a' at offset 5 overruns point_step 8"


def test_unknown_datatype_is_refused_even_with_count_zero():
    with pytest.raises(DataError) as err:
        cloud2_array([("a", 0, 9, 0)], False, 1, 1, 4, 4, bytes(4), WHERE)
    assert str(err.value) == f"{WHERE}: PointField 'a' has unknown datatype 9"


@pytest.mark.parametrize("height, width, point_step, row_step, nbytes", [
    (1, 2, 0, 0, 0),      # no point step
    (1, 2, 4, 7, 8),      # a row shorter than its points
    (2, 2, 4, 8, 15),     # fewer bytes than rows
])
def test_inconsistent_layouts_are_refused(height, width, point_step, row_step, nbytes):
    # (an array field, skipped, so that the point_step check is the one reached)
    with pytest.raises(DataError) as err:
        cloud2_array([("a", 0, 2, 3)], False, height, width, point_step, row_step,
                     bytes(nbytes), WHERE)
    assert str(err.value) == (
        f"{WHERE}: PointCloud2 layout inconsistent: {height}x{width} points, point_step "
        f"{point_step}, row_step {row_step}, {nbytes} data bytes")


def test_layouts_at_their_limits_are_accepted():
    # row_step == width x point_step and nbytes == height x row_step exactly
    arr, _ = cloud2_array([("a", 0, 2, 1)], False, 2, 2, 1, 2, bytes([1, 2, 3, 4]), WHERE)
    np.testing.assert_array_equal(arr["a"], [1, 2, 3, 4])


def test_pointcloud2_data_shorter_than_its_length_prefix_is_refused():
    msg = pointcloud2_msg(xyz_fields(), 1, 1, 12, 12, bytes(12))
    with pytest.raises(DataError, match="message ends after"):
        parse_pointcloud2(msg[:-6], WHERE)


# --- survivors of the first mutation run ---------------------------------------------------------


def test_reads_that_end_exactly_at_the_end_of_the_message():
    assert Cursor(b"\x05", WHERE).u8() == 5
    assert Cursor(struct.pack("<I", 7), WHERE).u32() == 7


def test_stamps_after_2038_are_unsigned():
    """ROS1 time is two uint32: a second count of 2^31 + 5 is 2038-01-19, not 1901."""
    c = Cursor(ros_header(2**31 + 5, 3_000_000_000 - 2**31), WHERE)
    stamp, _ = c.header()
    assert stamp == pytest.approx(2**31 + 5 + (3_000_000_000 - 2**31) * 1e-9, abs=1e-6)


def test_trailing_padding_in_each_point_is_skipped():
    """point_step 8 for one float32 field: each point carries 4 bytes of padding after it."""
    data = struct.pack("<f4xf4xf4x", 1.0, 2.0, 3.0)
    arr, _ = cloud2_array([("x", 0, 7, 1)], False, 1, 3, 8, 24, data, WHERE)
    np.testing.assert_array_equal(arr["x"], [1.0, 2.0, 3.0])


def test_padded_rows_with_extra_data_bytes_after_them():
    fields = [("a", 0, 6, 1), ("b", 4, 6, 1)]
    rows = [struct.pack("<4I", 1, 2, 3, 4) + b"\xee" * 4, struct.pack("<4I", 5, 6, 7, 8)
            + b"\xee" * 4]
    arr, _ = cloud2_array(fields, False, 2, 2, 8, 20, b"".join(rows) + b"\xdd" * 4, WHERE)
    np.testing.assert_array_equal(arr["a"], [1, 3, 5, 7])
    np.testing.assert_array_equal(arr["b"], [2, 4, 6, 8])


def test_errors_of_whole_messages_name_the_message():
    msg = pointcloud_msg(np.zeros((3, 3), np.float32), [])
    with pytest.raises(DataError, match=f"^{WHERE}: message ends after"):
        parse_pointcloud(msg[:-10], WHERE)
    msg2 = pointcloud2_msg(xyz_fields(), 1, 1, 12, 12, bytes(12))
    with pytest.raises(DataError, match=f"^{WHERE}: message ends after"):
        parse_pointcloud2(msg2[:-6], WHERE)
    bad = pointcloud2_msg([("x", 0, 11, 1)], 1, 1, 4, 4, bytes(4))
    with pytest.raises(DataError) as err:
        parse_pointcloud2(bad, WHERE)
    assert str(err.value) == f"{WHERE}: PointField 'x' has unknown datatype 11"
