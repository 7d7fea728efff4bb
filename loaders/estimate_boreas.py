"""The Boreas odometry benchmark's submission format, read as an estimate (``bench score``).

The format (pyboreas ``eval/odometry.md``, "File format"): one whitespace-separated row of 13
values per frame k; the first is the frame's stamp, a 64-bit integer in MICROSECONDS; the other
12 are the upper 3x4 block, row-major, of ``T_k_i``: the transform that maps a point of the
stationary frame i into the k-th robot frame (``p_k = T_k_i p_i``). A pose in this harness's
sense (``T_world_frame``, the frame in the world) is its inverse: ``T_i_k = inv(T_k_i)``, with
the stationary frame i as the world. The robot frame k is the applanix frame for the 3D
benchmark and the radar for the 2D one: give ``--pose-frame`` / ``--extrinsic`` accordingly.

Stamps are returned in microseconds as read (``loaders.estimate`` converts to seconds). A row
whose stamp is not a whole number, whose 3x3 block is no rotation (off orthonormal by more than
``loaders.posefile.ORTHONORMAL_TOLERANCE``: sheared, scaled, mirrored) or that is not 13
finite numbers is one ``DataError`` naming the file and line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from loaders.errors import DataError
from loaders.posefile import nearest_rotations, numeric_rows
from loaders.se3 import inv_T, make_T
from loaders.trajectory import Trajectory


def read_boreas(path: Path) -> tuple[Trajectory, list[int]]:
    """The poses ``T_i_k`` (inverses of the file's ``T_k_i``) at the file's stamps [us], and
    the line number of each row (``loaders.estimate`` checks that the stamps increase)."""
    path = Path(path)
    data, lines = numeric_rows(path, (13,), "13 values: stamp [us] and the 3x4 T_k_i row-major")
    stamps = data[:, 0]
    frac = np.flatnonzero(stamps != np.round(stamps))
    if len(frac):
        r = int(frac[0])
        raise DataError(f"{path}, line {lines[r]}: stamp {stamps[r]!r} is not a whole number; "
                        "expected a Boreas row: an integer stamp [us] then 12 values")
    M = data[:, 1:].reshape(-1, 3, 4)
    T_k_i = make_T(nearest_rotations(M[:, :, :3], str(path), lines, "3x3 block of T_k_i"),
                   M[:, :, 3])
    return Trajectory(stamps, inv_T(T_k_i)), lines
