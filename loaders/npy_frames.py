"""NumPy frame folders (the reference code's example format).

Layout: ``frame_001.npy`` (N, 3) points [m, sensor frame] and ``frame_001_dop.npy`` (N,) Doppler
[m/s, positive = receding], either in DIR or in DIR/frames, plus an optional TUM file with one
row per frame. Such TUM stamps are often not the sensor clock (the NTU4DRadLM sample has
0.0, 0.1, 0.2, ... for a 12 Hz radar): pass ``period_s`` to stamp scans as index x period, and
ground truth is then associated with frames by row order when the counts match (or by time,
interpolated at the frame stamps: frames outside its span are kept and excluded from scoring).

What the folder is: the sequence is named after DIR (after DIR's parent when DIR is a
``frames`` folder, whose name says nothing of the drive); the file numbers are the frames of
the source drive (a folder of ``frame_060.npy`` ... ``frame_249.npy`` records frames 60-249,
``frame_range`` in the provenance, so a cut is labelled by where it lies in the drive, "frame
files 60-249" since a folder may number from 0 or 1; numbers from 0 or 1 are the whole drive);
and
the sensor's class is set by ``model`` (e.g. ``radar-semidense`` for the Oculii Eagle, the class
the same drive gets from its own loader), else the generic "4D Radar" / "Dense 4D LiDAR".
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field

from loaders.assemble import finish_scan
from loaders.errors import DataError
from loaders.limits import check_file_size, check_frame_bytes
from loaders.options import LoaderOptions, OpensFromOptions
from loaders.posefile import read_tum
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

_FRAME = re.compile(r"^frame_(\d+)\.npy$")


def find_frames(folder: Path) -> tuple[Path, list[Path]]:
    """The folder holding ``frame_XXX.npy`` files (DIR or DIR/frames) and the files in order."""
    for candidate in (folder, folder / "frames"):
        files = [p for p in candidate.glob("frame_*.npy") if _FRAME.match(p.name)]
        if files:
            return candidate, sorted(files, key=lambda p: int(_FRAME.match(p.name).group(1)))
    raise DataError(f"{folder}: no frame_XXX.npy files (looked in {folder} and {folder}/frames)")


def find_tum(folder: Path) -> Path | None:
    """The single TUM-like .txt file in ``folder`` (None when there is none); several: a
    DataError naming them and asking for ``--gt`` (never "no ground truth found")."""
    candidates = sorted(folder.glob("*.txt"))
    if len(candidates) > 1:
        raise DataError(f"{folder}: {len(candidates)} .txt files beside the frames "
                        f"({', '.join(p.name for p in candidates)}); name the ground truth "
                        "with --gt FILE (option gt)")
    return candidates[0] if candidates else None


class Options(LoaderOptions):
    """``bench convert npy-frames`` / a dataset config's ``options``."""

    gt: Path | None = Field(None, description="TUM ground truth (default: the one .txt in "
                            "FOLDER)")
    period_s: float | None = Field(None, gt=0, description="scan period [s]: stamps = index x "
                                   "period")
    kind: Literal["radar", "lidar"] = Field("radar", description="radar or lidar")
    model: str = Field("", description="sensor model, which sets the sensor class: "
                       "radar-sparse, radar-semidense (e.g. the Oculii Eagle), lidar-dense or "
                       "lidar-fmcw, a device name may follow in parentheses (default: none, "
                       "class '4D Radar' or 'Dense 4D LiDAR' by --kind)")
    associate: Literal["order", "time"] = Field("order", description="GT association: order "
                                                "(one row per frame) or time")
    stamps_from_gt: bool = Field(False, description="stamp the frames with the TUM file's "
                                 "stamps (only when they are the sensor clock; else give "
                                 "--period)")


class NpyFramesSequence(OpensFromOptions, Sequence):
    """A folder of .npy frames read lazily, one frame at a time."""

    Options = Options
    inputs = "folder with frame_XXX.npy (or its frames/)"

    @classmethod
    def open(cls, paths: list[Path], options: Options) -> NpyFramesSequence:
        o = options
        return cls(paths[0], gt=o.gt, period_s=o.period_s, kind=o.kind, name=o.name,
                   associate=o.associate, stamps_from_gt=o.stamps_from_gt, model=o.model)

    def __init__(
        self,
        folder: str | Path,
        gt: str | Path | None = None,
        period_s: float | None = None,
        kind: str = "radar",
        name: str | None = None,
        associate: str = "order",
        stamps_from_gt: bool = False,
        model: str = "",
    ) -> None:
        folder = Path(folder)
        if not folder.is_dir():
            raise DataError(f"{folder}: not a folder")
        self.frame_dir, self.files = find_frames(folder)
        for f in self.files:
            if not f.with_name(f.stem + "_dop.npy").exists():
                raise DataError(
                    f"{f}: missing Doppler file {f.stem}_dop.npy (expected one per frame)"
                )
        gt_path = Path(gt) if gt is not None else find_tum(folder)
        trajectory = read_tum(gt_path) if gt_path is not None else None
        n = len(self.files)
        if period_s is not None and stamps_from_gt:
            raise DataError(f"{folder}: give either the scan period or stamps from the GT "
                            "file, not both")
        if period_s is not None:
            self._stamps = np.arange(n) * float(period_s)
        elif not stamps_from_gt:
            # the reference format's TUM stamps are often not the sensor clock (NTU4DRadLM's
            # sample: 0.1 s steps for a 12 Hz radar): taking them silently skews every speed
            raise DataError(
                f"{folder}: give the scan period (--period SECONDS, e.g. 0.0833333 for a 12 Hz "
                "radar), or --stamps-from-gt when the TUM file's stamps are the sensor clock")
        elif trajectory is not None and len(trajectory) == n:
            self._stamps = trajectory.stamps.copy()
            back = np.flatnonzero(np.diff(self._stamps) <= 0)
            if len(back):
                raise DataError(
                    f"{gt_path}, pose row {int(back[0]) + 1}: stamps must increase to stamp the "
                    f"frames ({len(back)} rows repeat or go backwards); give --period instead"
                )
            period_s = float(np.median(np.diff(self._stamps))) if n > 1 else 0.1
        else:
            raise DataError(f"{folder}: stamps from the GT file need one TUM row per frame "
                            f"({n} frames, {0 if trajectory is None else len(trajectory)} rows); "
                            "give the scan period (--period SECONDS) instead")
        self.ground_truth = None
        self.repeated_gt_poses = 0
        if trajectory is not None:
            self.ground_truth = self._associate(trajectory, gt_path, associate)
        resolved = folder.resolve()
        self.name = name or (resolved.parent.name if resolved.name == "frames" else folder.name)
        self.sensor = SensorInfo(kind=kind, period_s=float(period_s),
                                 model=model or "npy-frames")
        self.provenance = {
            "loader": "npy-frames", "folder": str(resolved), "frames": n,
            "gt": str(gt_path) if gt_path else None, "period_s": float(period_s),
            "gt_association": associate, "repeated_gt_poses": self.repeated_gt_poses,
        }
        numbers = np.array([int(_FRAME.match(f.name).group(1)) for f in self.files])
        steps = np.diff(numbers)
        if n and (n == 1 or (steps[0] > 0 and (steps == steps[0]).all())) and numbers[0] > 1:
            # the files are frames numbers[0], +step, ... of their drive: recorded, so a cut
            # folder is labelled by where it lies (one numbered from 0 or 1 is the whole drive)
            self.provenance["frame_range"] = {"start": int(numbers[0]), "frames": n,
                                              "stride": int(steps[0]) if n > 1 else 1,
                                              "from": "file numbers"}

    def _associate(self, traj: Trajectory, path: Path, associate: str) -> Trajectory:
        n = len(self.files)
        if associate == "order":
            back = np.flatnonzero(np.diff(traj.stamps) < 0)
            if len(back):  # rows out of time order: the poses would be given to wrong frames
                i = int(back[0]) + 1
                raise DataError(
                    f"{path}, pose row {i}: stamp {traj.stamps[i]:.6f} s goes backwards from "
                    f"{traj.stamps[i - 1]:.6f} s ({len(back)} such rows); association by order "
                    "needs the rows in time order (a garbled or concatenated file?)")
            if len(traj) != n:
                raise DataError(
                    f"{path}: {len(traj)} GT rows but {n} frames in {self.frame_dir}; "
                    "association by order needs one row per frame (use associate='time')"
                )
            # the largest change of any pose entry per step (none for a single frame)
            steps = np.abs(np.diff(traj.poses[:, :3, :], axis=0)).max(axis=(1, 2))
            self.repeated_gt_poses = int((steps == 0).sum())
            if self.repeated_gt_poses:
                warnings.warn(
                    f"{path}: {self.repeated_gt_poses} GT rows repeat the previous pose "
                    "exactly; frame-to-frame errors are meaningless, evaluate over metres",
                    stacklevel=3,
                )
            return traj.with_stamps(self._stamps)
        if associate == "time":
            # every frame stays; frames the GT does not cover are only excluded from scoring
            from loaders.gt import associate as associate_gt

            steps = np.diff(traj.stamps)
            steps = steps[steps > 0]
            max_gap = 3 * float(np.median(steps)) if len(steps) else None
            assoc = associate_gt(traj, self._stamps, max_gap_s=max_gap, gt_file=path,
                                 scan_file=self.frame_dir)
            self.gt_report = assoc.report
            return assoc.ground_truth
        raise DataError(f"unknown GT association {associate!r} (expected 'order' or 'time')")

    def __len__(self) -> int:
        return len(self.files)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def scan(self, index: int) -> Scan:
        path = self.files[index]
        source = f"{path}, frame {index}"
        try:
            points = _load_bounded(path, source)
            doppler = _load_bounded(path.with_name(path.stem + "_dop.npy"), source)
        except (OSError, ValueError) as err:
            if isinstance(err, DataError):
                raise
            raise DataError(f"{source}: cannot read the frame ({err})") from err
        if points.ndim != 2 or points.shape[1] != 3 or doppler.shape != (len(points),):
            raise DataError(f"{source}: expected points (N, 3) and Doppler (N,), got "
                            f"{points.shape} and {doppler.shape}")
        return finish_scan(self._stamps[index], points, doppler, {}, source)


def _load_bounded(path: Path, source: str) -> np.ndarray:
    """An .npy array, its size (file, then the header's shape) checked against the per-frame
    limit before it is read (memory-mapped first: a header may promise more than the file)."""
    check_file_size(path, source)
    arr = np.load(path, mmap_mode="r")
    check_frame_bytes(int(arr.nbytes), source, f"{path.name} ({arr.shape} {arr.dtype})")
    return np.array(arr)
