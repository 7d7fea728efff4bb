"""loaders.pcd on PCD files written here byte by byte after PCL's "PCD v0.7" description
(pointclouds.org/documentation/tutorials/pcd_file_format.html): header lines, then ``DATA
ascii`` lines or ``DATA binary`` packed little-endian records; the values read are the ones
written (packed with struct), ``write_pcd``'s header is the format's, and every inconsistency
is one DataError naming the file and what was expected."""

import struct

import numpy as np
import pytest

from loaders.errors import DataError
from loaders.pcd import read_pcd, read_pcd_header, write_pcd


def header(fields="x y z", size="4 4 4", type_="F F F", count="1 1 1", width=2, height=1,
           points=None, data="binary", extra="") -> bytes:
    lines = ["# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7",
             f"FIELDS {fields}", f"SIZE {size}", f"TYPE {type_}"]
    if count is not None:
        lines.append(f"COUNT {count}")
    if width is not None:
        lines.append(f"WIDTH {width}")
    if height is not None:
        lines.append(f"HEIGHT {height}")
    lines.append("VIEWPOINT 0 0 0 1 0 0 0")
    if points is not None:
        lines.append(f"POINTS {points}")
    return ("\n".join(lines) + "\n" + extra + f"DATA {data}\n").encode("ascii")


def write(tmp_path, raw: bytes, name="f.pcd"):
    path = tmp_path / name
    path.write_bytes(raw)
    return path


def xyz_binary(rows) -> bytes:
    return b"".join(struct.pack("<3f", *r) for r in rows)


# --- reading binary ------------------------------------------------------------------------


def test_binary_values_are_the_packed_ones(tmp_path):
    rows = [(1.5, -2.0, 3.25), (4.0, 5.5, -6.75)]
    path = write(tmp_path, header(points=2) + xyz_binary(rows))
    arr, names = read_pcd(path)
    assert names == ["x", "y", "z"]
    assert arr.dtype == np.dtype({"names": names, "formats": ["<f4"] * 3})
    np.testing.assert_array_equal(np.column_stack([arr[n] for n in names]), rows)


def test_binary_mixed_types_and_counts(tmp_path):
    """x F4, ring U2, id I8, rgb U1 COUNT 3, w F8: COUNT 3 becomes rgb_0..rgb_2."""
    raw = header("x ring id rgb w", "4 2 8 1 8", "F U I U F", "1 1 1 3 1", width=1,
                 points=1) + struct.pack("<fHq3Bd", -1.25, 65000, -(2**40), 1, 2, 250, 0.1)
    arr, names = read_pcd(write(tmp_path, raw))
    assert names == ["x", "ring", "id", "rgb_0", "rgb_1", "rgb_2", "w"]
    assert arr.dtype.itemsize == 4 + 2 + 8 + 3 + 8
    assert arr["x"][0] == np.float32(-1.25) and arr["ring"][0] == 65000
    assert arr["id"][0] == -(2**40) and arr["w"][0] == 0.1
    assert [arr[f"rgb_{j}"][0] for j in range(3)] == [1, 2, 250]


@pytest.mark.parametrize("kind, size, code, value", [
    ("F", 4, "f", 0.5), ("F", 8, "d", -0.1), ("I", 1, "b", -7), ("I", 2, "h", -300),
    ("I", 4, "i", -70000), ("I", 8, "q", -(2**50)), ("U", 1, "B", 200), ("U", 2, "H", 50000),
    ("U", 4, "I", 3000000000), ("U", 8, "Q", 2**63 + 5),
])
def test_every_type_and_size(tmp_path, kind, size, code, value):
    raw = header("v", str(size), kind.lower(), "1", width=1) + struct.pack("<" + code, value)
    arr, _ = read_pcd(write(tmp_path, raw))
    assert arr["v"][0] == value and arr.dtype["v"].itemsize == size


def test_binary_truncated_and_count_mismatch(tmp_path):
    rows = [(1, 2, 3), (4, 5, 6)]
    path = write(tmp_path, header(points=2) + xyz_binary(rows)[:-1])
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == (f"{path}: 23 data bytes are not a whole number of 12-byte "
                              "records (fields x y z); the file is truncated or its SIZE / "
                              "FIELDS header is wrong")
    path = write(tmp_path, header(width=3, points=3) + xyz_binary(rows))
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == (f"{path}: the header says POINTS 3 but the data hold 2 records "
                              "of 12 bytes (fields x y z)")


def test_binary_of_zero_points(tmp_path):
    arr, names = read_pcd(write(tmp_path, header(width=0, points=0)))
    assert len(arr) == 0 and names == ["x", "y", "z"]


# --- reading ascii -------------------------------------------------------------------------


def test_ascii_values_blank_lines_and_comments(tmp_path):
    raw = (b"# a comment line\n\n" + header("x y i", "4 4 2", "F F I", "1 1 1", width=3,
                                              data="ascii")
           + b"1.5 2 -3\n\n  -4 5.25 7  \n0 0 32767\n\n")
    arr, names = read_pcd(write(tmp_path, raw))
    assert names == ["x", "y", "i"]
    np.testing.assert_array_equal(arr["x"], [1.5, -4, 0])
    np.testing.assert_array_equal(arr["y"], [2, 5.25, 0])
    np.testing.assert_array_equal(arr["i"], [-3, 7, 32767])
    assert arr.dtype["i"] == np.dtype("<i2")


def test_ascii_errors_name_the_line_and_the_counts(tmp_path):
    head = header(width=2, data="ascii")
    path = write(tmp_path, head + b"1 2 3\n\n4 5\n")
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == f"{path}: data line 3 has 2 values; expected 3 (fields x y z)"
    path = write(tmp_path, head + b"1 2 3\n4 5 6\n7 8 9\n")
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == f"{path}: more data lines than the header's POINTS 2"
    path = write(tmp_path, head + b"1 2 3\n")
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == f"{path}: the header says POINTS 2 but the file has 1 data lines"
    path = write(tmp_path, head + b"1 2 3\n4 five 6\n")
    with pytest.raises(DataError, match=r"f\.pcd: a data value is not a number \("):
        read_pcd(path)


def test_ascii_exactly_points_lines_and_zero_points(tmp_path):
    arr, _ = read_pcd(write(tmp_path, header(width=2, data="ascii") + b"1 2 3\n4 5 6"))
    np.testing.assert_array_equal(arr["z"], [3, 6])
    arr, _ = read_pcd(write(tmp_path, header(width=0, data="ascii")))
    assert len(arr) == 0


def test_data_kind_is_case_insensitive_and_header_keys_too(tmp_path):
    raw = (b"fields a\nsize 4\ntype f\nwidth 1\ndata ASCII\n" + b"2.5\n")
    arr, names = read_pcd(write(tmp_path, raw))
    assert names == ["a"] and arr["a"][0] == 2.5


# --- the header ------------------------------------------------------------------------------


def test_header_offsets_defaults_and_reading_from_the_path(tmp_path):
    head = header(count=None, width=4, height=None, points=None)
    path = write(tmp_path, head + b"\x00" * 48)
    h = read_pcd_header(path)
    assert h.data_offset == len(head) and h.data == "binary" and h.points == 4
    assert h.fields == ["x", "y", "z"]
    h2 = read_pcd_header(path, head)
    assert h2 == h
    # HEIGHT multiplies WIDTH when POINTS is absent
    assert read_pcd_header(path, header(width=3, height=2)).points == 6


def test_no_data_line_and_a_data_line_without_newline(tmp_path):
    raw = b"VERSION 0.7\nFIELDS x\nSIZE 4\nTYPE F\nWIDTH 1\n"
    path = write(tmp_path, raw)
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == (
        f"{path}: not a PCD file: no DATA line in its first {len(raw)} bytes (expected a header "
        "VERSION / FIELDS / SIZE / TYPE / COUNT / WIDTH / HEIGHT / POINTS / DATA)")
    with pytest.raises(DataError, match="no DATA line in its first"):
        read_pcd_header(path, raw + b"DATA binary")  # the last line has no end yet


@pytest.mark.parametrize("missing", ["FIELDS", "SIZE", "TYPE"])
def test_a_missing_list_is_named(tmp_path, missing):
    raw = header().replace(f"{missing} ".encode(), b"#")
    path = write(tmp_path, raw)
    with pytest.raises(DataError) as err:
        read_pcd_header(path)
    assert str(err.value) == (f"{path}: PCD header has no {missing} line; expected FIELDS, SIZE "
                              "and TYPE lists of one entry per field")


def test_an_empty_list_is_missing(tmp_path):
    with pytest.raises(DataError, match="has no SIZE line"):
        read_pcd_header(tmp_path / "f.pcd", header().replace(b"SIZE 4 4 4", b"SIZE"))


@pytest.mark.parametrize("kw, counts", [
    ({"type_": "F F"}, "3 FIELDS (x y z) but 3 SIZE, 2 TYPE and 3 COUNT"),
    ({"count": "1 1"}, "3 FIELDS (x y z) but 3 SIZE, 3 TYPE and 2 COUNT"),
    ({"size": "4 4 4 4"}, "3 FIELDS (x y z) but 4 SIZE, 3 TYPE and 3 COUNT"),
    ({"count": None, "size": "4 4"}, "3 FIELDS (x y z) but 2 SIZE, 3 TYPE and 3 COUNT"),
])
def test_list_lengths_must_agree(tmp_path, kw, counts):
    with pytest.raises(DataError) as err:
        read_pcd_header(tmp_path / "f.pcd", header(**kw))
    assert str(err.value) == (f"{tmp_path / 'f.pcd'}: PCD header lists {counts} entries; "
                              "expected one of each per field")


@pytest.mark.parametrize("kw", [{"size": "4 x 4"}, {"count": "1 1 one"}, {"width": "2.0"},
                                {"height": "h"}, {"points": "many"}])
def test_non_integers_are_refused(tmp_path, kw):
    with pytest.raises(DataError, match=r"f\.pcd: PCD header has a non-integer SIZE / COUNT / "
                                        r"WIDTH / HEIGHT / POINTS \(invalid literal"):
        read_pcd_header(tmp_path / "f.pcd", header(**kw))


@pytest.mark.parametrize("kw, what", [
    ({"type_": "F F X"}, "'z' has TYPE X SIZE 4 COUNT 1"),
    ({"size": "4 4 2"}, "'z' has TYPE F SIZE 2 COUNT 1"),
    ({"count": "1 0 1"}, "'y' has TYPE F SIZE 4 COUNT 0"),
    ({"type_": "F I U", "size": "4 3 4"}, "'y' has TYPE I SIZE 3 COUNT 1"),
])
def test_unknown_types_sizes_and_counts(tmp_path, kw, what):
    with pytest.raises(DataError) as err:
        read_pcd_header(tmp_path / "f.pcd", header(**kw))
    assert str(err.value) == (f"{tmp_path / 'f.pcd'}: PCD field {what}; expected TYPE F (4/8), "
                              "I or U (1/2/4/8), COUNT >= 1")


def test_a_huge_record_is_refused_before_expanding_its_count(tmp_path):
    with pytest.raises(DataError, match=r"one point record of the PCD header \(8,000,000,008 "
                                        r"bytes: SIZE x COUNT summed over FIELDS\)"):
        read_pcd_header(tmp_path / "f.pcd", header("a b", "4 4", "F F", "2000000000 2",
                                                  width=1))


@pytest.mark.parametrize("kw, said", [
    ({"width": 2, "points": 3}, "POINTS 3 but WIDTH 2 x HEIGHT 1"),
    ({"width": None, "points": 2}, "POINTS 2 but WIDTH -1 x HEIGHT 1"),
    ({"width": 2, "height": 0, "points": 0}, "POINTS 0 but WIDTH 2 x HEIGHT 0"),
    ({"width": -2, "height": -1, "points": 2}, "POINTS 2 but WIDTH -2 x HEIGHT -1"),
    ({"width": None, "height": None}, "POINTS 1 but WIDTH -1 x HEIGHT 1"),
])
def test_points_must_be_width_times_height(tmp_path, kw, said):
    kw.setdefault("height", 1)
    raw = header(**kw)
    if kw["width"] is None and kw["height"] is None:  # no WIDTH, no HEIGHT: POINTS -1 x 1
        raw = raw.replace(b"DATA", b"POINTS 1\nDATA")
    with pytest.raises(DataError) as err:
        read_pcd_header(tmp_path / "f.pcd", raw)
    assert str(err.value) == (f"{tmp_path / 'f.pcd'}: PCD header says {said}; expected POINTS = "
                              "WIDTH * HEIGHT")


def test_a_repeated_field_name_is_refused(tmp_path):
    with pytest.raises(DataError) as err:
        read_pcd_header(tmp_path / "f.pcd", header("x y x"))
    assert str(err.value) == f"{tmp_path / 'f.pcd'}: PCD header repeats a field name (x y x)"
    # a COUNT 2 field "v" and a field "v_1" collide too
    with pytest.raises(DataError, match="repeats a field name"):
        read_pcd_header(tmp_path / "f.pcd", header("v v_1", "4 4", "F F", "2 1"))


def test_other_data_kinds(tmp_path):
    path = write(tmp_path, header(data="binary_compressed") + b"\x00" * 24)
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == (f"{path}: DATA binary_compressed is not supported (the Snail-Radar "
                              "tools write binary or ascii PCD); re-save it uncompressed, e.g. "
                              "with pcl_convert_pcd_ascii_binary")
    path = write(tmp_path, header(data="lzf") + b"\x00" * 24)
    with pytest.raises(DataError) as err:
        read_pcd(path)
    assert str(err.value) == f"{path}: unknown PCD DATA kind 'lzf'; expected ascii or binary"
    path = write(tmp_path, header().replace(b"DATA binary", b"DATA"))
    with pytest.raises(DataError, match="unknown PCD DATA kind ''"):
        read_pcd(path)


def test_unreadable_and_missing_files(tmp_path):
    folder = tmp_path / "a.pcd"
    folder.mkdir()
    with pytest.raises(DataError, match=r"a\.pcd: cannot read the PCD file \("):
        read_pcd(folder)
    with pytest.raises(DataError, match=r"nothing\.pcd: cannot read the file"):
        read_pcd(tmp_path / "nothing.pcd")


def test_a_header_longer_than_the_limit_has_no_data_line(tmp_path):
    raw = b"# " + b"c" * (64 * 1024) + b"\n" + header()
    path = write(tmp_path, raw)
    with pytest.raises(DataError, match=f"no DATA line in its first {64 * 1024} bytes"):
        read_pcd(path)


# --- writing ---------------------------------------------------------------------------------


def test_write_pcd_header_is_the_formats(tmp_path):
    arr = np.zeros(2, dtype=[("x", "<f4"), ("ring", "<u2"), ("id", "<i8")])
    path = write_pcd(tmp_path / "w.pcd", arr, "ascii")
    text = path.read_text()
    assert text.splitlines()[:11] == [
        "# .PCD v0.7 - Point Cloud Data file format", "VERSION 0.7", "FIELDS x ring id",
        "SIZE 4 2 8", "TYPE F U I", "COUNT 1 1 1", "WIDTH 2", "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0", "POINTS 2", "DATA ascii"]


def test_write_pcd_binary_bytes_are_little_endian_records(tmp_path):
    arr = np.array([(1.5, 7, -2), (-0.25, 65535, 9)],
                   dtype=[("x", ">f4"), ("ring", ">u2"), ("id", "<i8")])
    path = write_pcd(tmp_path / "w.pcd", arr)
    raw = path.read_bytes()
    body = raw[raw.index(b"DATA binary\n") + len(b"DATA binary\n"):]
    assert body == struct.pack("<fHq", 1.5, 7, -2) + struct.pack("<fHq", -0.25, 65535, 9)
    back, names = read_pcd(path)
    assert names == ["x", "ring", "id"]
    for name in names:
        np.testing.assert_array_equal(back[name], arr[name])


def test_write_pcd_ascii_rows_are_exact_and_read_back(tmp_path):
    arr = np.array([(0.1, -3), (2.0, 4)], dtype=[("x", "<f8"), ("k", "<i4")])
    path = write_pcd(tmp_path / "w.pcd", arr, "ascii")
    assert path.read_text().splitlines()[-2:] == ["0.1 -3", "2.0 4"]
    back, _ = read_pcd(path)
    np.testing.assert_array_equal(back["x"], [0.1, 2.0])
    np.testing.assert_array_equal(back["k"], [-3, 4])


def test_a_header_may_start_with_an_empty_line(tmp_path):
    arr, names = read_pcd(write(tmp_path, b"\n" + header(width=1) + struct.pack("<3f", 1, 2, 3)))
    assert names == ["x", "y", "z"] and arr["z"][0] == 3.0


def test_non_ascii_header_bytes_are_replaced_not_an_error(tmp_path):
    """The header is ASCII: a stray byte (here Latin-1 and UTF-8 text) becomes U+FFFD, one
    per byte, in a comment as in a field name."""
    raw = (b"# r\xe9sum\xc3\xa9 \xff\n"
           + header(width=1).replace(b"FIELDS x y z", b"FIELDS x y \xc3\xa9")
           + struct.pack("<3f", 1, 2, 3))
    arr, names = read_pcd(write(tmp_path, raw))
    assert names == ["x", "y", "\ufffd\ufffd"]
    assert arr["\ufffd\ufffd"][0] == 3.0


def test_read_pcd_header_from_the_path_reads_64_kib_only(tmp_path):
    path = write(tmp_path, b"# " + b"c" * (64 * 1024) + b"\n" + header())
    with pytest.raises(DataError, match=f"no DATA line in its first {64 * 1024} bytes"):
        read_pcd_header(path)


def test_the_huge_record_message_names_the_file(tmp_path):
    path = tmp_path / "f.pcd"
    with pytest.raises(DataError) as err:
        read_pcd_header(path, header("a", "4", "F", "2000000000", width=1))
    assert str(err.value).startswith(f"{path}: one point record of the PCD header "
                                     "(8,000,000,000 bytes: SIZE x COUNT summed over FIELDS) "
                                     "would take 8,000 MB, above the per-frame limit")
