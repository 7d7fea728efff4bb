"""Pose files and extrinsics: every file format of poses in one place.

- TUM: rows ``t x y z qx qy qz qw`` (``read_tum`` / ``write_tum``);
- KITTI: rows of 12 values, the 3x4 ``T_world_frame`` row-major, no stamps (``read_kitti`` /
  ``write_kitti``);
- reference CSV: ``time, M_p_L_x .. M_q_L_w, W_v_L_x ..`` (Snail-Radar's ``ref_tls_T_xt32.csv``,
  ``read_ref_csv``);
- ``read_gt_file``: any of these, detected from the header / first numeric row;
- ``parse_extrinsic``: a 4x4 transform from "x y z qx qy qz qw", 3, 7 or 16 numbers.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.fileio import atomic_write_text
from loaders.limits import check_file_size
from loaders.se3 import T_from_tum, make_T, tum_from_T
from loaders.trajectory import Trajectory


def numeric_rows(path: str | Path, widths: tuple[int, ...], expected: str, kind: str = "pose"
                 ) -> tuple[np.ndarray, list[int]]:
    """The numeric rows of a text file (all of one width, one of ``widths``) and their line
    numbers: '#' comments, blank lines and leading header lines (their first word not a
    number) are skipped, commas count as spaces; one ``DataError`` naming the file and the line
    for a row that is not numbers (the first row too: a pose row with a trailing comment is no
    header), of another width, or not finite (``expected`` says what a row holds)."""
    path = Path(path)
    check_file_size(path, str(path))
    plain = _plain_rows(path, widths)
    if plain is not None:
        return plain
    rows: list[list[float]] = []
    lines: list[int] = []
    with open(path, errors="replace") as f:
        for lineno, line in enumerate(f, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            parts = text.replace(",", " ").split()
            try:
                values = [float(v) for v in parts]
            except ValueError:
                if not rows and not _is_number(parts[0]):  # a header: "timestamp x y z ..."
                    continue
                want = " or ".join(map(str, widths))
                raise DataError(f"{path}, line {lineno}: expected {want} numbers ({expected}), "
                                f"got {text!r}") from None
            if len(values) not in widths or (rows and len(values) != len(rows[0])):
                want = len(rows[0]) if rows else " or ".join(map(str, widths))
                raise DataError(f"{path}, line {lineno}: expected {want} values ({expected}), "
                                f"got {len(values)}")
            rows.append(values)
            lines.append(lineno)
    if not rows:
        raise DataError(f"{path}: no {kind} rows found; expected {expected}")
    data = np.array(rows, dtype=np.float64)
    bad = ~np.isfinite(data).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path}, line {lines[k]}: non-finite value (NaN or inf); expected "
                        f"finite numbers ({expected})")
    return data, lines


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _plain_rows(path: Path, widths: tuple[int, ...]) -> tuple[np.ndarray, list[int]] | None:
    """``numeric_rows`` of a file of nothing but rows of finite numbers of one allowed width
    (as the harness writes them), parsed by NumPy: a 40,000-pose TUM file in about half the
    time of a ``float()`` per value. None for anything else (a header, a comment, a blank line,
    commas, a bad value): the line-by-line reader then reads it or names the line."""
    with open(path, errors="replace") as f:
        text = f.read()
    if not text.strip():
        return None
    lines = text.count("\n") + (not text.endswith("\n"))
    try:
        data = np.loadtxt(io.StringIO(text), dtype=np.float64, comments=None, ndmin=2)
    except ValueError:
        return None
    if (len(data) != lines or not len(data) or data.shape[1] not in widths
            or not np.isfinite(data).all()):
        return None
    return data, list(range(1, lines + 1))


def read_tum(path: str | Path) -> Trajectory:
    """Read TUM rows ``t x y z qx qy qz qw``; '#' comments and one leading header line that
    is not numeric are skipped."""
    data, linenos = numeric_rows(path, (8,), "t x y z qx qy qz qw", kind="TUM pose")
    quat = check_quaternions(data[:, 4:8], path, linenos, finite=data)
    return Trajectory(data[:, 0], T_from_tum(data[:, 1:4], quat))


#: a pose row's quaternion must have a norm within this of 1 (files print 6-9 digits)
QUAT_NORM_TOLERANCE = 0.01


def check_quaternions(quat: np.ndarray, path, linenos: list[int],
                      finite: np.ndarray | None = None) -> np.ndarray:
    """The unit quaternions of pose rows (normalised); a ``DataError`` naming the file and the
    line of the first row that is not finite (``finite``: the whole rows) or whose quaternion
    is not unit length within ``QUAT_NORM_TOLERANCE`` (a zero quaternion is no orientation)."""
    rows = quat if finite is None else finite
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path}, line {linenos[k]}: non-finite value in the pose row; expected "
                        "finite numbers")
    norms = np.linalg.norm(quat, axis=1)
    bad = np.abs(norms - 1.0) > QUAT_NORM_TOLERANCE
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path}, line {linenos[k]}: quaternion (qx qy qz qw) = "
                        f"{' '.join(f'{v:g}' for v in quat[k])} has norm {norms[k]:.4g}; "
                        "expected a unit quaternion (norm 1)")
    return quat / norms[:, None]

#: a rotation block may be off orthonormal by this much (max |R R^T - I|: rows printed with
#: 4 decimals are off by about 1e-4)
ORTHONORMAL_TOLERANCE = 1e-3


def nearest_rotations(R: np.ndarray, where: str, linenos: list[int], name: str = "3x3 block"
                      ) -> np.ndarray:
    """The nearest rotations of rotation blocks (rows printed with few digits); a ``DataError``
    naming the file and the line of the first block that is not a rotation within
    ``ORTHONORMAL_TOLERANCE``: a sheared or scaled block (even of determinant 1) or a
    reflection is refused, never silently made a rotation."""
    with np.errstate(invalid="ignore"):
        err = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = np.flatnonzero(~(err <= ORTHONORMAL_TOLERANCE) | ~(det > 0))
    if len(bad):
        k = int(bad[0])
        raise DataError(f"{where}, line {linenos[k]}: the {name} is no rotation (determinant "
                        f"{det[k]:.4f}, max |R R^T - I| = {err[k]:.3g}, beyond "
                        f"{ORTHONORMAL_TOLERANCE:g}; {len(bad)} such rows): sheared, scaled or "
                        "mirrored; expected a rigid pose (a rotation block)")
    U, _, Vt = np.linalg.svd(R)
    return U @ Vt


def write_tum(traj: Trajectory, path: str | Path) -> None:
    """Write TUM rows ``t x y z qx qy qz qw`` (9 decimals)."""
    atomic_write_text(path, tum_text(traj))


def tum_text(traj: Trajectory) -> str:
    """TUM rows ``t x y z qx qy qz qw`` (9 decimals) as text."""
    xyz, quat = tum_from_T(traj.poses)
    return _rows(np.column_stack([traj.stamps, xyz, quat]), "%.9f")

def read_kitti(path: str | Path, stamps: np.ndarray | None = None) -> Trajectory:
    """Read KITTI rows (12 values, 3x4 row-major); stamps default to the row index."""
    path = Path(path)
    check_file_size(path, str(path))
    try:
        data = np.loadtxt(path, ndmin=2)
    except ValueError as err:
        raise DataError(f"{path}: not a KITTI pose file ({err})") from err
    if data.shape[1] != 12:
        raise DataError(f"{path}: expected 12 values per KITTI row, got {data.shape[1]}")
    R = data[:, [0, 1, 2, 4, 5, 6, 8, 9, 10]].reshape(-1, 3, 3)
    with np.errstate(invalid="ignore"):
        err = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2))
    bad = ~np.isfinite(data).all(axis=1) | ~(err <= 1e-3) | ~(np.linalg.det(R) > 0)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"{path}, pose row {k + 1}: not a rigid transform (its 3x3 part is not "
                        "a rotation, or a value is not finite); expected 12 values, a 3x4 "
                        "[R | t] row-major")
    poses = make_T(R, data[:, [3, 7, 11]])
    if stamps is None:
        stamps = np.arange(len(poses), dtype=np.float64)
    elif len(stamps) != len(poses):
        raise DataError(f"{path}: {len(poses)} poses but {len(stamps)} stamps")
    return Trajectory(np.asarray(stamps, dtype=np.float64), poses)

def write_kitti(traj: Trajectory, path: str | Path) -> None:
    """Write KITTI rows (3x4 row-major, no stamps)."""
    atomic_write_text(path, _rows(traj.poses[:, :3, :].reshape(-1, 12), "%.9e"))


def _rows(values: np.ndarray, fmt: str) -> str:
    """Space-separated rows of ``values`` in the ``%`` format ``fmt`` (as ``np.savetxt``)."""
    values = np.asarray(values, dtype=np.float64)
    line = " ".join([fmt] * values.shape[1]) + "\n" if values.ndim == 2 else "\n"
    return "".join(line % tuple(row) for row in values.tolist())


def parse_extrinsic(text: str | list | tuple | np.ndarray | None) -> np.ndarray:
    """A 4x4 extrinsic from "x y z qx qy qz qw" (TUM order), 7 numbers, 16 numbers (row-major
    4x4) or a 4x4 array; ``None`` gives the identity."""
    if text is None:
        return np.eye(4)
    if isinstance(text, str):
        try:
            values = [float(v) for v in text.replace(",", " ").split()]
        except ValueError as err:
            raise DataError(
                f"extrinsic {text!r}: expected numbers 'x y z qx qy qz qw' ({err})"
            ) from None
    else:
        values = np.asarray(text, dtype=np.float64).ravel().tolist()
    v = np.asarray(values, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise DataError(f"extrinsic {values}: expected finite numbers")
    if v.size == 16:
        T = v.reshape(4, 4)
        if not np.allclose(T[3], [0, 0, 0, 1]) or not np.allclose(
            T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5
        ):
            raise DataError(f"extrinsic {values}: the 4x4 matrix is not a rigid transform")
        return T
    if v.size == 3:
        return make_T(np.eye(3), v)
    if v.size != 7:
        raise DataError(
            f"extrinsic {values}: expected 7 numbers 'x y z qx qy qz qw', 3 (translation only) "
            f"or 16 (row-major 4x4), got {v.size}"
        )
    q = v[3:]
    if not np.isclose(np.linalg.norm(q), 1.0, atol=1e-3):
        raise DataError(f"extrinsic {values}: quaternion (qx qy qz qw) is not unit length")
    from scipy.spatial.transform import Rotation

    return make_T(Rotation.from_quat(q / np.linalg.norm(q)).as_matrix(), v[:3])


#: the columns of the Snail-Radar reference trajectories in CSV form (``ref_tls_T_xt32.csv``,
#: the header the dataset authors' TLS localisation writes): the XT32 lidar's pose in the map
#: (position M_p_L, quaternion M_q_L x y z w) and its velocity in the world frame W_v_L
REF_CSV_COLUMNS = ("time", "M_p_L_x", "M_p_L_y", "M_p_L_z", "M_q_L_x", "M_q_L_y", "M_q_L_z",
                   "M_q_L_w", "W_v_L_x", "W_v_L_y", "W_v_L_z")


def _csv_header(line: str) -> list[str]:
    """Column names of a header line, separated by commas and / or spaces."""
    return [c for c in re.split(r"[,\s]+", line.lstrip("#").strip()) if c]


def read_ref_csv(path: str | Path) -> Trajectory:
    """A reference trajectory in the comma-separated form ``ref_tls_T_xt32.csv``: one ``#``
    header line naming the columns ``REF_CSV_COLUMNS`` (11: time, position, quaternion x y z w,
    world velocity; a file without the velocity columns, 8, is read too), then one row per
    pose. The header's first 8 names must be those (by name: a file of other columns is
    refused); the velocity columns are not used. Stamps in seconds (nanoseconds, detected
    from the magnitude, are converted)."""
    path = Path(path)
    check_file_size(path, str(path))
    rows: list[list[float]] = []
    linenos: list[int] = []
    header: list[str] | None = None
    with open(path, errors="replace") as f:
        for lineno, line in enumerate(f, start=1):
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                if header is None and not rows:
                    header = _csv_header(text)
                continue
            parts = [p.strip() for p in text.split(",")]
            try:
                values = [float(v) for v in parts]
            except ValueError:
                if header is None and not rows:  # an uncommented header line
                    header = _csv_header(text)
                    continue
                raise DataError(f"{path}, line {lineno}: expected comma-separated numbers "
                                f"({', '.join(REF_CSV_COLUMNS)}), got {text[:80]!r}") from None
            if len(values) not in (8, 11) or (rows and len(values) != len(rows[0])):
                raise DataError(f"{path}, line {lineno}: {len(values)} values; expected 11 "
                                f"({', '.join(REF_CSV_COLUMNS)}) or the first 8")
            rows.append(values)
            linenos.append(lineno)
    if header is not None and [h.lower() for h in header[:8]] != [
            c.lower() for c in REF_CSV_COLUMNS[:8]]:
        raise DataError(f"{path}: header columns {', '.join(header[:11])}; expected "
                        f"{', '.join(REF_CSV_COLUMNS)} (the Snail-Radar reference trajectory)")
    if not rows:
        raise DataError(f"{path}: no pose rows; expected lines of "
                        f"{', '.join(REF_CSV_COLUMNS)}")
    data = np.array(rows)
    quat = check_quaternions(data[:, 4:8], path, linenos, finite=data[:, :8])
    stamps = data[:, 0] * (1e-9 if np.median(np.abs(data[:, 0])) > 1e17 else 1.0)
    return Trajectory(stamps, T_from_tum(data[:, 1:4], quat))


def is_ref_csv(path: str | Path) -> bool:
    """The file is a reference trajectory in CSV form: its header names ``M_p_L_x``, or its
    first row has 11 comma-separated values."""
    check_file_size(Path(path), str(path))
    with open(path, errors="replace") as f:
        for line in f:
            text = line.strip()
            if not text:
                continue
            if "M_p_L_x" in text:
                return True
            if text.startswith("#"):
                continue
            return text.count(",") == len(REF_CSV_COLUMNS) - 1
    return False


def first_numeric_width(path: str | Path) -> int | None:
    """How many values the first all-numeric row of a pose file holds (commas read as spaces,
    ``#`` comments and other rows passed over); None without such a row."""
    with open(path, errors="replace") as f:
        for line in f:
            parts = line.replace(",", " ").split()
            if not parts or parts[0].startswith("#"):
                continue
            try:
                [float(p) for p in parts]
            except ValueError:
                continue
            return len(parts)
    return None


def detect_pose_format(path: str | Path) -> str:
    """"ref-csv" for a reference trajectory in CSV form (``is_ref_csv``), "kitti" when the first
    numeric row has 12 values, else "tum"."""
    if is_ref_csv(path):  # (checks the file's size against the per-file limit first)
        return "ref-csv"
    return "kitti" if first_numeric_width(path) == 12 else "tum"


def read_gt_file(path: str | Path, fmt: str = "auto", stamps: np.ndarray | None = None
                 ) -> Trajectory:
    """Read a TUM (8 columns), KITTI (12 columns) or reference-CSV (``read_ref_csv``) pose
    file; ``fmt`` "auto" decides (``detect_pose_format``). KITTI rows get ``stamps`` (default:
    the row index)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: ground-truth file not found")
    if fmt == "auto":
        fmt = detect_pose_format(path)
    elif fmt == "tum" and is_ref_csv(path):  # the reference CSV is T_world_frame rows too
        fmt = "ref-csv"
    if fmt == "tum":
        return read_tum(path)
    if fmt == "kitti":
        return read_kitti(path, stamps)
    if fmt == "ref-csv":
        return read_ref_csv(path)
    raise DataError(f"{path}: unknown ground-truth format {fmt!r} (expected tum, kitti or "
                    "ref-csv)")
