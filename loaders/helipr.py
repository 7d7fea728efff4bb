"""HeLiPR / HeRCULES: the Aeva Aeries II FMCW LiDAR's scans of one sequence folder.

Format facts (minwoo0611/HeLiPR-File-Player ``src/ROSThread.cpp`` ``AevaThread``; PRBonn/kiss-icp
``python/kiss_icp/datasets/helipr.py``; minwoo0611/HeLiPR-Pointcloud-Toolbox
``python/transformINStoLiDAR.py``):

- Scans ``LiDAR/Aeva/<t_ns>.bin``, the file name the scan stamp [ns]. Packed little-endian
  records, read field by field: ``x, y, z, reflectivity, velocity`` (float32),
  ``time_offset_ns`` (int32), ``line_index`` (uint8), and ``intensity`` (float32) only in files
  whose stamp is after 1691936557946849179 (``if(data > 1691936557946849179)``): 25 or 29 bytes
  a point, no header.
- Ground truth ``LiDAR_GT/Aeva_gt.txt`` or ``LiDAR_GT/global_Aeva_gt.txt`` (kiss-icp reads the
  latter; both names are in use): ``t_ns x y z qx qy qz qw`` a line, the pose of the Aeva frame
  itself (the toolbox writes each LiDAR's GT by applying INS -> LiDAR extrinsics, so no
  extrinsic is applied here; option ``extrinsic`` to apply one). Ground truth at its own rate is
  interpolated at the scan stamps (``loaders.gt.associate``).
- Per-point times: ``time_offset_ns`` -> the ``time_offset_s`` field (relative to the stamp).
- **The released velocities are ego-motion compensated**: the maintainers state the Aeva was
  set to publish absolute velocities (HeLiPR-File-Player issue #4, "the velocities in the
  dataset is absolute velocities ... directly obtained by the sensor"; static points read about
  0 m/s while driving). They are stored as ``doppler_kind = "ego-compensated"``: a Doppler
  method cannot use them as radial velocity.
- Opt-in ``reconstruct_doppler_from_gt``: rebuild the raw radial velocity from the GT's ego
  motion, ``v_radial = v_compensated - d . v_sensor`` (receding positive; ``d`` the point's unit
  direction, ``v_sensor`` the sensor origin's velocity in its own frame at the point's time:
  central differences of the GT over one GT step each side at the scan stamp and one period
  later, interpolated linearly by ``time_offset_ns``; rotation adds nothing along ``d``). The
  store is then ``doppler_kind = "gt-reconstructed"``, and every result made from it is labelled
  GT-assisted: the Doppler carries the ground truth's motion. Scans outside the GT (or inside a
  GT gap) cannot be reconstructed: the ends are trimmed and a gap inside is a ``DataError``.
- Sign: Aeva's convention is receding positive (as in the Doppler-ICP release), the harness's.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import MAX_FAR_SHARE, MAX_POINT_RANGE_M, finish_scan, median_period
from loaders.errors import DataError
from loaders.gt import associate, clean_trajectory
from loaders.limits import check_file_size, file_number
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.posefile import parse_extrinsic, read_tum
from loaders.records import read_records, record_dtype
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

#: files with a stamp after this [ns] carry the intensity field (HeLiPR-File-Player ROSThread.cpp)
INTENSITY_AFTER_NS = 1691936557946849179
_BASE = [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("reflectivity", "<f4"), ("velocity", "<f4"),
         ("time_offset_ns", "<i4"), ("line_index", "u1")]
RECORD_25 = record_dtype(_BASE)
RECORD_29 = record_dtype([*_BASE, ("intensity", "<f4")])
GT_NAMES = ("Aeva_gt.txt", "global_Aeva_gt.txt")
NOMINAL_PERIOD_S = 0.1
_FRAME = re.compile(r"^(\d+)\.bin$")


class Options(LoaderOptions):
    """Options of the HeLiPR / HeRCULES Aeva loader."""

    gt: Path | None = Field(None, description=(
        "GT file 't_ns x y z qx qy qz qw' (default: LiDAR_GT/Aeva_gt.txt, else "
        "LiDAR_GT/global_Aeva_gt.txt)"))
    reconstruct_doppler_from_gt: bool = Field(False, description=(
        "rebuild raw radial velocity from the released ego-compensated one and the GT's ego "
        "motion (opt-in: every result made from it is labelled GT-assisted)"))
    intensity: Literal["auto", "yes", "no"] = Field("auto", description=(
        "records carry the trailing intensity float: auto (files stamped after "
        "1691936557946849179 ns, the devkit's rule), yes (29 bytes a point) or no (25)"))
    extrinsic: str | None = Field(None, description=(
        'Aeva -> GT frame "x y z qx qy qz qw" (default: identity, the GT is the Aeva frame)'))
    doppler_sign: float = Field(1.0, description="+1 (receding positive, Aeva's convention) "
                                "or -1")
    time_offset: float = Field(0.0, description="GT clock offset (s): gt_stamp + offset = "
                               "sensor clock")
    max_gap: float | None = Field(None, gt=0, description=(
        "largest GT gap interpolated across (s) (default: 3 median GT steps, at least 0.3 s)"))
    uncovered: Literal["keep", "trim", "error"] = Field("keep", description=(
        "scans without GT: keep (run, unscored), trim (cut the ends) or error"))


def _layout_name(has_intensity: bool) -> str:
    return (f"{29 if has_intensity else 25}-byte records ("
            f"{'with' if has_intensity else 'without'} intensity)")


def check_layouts(files: list[Path], with_intensity: np.ndarray) -> None:
    """Every file's size (``stat`` only, nothing read) within the per-frame limit and a whole
    number of its layout's records: one ``DataError`` naming the first file that is not."""
    for k, (path, has_i) in enumerate(zip(files, with_intensity, strict=True)):
        where = f"{path}, frame {k}"
        size = check_file_size(path, where)
        rec = 29 if has_i else 25
        if size == 0 or size % rec == 0:
            continue  # empty files are refused when read (naming the frame)
        other = 25 if has_i else 29
        hint = (f"; it is a whole number of {_layout_name(not has_i)}: the sequence mixes the "
                "two layouts (set --intensity yes/no for the whole sequence, or remove the "
                "frame)" if size % other == 0 else "; the file is truncated or not this layout")
        raise DataError(f"{where}: {size} bytes is not a whole number of "
                        f"{_layout_name(bool(has_i))}, the layout of its stamp (intensity after "
                        f"{INTENSITY_AFTER_NS} ns){hint}")


def implausible_share(rec: np.ndarray) -> float:
    """Share of the records that cannot be Aeva points: a coordinate not finite or beyond
    ``MAX_POINT_RANGE_M``, or a per-point time offset beyond +-1 s (a scan lasts 0.1 s)."""
    xyz = np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)
    with np.errstate(invalid="ignore"):
        bad = ~(np.abs(xyz) <= MAX_POINT_RANGE_M).all(axis=1)
    bad |= np.abs(rec["time_offset_ns"].astype(np.int64)) > 1_000_000_000
    return float(bad.mean()) if len(rec) else 0.0


def find_aeva_dir(path: Path) -> tuple[Path, Path]:
    """(sequence root, folder of the Aeva .bin files) for a root or its LiDAR/Aeva folder."""
    path = Path(path)
    if (path / "LiDAR" / "Aeva").is_dir():
        return path, path / "LiDAR" / "Aeva"
    if path.name == "Aeva" and path.parent.name == "LiDAR" and path.is_dir():
        return path.parent.parent, path
    if not path.exists():
        raise DataError(f"{path}: not found; expected a HeLiPR/HeRCULES sequence folder with "
                        "LiDAR/Aeva/<t_ns>.bin and LiDAR_GT/Aeva_gt.txt")
    raise DataError(f"{path}: no LiDAR/Aeva folder; expected a HeLiPR/HeRCULES sequence folder "
                    "with LiDAR/Aeva/<t_ns>.bin and LiDAR_GT/Aeva_gt.txt (or global_Aeva_gt.txt)")


def read_gt(path: Path) -> Trajectory:
    """A HeLiPR GT file; stamps in ns (or s, detected from the magnitude) -> seconds."""
    traj = read_tum(path)
    scale = 1e-9 if np.median(np.abs(traj.stamps)) > 1e17 else 1.0
    return traj.with_stamps(traj.stamps * scale)


def sensor_velocity(gt: Trajectory, t: np.ndarray, h: float) -> np.ndarray:
    """Velocity of the sensor origin in its own frame at stamps ``t`` (N, 3): a central
    difference of the GT positions over ``t +- h``; near the ends of the GT the window moves
    inside its span (the velocity there is held)."""
    s0, s1 = gt.stamps[0], gt.stamps[-1]
    h = min(h, (s1 - s0) / 2)
    centre = np.clip(t, s0 + h, s1 - h)
    lo, hi = centre - h, centre + h
    p_lo = gt.interpolate(lo).positions
    p_hi = gt.interpolate(hi).positions
    R = gt.interpolate(centre).poses[:, :3, :3]
    v_world = (p_hi - p_lo) / (hi - lo)[:, None]
    return np.einsum("nji,nj->ni", R, v_world)


class HeliprSequence(OpensFromOptions, Sequence):
    """The Aeva scans of one HeLiPR / HeRCULES sequence with ``T_world_aeva`` ground truth."""

    Options = Options
    inputs = "HeLiPR/HeRCULES sequence folder (LiDAR/Aeva/<t_ns>.bin, LiDAR_GT/Aeva_gt.txt)"
    many_inputs = False

    def __init__(self, path: str | Path, options: Options | None = None, **kwargs) -> None:
        opts = options if options is not None else Options(**kwargs)
        if float(opts.doppler_sign) not in (1.0, -1.0):
            raise DataError(f"doppler_sign must be +1 or -1, got {opts.doppler_sign}")
        self.options = opts
        self.root, frame_dir = find_aeva_dir(Path(path))
        numbered = sorted((file_number(p.stem, p), p) for p in frame_dir.iterdir()
                          if _FRAME.match(p.name))
        if not numbered:
            raise DataError(f"{frame_dir}: no <t_ns>.bin Aeva scans")
        files = [p for _, p in numbered]
        self._files = files
        self._ns = np.array([n for n, _ in numbered], dtype=np.int64)
        stamps = self._ns.astype(np.float64) * 1e-9
        if np.any(np.diff(self._ns) == 0):
            raise DataError(f"{frame_dir}: two scans share a stamp")
        self._stamps_all = stamps
        if opts.intensity == "auto":
            with_intensity = self._ns > INTENSITY_AFTER_NS
        else:
            with_intensity = np.full(len(files), opts.intensity == "yes")
        self._with_intensity = with_intensity
        check_layouts(files, with_intensity)
        # a store keeps the same fields in every frame: intensity only when all frames have it
        self._keep_intensity = bool(with_intensity.all())
        T = parse_extrinsic(opts.extrinsic) if opts.extrinsic else np.eye(4)

        if opts.gt is not None:
            gt_path = Path(opts.gt)
        else:
            cands = [self.root / "LiDAR_GT" / name for name in GT_NAMES]
            gt_path = next((c for c in cands if c.exists()), None)
        if gt_path is None and opts.reconstruct_doppler_from_gt:
            raise DataError(f"{self.root}: reconstruct_doppler_from_gt needs the ground truth, "
                            f"but neither LiDAR_GT/{GT_NAMES[0]} nor LiDAR_GT/{GT_NAMES[1]} "
                            "exists (or give gt=FILE)")
        self.provenance: dict = {
            "loader": "helipr",
            "root": str(self.root),
            "frames_found": len(files),
            "stamp_source": f"{frame_dir}/<t_ns>.bin file names",
            "record_layout": (f"intensity {opts.intensity}: "
                              f"{int(with_intensity.sum())} files of 29 bytes a point, "
                              f"{int((~with_intensity).sum())} of 25"),
            "T_gt_sensor": T.tolist(),
            "calibration_source": ("option extrinsic" if opts.extrinsic else
                                   "identity: the GT file is the Aeva frame's pose"),
            "doppler_sign": float(opts.doppler_sign),
            "doppler_source": ("velocity field, ego-motion compensated by the sensor "
                               "(HeLiPR-File-Player issue #4)"),
            "nan_points_dropped": 0,
        }
        keep = np.arange(len(files))
        self.ground_truth = None
        self._v_sensor = None
        if gt_path is not None:
            if not gt_path.exists():
                raise DataError(f"{gt_path}: ground-truth file not found")
            gt_raw, _ = clean_trajectory(read_gt(gt_path), str(gt_path))
            steps = np.diff(gt_raw.stamps)
            step = float(np.median(steps)) if len(steps) else NOMINAL_PERIOD_S
            max_gap = opts.max_gap if opts.max_gap is not None else max(3.0 * step, 0.3)
            uncovered = "trim" if opts.reconstruct_doppler_from_gt else opts.uncovered
            assoc = associate(gt_raw, stamps, offset_s=opts.time_offset, max_gap_s=max_gap,
                              T_body_sensor=T, uncovered=uncovered, gt_file=gt_path,
                              scan_file=frame_dir)
            keep = assoc.keep
            self.ground_truth = assoc.ground_truth
            self.provenance["gt_association"] = assoc.report
            if opts.reconstruct_doppler_from_gt:
                if assoc.uncovered_inside:
                    bad = int(keep[np.flatnonzero(~assoc.covered)[0]])
                    raise DataError(
                        f"{files[bad]}, frame {bad}: inside a gap of {gt_path} longer than "
                        f"{max_gap} s ({assoc.uncovered_inside} scans): their radial velocity "
                        "cannot be reconstructed from the GT; cut the sequence before the gap")
                gt_sensor = Trajectory(gt_raw.stamps + opts.time_offset, gt_raw.poses @ T)
                h = max(step, 1e-3)
                self._v_period = median_period(stamps[keep], NOMINAL_PERIOD_S)
                # the sensor velocity at each scan's stamp and one period later: points take
                # it at their own time (a scan lasts a period; the car accelerates meanwhile)
                self._v_sensor = np.stack([
                    sensor_velocity(gt_sensor, stamps[keep], h),
                    sensor_velocity(gt_sensor, stamps[keep] + self._v_period, h)], axis=1)
                self.provenance["doppler_reconstruction"] = (
                    f"v_radial = v_compensated - d . v_sensor, v_sensor from {gt_path} (central "
                    f"difference over +-{step:.4f} s): GT-assisted")
        self._keep = keep
        self._stamps = stamps[keep]
        self.doppler_sign = float(opts.doppler_sign)
        self.name = opts.name or self.root.name
        kind = "gt-reconstructed" if opts.reconstruct_doppler_from_gt else "ego-compensated"
        self.sensor = SensorInfo("lidar", median_period(self._stamps, NOMINAL_PERIOD_S), T,
                                 "lidar-fmcw (Aeva Aeries II, HeLiPR)", doppler_kind=kind)

    def __len__(self) -> int:
        return len(self._keep)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        k = int(self._keep[index])
        path = self._files[k]
        where = f"{path}, frame {index}"
        has_i = bool(self._with_intensity[k])
        dtype, other = (RECORD_29, 25) if has_i else (RECORD_25, 29)
        layout = (f"HeLiPR Aeva {dtype.itemsize}-byte records "
                  f"({'with' if has_i else 'without'} intensity: stamp "
                  f"{'after' if has_i else 'at or before'} {INTENSITY_AFTER_NS} ns)")
        alt = {f"the {other}-byte layout ({'without' if has_i else 'with'} intensity)": other}
        rec = read_records(path, dtype, where, layout, alt)
        if implausible_share(rec) > MAX_FAR_SHARE:
            self._refuse_layout(path, where, has_i, rec)
        points = np.column_stack([rec["x"], rec["y"], rec["z"]]).astype(np.float64)
        doppler = self.doppler_sign * rec["velocity"].astype(np.float64)
        if self._v_sensor is not None:
            r = np.linalg.norm(points, axis=1)
            d = points / np.where(r > 0, r, 1.0)[:, None]
            v0, v1 = self._v_sensor[index]
            w = np.clip(rec["time_offset_ns"] * 1e-9 / self._v_period, 0.0, 1.0)[:, None]
            doppler = doppler - np.einsum("ij,ij->i", d, v0 + w * (v1 - v0))
        fields = {"reflectivity": rec["reflectivity"].copy(),
                  "time_offset_s": (rec["time_offset_ns"].astype(np.float64)
                                    * 1e-9).astype(np.float32),
                  "line_index": rec["line_index"].astype(np.float32)}
        if self._keep_intensity:
            fields["intensity"] = rec["intensity"].copy()
        return finish_scan(float(self._stamps_all[k]), points, doppler, fields, where,
                           self.provenance)

    @staticmethod
    def _refuse_layout(path: Path, where: str, has_i: bool, rec: np.ndarray) -> None:
        """The records decode to impossible points: say whether the other layout fits."""
        share = implausible_share(rec)
        other = RECORD_25 if has_i else RECORD_29
        size = path.stat().st_size
        hint = "; the file is corrupt or not an Aeva scan"
        if size % other.itemsize == 0:
            alt = np.fromfile(path, dtype=other, count=size // other.itemsize)
            if implausible_share(alt) <= MAX_FAR_SHARE:
                hint = (f"; read as {_layout_name(not has_i)} they are plausible: this frame has "
                        "the other layout than its stamp says (set --intensity yes/no for the "
                        "whole sequence, or remove the frame)")
        raise DataError(
            f"{where}: read as {_layout_name(has_i)} (the layout of its stamp), "
            f"{100 * share:.0f} % of the points are impossible (a coordinate beyond "
            f"{MAX_POINT_RANGE_M:,.0f} m or not finite, or a time offset beyond 1 s){hint}")
