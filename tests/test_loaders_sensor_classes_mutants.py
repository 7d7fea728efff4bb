"""loaders.sensor_classes: the class names and order are the paper's (paper/table3.csv, read
here), a model's class is found by its name before a parenthesised device, the device names
of older stores keep their class, unknown models fall back on the kind, and the synthetic mark
and test are what the tables rely on."""

import csv
from pathlib import Path

import numpy as np
import pytest

from loaders.scan import SensorInfo
from loaders.sensor_classes import (
    CLASS_ORDER,
    DENSE_LIDAR,
    SEMI_DENSE_RADAR,
    SPARSE_RADAR,
    SYNTHETIC_MARK,
    class_rank,
    is_synthetic,
    sensor_class,
)

ROOT = Path(__file__).resolve().parents[1]


def paper_class_order() -> list[str]:
    """The classes of paper/table3.csv's first column, in order of first appearance."""
    with open(ROOT / "paper" / "table3.csv", newline="") as f:
        rows = list(csv.reader(f))[1:]
    seen: list[str] = []
    for row in rows:
        if row and row[0] not in seen:
            seen.append(row[0])
    return seen


def sensor(model: str, kind: str = "radar") -> SensorInfo:
    return SensorInfo(kind, 0.1, np.eye(4), model)


def test_class_names_and_order_are_the_papers():
    assert list(CLASS_ORDER) == paper_class_order()
    assert (SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR) == CLASS_ORDER
    assert CLASS_ORDER == ("Sparse 4D Radar", "Semi-Dense 4D Radar", "Dense 4D LiDAR")


@pytest.mark.parametrize("model, kind, klass", [
    ("radar-sparse", "radar", "Sparse 4D Radar"),
    ("radar-semidense", "radar", "Semi-Dense 4D Radar"),
    ("lidar-dense", "lidar", "Dense 4D LiDAR"),
    ("lidar-fmcw", "lidar", "Dense 4D LiDAR"),
    # the device after the class, in parentheses
    ("radar-semidense (Oculii Eagle)", "radar", "Semi-Dense 4D Radar"),
    ("radar-sparse (ZF FRGen21, VoD)", "radar", "Sparse 4D Radar"),
    ("lidar-fmcw (CARLA)", "lidar", "Dense 4D LiDAR"),
    ("  radar-sparse   (padded)", "radar", "Sparse 4D Radar"),
    # stores converted before the models named the class
    ("ZF FRGen21", "radar", "Sparse 4D Radar"),
    ("TI AWR1843 single-chip", "radar", "Sparse 4D Radar"),
    ("Aeva Aeries II FMCW", "lidar", "Dense 4D LiDAR"),
    # a lidar class model on a radar kind: the model decides
    ("lidar-dense", "radar", "Dense 4D LiDAR"),
])
def test_class_by_model(model, kind, klass):
    assert sensor_class(sensor(model, kind)) == klass


@pytest.mark.parametrize("model, kind, klass", [
    ("", "radar", "4D Radar"),
    ("", "lidar", "Dense 4D LiDAR"),
    ("some radar", "radar", "4D Radar"),
    ("some lidar", "lidar", "Dense 4D LiDAR"),
    ("radar-sparse(no space)", "radar", "4D Radar"),  # only " (" starts a device name
    ("RADAR-SPARSE", "radar", "4D Radar"),  # model names are exact
])
def test_unknown_models_fall_back_on_the_kind(model, kind, klass):
    assert sensor_class(sensor(model, kind)) == klass


def test_a_missing_model_falls_back_on_the_kind():
    s = sensor("", "lidar")
    object.__setattr__(s, "model", None)
    assert sensor_class(s) == DENSE_LIDAR
    r = sensor("", "radar")
    object.__setattr__(r, "model", None)
    assert sensor_class(r) == "4D Radar"


def test_class_rank_is_the_paper_order_and_unknown_last():
    assert [class_rank(k) for k in CLASS_ORDER] == [0, 1, 2]
    assert class_rank("4D Radar") == 3
    assert class_rank("") == 3
    assert sorted(["4D Radar", DENSE_LIDAR, SPARSE_RADAR, SEMI_DENSE_RADAR],
                  key=class_rank) == [SPARSE_RADAR, SEMI_DENSE_RADAR, DENSE_LIDAR, "4D Radar"]


def test_synthetic_mark_and_test():
    assert SYNTHETIC_MARK == "(synthetic)"
    assert is_synthetic({"source": "synthetic"}) is True
    assert is_synthetic({"notice": "generated, not measured"}) is True
    assert is_synthetic({"source": "synthetic", "notice": ""}) is True
    assert is_synthetic({"source": "vod"}) is False
    assert is_synthetic({"notice": ""}) is False
    assert is_synthetic({"notice": None, "source": "Synthetic"}) is False
    assert is_synthetic({}) is False
