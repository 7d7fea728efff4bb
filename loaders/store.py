"""The HDF5 store: one file per sequence, read frame by frame.

Layout (format ``doppler-bench-store``, version 2)::

    /                      attrs: format, format_version, name, sensor_kind, sensor_model,
                                  doppler_kind (radial | ego-compensated | gt-reconstructed;
                                  absent in older stores = radial),
                                  period_s, n_frames, n_points, fields (JSON list),
                                  provenance (JSON object)
    /frames/stamp          (F,)    float64  scan stamps [s, sensor clock]
    /frames/offset         (F+1,)  int64    frame i owns points [offset[i], offset[i+1])
    /points/xyz            (P, 3)  float32  sensor frame [m]
    /points/doppler        (P,)    float32  [m/s, positive = receding]; absent without Doppler
    /points/<field>        (P,)    float32  optional per-point arrays (power, rcs, snr,
                                            intensity, time_offset_s, ...)
    /extrinsic/T_body_sensor (4, 4) float64
    /ground_truth/stamps   (G,)    float64  [s]                (absent without ground truth)
    /ground_truth/poses    (G, 4, 4) float64  T_world_sensor

Per-point values are stored as float32: a round trip is exact at that precision. Writing goes
to a temporary file renamed at the end, and dataset timestamps are off, so the same sequence
always gives a byte-identical file.

Storage and reading (version 2; chosen so that reading a scan costs less than registering it):
every per-point array is chunked in ``CHUNK_POINTS`` (65,536) points; the arrays methods read
every frame (``INPUT_ARRAYS``: xyz, doppler, time_offset_s) are stored uncompressed (LZF takes
about 10x longer to decompress a radar scan than to read it raw and saves little on float
coordinates), the annotations (power, rcs, snr, synthetic labels, ...) shuffle + LZF: they
compress well and no method reads them. ``compression="gzip"`` (files kept in the repository)
or ``"lzf"`` compress every array. A reader asks for the per-point arrays it needs
(``StoreSequence(path, fields=...)``: a method's ``reads_fields``) and scans are served from
blocks of whole chunks (at least ``BLOCK_POINTS``) read with one call per array, instead of one
small slice per array per scan. Version 1 stores (every array shuffle + LZF or gzip in 32,768-
point chunks) read the same way and give the same values, at the cost of decompressing them.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path

import h5py
import numpy as np

from loaders.errors import DataError
from loaders.fileio import atomic_path, create_hdf5
from loaders.scan import Scan, SensorInfo, Sequence
from loaders.trajectory import Trajectory

FORMAT_NAME = "doppler-bench-store"
FORMAT_VERSION = 2
#: points per chunk of every per-point array (version 1: 32,768)
CHUNK_POINTS = 65536
#: scans are read in blocks of whole chunks of at least this many points (one read per array)
BLOCK_POINTS = 1 << 18
_FLUSH_POINTS = 1 << 18
#: the per-point arrays methods read every frame: stored uncompressed by default
INPUT_ARRAYS = frozenset({"xyz", "doppler", "time_offset_s"})
_RAW = dict(track_times=False)
_LZF = dict(compression="lzf", shuffle=True, track_times=False)
_GZIP = dict(_LZF, compression="gzip", compression_opts=9)
#: filters by name, as (inputs, annotations): "fast" (the default: inputs raw, annotations
#: LZF), "lzf" (every array) or "gzip" (level 9, every array: the smallest files, for files
#: kept in the repository such as the vendored real sample)
COMPRESSION = {"fast": (_RAW, _LZF), "lzf": (_LZF, _LZF), "gzip": (_GZIP, _GZIP)}


class _Writer:
    """Appends scans to resizable datasets, buffering small frames into large blocks."""

    def __init__(self, h5: h5py.File, has_doppler: bool, fields: list[str],
                 compression: str = "fast") -> None:
        self.h5 = h5
        inputs, annotations = COMPRESSION[compression]
        self.has_doppler = has_doppler
        self.fields = fields
        pts = h5.create_group("points")
        self.ds = {"xyz": pts.create_dataset(
            "xyz", shape=(0, 3), maxshape=(None, 3), dtype="f4", chunks=(CHUNK_POINTS, 3),
            **inputs)}
        names = (["doppler"] if has_doppler else []) + fields
        for name in names:
            self.ds[name] = pts.create_dataset(
                name, shape=(0,), maxshape=(None,), dtype="f4", chunks=(CHUNK_POINTS,),
                **(inputs if name in INPUT_ARRAYS else annotations))
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


def store_has_ground_truth(path: str | Path) -> bool | None:
    """Whether the store at ``path`` holds ground truth (None when it cannot be read as a
    store: the caller's own reading reports that)."""
    try:
        with h5py.File(path, "r") as h5:
            return "ground_truth" in h5
    except (OSError, ValueError):
        return None


def write_store(
    sequence: Sequence,
    path: str | Path,
    progress: Callable[[int], None] | None = None,
    compression: str = "fast",
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
        with create_hdf5(tmp, libver="earliest") as h5:
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


class _Block:
    """Consecutive points [lo, hi) of the arrays being read, read together."""

    __slots__ = ("lo", "hi", "arrays")

    def __init__(self, lo: int, hi: int, arrays: dict[str, np.ndarray]) -> None:
        self.lo, self.hi, self.arrays = lo, hi, arrays


def _check_header(seq) -> None:
    """The values a store's attributes and ground truth must hold (a DataError naming what is
    wrong): the fields a list of names, a name that is not empty (a label: the harness makes
    any name one results folder), a provenance mapping, ground-truth poses that are finite
    rigid transforms at finite stamps."""
    path = seq.path
    if not (isinstance(seq.fields, list) and all(isinstance(f, str) for f in seq.fields)):
        raise DataError(f"{path}: damaged store: attribute fields is {seq.fields!r}; expected "
                        "a list of field names")
    name = seq.name  # a label: separators and dots are made one folder by the harness
    if not name.strip() or "\0" in name:
        raise DataError(f"{path}: damaged store: attribute name {name!r} is empty or holds a "
                        "NUL byte; expected the sequence's name")
    if not isinstance(seq.provenance, dict):
        raise DataError(f"{path}: damaged store: attribute provenance is not a mapping")
    if not np.isfinite(seq._stamps).all():
        k = int(np.flatnonzero(~np.isfinite(seq._stamps))[0])
        raise DataError(f"{path}: damaged store: frame {k}'s stamp is {seq._stamps[k]}; "
                        "expected finite stamps [s]")
    gt = seq.ground_truth
    if gt is not None and len(gt):
        R = gt.poses[:, :3, :3]
        with np.errstate(invalid="ignore", over="ignore"):
            err = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2))
            det = np.linalg.det(np.nan_to_num(R))
        bad = (~np.isfinite(gt.poses).all(axis=(1, 2)) | ~np.isfinite(gt.stamps)
               | ~(err <= 1e-3) | ~(det > 0))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise DataError(f"{path}: damaged store: ground-truth pose {k} (stamp "
                            f"{gt.stamps[k]}) is not a rigid transform (its rotation is not a "
                            "rotation, or a value is not finite)")


class StoreSequence(Sequence):
    """A sequence read from a store, one frame at a time (the file opens lazily, so instances
    can be sent to worker processes).

    ``fields``: the per-point arrays to read besides the points ("doppler" and names of
    ``Scan.fields``; what a method declares in ``reads_fields``); a scan carries only those
    the store has. None (the default): every stored array. Scans are served from a block of
    whole chunks (``BLOCK_POINTS``) read ahead: memory holds one block of the arrays read."""

    def __init__(self, path: str | Path, fields: Iterable[str] | None = None) -> None:
        self.path = Path(path)
        self._block: _Block | None = None
        self._datasets: dict[str, h5py.Dataset] | None = None
        if not self.path.exists():
            raise DataError(f"{self.path}: store not found")
        if not h5py.is_hdf5(self.path):
            raise DataError(f"{self.path}: not an HDF5 file (truncated, or not a store: a "
                            "raw recording is converted first with `bench convert LOADER`)")
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
            n_frames = int(attrs["n_frames"])
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
            _check_header(self)
        except DataError as err:
            self.close()
            if str(self.path) in str(err):
                raise
            raise DataError(f"{self.path}: damaged store: {err}") from None
        except (OSError, KeyError, ValueError, TypeError) as err:
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
        stored = (["doppler"] if self.has_doppler else []) + self.fields
        #: the per-point arrays a scan carries besides xyz (stored and asked for)
        self.reads: tuple[str, ...] = tuple(
            name for name in stored if fields is None or name in set(fields))
        chunks = h5["points/xyz"].chunks
        self._chunk = int(chunks[0]) if chunks else 1
        self._n_points = int(n_points)
        if (len(self._offsets) != len(self._stamps) + 1 or self._offsets[-1] != n_points
                or n_frames != len(self._stamps)):
            self.close()
            raise DataError(
                f"{self.path}: truncated store: {len(self._stamps)} stamps, "
                f"{len(self._offsets)} offsets, {n_points} points, header says "
                f"{n_frames} frames"
            )

    def _file(self) -> h5py.File:
        if self._h5 is None:
            # blocks are whole chunks, read once: a small chunk cache (per array) is enough
            self._h5 = h5py.File(self.path, "r", rdcc_nbytes=1 << 20)
        return self._h5

    def close(self) -> None:
        self._block = self._datasets = None
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_h5"] = state["_block"] = state["_datasets"] = None
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
        block = self._block
        if block is None or lo < block.lo or hi > block.hi:
            try:
                block = self._block = self._read_block(lo, hi)
            except OSError as err:
                raise DataError(f"{self.path}, frame {index}: cannot read points ({err})"
                                ) from err
        a, b = lo - block.lo, hi - block.lo
        arrays = block.arrays
        doppler = arrays.get("doppler")
        return Scan(
            stamp=self._stamps[index],
            points=arrays["xyz"][a:b],  # Scan copies points and doppler (to float64)
            doppler=None if doppler is None else doppler[a:b],
            fields={name: arrays[name][a:b].copy() for name in self.reads if name != "doppler"},
            source=f"{self.path}, frame {index}",
        )

    def _read_block(self, lo: int, hi: int) -> _Block:
        """Points [start, stop) around [lo, hi) of every array read: whole chunks (each
        decompressed once, none read twice when frames stream in order), at least
        ``BLOCK_POINTS`` of them, one read per array."""
        if self._datasets is None:
            pts = self._file()["points"]
            self._datasets = {name: pts[name] for name in ("xyz", *self.reads)}
        chunk = self._chunk
        start = lo // chunk * chunk
        stop = min(self._n_points, -(-max(hi, start + BLOCK_POINTS) // chunk) * chunk)
        self._block = None  # the old block is released before the new one is read
        return _Block(start, stop, {name: ds[start:stop]
                                    for name, ds in self._datasets.items()})
