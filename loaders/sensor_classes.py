"""The sensor classes of the paper's tables, in the paper's order, and the class of a sensor
model (the synthetic sensors and the real datasets' sensors)."""

from __future__ import annotations

from loaders.scan import SensorInfo

SPARSE_RADAR = "Sparse 4D Radar"
SEMI_DENSE_RADAR = "Semi-Dense 4D Radar"
DENSE_LIDAR = "Dense 4D LiDAR"
#: the paper's row order (Table III)
CLASS_ORDER = (SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR)
#: sensor model -> class: the synthetic sensors' names and the real loaders' models, which
#: name the device after the class ("radar-semidense (Oculii Eagle)", "lidar-fmcw (CARLA)")
BY_MODEL = {"radar-sparse": SPARSE_RADAR, "radar-semidense": SEMI_DENSE_RADAR,
            "lidar-dense": DENSE_LIDAR, "lidar-fmcw": DENSE_LIDAR,
            # the device names of stores converted before their models named the class
            # (View-of-Delft, ColoRadar, HeLiPR): the class `bench datasets` states for them
            "ZF FRGen21": SPARSE_RADAR, "TI AWR1843 single-chip": SPARSE_RADAR,
            "Aeva Aeries II FMCW": DENSE_LIDAR}


def sensor_class(sensor: SensorInfo) -> str:
    """The class of ``sensor`` by its model (the part before a parenthesised device name, so a
    store of the Oculii Eagle is "Semi-Dense 4D Radar" in a single run as in the paper's
    tables), else by its kind ("4D Radar" when unknown)."""
    model = (sensor.model or "").split(" (")[0].strip()
    return BY_MODEL.get(model) or (DENSE_LIDAR if sensor.kind == "lidar" else "4D Radar")


#: the mark every name shown from a synthetic store carries (tables, figures, file names)
SYNTHETIC_MARK = "(synthetic)"


def is_synthetic(provenance: dict) -> bool:
    """A store made by the synthetic generator (its provenance says so)."""
    return provenance.get("source") == "synthetic" or bool(provenance.get("notice"))


def class_rank(klass: str) -> int:
    """Position of a class in the paper's order (unknown classes last)."""
    return CLASS_ORDER.index(klass) if klass in CLASS_ORDER else len(CLASS_ORDER)
