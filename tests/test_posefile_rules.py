"""loaders.posefile at unit level: TUM, KITTI, reference-CSV rows and extrinsics read into the
poses their formats define (cross-checked against scipy / numpy), and every bad input one
DataError naming the file, the row and what was expected."""

import re

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from loaders.errors import DataError
from loaders.posefile import (
    QUAT_NORM_TOLERANCE,
    REF_CSV_COLUMNS,
    check_quaternions,
    detect_pose_format,
    first_numeric_width,
    is_ref_csv,
    nearest_rotations,
    numeric_rows,
    parse_extrinsic,
    read_gt_file,
    read_kitti,
    read_ref_csv,
    read_tum,
    tum_text,
    write_kitti,
    write_tum,
)
from loaders.trajectory import Trajectory

ROT = Rotation.from_euler("zyx", [[0.1, 0.2, -0.3], [0.5, -0.1, 0.2], [-1.0, 0.3, 0.05]])
XYZ = np.array([[1.0, 2.0, 3.0], [-4.0, 0.5, 0.25], [7.0, -8.0, 9.5]])
STAMPS = np.array([10.0, 10.5, 11.25])


def expected_poses(rot=ROT, xyz=XYZ) -> np.ndarray:
    """T_world_frame by definition: [R | t; 0 0 0 1], R from scipy."""
    T = np.tile(np.eye(4), (len(xyz), 1, 1))
    T[:, :3, :3] = rot.as_matrix()
    T[:, :3, 3] = xyz
    return T


def tum_rows(stamps=STAMPS, xyz=XYZ, quat=None) -> list[str]:
    quat = ROT.as_quat() if quat is None else quat
    return [" ".join(f"{v:.17g}" for v in [t, *p, *q]) for t, p, q in zip(stamps, xyz, quat,
                                                                        strict=True)]


def setcol(row: str, i: int, value: str) -> str:
    parts = row.split()
    parts[i] = value
    return " ".join(parts)


def write(tmp_path, lines, name="poses.txt", end="\n") -> object:
    path = tmp_path / name
    path.write_text("\n".join(lines) + end)
    return path


def raises(path, *words):
    """A DataError whose message starts with the file's path and holds ``words``."""
    class _Check:
        def __enter__(self):
            self.ctx = pytest.raises(DataError)
            self.info = self.ctx.__enter__()
            return self.info

        def __exit__(self, *exc):
            out = self.ctx.__exit__(*exc)
            msg = str(self.info.value)
            assert msg.startswith(str(path)), msg
            for w in words:
                assert w in msg, (w, msg)
            return out
    return _Check()


# -- TUM ------------------------------------------------------------------------------------


def test_tum_rows_are_the_poses_scipy_makes_of_them(tmp_path):
    tr = read_tum(write(tmp_path, tum_rows()))
    assert isinstance(tr, Trajectory)
    np.testing.assert_allclose(tr.stamps, STAMPS, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.poses, expected_poses(), rtol=0, atol=1e-12)


def test_tum_comments_blank_lines_header_and_commas_are_read_through(tmp_path):
    lines = ["timestamp x y z qx qy qz qw", "# a comment", "", *tum_rows()[:2], "   ",
             "# another", tum_rows()[2].replace(" ", ", ")]
    path = write(tmp_path, lines, end="")  # no final newline either
    tr = read_tum(path)
    np.testing.assert_allclose(tr.stamps, STAMPS, rtol=0, atol=1e-12)
    np.testing.assert_allclose(tr.poses, expected_poses(), rtol=0, atol=1e-12)
    data, lines_read = numeric_rows(path, (8,), "t x y z qx qy qz qw")
    assert lines_read == [4, 5, 8]
    np.testing.assert_allclose(data[:, 0], STAMPS)


def test_plain_rows_give_their_line_numbers(tmp_path):
    for end in ("\n", ""):
        path = write(tmp_path, tum_rows(), end=end)
        data, lines = numeric_rows(path, (8,), "t x y z qx qy qz qw")
        assert lines == [1, 2, 3]
        assert data.shape == (3, 8)
        np.testing.assert_allclose(data[:, 1:4], XYZ)


def test_line_numbers_count_blank_lines_and_a_comment_after_a_row_is_refused(tmp_path):
    quat = ROT.as_quat()
    quat[2] *= 1.5
    rows = tum_rows(quat=quat)
    path = write(tmp_path, [rows[0], "", rows[1], rows[2]], name="gap.txt")
    with raises(path, "line 4", "has norm 1.5"):
        read_tum(path)
    noted = write(tmp_path, [tum_rows()[0], tum_rows()[1] + " # note", tum_rows()[2]],
                  name="noted.txt")
    with raises(noted, "line 2", "expected 8 numbers"):
        read_tum(noted)
    # the first pose row with a comment is refused as well: no header (its first word is a
    # number), not a row to drop in silence
    first = write(tmp_path, [tum_rows()[0] + " # first", *tum_rows()[1:]], name="first.txt")
    with raises(first, "line 1", "expected 8 numbers"):
        read_tum(first)
    headed = write(tmp_path, ["# t x y z", "stamp x y z qx qy qz qw", tum_rows()[0] + " # a",
                              *tum_rows()[1:]], name="headed.txt")
    with raises(headed, "line 3", "expected 8 numbers"):
        read_tum(headed)
    # the first word decides: a corrupt first row is refused, a header with numbers after its
    # first word is a header
    corrupt = write(tmp_path, ["1 x 0 0 0 0 0 1", *tum_rows()[1:]], name="corrupt.txt")
    with raises(corrupt, "line 1", "expected 8 numbers"):
        read_tum(corrupt)
    numbered = write(tmp_path, ["stamp 1 2 3 4 5 6 7", *tum_rows()], name="numbered.txt")
    assert numeric_rows(numbered, (8,), "t x y z qx qy qz qw")[1] == [2, 3, 4]


def test_a_non_utf8_byte_in_a_comment_is_no_crash(tmp_path):
    path = tmp_path / "latin.txt"
    path.write_bytes(b"# caf\xe9 \xff\n" + ("\n".join(tum_rows()) + "\n").encode())
    np.testing.assert_allclose(read_tum(path).poses, expected_poses(), atol=1e-12)
    assert first_numeric_width(path) == 8
    assert detect_pose_format(path) == "tum"
    plain = tmp_path / "latin_row.txt"  # a stray byte in a row: that row named, no crash
    plain.write_bytes(("\n".join(tum_rows()) + "\n").encode() + b"1 2 3 4 5 6 7 \xff\n")
    with raises(plain, "line 4", "expected 8 numbers", "t x y z qx qy qz qw"):
        read_tum(plain)


@pytest.mark.parametrize("edit, words", [
    (lambda r: r[:1] + [" ".join(r[1].split()[:7])] + r[2:],
     ["line 2", "expected 8 values", "t x y z qx qy qz qw", "got 7"]),
    (lambda r: r[:2] + [r[2] + " 5"], ["line 3", "expected 8 values", "got 9"]),
    (lambda r: r[:1] + [setcol(r[1], 2, "abc")] + r[2:],
     ["line 2", "expected 8 numbers (t x y z qx qy qz qw)", "abc"]),
    (lambda r: r[:1] + [setcol(r[1], 3, "nan")] + r[2:],
     ["line 2", "non-finite", "t x y z qx qy qz qw"]),
    (lambda r: ["# c"] + r[:2] + [setcol(r[2], 1, "inf")],
     ["line 4", "non-finite"]),
    (lambda r: ["# only comments", ""], ["no TUM pose rows found", "t x y z qx qy qz qw"]),
    (lambda r: [], ["no TUM pose rows found"]),
])
def test_bad_tum_rows_are_one_error_naming_file_and_line(tmp_path, edit, words):
    path = write(tmp_path, edit(tum_rows()))
    with raises(path, *words):
        read_tum(path)


def test_rows_of_mixed_allowed_widths_are_refused(tmp_path):
    path = write(tmp_path, ["1 2", "3 4 5", "6 7"], name="w.txt")
    with raises(path, "line 2", "expected 2 values", "got 3"):
        numeric_rows(path, (2, 3), "pairs")
    wrong = write(tmp_path, ["1 2 3 4"], name="w4.txt")
    with raises(wrong, "line 1", "expected 2 or 3 values (pairs)", "got 4"):
        numeric_rows(wrong, (2, 3), "pairs")
    bad = write(tmp_path, ["1 2", "x y"], name="w5.txt")
    with raises(bad, "line 2", "expected 2 or 3 numbers (pairs)", "'x y'"):
        numeric_rows(bad, (2, 3), "pairs")
    data, lines = numeric_rows(write(tmp_path, ["1 2 3", "4 5 6"], name="w6.txt"), (2, 3), "p")
    np.testing.assert_array_equal(data, [[1, 2, 3], [4, 5, 6]])
    assert lines == [1, 2]


def test_a_missing_pose_file_is_named(tmp_path):
    for reader in (lambda p: numeric_rows(p, (8,), "x"), read_tum, read_kitti, read_ref_csv,
                   is_ref_csv):
        with raises(tmp_path / "nope.txt", "cannot read the file"):
            reader(tmp_path / "nope.txt")


@pytest.mark.parametrize("scale, ok", [(1.009, True), (0.991, True), (1.011, False),
                                       (0.989, False), (0.0, False)])
def test_tum_quaternion_norm_within_the_tolerance_only(tmp_path, scale, ok):
    assert QUAT_NORM_TOLERANCE == pytest.approx(0.01)
    quat = ROT.as_quat()
    quat[1] *= scale
    path = write(tmp_path, tum_rows(quat=quat))
    if ok:
        np.testing.assert_allclose(read_tum(path).poses, expected_poses(), atol=1e-12)
    else:
        with raises(path, "line 2", "quaternion (qx qy qz qw)", "expected a unit quaternion",
                    f"norm {scale:.4g}"):
            read_tum(path)


def test_check_quaternions_normalises_and_names_the_row():
    q = ROT.as_quat() * np.array([[1.005], [0.995], [1.0]])
    out = check_quaternions(q, "f.txt", [3, 5, 9])
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(out, ROT.as_quat(), atol=1e-15)
    rows = np.column_stack([STAMPS, XYZ, q])
    rows[2, 1] = np.inf
    with pytest.raises(DataError, match=r"^f.txt, line 9: non-finite value .*expected finite"):
        check_quaternions(q, "f.txt", [3, 5, 9], finite=rows)
    q[1] = [np.nan, 0, 0, 1]
    with pytest.raises(DataError, match=r"^f.txt, line 5: non-finite"):
        check_quaternions(q, "f.txt", [3, 5, 9])
    q[1] = [0, 0, 0, 2.0]
    with pytest.raises(DataError, match=r"^f.txt, line 5: quaternion \(qx qy qz qw\) = 0 0 0 2 "
                                        r"has norm 2; expected a unit quaternion"):
        check_quaternions(q, "f.txt", [3, 5, 9])


def test_write_tum_reads_back_with_nine_decimals(tmp_path):
    tr = Trajectory(STAMPS + 1.7e9, expected_poses())
    text = tum_text(tr)
    rows = text.splitlines()
    assert text.endswith("\n") and len(rows) == 3
    for row in rows:
        fields = row.split(" ")
        assert len(fields) == 8
        assert all(re.fullmatch(r"-?\d+\.\d{9}", f) for f in fields), row
    path = tmp_path / "out.txt"
    write_tum(tr, path)
    assert path.read_text() == text
    back = read_tum(path)
    np.testing.assert_allclose(back.stamps, tr.stamps, rtol=0, atol=1e-6)
    np.testing.assert_allclose(back.poses, tr.poses, rtol=0, atol=1e-8)
    # quaternion column order x y z w, as Rotation.as_quat (up to sign)
    q = np.array([[float(v) for v in r.split()[4:]] for r in rows])
    sign = np.sign(np.sum(q * ROT.as_quat(), axis=1))[:, None]
    np.testing.assert_allclose(q * sign, ROT.as_quat(), atol=2e-9)


# -- KITTI ----------------------------------------------------------------------------------


def kitti_rows(T) -> list[str]:
    return [" ".join(f"{v:.17g}" for v in M[:3, :].ravel()) for M in T]


def test_kitti_rows_are_the_3x4_matrices_row_major(tmp_path):
    path = write(tmp_path, kitti_rows(expected_poses()))
    tr = read_kitti(path)
    np.testing.assert_allclose(tr.poses, expected_poses(), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(tr.stamps, [0.0, 1.0, 2.0])
    tr = read_kitti(path, STAMPS)
    np.testing.assert_array_equal(tr.stamps, STAMPS)
    # one row by hand: row-major [R | t]
    row = np.array([[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 1, 7]], dtype=float)
    one = write(tmp_path, [" ".join(map(str, row.ravel()))], name="one.txt")
    single = read_kitti(one)
    assert len(single) == 1
    np.testing.assert_allclose(single.poses[0], np.vstack([row, [0, 0, 0, 1]]))
    # a shear of exactly the tolerance, max |R R^T - I| = 1e-3: read
    edge = write(tmp_path, ["1 0.001 0 0 0 1 0 0 0 0 1 0"] * 2, name="edge.txt")
    np.testing.assert_allclose(read_kitti(edge).poses[0, 0, :3], [1, 0.001, 0])
    with raises(path, "3 poses but 2 stamps"):
        read_kitti(path, STAMPS[:2])


def test_write_kitti_reads_back(tmp_path):
    tr = Trajectory(STAMPS, expected_poses())
    path = tmp_path / "k.txt"
    write_kitti(tr, path)
    rows = path.read_text().splitlines()
    assert len(rows) == 3 and all(len(r.split(" ")) == 12 for r in rows)
    assert all(re.fullmatch(r"-?\d\.\d{9}e[+-]\d\d", f) for r in rows for f in r.split(" "))
    np.testing.assert_allclose(read_kitti(path, STAMPS).poses, tr.poses, rtol=0, atol=1e-8)


@pytest.mark.parametrize("edit, words", [
    (lambda M: M[:, :, :3].__imul__(1.01), ["pose row 1", "not a rigid transform"]),
    (lambda M: M[1:, 0, :3].__imul__(-1), ["pose row 2", "not a rigid transform"]),
    (lambda M: M[2:, 0, 1].__iadd__(0.5),
     ["pose row 3: not a rigid transform (its 3x3 part is not a rotation, or a value is not "
      "finite); expected 12 values, a 3x4 [R | t] row-major"]),
    (lambda M: M[2:, 1, 3].__iadd__(np.nan), ["pose row 3", "not finite"]),
])
def test_kitti_rows_that_are_no_rigid_transform(tmp_path, edit, words):
    T = expected_poses()
    edit(T)
    path = write(tmp_path, kitti_rows(T))
    with raises(path, *words):
        read_kitti(path)


def test_kitti_rotation_within_1e3_of_orthonormal_is_read(tmp_path):
    T = expected_poses()
    T[1, :3, :3] *= 1.0004  # |R R^T - I| about 8e-4
    np.testing.assert_allclose(read_kitti(write(tmp_path, kitti_rows(T))).poses[1], T[1])
    T[1, :3, :3] *= 1.0002  # 1.0006 in all: about 1.2e-3
    with raises(tmp_path / "poses.txt", "pose row 2"):
        read_kitti(write(tmp_path, kitti_rows(T)))


def test_kitti_of_another_width_or_not_numbers(tmp_path):
    path = write(tmp_path, [" ".join(["1"] * 11)] * 2)
    with raises(path, "expected 12 values per KITTI row", "got 11"):
        read_kitti(path)
    bad = write(tmp_path, kitti_rows(expected_poses())[:1] + ["a b c"], name="bad.txt")
    with raises(bad, "not a KITTI pose file"):
        read_kitti(bad)


# -- nearest rotations ----------------------------------------------------------------------


def test_nearest_rotations_projects_slightly_off_blocks_and_refuses_others():
    R = ROT.as_matrix()
    noisy = R + 2e-4 * np.array([[1, -1, 0], [0, 1, 1], [1, 0, -1]])
    out = nearest_rotations(noisy, "f.txt", [4, 6, 8])
    U, _, Vt = np.linalg.svd(noisy)
    np.testing.assert_allclose(out, U @ Vt, atol=1e-12)
    np.testing.assert_allclose(out @ np.swapaxes(out, 1, 2), np.broadcast_to(np.eye(3), (3, 3, 3)),
                               atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(out), 1.0, atol=1e-12)
    np.testing.assert_allclose(out, R, atol=1e-3)
    for name, bad, k, count in [("scaled", R * np.array([1, 1.01, 1.01])[:, None, None], 1, 2),
                                ("mirrored", R * np.array([1, 1, -1])[:, None, None], 2, 1),
                                ("sheared", R + np.array([0, 0, 1])[:, None, None]
                                 * np.array([[0, 0.01, 0], [0] * 3, [0] * 3]), 2, 1),
                                ("nan", np.where(np.arange(3)[:, None, None] == 0, np.nan, R),
                                 0, 1)]:
        with pytest.raises(DataError) as err:
            nearest_rotations(bad, "f.txt", [4, 6, 8], "3x3 of X")
        msg = str(err.value)
        assert msg.startswith(f"f.txt, line {[4, 6, 8][k]}: the 3x3 of X is no rotation"), name
        assert f"{count} such rows" in msg, (name, msg)
        assert "sheared, scaled or mirrored; expected a rigid pose (a rotation block)" in msg
    # determinant 1 but sheared: refused
    shear = np.eye(3)[None].copy()
    shear[0, 0, 1] = 0.01
    with pytest.raises(DataError, match="line 1: the 3x3 block is no rotation"):
        nearest_rotations(shear, "f.txt", [1])
    # just within the tolerance (1e-3): read
    ok = np.eye(3)[None] * 1.0004
    np.testing.assert_allclose(nearest_rotations(ok, "f", [1]), np.eye(3)[None], atol=1e-12)
    # a shear of exactly the tolerance: max |R R^T - I| = 1e-3, read
    edge = np.eye(3)[None].copy()
    edge[0, 0, 1] = 1e-3
    assert np.abs(edge[0] @ edge[0].T - np.eye(3)).max() == 1e-3
    out = nearest_rotations(edge, "f", [1])
    np.testing.assert_allclose(out[0] @ out[0].T, np.eye(3), atol=1e-12)


# -- extrinsics -----------------------------------------------------------------------------


def test_parse_extrinsic_forms_against_scipy():
    np.testing.assert_array_equal(parse_extrinsic(None), np.eye(4))
    q = ROT[0].as_quat()
    text = " ".join(f"{v:.17g}" for v in [1, 2, 3, *q])
    want = expected_poses()[0]
    want[:3, 3] = [1, 2, 3]
    np.testing.assert_allclose(parse_extrinsic(text), want, atol=1e-12)
    np.testing.assert_allclose(parse_extrinsic(text.replace(" ", ",")), want, atol=1e-12)
    np.testing.assert_allclose(parse_extrinsic([1, 2, 3, *q]), want, atol=1e-12)
    np.testing.assert_allclose(parse_extrinsic(want), want, atol=1e-12)
    np.testing.assert_allclose(parse_extrinsic(" ".join(map(repr, want.ravel().tolist()))), want,
                               atol=1e-12)
    np.testing.assert_allclose(parse_extrinsic("4 5 6"), np.r_[np.c_[np.eye(3), [4, 5, 6]],
                                                              [[0, 0, 0, 1]]])
    # a quaternion off unit length by less than 1e-3: normalised
    np.testing.assert_allclose(parse_extrinsic([1, 2, 3, *(1.0008 * q)]), want, atol=1e-12)


@pytest.mark.parametrize("value, words", [
    ("1 2 3 a 0 0 1", ["extrinsic '1 2 3 a 0 0 1'", "expected numbers 'x y z qx qy qz qw'"]),
    ("1 2 3 0 0 0 nan", ["expected finite numbers"]),
    ([1, 2, np.inf], ["expected finite numbers"]),
    ("1 2 3 4", ["expected 7 numbers 'x y z qx qy qz qw', 3", "or 16", "got 4"]),
    ("1 2 3 0 0 0 1 0", ["got 8"]),
    ("0 0 0 0 0 0 1.002", ["quaternion (qx qy qz qw) is not unit length"]),
    ("0 0 0 0 0 0 0.998", ["quaternion (qx qy qz qw) is not unit length"]),
    (np.diag([1.0, 1.0, 1.0, 2.0]), ["the 4x4 matrix is not a rigid transform"]),
    (np.diag([1.0, 1.0, 1.0001, 1.0]), ["the 4x4 matrix is not a rigid transform"]),
    (np.r_[np.eye(4)[:3], [[0, 0.1, 0, 1]]], ["the 4x4 matrix is not a rigid transform"]),
])
def test_parse_extrinsic_refuses(value, words):
    with pytest.raises(DataError) as err:
        parse_extrinsic(value)
    msg = str(err.value)
    assert msg.startswith("extrinsic "), msg
    for w in words:
        assert w in msg, (w, msg)


def test_a_4x4_within_1e5_of_orthonormal_is_taken_as_floats():
    T = np.eye(4)
    T[0, 1] = 4e-6  # R R^T off the identity by 4e-6 off the diagonal
    np.testing.assert_array_equal(parse_extrinsic(T), T)
    T[0, 1] = 2e-5
    with pytest.raises(DataError, match="not a rigid transform"):
        parse_extrinsic(T)
    ints = parse_extrinsic(np.eye(4, dtype=int))
    assert ints.dtype == np.float64
    np.testing.assert_array_equal(ints, np.eye(4))


# -- reference CSV --------------------------------------------------------------------------


def ref_rows(stamps=STAMPS, velocity=True) -> list[str]:
    q = ROT.as_quat()
    out = []
    for k, t in enumerate(stamps):
        values = [t, *XYZ[k], *q[k]] + ([0.1, 0.2, 0.3] if velocity else [])
        out.append(", ".join(f"{v:.17g}" for v in values))
    return out


def test_ref_csv_header_and_rows(tmp_path):
    header = "# " + ", ".join(REF_CSV_COLUMNS)
    for lines in ([header, *ref_rows()], [header.lstrip("# ").upper(), "", *ref_rows()],
                  ["#" + " ".join(REF_CSV_COLUMNS[:8]), *ref_rows(velocity=False)],
                  ref_rows()):
        path = write(tmp_path, lines, name="ref.csv")
        tr = read_ref_csv(path)
        np.testing.assert_allclose(tr.stamps, STAMPS, rtol=0, atol=1e-12)
        np.testing.assert_allclose(tr.poses, expected_poses(), rtol=0, atol=1e-12)
        assert is_ref_csv(path) is (len(lines[-1].split(",")) == 11 or "M_p_L_x" in lines[0]
                                    or "M_P_L_X" in lines[0])
        assert read_gt_file(path).stamps.tolist() == tr.stamps.tolist()


def test_ref_csv_velocity_columns_are_not_used_and_odd_bytes_pass(tmp_path):
    rows = ref_rows()
    rows[1] = ", ".join(rows[1].split(", ")[:8] + ["nan", "inf", "0"])
    path = tmp_path / "v.csv"
    path.write_bytes(b"# " + ", ".join(REF_CSV_COLUMNS).encode() + b"\n# caf\xe9\n"
                     + "\n".join(rows).encode() + b"\n")
    np.testing.assert_allclose(read_ref_csv(path).poses, expected_poses(), atol=1e-12)


def test_ref_csv_nanosecond_stamps_become_seconds(tmp_path):
    ns = np.array([1_700_000_000_000_000_000, 1_700_000_000_500_000_000,
                   1_700_000_001_250_000_000])
    path = write(tmp_path, ["# " + ",".join(REF_CSV_COLUMNS), *ref_rows(stamps=ns)],
                 name="ns.csv")
    np.testing.assert_allclose(read_ref_csv(path).stamps, ns * 1e-9, rtol=0, atol=1e-6)
    # seconds of today's epoch (about 1.7e9) stay seconds
    s = write(tmp_path, ref_rows(stamps=STAMPS + 1.7e9), name="s.csv")
    np.testing.assert_allclose(read_ref_csv(s).stamps, STAMPS + 1.7e9, rtol=0, atol=1e-6)
    big = write(tmp_path, ref_rows(stamps=np.array([0.5e17, 0.6e17, 0.7e17])), name="b.csv")
    np.testing.assert_allclose(read_ref_csv(big).stamps, [0.5e17, 0.6e17, 0.7e17])


@pytest.mark.parametrize("lines, words", [
    (lambda r: ["# time, x, y, z, qx, qy, qz, qw", *r], ["header columns time, x, y",
                                                         "expected time, M_p_L_x",
                                                         "Snail-Radar reference"]),
    (lambda r: ["time, x, y, z, qx, qy, qz, qw, a, b, c, d", *r],
     ["header columns time, x, y, z, qx, qy, qz, qw, a, b, c; expected "
      + ", ".join(REF_CSV_COLUMNS) + " (the Snail-Radar"]),
    (lambda r: [r[0], "1, 2, x, 4, 0, 0, 0, 1, 0, 0, 0"],
     ["line 2", "expected comma-separated numbers", "time, M_p_L_x", "'1, 2, x"]),
    (lambda r: [r[0], "1, 2, 3, 4, 0, 0, 0, 1, 0"],
     ["line 2: 9 values; expected 11 (" + ", ".join(REF_CSV_COLUMNS) + ") or the first 8"]),
    (lambda r: [r[0], ", ".join(r[1].split(", ")[:8])], ["line 2", "8 values; expected 11"]),
    (lambda r: ["# " + ", ".join(REF_CSV_COLUMNS)],
     ["no pose rows; expected lines of " + ", ".join(REF_CSV_COLUMNS)]),
    (lambda r: [r[0], "1, 2, " + "x" * 100],
     ["line 2", ", got " + repr(("1, 2, " + "x" * 100)[:80])]),
    (lambda r: [r[0], "4, 1, 2, 3, 0, 0, 0, 1.5, 0, 0, 0"],
     ["line 2", "quaternion", "expected a unit quaternion"]),
    (lambda r: ["", r[0], "4, 1, 2, nan, 0, 0, 0, 1, 0, 0, 0"], ["line 3", "non-finite"]),
])
def test_bad_ref_csv_is_one_error_naming_file_and_line(tmp_path, lines, words):
    path = write(tmp_path, lines(ref_rows()), name="ref.csv")
    with raises(path, *words):
        read_ref_csv(path)


def test_a_ref_csv_comment_after_the_rows_is_no_header(tmp_path):
    path = write(tmp_path, [*ref_rows()[:2], "# time x y", ref_rows()[2]], name="r.csv")
    np.testing.assert_allclose(read_ref_csv(path).poses, expected_poses(), atol=1e-12)
    late = write(tmp_path, [ref_rows()[0], "time, a, b"], name="late.csv")
    with raises(late, "line 2", "expected comma-separated numbers"):
        read_ref_csv(late)


# -- detection ------------------------------------------------------------------------------


def test_format_detection(tmp_path):
    tum = write(tmp_path, ["#", "# c", "t x y z qx qy qz qw", *tum_rows()], name="t.txt")
    kitti = write(tmp_path, ["", "# c", *kitti_rows(expected_poses())], name="k.txt")
    ref = write(tmp_path, ["", "# made by the TLS localisation", *ref_rows()], name="r.csv")
    named = write(tmp_path, ["# time M_p_L_x", *ref_rows(velocity=False)], name="n.csv")
    eight = write(tmp_path, ref_rows(velocity=False), name="e.csv")
    empty = write(tmp_path, ["", "# nothing"], name="empty.txt")
    assert [first_numeric_width(p) for p in (tum, kitti, ref, empty)] == [8, 12, 11, None]
    assert first_numeric_width(write(tmp_path, ["1,2,3", "1 2"], name="c.txt")) == 3
    assert [is_ref_csv(p) for p in (tum, kitti, ref, named, eight, empty)] == [
        False, False, True, True, False, False]
    assert [detect_pose_format(p) for p in (tum, kitti, ref, named, eight)] == [
        "tum", "kitti", "ref-csv", "ref-csv", "tum"]


def test_read_gt_file_by_format(tmp_path):
    tum = write(tmp_path, tum_rows(), name="t.txt")
    kitti = write(tmp_path, kitti_rows(expected_poses()), name="k.txt")
    ref = write(tmp_path, ref_rows(), name="r.csv")
    for path, fmt in [(tum, "auto"), (tum, "tum"), (kitti, "auto"), (kitti, "kitti"),
                      (ref, "auto"), (ref, "tum"), (ref, "ref-csv")]:
        tr = read_gt_file(path, fmt, stamps=STAMPS)
        np.testing.assert_allclose(tr.poses, expected_poses(), atol=1e-12)
        np.testing.assert_allclose(tr.stamps, STAMPS, atol=1e-12)
    np.testing.assert_array_equal(read_gt_file(kitti).stamps, [0, 1, 2])
    with raises(tum, "unknown ground-truth format 'csv'", "expected tum, kitti or ref-csv"):
        read_gt_file(tum, "csv")
    with raises(tmp_path / "gone.txt", "ground-truth file not found"):
        read_gt_file(tmp_path / "gone.txt")
    with raises(kitti, "expected 8 values"):  # KITTI rows read as TUM: the width named
        read_gt_file(kitti, "tum")
