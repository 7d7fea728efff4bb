"""What a bag ``bench export`` writes calls its frames and says of its clock, from the store's
provenance, so that a ROS tool reading the bag is not misled:

- frames (``BagFrames``): the world the ground truth is in (the loader's ``world_frame``, e.g.
  ``odom`` for View-of-Delft, else ``world``), the body the ground-truth poses are of (its
  ``body_frame``, e.g. ``camera`` for View-of-Delft, else ``base_link``) and the sensor the
  points are in (its ``sensor_frame``, else the sensor's kind: ``radar`` or ``lidar``);
- the clock (``clock_note``): a store whose clock starts at or before 0 s (synthetic; a
  View-of-Delft store converted before its frames were stamped by their numbers) and a clock a
  loader made up for a dataset that publishes no stamps (provenance ``clock_origin_s``, e.g.
  View-of-Delft's ``1000 s + frame number x period``) are said in the printed note and the
  bag's description; the stamps themselves are always the store's.

Stores written before the loaders named their frames: a View-of-Delft store (provenance
``loader`` ``vod``) still gets ``odom`` / ``camera`` / ``radar`` (its ``world`` option's first
word for the world).
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from loaders.vod import CLOCK_ORIGIN_S as VOD_CLOCK_ORIGIN_S

#: frames of a store whose loader names none
WORLD_FRAME, BODY_FRAME = "world", "base_link"
#: the frames a View-of-Delft store's poses and points are in (its loader's names)
VOD_FRAMES = {"body_frame": "camera", "sensor_frame": "radar"}


@dataclass(frozen=True)
class BagFrames:
    """Frame ids of the bag: ground truth ``T_world_body`` (header ``world``, child ``body``),
    ``/tf_static`` ``body -> sensor``, the points in ``sensor``."""

    world: str
    body: str
    sensor: str


def _vod(prov: dict) -> bool:
    return prov.get("loader") == "vod"


def bag_frames(seq) -> BagFrames:
    """The frames of ``seq`` (a store) as the bag names them (see the module docstring)."""
    prov = getattr(seq, "provenance", {}) or {}
    world = prov.get("world_frame")
    if not world and _vod(prov) and isinstance(prov.get("world"), str):
        world = prov["world"].split()[0]  # "odom (odomToCamera)"
    body = prov.get("body_frame") or (VOD_FRAMES["body_frame"] if _vod(prov) else None)
    sensor = prov.get("sensor_frame") or (VOD_FRAMES["sensor_frame"] if _vod(prov) else None)
    return BagFrames(str(world or WORLD_FRAME), str(body or BODY_FRAME),
                     str(sensor or seq.sensor.kind))


def clock_note(seq) -> str | None:
    """What the export says of the store's clock (printed and in the bag's description), None
    for a clock the dataset published that starts after 0 s."""
    prov = getattr(seq, "provenance", {}) or {}
    first = float(seq.stamps[0])
    if first <= 0:
        note = (f"the store's clock starts at {first:g} s (its dataset publishes no stamps, or "
                "it is synthetic), kept as it is so that a trajectory made from the bag scores "
                "against the store unchanged; ROS tools may read a 0 s stamp as 'no time'")
        if _vod(prov):
            note += (f"; convert the View-of-Delft folder again for a clock that does not "
                     f"start at 0 s (frame NNNNN at {VOD_CLOCK_ORIGIN_S:g} s + NNNNN x period)")
        return note
    if "clock_origin_s" not in prov:
        return None
    source = prov.get("stamp_source") or f"{prov['clock_origin_s']} s + index x period"
    shown = datetime.fromtimestamp(first, UTC).strftime("%Y-%m-%d %H:%M:%S")
    return (f"the store's stamps are {source}, set when it was converted; the bag keeps them "
            f"(first stamp {first:.9g} s, which ROS tools show as {shown} UTC) so that a "
            "trajectory made from the bag scores against the store unchanged")
