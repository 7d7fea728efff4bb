"""Any store back out as a ROS bag (``bench export STORE --format ros1|ros2|mcap``).

One uniform form for every dataset the harness loads, to feed a ROS node:

- ``/points`` ``sensor_msgs/PointCloud2`` (frame: the sensor's, ``radar`` or ``lidar``), one
  message per scan stamped with the scan's stamp: float32 fields ``x y z`` [m, sensor frame],
  ``doppler`` [m/s] in the
  harness's sign (``DOPPLER_SIGN``: positive when the point recedes from the sensor; a static
  point ahead of a forward-moving sensor reads negative), then every per-point field of the
  store (``intensity``, ``power``, ``rcs``, ...) by its name;
- ``/ground_truth`` ``nav_msgs/Odometry`` (frame: the GT's world, ``world`` or the loader's,
  e.g. ``odom`` for View-of-Delft; child: the body frame, ``base_link`` or the frame the
  dataset's poses are of, e.g. ``camera`` for View-of-Delft): the GT body pose ``T_world_body
  = T_world_sensor @ inv(T_body_sensor)`` at each scan that has GT (twist zero: not given);
- ``/tf_static`` ``tf2_msgs/TFMessage``: body frame -> sensor frame, the store's
  ``T_body_sensor``;
- ``/doppler_bench/description`` ``std_msgs/String``: a JSON text stating the fields, the
  Doppler sign and kind, the frames, the clock, the sensor and the store it came from.

The frame ids and the note on the clock: ``bench.data.export_frames``. Stamps: the store's
stamps, rounded to the nanosecond, never shifted: a trajectory an odometry makes from the bag
is on the store's clock and scores against it unchanged. A dataset that publishes no stamps
gets its clock when it is converted (View-of-Delft: frame NNNNN at 1000 s + NNNNN x period,
never 0 s), and the export says so; a store whose clock starts at 0 s (synthetic) keeps it,
and the export says that ROS tools may read a 0 s stamp as "no time" (``clock_note``).

A store without Doppler exports ``x y z`` and its other fields (no ``doppler``); the description
says so and the read-back command carries ``--doppler-field none``.

Formats: ``ros1`` (one ``.bag`` file: an ``--out`` without the extension gets ``.bag``),
``ros2`` (a rosbag2 folder, sqlite3 storage) and ``mcap`` (a rosbag2 folder, mcap storage),
written with ``rosbags``. The output is checked by the output guard (``bench.guard``): never
the store itself or a folder holding it; an existing bag replaced only with ``--force`` and
only when it is a bag (a ROS1 bag file, a rosbag2 folder of nothing but its metadata and
storage files), never a folder of other files. Streaming: one scan is read from the store,
serialised and written at a time, so memory stays flat in the sequence length. Atomic: the bag
is written beside its destination under a temporary name and renamed when complete. ``bench
convert rosbag`` reads it back to the same store contents (``reimport_command`` prints the
exact command, writing ``NAME.h5``, or ``NAME_FMT.h5`` when ``NAME.h5`` exists: never the
store; ``bench convert rosbag BAG`` alone reads the same options from the bag's
description). The messages and the writer over rosbags' formats: ``bench.data.bag_messages``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bench import guard
from bench.data.bag_messages import (
    CLOUD,
    ODOM,
    STRING,
    TF,
    BagWriter,
    cloud_msg,
    odometry_msg,
    tf_static_msg,
)
from bench.data.export_frames import bag_frames, clock_note
from bench.guard import is_ros1_bag, is_rosbag2_folder, replaceable
from loaders.errors import DataError
from loaders.rosbag import DESCRIPTION_TOPIC, NO_DOPPLER
from loaders.se3 import inv_T, tum_from_T
from loaders.store import StoreSequence

FORMATS = ("ros1", "ros2", "mcap")
POINTS_TOPIC = "/points"
GT_TOPIC = "/ground_truth"
TF_TOPIC = "/tf_static"
INFO_TOPIC = DESCRIPTION_TOPIC

#: the Doppler sign of the exported field (the harness's: positive = receding)
DOPPLER_SIGN = ("doppler [m/s]: radial velocity of the point relative to the sensor, positive "
                "when the point recedes (moves away from the sensor); a static point ahead of "
                "a forward-moving sensor reads negative")


@dataclass(frozen=True)
class ExportSummary:
    path: Path
    format: str
    frames: int
    gt_poses: int
    fields: list[str]


def default_out(store: Path, fmt: str) -> Path:
    """``STORE.bag`` (ros1), ``STORE_ros2/`` or ``STORE_mcap/`` beside the store."""
    store = Path(store)
    return store.with_suffix(".bag") if fmt == "ros1" else \
        store.with_name(f"{store.stem}_{fmt}")


def bag_path(out: Path, fmt: str) -> Path:
    """``out`` as the bag is written: a ROS1 bag always ends in ``.bag`` (rosbags' reader,
    kiss-icp and ``bench convert rosbag`` recognise a ROS1 bag by it)."""
    out = Path(out)
    return out if fmt != "ros1" or out.suffix == ".bag" else out.with_name(out.name + ".bag")


def description(seq: StoreSequence, store: Path, fields: list[str]) -> dict:
    """The bag's description (``INFO_TOPIC``): fields, Doppler sign and kind, frames, sensor,
    the clock. ``loaders.rosbag`` reads it back (``bench convert rosbag BAG``)."""
    frames = bag_frames(seq)
    return {
        "exported_by": "doppler-bench (bench export)", "store": str(store),
        "sequence": seq.name, "points_topic": POINTS_TOPIC, "ground_truth_topic": GT_TOPIC,
        "fields": ["x", "y", "z", *fields],
        "units": "x y z [m] in the sensor frame; doppler [m/s]; other fields as stored",
        "doppler": DOPPLER_SIGN if seq.has_doppler else "none (the store has no Doppler)",
        "doppler_kind": seq.sensor.doppler_kind if seq.has_doppler else NO_DOPPLER,
        "sensor_kind": seq.sensor.kind,
        "sensor_model": seq.sensor.model, "period_s": seq.sensor.period_s,
        "frames": {"world": frames.world, "body": frames.body, "sensor": frames.sensor},
        "ground_truth": f"nav_msgs/Odometry: T_{frames.world}_{frames.body} at the scans with "
                        f"ground truth; the sensor ({frames.sensor}) pose is that @ "
                        f"T_{frames.body}_{frames.sensor} ({TF_TOPIC})",
        "stamps": clock_note(seq) or "the store's stamps, rounded to the nanosecond",
        "first_stamp_s": float(seq.stamps[0]),
        "T_body_sensor": np.asarray(seq.sensor.T_body_sensor).tolist(),
    }


def write_bag(seq: StoreSequence, store: Path, path: Path, fmt: str,
              progress: Callable[[int], None] | None = None) -> ExportSummary:
    """Write ``seq`` to a new bag at ``path`` (must not exist), one scan at a time."""
    bag = BagWriter(path, fmt)
    try:
        stamps = seq.stamps
        T_bs = np.asarray(seq.sensor.T_body_sensor, dtype=np.float64)
        gt = seq.ground_truth
        fields = (["doppler"] if seq.has_doppler else []) + list(seq.fields)
        frames = bag_frames(seq)
        cloud = bag.connection(POINTS_TOPIC, CLOUD)
        tf = bag.connection(TF_TOPIC, TF, latched=True)
        info = bag.connection(INFO_TOPIC, STRING, latched=True)
        odom = bag.connection(GT_TOPIC, ODOM) if gt is not None else None
        t0 = float(stamps[0])
        bag.write(tf, t0, tf_static_msg(bag, t0, T_bs, frames.body, frames.sensor))
        text = json.dumps(description(seq, store, fields), indent=1)
        bag.write(info, t0, bag.store.types[STRING](data=text))
        gt_stamps = gt.stamps if gt is not None else np.zeros(0)
        T_sb = inv_T(T_bs)

        def write_gt(k: int) -> None:
            tg = float(gt_stamps[k])
            bag.write(odom, tg, odometry_msg(bag, tg, gt.poses[k] @ T_sb, frames.world,
                                             frames.body))

        g = 0
        for i in range(len(seq)):
            t = float(stamps[i])
            while g < len(gt_stamps) and gt_stamps[g] <= t:  # GT in time order with the scans
                write_gt(g)
                g += 1
            scan = seq.scan(i)
            values = {} if scan.doppler is None else {"doppler": scan.doppler}
            values.update({name: scan.fields[name] for name in seq.fields})
            bag.write(cloud, t, cloud_msg(bag, t, scan.points, values, frames.sensor))
            if progress:
                progress(i)
        for k in range(g, len(gt_stamps)):
            write_gt(k)
    finally:
        bag.close()
    return ExportSummary(path, fmt, len(seq), len(gt_stamps), fields)


def export_store(store: Path, fmt: str, out: Path | None = None, force: bool = False,
                 progress: Callable[[int], None] | None = None) -> ExportSummary:
    """Export ``store`` as a ``fmt`` bag to ``out`` (default ``default_out``; a ROS1 bag gets
    ``.bag``, ``bag_path``); an existing ``out`` is replaced only with ``force`` and only when
    it is a bag of that format (``bench.guard``). Written under a temporary name, then
    renamed."""
    if fmt not in FORMATS:
        raise DataError(f"--format {fmt!r}: expected one of {', '.join(FORMATS)}")
    store = Path(store)
    if out is not None:
        guard.check_out(out)
    out = bag_path(out, fmt) if out is not None else default_out(store, fmt)
    if fmt == "ros1":
        replaceable(out, force, _exported_ros1, "a ROS1 bag", inputs=[store])
    else:
        replaceable(out, force, _rosbag2_or_empty, "a rosbag2 folder (metadata.yaml and its "
                    "storage files only)", inputs=[store])
    seq = StoreSequence(store)
    try:
        if fmt == "ros1":
            made = []
            guard.write_via(out, lambda tmp: made.append(write_bag(seq, store, Path(tmp), fmt,
                                                                   progress)),
                            _exported_ros1, "a ROS1 bag", fresh=True)
            return replace(made[0], path=out)
        # a rosbag2 bag is a folder named like its storage file: written in a temporary
        # parent folder under its final name, then moved into place
        work = out.parent / f".{out.name}.{os.getpid()}.export"

        def own_work(path: Path) -> bool:
            return path == work

        guard.remove_folder(work, own_work, "this export's work folder")
        guard.make_folder(work)
        try:
            summary = write_bag(seq, store, work / out.name, fmt, progress)
            guard.move_into_place(work / out.name, out, _rosbag2_or_empty, "a rosbag2 folder")
        finally:
            guard.remove_folder(work, own_work, "this export's work folder")
        return replace(summary, path=out)
    finally:
        seq.close()


def _exported(path: Path) -> bool:
    """A bag this command wrote: it carries ``DESCRIPTION_TOPIC``. A dataset's own recording
    (no description) is never what ``--force`` replaces."""
    from loaders.rosbag import bag_topics

    try:
        return DESCRIPTION_TOPIC in bag_topics([Path(path)])
    except Exception:  # noqa: BLE001 - unreadable as a bag: not one of ours
        return False


def _exported_ros1(path: Path) -> bool:
    return is_ros1_bag(path) and _exported(path)


def _rosbag2_or_empty(path: Path) -> bool:
    return ((is_rosbag2_folder(path) and _exported(path))
            or (path.is_dir() and not any(path.iterdir())))


def readback_out(seq_name: str, fmt: str) -> str:
    """The read-back command's ``--out``: ``NAME.h5`` in the current folder, or ``NAME_FMT.h5``
    when ``NAME.h5`` is there already (e.g. the exported store itself, named by its sequence:
    the command would be refused, and must never replace it)."""
    return f"{seq_name}_{fmt}.h5" if Path(f"{seq_name}.h5").exists() else f"{seq_name}.h5"


def reimport_command(summary: ExportSummary, seq_name: str, sensor_kind: str, model: str,
                     doppler_kind: str, T_body_sensor: np.ndarray, out: str | None = None
                     ) -> str:
    """The ``bench convert rosbag`` command that reads the bag back to the same store (every
    option spelled out, quoted for a POSIX shell; ``bench convert rosbag BAG`` alone takes the
    same values from the bag's description), writing ``out`` (default ``NAME.h5``). A store
    without Doppler (no ``doppler`` among ``summary.fields``): ``--doppler-field none``."""
    from shlex import quote

    xyz, quat = tum_from_T(np.asarray(T_body_sensor, dtype=np.float64)[None])
    ext = " ".join(f"{v:.17g}" for v in [*xyz[0], *quat[0]])
    gt = f" --gt-topic {GT_TOPIC}" if summary.gt_poses else ""
    model_opt = f" --model {quote(model)}" if model else ""
    has_doppler = "doppler" in summary.fields
    doppler = (f" --doppler-kind {doppler_kind}" if has_doppler and doppler_kind in
               ("radial", "ego-compensated") else "" if has_doppler else
               f" --doppler-field {NO_DOPPLER}")
    text = (f"bench convert rosbag {quote(str(summary.path))} --topic {POINTS_TOPIC}{gt} "
            f"--T-body-sensor '{ext}' --sensor-kind {sensor_kind}{model_opt}{doppler} "
            f"--name {quote(seq_name)} --out {quote(out or seq_name + '.h5')}")
    return text


def doppler_kind_note(summary: ExportSummary, doppler_kind: str) -> str | None:
    """A line said beside the read-back command (never inside it: the command stays one a
    shell runs) when the store's Doppler kind is one the rosbag loader does not take."""
    if "doppler" not in summary.fields or doppler_kind in ("radial", "ego-compensated"):
        return None
    return (f"this store's Doppler is {doppler_kind}, which the rosbag loader does not take "
            "(read back as radial): results from its bag are not independent of the ground "
            "truth")


def export_command(console, store: Path, fmt: str, out: Path | None, force: bool) -> None:
    """``bench export``: write the bag, then print what it holds and how to read it back."""
    summary = export_store(store, fmt, out, force)
    seq = StoreSequence(store)
    try:
        back = reimport_command(summary, seq.name, seq.sensor.kind, seq.sensor.model,
                                seq.sensor.doppler_kind, seq.sensor.T_body_sensor,
                                readback_out(seq.name, fmt))
    finally:
        clock, kind = clock_note(seq), seq.sensor.doppler_kind
        seq.close()
    doppler = (DOPPLER_SIGN if "doppler" in summary.fields else
               "no Doppler field: the store has no Doppler (methods that need it cannot run "
               "on this bag)")
    console.print(
        f"wrote {summary.path} ({summary.format}): {summary.frames} scans on {POINTS_TOPIC} "
        f"(fields {' '.join(['x', 'y', 'z', *summary.fields])}), {summary.gt_poses} "
        f"ground-truth poses on {GT_TOPIC}, the extrinsic on {TF_TOPIC}, the description on "
        f"{INFO_TOPIC}; {doppler}", markup=False)
    for note in (clock, doppler_kind_note(summary, kind)):
        if note:
            console.print(f"note: {note}", markup=False)
    console.print(f"read it back with: {back}", markup=False)
