"""Every loader puts its stores in the sensor class `bench datasets` states for them: each
catalogue row with one of the paper's classes is opened from a small fixture of its layout by
its loader, and the class of the loader's output (``loaders.sensor_classes.sensor_class``, what
tables, figures and the summary group by) is the row's. A row added without a fixture here
fails the test."""

import numpy as np
import pytest

from helpers_bags import Motion, make_truth, write_aeva_folder, write_campus_bag, write_ntu_bag
from helpers_public import write_coloradar, write_helipr, write_vod
from helpers_snail import radar_array, write_snail_folder
from loaders.registry import LOADERS
from loaders.scan import SensorInfo
from loaders.sensor_classes import CLASS_ORDER, SPARSE_RADAR, sensor_class


def _truth():
    return make_truth(Motion(), frames=6, points=60, period=0.1)


def _snail(tmp_path, sensor: str):
    from loaders.snail_radar import SnailRadarSequence

    t = _truth()
    rng = np.random.default_rng(0)
    items = [(1706000000.0 + s, radar_array("eagle" if sensor == "eagle" else "ars548", p, d,
                                            rng)) for s, p, d in
             zip(t.stamps, t.points, t.doppler, strict=True)]
    sub = ("eagleg7", "enhanced") if sensor == "eagle" else ("ars548", "points")
    seq = tmp_path / "20240123" / "data1"
    write_snail_folder(seq / sub[0] / sub[1], items)
    return SnailRadarSequence(seq, sensor=sensor)


def _vod(tmp_path):
    from loaders.vod import VodSequence

    t = _truth()
    with pytest.warns(UserWarning, match="no frame stamps"):
        return VodSequence(write_vod(tmp_path, t.points, t.doppler, t.sensor_poses()))


def _coloradar(tmp_path):
    from loaders.coloradar import ColoradarSequence

    t = _truth()
    return ColoradarSequence(write_coloradar(tmp_path / "run0", t.stamps, t.points, t.doppler,
                                             t.stamps, t.sensor_poses()))


def _helipr(tmp_path):
    from loaders.helipr import HeliprSequence

    t = _truth()
    ns = (1690000000.0 + t.stamps) * 1e9
    return HeliprSequence(write_helipr(tmp_path, ns.astype(np.int64), t.points, t.doppler,
                                       ns.astype(np.int64), t.sensor_poses()))


def _aeva(tmp_path, layout: str):
    from loaders.aeva import AevaSequence

    return AevaSequence(write_aeva_folder(tmp_path / layout, _truth(), layout))


def _campus(tmp_path):
    from loaders.campus import CampusSequence

    path, _ = write_campus_bag(tmp_path / "Campus_1.bag", _truth())
    return CampusSequence(path)


def _ntu(tmp_path):
    from loaders.ntu4dradlm import NtuSequence

    return NtuSequence(write_ntu_bag(tmp_path / "loop1_0.bag", _truth()))


#: (loader, the row's sensor) -> a sequence of that layout opened by the loader
OPENERS = {
    ("ntu4dradlm", "Oculii Eagle 4D radar, ~12 Hz"): _ntu,
    ("snail-radar", "Oculii Eagle G7 4D radar"): lambda p: _snail(p, "eagle"),
    ("snail-radar", "Continental ARS548 4D radar"): lambda p: _snail(p, "ars548"),
    ("vod", "ZF FRGen21 4D radar, ~10 Hz (no stamps published)"): _vod,
    ("coloradar", "TI AWR1843 single-chip radar"): _coloradar,
    ("helipr", "Aeva Aeries II FMCW LiDAR"): _helipr,
    ("aeva", "simulated FMCW LiDAR (CARLA), 10 Hz"): lambda p: _aeva(p, "dicp"),
    ("aeva", "Aeva Aeries I FMCW LiDAR, 10 Hz"): lambda p: _aeva(p, "steam"),
    ("campus", "ZF FRGen21 4D radar, ~16.7 Hz"): _campus,
}

ROWS = [(entry.name, row) for entry in LOADERS.values() for row in entry.rows()
        if row.sensor_class in CLASS_ORDER]


def test_every_catalogue_row_with_a_class_has_a_fixture_here():
    assert sorted((name, row.sensor) for name, row in ROWS) == sorted(OPENERS)


@pytest.mark.parametrize("name,row", ROWS, ids=[f"{n}: {r.sensor}" for n, r in ROWS])
def test_the_loaders_output_is_in_the_catalogues_class(tmp_path, name, row):
    seq = OPENERS[(name, row.sensor)](tmp_path)
    assert sensor_class(seq.sensor) == row.sensor_class, (name, seq.sensor.model)


def test_stores_converted_before_the_models_named_their_class_keep_it():
    """Stores written before VoD / ColoRadar models named their class read by device name."""
    for model in ("ZF FRGen21 (VoD)", "TI AWR1843 single-chip (ColoRadar)"):
        assert sensor_class(SensorInfo("radar", 0.1, model=model)) == SPARSE_RADAR
    assert sensor_class(SensorInfo("radar", 0.1, model="some radar")) == "4D Radar"
