"""The HDF5 store: one file per sequence, read frame by frame.

Layout (format ``doppler-bench-store``, version 1)::

    /                      attrs: format, format_version, name, sensor_kind, sensor_model,
                                  doppler_kind (radial | ego-compensated | gt-reconstructed;
                                  absent in older stores = radial),
                                  period_s, n_frames, n_points, fields (JSON list),
                                  provenance (JSON object)
    /frames/stamp          (F,)    float64  scan stamps [s, sensor clock]
    /frames/offset         (F+1,)  int64    frame i owns points [offset[i], offset[i+1])
    /points/xyz            (P, 3)  float32  sensor frame [m]; chunked, shuffle + lzf
    /points/doppler        (P,)    float32  [m/s, positive = receding]; absent without Doppler
    /points/<field>        (P,)    float32  optional per-point arrays (power, rcs, snr,
                                            intensity, time_offset_s, ...)
    /extrinsic/T_body_sensor (4, 4) float64
    /ground_truth/stamps   (G,)    float64  [s]                (absent without ground truth)
    /ground_truth/poses    (G, 4, 4) float64  T_world_sensor

Per-point values are stored as float32: a round trip is exact at that precision. Writing goes
to a temporary file renamed at the end, and dataset timestamps are off, so the same sequence
always gives a byte-identical file.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np

from loaders.errors import DataError
from loaders.fileio import atomic_path
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

FORMAT_NAME = "doppler-bench-store"
FORMAT_VERSION = 1
CHUNK_POINTS = 32768
_FLUSH_POINTS = 1 << 18
_DS = dict(compression="lzf", shuffle=True, track_times=False)
#: filters by name: lzf (fast, the default) or gzip (level 9: about 15 % smaller, for files kept
#: in the repository such as the vendored real sample)
COMPRESSION = {"lzf": _DS, "gzip": dict(_DS, compression="gzip", compression_opts=9)}


class _Writer:
    """Appends scans to resizable datasets, buffering small frames into large blocks."""

    def __init__(self, h5: h5py.File, has_doppler: bool, fields: list[str],
                 compression: str = "lzf") -> None:
        self.h5 = h5
        filters = COMPRESSION[compression]
        self.has_doppler = has_doppler
        self.fields = fields
        pts = h5.create_group("points")
        self.ds = {"xyz": pts.create_dataset(
            "xyz", shape=(0, 3), maxshape=(None, 3), dtype="f4", chunks=(CHUNK_POINTS, 3),
            **filters)}
        names = (["doppler"] if has_doppler else []) + fields
        for name in names:
            self.ds[name] = pts.create_dataset(
                name, shape=(0,), maxshape=(None,), dtype="f4", chunks=(CHUNK_POINTS,), **filters
            )
        self.buffer: dict[str, list[np.ndarray]] = {k: [] for k in self.ds}
        self.buffered = 0
        self.stamps: list[float] = []
        self.offsets = [0]

    def append(self, scan: Scan, index: int, source: str) -> None:
        if len(scan) == 0:
            raise DataError(f"{source}, frame {index}: empty scan (0 points); expected at least "
                            "one point")
        if scan.has_doppler != self.has_doppler:
            raise DataError(
                f"{source}, frame {index}: Doppler is "
                f"{'present' if scan.has_doppler else 'missing'} but was "
                f"{'present' if self.has_doppler else 'missing'} in frame 0"
            )
        if sorted(scan.fields) != sorted(self.fields):
            raise DataError(
                f"{source}, frame {index}: per-point fields {sorted(scan.fields)} differ from "
                f"frame 0's {sorted(self.fields)}"
            )
        self.buffer["xyz"].append(scan.points.astype(np.float32))
        if self.has_doppler:
            self.buffer["doppler"].append(scan.doppler.astype(np.float32))
        for name in self.fields:
            self.buffer[name].append(np.asarray(scan.fields[name], dtype=np.float32))
        self.buffered += len(scan)
        self.stamps.append(scan.stamp)
        self.offsets.append(self.offsets[-1] + len(scan))
        if self.buffered >= _FLUSH_POINTS:
            self.flush()

    def flush(self) -> None:
        if not self.buffered:
            return
        for name, ds in self.ds.items():
            block = np.concatenate(self.buffer[name])
            start = ds.shape[0]
            ds.resize(start + len(block), axis=0)
            ds[start:] = block
            self.buffer[name] = []
        self.buffered = 0


def write_store(
    sequence: Sequence,
    path: str | Path,
    progress: Callable[[int], None] | None = None,
    compression: str = "lzf",
) -> Path:
    """Write ``sequence`` to ``path`` (streaming, atomic). ``progress(i)`` is called per frame;
    ``compression``: a key of ``COMPRESSION`` (the reader does not care which)."""
    if compression not in COMPRESSION:
        raise DataError(f"unknown store compression {compression!r}; choose from "
                        f"{', '.join(COMPRESSION)}")
    path = Path(path)
    source = getattr(sequence, "name", str(path))
    scans = iter(sequence)
    try:
        first = next(scans)
    except StopIteration:
        raise DataError(f"{source}: the sequence has no frames; nothing to store") from None
    with atomic_path(path) as tmp:
        with h5py.File(tmp, "w", libver="earliest") as h5:
            writer = _Writer(h5, first.has_doppler, sorted(first.fields), compression)
            writer.append(first, 0, source)
            if progress:
                progress(0)
            for i, scan in enumerate(scans, start=1):
                writer.append(scan, i, source)
                if progress:
                    progress(i)
            writer.flush()
            frames = h5.create_group("frames")
            for key, values, dtype in (("stamp", writer.stamps, "f8"),
                                       ("offset", writer.offsets, "i8")):
                frames.create_dataset(key, data=np.asarray(values, dtype), track_times=False)
            ext = h5.create_group("extrinsic")
            ext.create_dataset("T_body_sensor", data=sequence.sensor.T_body_sensor,
                               track_times=False)
            gt = sequence.ground_truth
            if gt is not None:
                g = h5.create_group("ground_truth")
                g.create_dataset("stamps", data=gt.stamps, track_times=False)
                g.create_dataset("poses", data=gt.poses, track_times=False)
            h5.attrs.update({
                "format": FORMAT_NAME,
                "format_version": FORMAT_VERSION,
                "name": sequence.name,
                "sensor_kind": sequence.sensor.kind,
                "sensor_model": sequence.sensor.model,
                "doppler_kind": sequence.sensor.doppler_kind,
                "period_s": float(sequence.sensor.period_s),
                "n_frames": len(writer.stamps),
                "n_points": int(writer.offsets[-1]),
                "fields": json.dumps(writer.fields),
                "provenance": json.dumps(sequence.provenance, sort_keys=True, default=str),
            })
    return path


class StoreSequence(Sequence):
    """A sequence read from a store, one frame at a time (the file opens lazily, so instances
    can be sent to worker processes)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        if not self.path.exists():
            raise DataError(f"{self.path}: store not found")
        if not h5py.is_hdf5(self.path):
            raise DataError(f"{self.path}: not an HDF5 file (truncated, or not a store)")
        self._h5: h5py.File | None = None
        try:
            h5 = self._file()
            attrs = dict(h5.attrs)
            if attrs.get("format") != FORMAT_NAME:
                raise DataError(
                    f"{self.path}: not a {FORMAT_NAME} file (format attribute "
                    f"{attrs.get('format')!r}); convert data with `bench convert`"
                )
            version = int(attrs["format_version"])
            if version > FORMAT_VERSION:
                raise DataError(
                    f"{self.path}: store format version {version} is newer than this "
                    f"package's {FORMAT_VERSION}; upgrade doppler-bench"
                )
            self._stamps = h5["frames/stamp"][:]
            self._offsets = h5["frames/offset"][:]
            n_points = h5["points/xyz"].shape[0]
            self.fields: list[str] = json.loads(attrs["fields"])
            self.has_doppler = "points/doppler" in h5
            self.name = str(attrs["name"])
            self.sensor = SensorInfo(
                kind=str(attrs["sensor_kind"]),
                period_s=float(attrs["period_s"]),
                T_body_sensor=h5["extrinsic/T_body_sensor"][:],
                model=str(attrs.get("sensor_model", "")),
                doppler_kind=str(attrs.get("doppler_kind", "radial")),
            )
            self.ground_truth = (
                Trajectory(h5["ground_truth/stamps"][:], h5["ground_truth/poses"][:])
                if "ground_truth" in h5 else None
            )
            self.provenance = json.loads(attrs.get("provenance", "{}"))
        except DataError:
            self.close()
            raise
        except (OSError, KeyError, ValueError) as err:
            self.close()
            raise DataError(f"{self.path}: damaged or truncated store ({err})") from err
        for name in (["doppler"] if self.has_doppler else []) + self.fields:
            rows = h5[f"points/{name}"].shape[0] if f"points/{name}" in h5 else None
            if rows != n_points:
                self.close()
                raise DataError(
                    f"{self.path}: damaged store: points/{name} has "
                    f"{'no dataset' if rows is None else f'{rows} rows'}, points/xyz has "
                    f"{n_points}; expected one value per point"
                )
        if (len(self._offsets) != len(self._stamps) + 1 or self._offsets[-1] != n_points
                or int(attrs["n_frames"]) != len(self._stamps)):
            self.close()
            raise DataError(
                f"{self.path}: truncated store: {len(self._stamps)} stamps, "
                f"{len(self._offsets)} offsets, {n_points} points, header says "
                f"{int(attrs['n_frames'])} frames"
            )

    def _file(self) -> h5py.File:
        if self._h5 is None:
            # a 16 MiB chunk cache keeps the current compressed block while frames stream out
            self._h5 = h5py.File(self.path, "r", rdcc_nbytes=16 << 20)
        return self._h5

    def close(self) -> None:
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_h5"] = None
        return state

    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def stamps(self) -> np.ndarray:
        return self._stamps.copy()

    def points_per_frame(self) -> np.ndarray:
        return np.diff(self._offsets)

    def scan(self, index: int) -> Scan:
        lo, hi = int(self._offsets[index]), int(self._offsets[index + 1])
        if hi <= lo:
            raise DataError(f"{self.path}, frame {index}: empty scan ({hi - lo} points); "
                            "expected at least one point")
        h5 = self._file()
        try:
            pts = h5["points"]
            return Scan(
                stamp=self._stamps[index],
                points=pts["xyz"][lo:hi],
                doppler=pts["doppler"][lo:hi] if self.has_doppler else None,
                fields={name: pts[name][lo:hi] for name in self.fields},
                source=f"{self.path}, frame {index}",
            )
        except OSError as err:
            raise DataError(f"{self.path}, frame {index}: cannot read points ({err})") from err
