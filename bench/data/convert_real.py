"""``bench convert ntu4dradlm|campus|aeva``: real datasets -> HDF5 stores.

``register(convert_app, write)`` adds the three commands to the ``convert`` Typer group;
``write(sequence, out)`` writes the store with a progress bar and prints the throughput.
``DataError`` propagates (the CLI prints it without a traceback).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer

from bench.data.convert_options import Frames, Stride
from bench.data.datasets import read_dataset_config
from loaders.scan import Sequence, select_frames

Start = Annotated[int, typer.Option(help="first frame (after GT trimming)")]
Out = Annotated[Path, typer.Option(help="store to write, e.g. data/real/Loop1_0.h5")]
Name = Annotated[str | None, typer.Option(help="sequence name stored in the file")]
TimeOffset = Annotated[float, typer.Option(
    "--time-offset", help="GT clock offset (s): gt_stamp + offset = sensor clock")]
MaxGap = Annotated[float | None, typer.Option(
    "--max-gap", help="largest GT gap interpolated across (s) (default: loader's)")]
Uncovered = Annotated[str, typer.Option(
    help="scans without GT: keep (run, unscored), trim (cut the ends) or error")]
Stamp = Annotated[str, typer.Option(
    help="scan stamps: header (header.stamp) or record (bag record time)")]


def register(convert_app: typer.Typer, write: Callable[[Sequence, Path], object]) -> None:
    """Add the ``ntu4dradlm``, ``campus`` and ``aeva`` commands to ``convert_app``."""

    @convert_app.command("dataset", short_help="a paper sequence from its dataset config")
    def dataset(
        config: Annotated[str, typer.Argument(help="paper sequence name (e.g. Loop1_0) or a "
                                              "configs/datasets/*.yaml path")],
        raw_dir: Annotated[Path | None, typer.Option(help="folder with the raw files "
                                                     "(default: the config's raw_dir)")] = None,
        data_dir: Annotated[Path, typer.Option(help="the store goes to DATA_DIR/real/")]
        = Path("data"),
        out: Annotated[Path | None, typer.Option(help="store path (default: "
                                                 "DATA_DIR/real/<store>)")] = None,
    ) -> None:
        """A paper sequence from configs/datasets/<Name>.yaml -> data/real/<Name>.h5."""
        cfg = read_dataset_config(config)
        write(cfg.open(raw_dir), out or data_dir / "real" / cfg.store)

    @convert_app.command("ntu4dradlm", short_help="NTU4DRadLM ROS1 bags (+ gt_odom.txt)")
    def ntu4dradlm(
        bags: Annotated[list[Path], typer.Argument(help="ROS1 bag(s) of one route, merged in "
                                                   "time order")],
        out: Out,
        gt: Annotated[Path | None, typer.Option(help="gt_odom.txt (TUM)")] = None,
        topic: Annotated[str, typer.Option(help="radar topic (PointCloud or PointCloud2)")]
        = "/radar_enhanced_pcl",
        doppler_field: Annotated[str, typer.Option(help="Doppler channel / PointField name")]
        = "Doppler",
        extrinsic: Annotated[str | None, typer.Option(
            help='radar -> GT body "x y z qx qy qz qw" (default: 0.296 -0.130 -0.005, '
                 "identity rotation; unconfirmed)")] = None,
        time_offset: TimeOffset = 0.0,
        max_gap: MaxGap = None,
        uncovered: Uncovered = "keep",
        doppler_sign: Annotated[float, typer.Option(help="+1 or -1")] = 1.0,
        stamp: Stamp = "header",
        name: Name = None,
        start: Start = 0, frames: Frames = None, stride: Stride = 1,
    ) -> None:
        """NTU4DRadLM ROS1 bags (+ gt_odom.txt) -> store."""
        from loaders.ntu4dradlm import DEFAULT_T_GTBODY_RADAR, NtuSequence

        kw = {} if max_gap is None else {"max_gap_s": max_gap}
        seq = NtuSequence(bags, gt=gt, topic=topic, doppler_field=doppler_field,
                          T_gtbody_radar=extrinsic or DEFAULT_T_GTBODY_RADAR,
                          time_offset_s=time_offset, uncovered=uncovered,
                          doppler_sign=doppler_sign, stamp=stamp, name=name, **kw)
        write(select_frames(seq, start, frames, stride), out)

    @convert_app.command("campus", short_help="Campus ROS1 bags (ZF FRGen21 radar)")
    def campus(
        bags: Annotated[list[Path], typer.Argument(help="ROS1 bag(s) with RadarScanExtended")],
        out: Out,
        topic: Annotated[str, typer.Option(help="radar topic")] = "/radar_scan",
        gt_topic: Annotated[str, typer.Option(help="nav_msgs/Odometry GT topic ('' for none)")]
        = "/ground_truth",
        gt: Annotated[Path | None, typer.Option(help="TUM GT file instead of the topic")] = None,
        elevation_sign: Annotated[float, typer.Option(
            help="z = sign * r sin(el); check with `bench inspect` (road below the sensor)")]
        = 1.0,
        doppler_sign: Annotated[float, typer.Option(help="doppler = sign * velocity")] = 1.0,
        extrinsic: Annotated[str | None, typer.Option(
            help='radar -> GT body "x y z qx qy qz qw" (default identity: unknown)')] = None,
        keep_utm: Annotated[bool, typer.Option(help="keep the UTM origin in the GT")] = False,
        time_offset: TimeOffset = 0.0,
        max_gap: MaxGap = None,
        uncovered: Uncovered = "keep",
        stamp: Stamp = "header",
        name: Name = None,
        start: Start = 0, frames: Frames = None, stride: Stride = 1,
    ) -> None:
        """Campus (Li, Zhang, Chen, RA-L 2023; ZF FRGen21 sparse 4D radar) ROS1 bags -> store."""
        from loaders.campus import CampusSequence

        kw = {} if max_gap is None else {"max_gap_s": max_gap}
        seq = CampusSequence(bags, topic=topic, gt_topic=gt_topic or None, gt=gt,
                             elevation_sign=elevation_sign, doppler_sign=doppler_sign,
                             T_body_radar=extrinsic, remove_gt_origin=not keep_utm,
                             time_offset_s=time_offset, uncovered=uncovered, stamp=stamp,
                             name=name, **kw)
        write(select_frames(seq, start, frames, stride), out)

    @convert_app.command("aeva", short_help="Aeva / CARLA per-frame folders")
    def aeva(
        folder: Annotated[Path, typer.Argument(help="sequence folder (point_clouds/, "
                                               "xyzd_sequence/ or frames/)")],
        out: Out,
        layout: Annotated[str, typer.Option(help="auto, dicp, open3d or steam")] = "auto",
        period: Annotated[float | None, typer.Option(
            help="frame period (s) when there are no stamps (default: calibration or 0.1)")]
        = None,
        extrinsic: Annotated[str | None, typer.Option(
            help='sensor -> vehicle "x y z qx qy qz qw" or 16 numbers (default: the layout\'s)'
        )] = None,
        invert_calibration: Annotated[bool, typer.Option(
            help="use the inverse of calibration.json's matrix")] = False,
        gt: Annotated[Path | None, typer.Option(help="GT file (default: the layout's)")] = None,
        no_gt: Annotated[bool, typer.Option(help="ignore ground truth")] = False,
        gt_association: Annotated[str, typer.Option(help="auto, index or time")] = "auto",
        time_offset: TimeOffset = 0.0,
        doppler_sign: Annotated[float, typer.Option(help="+1 or -1")] = 1.0,
        name: Name = None,
        start: Start = 0, frames: Frames = None, stride: Stride = 1,
    ) -> None:
        """Aeva / CARLA per-frame folders -> store."""
        from loaders.aeva import AevaSequence

        seq = AevaSequence(folder, layout=layout, period_s=period, T_vehicle_sensor=extrinsic,
                           invert_calibration=invert_calibration,
                           gt=False if no_gt else gt, gt_association=gt_association,
                           time_offset_s=time_offset, doppler_sign=doppler_sign, name=name)
        write(select_frames(seq, start, frames, stride), out)
