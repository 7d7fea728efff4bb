"""bench.data.export_frames: the frame ids a bag of `bench export` names from the store's
provenance, and what the export says of the store's clock (make mutate's survivors)."""

from datetime import UTC, datetime
from types import SimpleNamespace

import numpy as np
import pytest

from bench.data.export_frames import BagFrames, bag_frames, clock_note


def store_like(provenance=None, kind: str = "radar", first: float = 1654232000.25,
               **extra) -> SimpleNamespace:
    """What the two functions read of a store: provenance, the sensor's kind, the stamps."""
    return SimpleNamespace(provenance=provenance, sensor=SimpleNamespace(kind=kind),
                           stamps=np.array([first, first + 0.1]), **extra)


@pytest.mark.parametrize("prov", [None, {}, {"loader": "test"}])
def test_a_store_whose_loader_names_no_frame_gets_world_base_link_and_its_sensor_kind(prov):
    assert bag_frames(store_like(prov, "radar")) == BagFrames("world", "base_link", "radar")
    assert bag_frames(store_like(prov, "lidar")) == BagFrames("world", "base_link", "lidar")


def test_a_store_without_provenance_attribute_gets_the_default_frames():
    seq = SimpleNamespace(sensor=SimpleNamespace(kind="lidar"), stamps=np.array([1.0]))
    assert bag_frames(seq) == BagFrames("world", "base_link", "lidar")


def test_the_frames_the_loader_named_are_used_as_they_are():
    prov = {"loader": "vod", "world_frame": "map", "body_frame": "imu",
            "sensor_frame": "radar_front", "world": "odom (odomToCamera)"}
    assert bag_frames(store_like(prov)) == BagFrames("map", "imu", "radar_front")
    prov = {"loader": "ntu", "world_frame": "map", "body_frame": "imu",
            "sensor_frame": "oculii"}
    assert bag_frames(store_like(prov, "lidar")) == BagFrames("map", "imu", "oculii")


def test_an_old_vod_store_gets_odom_camera_radar_from_its_world_option():
    prov = {"loader": "vod", "world": "odom (odomToCamera)"}
    assert bag_frames(store_like(prov, "radar")) == BagFrames("odom", "camera", "radar")
    # a VoD store's sensor frame is radar even if the kind said otherwise
    assert bag_frames(store_like(prov, "lidar")).sensor == "radar"


def test_a_vod_world_option_that_is_no_text_and_another_loaders_world_are_not_frames():
    vod = {"loader": "vod", "world": 3}
    assert bag_frames(store_like(vod)) == BagFrames("world", "camera", "radar")
    other = {"loader": "ntu", "world": "odom (odomToCamera)"}
    assert bag_frames(store_like(other)) == BagFrames("world", "base_link", "radar")


@pytest.mark.parametrize("first", [0.0, -2.5])
def test_a_clock_from_zero_or_before_is_said_and_kept(first):
    note = clock_note(store_like({"loader": "test"}, first=first))
    assert note.startswith(f"the store's clock starts at {first:g} s (its dataset publishes no "
                           "stamps, or it is synthetic)")
    assert "ROS tools may read a 0 s stamp as 'no time'" in note
    assert "scores against the store unchanged" in note
    assert "View-of-Delft" not in note


def test_a_vod_store_from_zero_is_told_to_be_converted_again_for_the_frame_clock():
    note = clock_note(store_like({"loader": "vod"}, first=0.0))
    assert note.startswith("the store's clock starts at 0 s (its dataset publishes no stamps")
    assert note.endswith("; convert the View-of-Delft folder again for a clock that does not "
                         "start at 0 s (frame NNNNN at 1000 s + NNNNN x period)")


@pytest.mark.parametrize("first", [1e-9, 0.5, 1654232000.25])
def test_a_published_clock_after_zero_says_nothing(first):
    assert clock_note(store_like({"loader": "test"}, first=first)) is None
    assert clock_note(store_like(None, first=first)) is None
    assert clock_note(SimpleNamespace(stamps=np.array([first]))) is None


@pytest.fixture
def tokyo_time(monkeypatch):
    """The machine's local time 9 h ahead of UTC (UTC shown whatever the machine's zone)."""
    import time

    monkeypatch.setenv("TZ", "JST-9")  # POSIX rule: no zone database needed
    time.tzset()
    yield
    monkeypatch.undo()
    time.tzset()


def test_a_clock_a_loader_made_up_is_said_with_its_first_stamp_as_ros_shows_it(tokyo_time):
    first = 1000.0 + 17 * 0.1  # View-of-Delft frame 17 at 1000 s + 17 x period
    prov = {"loader": "vod", "clock_origin_s": 1000.0,
            "stamp_source": "1000 s + frame number x 0.1 s"}
    note = clock_note(store_like(prov, first=first))
    # 1001.7 s after the epoch: 00:16:41 on 1 January 1970 (16 min 41.7 s)
    assert note == ("the store's stamps are 1000 s + frame number x 0.1 s, set when it was "
                    "converted; the bag keeps them (first stamp 1001.7 s, which ROS tools "
                    "show as 1970-01-01 00:16:41 UTC) so that a trajectory made from the bag "
                    "scores against the store unchanged")
    assert datetime(1970, 1, 1, 0, 16, 41, tzinfo=UTC).timestamp() == pytest.approx(
        first - 0.7)


def test_a_made_up_clock_without_its_source_is_said_by_its_origin():
    prov = {"clock_origin_s": 2000.0}
    note = clock_note(store_like(prov, first=86400.0 + 3600.0 + 61.0))
    assert note.startswith("the store's stamps are 2000.0 s + index x period, set when")
    assert "(first stamp 90061 s, which ROS tools show as 1970-01-02 01:01:01 UTC)" in note
    # 9 significant digits of the first stamp
    note = clock_note(store_like({"clock_origin_s": 0}, first=1234.567891234))
    assert "(first stamp 1234.56789 s," in note
