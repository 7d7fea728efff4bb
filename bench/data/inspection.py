"""``bench inspect``: what is in a store (or a frame folder), and is its Doppler sign right."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from bench import guard
from bench.data.inspect_checks import clock_offset_lines, height_advice
from loaders.doppler_check import (
    SignCheck,
    doppler_kind_check,
    doppler_sign_check,
    low_points_median_z,
)
from loaders.errors import DataError
from loaders.gt import gt_for_frames
from loaders.gt_report import gt_sanity_report
from loaders.scan import Sequence
from methods.ego_velocity import speed_from_doppler

#: the first bytes of an HDF5 file (a store), and of the raw inputs a user may pass instead
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
RAW_INPUTS = ((b"#ROSBAG V2.0", "a ROS1 bag"), (b"SQLite format 3\x00", "a ROS2 bag (sqlite3)"),
              (b"\x89MCAP", "a ROS2 bag (mcap)"), (b"# .PCD", "a PCD frame"),
              (b"VERSION", "a PCD frame"))


def raw_input_kind(path: Path) -> str | None:
    """What a non-store input is ("a ROS1 bag", ...) from its first bytes or its folder (a ROS2
    bag folder holds metadata.yaml); None for anything else."""
    if path.is_dir():
        return "a ROS2 bag folder" if (path / "metadata.yaml").is_file() else None
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError:
        return None
    if head.startswith(HDF5_MAGIC):
        return None
    return next((what for magic, what in RAW_INPUTS if head.startswith(magic)), None)


def open_sequence(path: Path, period_s: float | None = None) -> Sequence:
    """A store file, or a NumPy frame folder. A raw recording (a bag, a PCD frame) is refused
    with the command that converts it."""
    path = Path(path)
    kind = raw_input_kind(path) if path.exists() else None
    if kind is not None:
        how = (f"bench convert snail-radar {path.parent} --out STORE.h5" if "PCD" in kind
               else f"bench convert rosbag {path} --out STORE.h5")
        raise DataError(f"{path}: {kind}, not a store: convert it first, e.g. `{how}` (or with "
                        "its dataset's loader: `bench datasets` lists them), then `bench "
                        "inspect STORE.h5`")
    if path.is_dir():
        from loaders.npy_frames import NpyFramesSequence

        return NpyFramesSequence(path, period_s=period_s)
    from loaders.store import StoreSequence

    return StoreSequence(path)


def default_plot(path: Path) -> Path:
    """The speed plot's default: ``NAME_speed.png`` next to the store (or frame folder), never
    inside the current folder's results/."""
    path = Path(path)
    return path.parent / f"{path.stem if path.is_file() else path.name}_speed.png"


def inspect_path(path: Path, period_s: float | None, console: Console,
                 plot: Path | None = None) -> dict:
    """Print the figures of a store or frame folder; with GT and Doppler also the
    sensor-to-GT rotation check and (``plot``) a PNG of Doppler speed against GT speed. The
    plot is checked by the output guard first: not the input, an existing file only when it is
    a plot this command wrote (its PNG metadata carries ``bench.guard.MARK``)."""
    if plot is not None:
        guard.regenerated_file(plot, guard.derived, "a speed plot", "--plot", [path])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        seq = open_sequence(path, period_s)
    for w in caught:
        console.print(f"[yellow]warning:[/] {w.message}", highlight=False)
    report = inspect_sequence(seq)
    table = Table(title=f"{path}", title_justify="left", show_header=False)
    for key, value in report["rows"]:
        table.add_row(f"[bold]{key}[/]", value)
    console.print(table)
    for finding in report["gt_findings"]:
        console.print(f"  [yellow]GT:[/] {finding}", highlight=False)
    kind = report["kind"]
    if kind is not None:
        bad = kind.measured == "ego-compensated" or kind.disagrees
        style = "yellow" if bad or kind.measured != "radial" else "green"
        console.print(f"[{style}]{escape(kind.describe())}[/]", highlight=False)
    style = "green" if report["sign"].verdict == "confirmed" else "yellow"
    console.print(f"[{style}]{report['sign'].describe()}[/]", highlight=False)
    compensated = kind is not None and kind.measured == "ego-compensated"
    if seq.ground_truth is not None and len(seq) and seq[0].doppler is not None \
            and not compensated:  # compensated Doppler carries no ego velocity to compare
        from bench.data.calibration.estimate import rotation_check, rotation_consistent_text

        cal, warning = rotation_check(seq)
        if warning:
            console.print(f"[yellow]warning:[/] {escape(warning)}")
        elif cal is not None:
            console.print(rotation_consistent_text(cal), highlight=False, markup=False)
        for style, line in clock_offset_lines(seq, speed_from_doppler(seq)):
            console.print(f"[{style}]{escape(line)}[/]", highlight=False)
        if plot is not None:
            console.print(f"speed from Doppler vs GT: {plot_speed(seq, plot)}", markup=False)
    return report


def scored_text(has_gt: np.ndarray, provenance: dict) -> str:
    """How many frames a run on the store scores: those with ground truth, less the frames
    ``bench calibrate --write`` estimated its correction on (never scored)."""
    n = len(has_gt)
    frames = (provenance.get("calibration") or {}).get("frames")
    if not frames:
        return f"{int(has_gt.sum())} of {n} have ground truth (the others run, unscored)"
    first, stop = int(frames[0]), int(frames[1])
    used = np.zeros(n, dtype=bool)
    used[max(first, 0):min(stop, n)] = True
    return (f"{int((has_gt & ~used).sum())} of {n}: {int(has_gt.sum())} have ground truth, and "
            f"frames {first}-{stop - 1}, on which bench calibrate estimated the GT correction, "
            "are run but not scored")


def calibration_text(provenance: dict) -> str:
    """What ``bench calibrate --write`` applied to a store's ground truth: the angles, from
    which estimate and frames, and the angles it left alone; "" for a store it did not write."""
    cal = provenance.get("calibration") or {}
    if not cal:
        return ""
    angles = cal.get("applied_rpy_deg") or cal.get("roll_pitch_yaw_deg") or []
    names = ("roll", "pitch", "yaw")
    left = cal.get("left_alone") or {}
    applied = ", ".join(f"{n} {float(v):+.3f}" for n, v in zip(names, angles, strict=False)
                        if n not in left) or "none"
    frames = cal.get("frames")
    text = (f"applied {applied} deg (R_gt_sensor, to {cal.get('applied_to', 'the ground truth')})"
            f" from the {cal.get('applied_estimate', 'doppler')} estimate")
    if frames:
        text += f" on frames {int(frames[0])}-{int(frames[1]) - 1}"
    if left:
        text += "; left alone (0): " + ", ".join(f"{k} ({v})" for k, v in left.items())
    return text


def inspect_sequence(seq: Sequence) -> dict:
    counts = (seq.points_per_frame() if hasattr(seq, "points_per_frame")
              else np.array([len(s) for s in seq]))
    stamps = seq.stamps
    dts = np.diff(stamps)
    rows = [
        ("name", seq.name),
        ("sensor", f"{seq.sensor.kind} ({seq.sensor.model or 'unknown model'})"),
        ("frames", f"{len(seq)}"),
        ("points per frame", f"min {counts.min()}, median {np.median(counts):.0f}, "
                             f"max {counts.max()}"),
        ("period", f"nominal {seq.sensor.period_s:.6f} s, measured median "
                   f"{np.median(dts):.6f} s" if len(dts) else f"{seq.sensor.period_s} s"),
        ("duration", f"{stamps[-1] - stamps[0]:.3f} s"),
    ]
    gt_findings: list[str] = []
    gt_poses = None
    gt = seq.ground_truth
    if gt is None:
        rows.append(("ground truth", "none"))
    else:
        rows.append(("ground truth", f"{len(gt)} poses, path length {gt.path_length_m():.2f} m"))
        sanity = gt_sanity_report(gt, stamps)
        gt_findings = list(sanity["findings"])
        if len(gt) == 0:  # the report has only its finding ("ground truth has no poses")
            rows.append(("GT coverage of scans", "0.0 % (no poses)"))
        else:
            rows.append(("GT coverage of scans", f"{sanity['scan_coverage_pct']:.1f} %, "
                         f"{sanity['repeated_poses']} repeated poses, {len(sanity['gaps'])} "
                         "gaps"))
        try:
            poses, scored = gt_for_frames(gt, stamps)
            rows.append(("frames scored", scored_text(scored, seq.provenance or {})))
            gt_poses = poses  # NaN where a frame has no GT: the sign check skips those
        except DataError as err:
            gt_findings.append(f"cannot associate GT with the scans: {err}")
    calibrated = calibration_text(seq.provenance or {})
    if calibrated:
        rows.append(("GT calibrated", calibrated))
    if seq.sensor.kind == "radar":  # elevation-sign check: the road should be below the sensor
        z = low_points_median_z(seq)
        rows.append(("height check", height_advice(seq, z)))
    kind = None
    if len(seq) and seq[0].doppler is not None:
        rows.append(("Doppler kind", f"{seq.sensor.doppler_kind} (declared by the loader)"))
        kind = doppler_kind_check(seq, gt_poses)
    if kind is not None and kind.measured == "ego-compensated":
        # the sign and speed of compensated values say nothing about the convention
        sign = SignCheck(0, np.nan, np.nan, "not checked (the Doppler is ego-compensated)")
    else:
        sign = doppler_sign_check(seq, gt_poses)
    return {"rows": rows, "gt_findings": gt_findings, "sign": sign, "kind": kind,
            "counts": counts}


def plot_speed(sequence: Sequence, path: str | Path) -> Path:
    """Speed from Doppler against GT speed over time (PNG at ``path``), for ``bench inspect``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = speed_from_doppler(sequence)
    t = s["stamps"] - s["stamps"][0]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.plot(t, s["speed_gt"], label="ground truth", color="k", lw=1.2)
    ax.plot(t, s["speed_doppler"], ".", ms=3, label="Doppler ego velocity", color="C1")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("speed [m/s]")
    ax.set_title(f"{sequence.name}: speed from Doppler vs ground truth")
    ax.legend(loc="best")
    fig.tight_layout()
    path = Path(path)
    guard.savefig(fig, path, "png", guard.derived, "a speed plot", dpi=120,
                  metadata={"Software": f"{guard.MARK} (bench inspect)"})
    plt.close(fig)
    return path
