"""The elevation (height) check of `bench inspect` on real frames, in every public radar layout
the loaders read.

The vendored NTU4DRadLM sample (Oculii Eagle, 250 real frames) holds a stretch whose densest
near-field layer is ABOVE the radar: frames 200-229 at about +1.4 m (a wall or vehicle beside
the road) and 230-249 at about +0.1 m; the road elsewhere lies at -0.6 m. Rolled so that this
stretch comes first (frames 190-249, then 0-189), the first 50 frames are what a check of the
first frames only called "elevation looks mirrored" on the Snail-Radar, VoD and ColoRadar
stores. Written in each layout (the layouts' writers of helpers_public / helpers_snail) and
read by its loader, the check must say "road below", and the same frames mirrored (z negated)
must warn, in every layout."""

import numpy as np
import pytest

from conftest import SAMPLE_STORE
from helpers_public import write_coloradar, write_npy_frames, write_vod
from helpers_snail import radar_array, write_ros2_bag, write_snail_bag, write_snail_folder
from loaders.doppler_check import low_points_median_z
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.store import StoreSequence

ORDER = [*range(190, 250), *range(0, 190)]
T0 = 1706000000.0  # an epoch clock for the layouts whose file names are stamps
PERIOD_S = 0.1


@pytest.fixture(scope="module")
def frames():
    """(stamps, points, doppler, poses) of the rolled real sample (float32 as the layouts
    store them; poses: a straight drive, the check does not read them)."""
    seq = StoreSequence(SAMPLE_STORE)
    assert len(seq) == 250
    scans = [seq.scan(i) for i in ORDER]
    stamps = T0 + PERIOD_S * np.arange(len(scans))
    poses = np.stack([make_T(np.eye(3), [0.5 * k, 0.0, 0.0]) for k in range(len(scans))])
    return (stamps, [s.points.astype(np.float32) for s in scans],
            [s.doppler.astype(np.float32) for s in scans], poses)


def _layouts(root, stamps, points, doppler, poses):
    """The frames in every public radar layout, opened by its loader: {name: Sequence}."""
    from loaders.coloradar import ColoradarSequence
    from loaders.npy_frames import NpyFramesSequence
    from loaders.rosbag import RosbagSequence
    from loaders.snail_radar import SnailRadarSequence
    from loaders.vod import VodSequence

    rng = np.random.default_rng(0)
    with pytest.warns(UserWarning, match="View-of-Delft publishes no frame stamps"):
        vod = VodSequence(write_vod(root / "vod", points, doppler, poses))
    eagle = [(t, radar_array("eagle", p, d, rng)) for t, p, d in
             zip(stamps, points, doppler, strict=True)]
    write_snail_folder(root / "data1" / "eagleg7" / "enhanced", eagle)
    write_ros2_bag(root / "bag_mcap", eagle, "mcap")
    (root / "20240123").mkdir()
    ros1 = write_snail_bag(root / "20240123" / "data1.bag", {"/radar_enhanced_pcl2": eagle})
    return {
        "snail-radar (ROS1 bag)": SnailRadarSequence(ros1),
        "rosbag (ROS1)": RosbagSequence([ros1], topic="/radar_enhanced_pcl2",
                                        doppler_field="Doppler"),
        "npy-frames": NpyFramesSequence(write_npy_frames(root / "npy", points, doppler, stamps,
                                                         poses), period_s=PERIOD_S),
        "vod": vod,
        "coloradar": ColoradarSequence(write_coloradar(root / "col" / "run0", stamps, points,
                                                       doppler, stamps, poses)),
        "snail-radar": SnailRadarSequence(root / "data1"),
        "rosbag": RosbagSequence([root / "bag_mcap"], doppler_field="Doppler"),
    }


def _first(seq, n: int) -> MemorySequence:
    return MemorySequence("first", SensorInfo("radar", PERIOD_S),
                          [seq.scan(i) for i in range(n)], None, {})


def test_the_rolled_sample_fools_a_check_of_the_first_frames(frames):
    """The fixture is the case of the issue: its first 50 frames alone put the densest near
    layer above the sensor."""
    stamps, points, doppler, _ = frames
    seq = MemorySequence("rolled", SensorInfo("radar", PERIOD_S),
                         [Scan(t, p, d) for t, p, d in zip(stamps, points, doppler,
                                                            strict=True)], None, {})
    assert low_points_median_z(_first(seq, 50))["dominant_layer_z_m"] > 0.5
    whole = low_points_median_z(seq)
    assert whole["frames"] == 60 and -0.8 < whole["dominant_layer_z_m"] < -0.4
    assert 0.6 < whole["frames_below_sensor"] < 0.9  # the stretch above is a minority


@pytest.mark.parametrize("mirrored", [False, True])
def test_every_public_layout_of_the_real_sample_reads_the_road_below(frames, tmp_path,
                                                                     mirrored):
    from bench.data.inspection import inspect_sequence

    stamps, points, doppler, poses = frames
    sign = np.float32([1, 1, -1]) if mirrored else np.float32([1, 1, 1])
    seqs = _layouts(tmp_path, stamps, [p * sign for p in points], doppler, poses)
    seqs["store (ntu4dradlm)"] = StoreSequence(SAMPLE_STORE) if not mirrored else None
    for name, seq in seqs.items():
        if seq is None:
            continue
        assert len(seq) == 250, name
        z = low_points_median_z(seq)
        row = dict(inspect_sequence(seq)["rows"])["height check"]
        if mirrored:
            assert 0.4 < z["dominant_layer_z_m"] < 0.8, (name, z)
            assert "looks mirrored" in row, (name, row)
        else:
            assert -0.8 < z["dominant_layer_z_m"] < -0.4, (name, z)
            assert "road below the sensor" in row and "mirrored" not in row, (name, row)


def test_the_estimate_is_per_frame_not_pooled_points(frames):
    """The ground is the height most frames agree on, not the densest layer of all their
    points pooled: the rolled sample with its frames whose densest layer is +1.4 m (original
    frames 200-229) 30 times as dense (each point repeated, as a much denser sensor mode would
    give) still reads the road below; pooled, those frames' points outvote the road."""
    from loaders.doppler_check import _densest_layer

    stamps, points, doppler, _ = frames
    dense = [np.tile(p, (30, 1)) if 10 <= k < 40 else p for k, p in enumerate(points)]
    seq = MemorySequence("dense", SensorInfo("radar", PERIOD_S),
                         [Scan(t, p, np.zeros(len(p))) for t, p in zip(stamps, dense,
                                                                          strict=True)],
                         None, {})
    idx = np.unique(np.linspace(0, 249, 60).round().astype(int))
    near = [dense[i][np.hypot(dense[i][:, 0], dense[i][:, 1]) <= 30, 2] for i in idx]
    assert _densest_layer(np.concatenate(near)) > 0.5  # pooling would call it mirrored
    z = low_points_median_z(seq)
    assert -0.8 < z["dominant_layer_z_m"] < -0.4 and "road below" in z["verdict"]
