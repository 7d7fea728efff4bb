"""``bench inspect`` (bench.data.inspection) decides on evidence: a raw recording is told from a
store by its first bytes and refused with the command that converts it, a store is opened; the
rows, the frames scored and the calibration applied are said as the data give them; and each
finding is printed in the style its verdict earns (green only when the check agrees)."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

import bench.data.calibration.estimate as estimate
import bench.data.inspection as insp
from bench import guard
from loaders.doppler_check import KindCheck, SignCheck
from loaders.errors import DataError
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.se3 import make_T
from loaders.store import write_store
from loaders.trajectory import Trajectory

PERIOD = 0.125


# -- what the input is ----------------------------------------------------------------------

@pytest.mark.parametrize("head, kind", [
    (b"#ROSBAG V2.0\nE\x00\x00", "a ROS1 bag"),
    (b"SQLite format 3\x00\x10\x00", "a ROS2 bag (sqlite3)"),
    (b"\x89MCAP0\r\n\x00\x01", "a ROS2 bag (mcap)"),
    (b"# .PCD v0.7 - Point Cloud", "a PCD frame"),
    (b"VERSION 0.7\nFIELDS x y z", "a PCD frame"),
    (b"\x89HDF\r\n\x1a\n\x00\x00\x00", None),
    (b"1403636579.76 0 0 0", None),
    (b"", None),
])
def test_a_raw_input_is_told_by_its_first_bytes(tmp_path, head, kind):
    path = tmp_path / "input"
    path.write_bytes(head)
    assert insp.raw_input_kind(path) == kind


def test_a_ros2_bag_folder_is_told_by_its_metadata(tmp_path):
    assert insp.raw_input_kind(tmp_path) is None
    (tmp_path / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert insp.raw_input_kind(tmp_path) == "a ROS2 bag folder"
    (tmp_path / "metadata.yaml").unlink()
    (tmp_path / "metadata.yaml").mkdir()
    assert insp.raw_input_kind(tmp_path) is None
    assert insp.raw_input_kind(tmp_path / "missing.bag") is None


def test_a_raw_recording_is_refused_with_the_command_that_converts_it(tmp_path):
    bag = tmp_path / "drive.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    with pytest.raises(DataError) as err:
        insp.open_sequence(bag)
    assert str(err.value) == (
        f"{bag}: a ROS1 bag, not a store: convert it first, e.g. `bench convert rosbag {bag} "
        "--out STORE.h5` (or with its dataset's loader: `bench datasets` lists them), then "
        "`bench inspect STORE.h5`")
    pcd = tmp_path / "frame.pcd"
    pcd.write_bytes(b"# .PCD v0.7\n")
    with pytest.raises(DataError, match=rf"^{pcd}: a PCD frame, not a store: convert it first, "
                                        rf"e\.g\. `bench convert snail-radar {tmp_path} --out "
                                        r"STORE\.h5`"):
        insp.open_sequence(pcd)
    (tmp_path / "metadata.yaml").write_text("x: 1\n")
    with pytest.raises(DataError, match="a ROS2 bag folder, not a store.*bench convert rosbag"):
        insp.open_sequence(tmp_path)


def _scans(n: int = 6, counts=(3, 5, 4, 6, 4, 4), doppler: bool = True) -> list[Scan]:
    rng = np.random.default_rng(0)
    out = []
    for k in range(n):
        p = rng.uniform(2, 20, (counts[k % len(counts)], 3))
        out.append(Scan(k * PERIOD, p, np.zeros(len(p)) if doppler else None))
    return out


def test_a_store_is_opened_as_a_store(tmp_path):
    seq = MemorySequence("drive", SensorInfo("radar", PERIOD), _scans())
    path = write_store(seq, tmp_path / "drive.h5")
    opened = insp.open_sequence(path)
    try:
        assert type(opened).__name__ == "StoreSequence" and len(opened) == 6
    finally:
        opened.close()


def test_the_speed_plot_goes_next_to_the_input(tmp_path):
    store = tmp_path / "a" / "drive.h5"
    store.parent.mkdir()
    store.write_bytes(b"")
    assert insp.default_plot(store) == tmp_path / "a" / "drive_speed.png"
    frames = tmp_path / "frames.d"
    frames.mkdir()
    assert insp.default_plot(frames) == tmp_path / "frames.d_speed.png"


# -- the rows ----------------------------------------------------------------------------------

def test_the_frames_scored_leave_out_the_calibration_frames():
    has = np.array([True] * 8 + [False] * 2)
    assert insp.scored_text(has, {}) == "8 of 10 have ground truth (the others run, unscored)"
    assert insp.scored_text(has, {"calibration": None}) == insp.scored_text(has, {})
    assert insp.scored_text(has, {"calibration": {"frames": None}}) == insp.scored_text(has, {})
    assert insp.scored_text(has, {"calibration": {"frames": [2, 5]}}) == (
        "5 of 10: 8 have ground truth, and frames 2-4, on which bench calibrate estimated the "
        "GT correction, are run but not scored")
    # frames past the end, or before the start, are clipped
    assert insp.scored_text(has, {"calibration": {"frames": [7, 15]}}).startswith("7 of 10:")
    assert insp.scored_text(has, {"calibration": {"frames": [-3, 1]}}).startswith("7 of 10:")
    assert insp.scored_text(has, {"calibration": {"frames": [0, 10]}}).startswith("0 of 10:")


def test_the_calibration_applied_is_said_in_full():
    assert insp.calibration_text({}) == "" and insp.calibration_text({"calibration": None}) == ""
    cal = {"applied_rpy_deg": [0.5, -2.5, 0.25], "frames": [0, 8],
           "applied_to": "ground truth and T_body_sensor (points unchanged)",
           "applied_estimate": "road plane", "left_alone": {"roll": "too wide"}}
    assert insp.calibration_text({"calibration": cal}) == (
        "applied pitch -2.500, yaw +0.250 deg (R_gt_sensor, to ground truth and T_body_sensor "
        "(points unchanged)) from the road plane estimate on frames 0-7; left alone (0): roll "
        "(too wide)")
    plain = {"roll_pitch_yaw_deg": [1.0, 0.0, -0.125]}
    assert insp.calibration_text({"calibration": plain}) == (
        "applied roll +1.000, pitch +0.000, yaw -0.125 deg (R_gt_sensor, to the ground truth) "
        "from the doppler estimate")
    # a record without angles: none applied
    assert insp.calibration_text({"calibration": {"frames": [0, 4]}}) == (
        "applied none deg (R_gt_sensor, to the ground truth) from the doppler estimate on "
        "frames 0-3")
    # the applied angles win over the estimated ones; everything left alone: none applied
    both = {"applied_rpy_deg": [0.0, 0.0, 0.0], "roll_pitch_yaw_deg": [9.0, 9.0, 9.0],
            "left_alone": {"roll": "a", "pitch": "b", "yaw": "c"}}
    assert insp.calibration_text({"calibration": both}).startswith(
        "applied none deg (R_gt_sensor, to the ground truth) from the doppler estimate; left "
        "alone (0): roll (a), pitch (b), yaw (c)")


def _gt(n: int, speed: float = 4.0) -> Trajectory:
    t = np.arange(n) * PERIOD
    return Trajectory(t, np.array([make_T(np.eye(3), np.array([speed * s, 0.0, 0.0]))
                                   for s in t]))


def test_the_rows_of_a_store_without_ground_truth():
    seq = MemorySequence("drive", SensorInfo("lidar", PERIOD, model="aeva"), _scans())
    report = insp.inspect_sequence(seq)
    rows = dict(report["rows"])
    assert rows == {"name": "drive", "sensor": "lidar (aeva)", "frames": "6",
                    "points per frame": "min 3, median 4, max 6",
                    "period": "nominal 0.125000 s, measured median 0.125000 s",
                    "duration": "0.625 s", "ground truth": "none",
                    "Doppler kind": "radial (declared by the loader)"}
    assert [k for k, _ in report["rows"]][:2] == ["name", "sensor"]
    np.testing.assert_array_equal(report["counts"], [3, 5, 4, 6, 4, 4])
    assert report["sign"].verdict == "not checked (no ground truth)"
    assert report["kind"].measured == "not checked (no ground truth)"
    assert report["gt_findings"] == []


def test_one_frame_without_doppler_on_a_radar():
    scans = [Scan(0.0, np.column_stack([np.full(300, 10.0), np.zeros(300), np.full(300, -0.5)]))]
    seq = MemorySequence("one", SensorInfo("radar", PERIOD), scans)
    report = insp.inspect_sequence(seq)
    rows = dict(report["rows"])
    assert rows["sensor"] == "radar (unknown model)" and rows["period"] == "0.125 s"
    assert rows["duration"] == "0.000 s" and "Doppler kind" not in rows
    assert rows["height check"].startswith("densest layer at z = -0.50 m")
    assert report["kind"] is None and report["sign"].verdict == "not checked (no ground truth)"


def test_the_rows_with_ground_truth_and_the_sign_checked():
    n = 24
    rng = np.random.default_rng(1)
    scans = []
    for k in range(n):
        p = rng.uniform(-1, 1, (150, 3)) * [30, 30, 2] + [40, 0, 0]
        d = -(p / np.linalg.norm(p, axis=1, keepdims=True)) @ np.array([4.0, 0, 0])
        scans.append(Scan(k * PERIOD, p, d))
    seq = MemorySequence("gt", SensorInfo("lidar", PERIOD), scans, _gt(n))
    report = insp.inspect_sequence(seq)
    rows = dict(report["rows"])
    assert rows["ground truth"] == f"24 poses, path length {4.0 * 23 * PERIOD:.2f} m"
    assert rows["GT coverage of scans"] == "100.0 %, 0 repeated poses, 0 gaps"
    assert rows["frames scored"] == "24 of 24 have ground truth (the others run, unscored)"
    assert report["sign"].verdict == "confirmed" and report["sign"].frames_used == 24
    assert report["kind"].measured == "radial"
    # the same scans with the motion removed: the sign is not checked on them
    comp = MemorySequence("c", SensorInfo("lidar", PERIOD, doppler_kind="ego-compensated"),
                          [Scan(s.stamp, s.points, np.zeros(len(s))) for s in scans], _gt(n))
    report = insp.inspect_sequence(comp)
    assert report["kind"].measured == "ego-compensated"
    assert report["sign"].verdict == "not checked (the Doppler is ego-compensated)"
    assert report["sign"].frames_used == 0
    assert np.isnan(report["sign"].median_cosine) and np.isnan(report["sign"].median_speed_ratio)


def test_ground_truth_out_of_time_order_is_a_finding_not_a_crash():
    gt = _gt(6)
    bad = Trajectory(gt.stamps[[0, 1, 3, 2, 4, 5]], gt.poses)
    seq = MemorySequence("bad", SensorInfo("lidar", PERIOD), _scans(doppler=False), bad)
    report = insp.inspect_sequence(seq)
    assert any(f.startswith("cannot associate GT with the scans: ") for f in
               report["gt_findings"])
    assert "frames scored" not in dict(report["rows"])
    assert report["sign"].verdict == "not checked (no ground truth)"


# -- what bench inspect prints -----------------------------------------------------------------

class Recorder:
    def __init__(self):
        self.lines: list[str] = []
        self.kwargs: list[dict] = []

    def print(self, what="", **kwargs):
        self.lines.append(what if isinstance(what, str) else f"<{type(what).__name__}>")
        self.kwargs.append(kwargs)


def _show(monkeypatch, tmp_path, seq, kind, sign, findings=(), warn=None, plot=None,
          rotation=(None, None)):
    def opened(path, period_s):
        if warn:
            import warnings

            warnings.warn(warn, stacklevel=1)
        return seq

    calls = {}
    monkeypatch.setattr(insp, "open_sequence", opened)
    monkeypatch.setattr(insp, "inspect_sequence", lambda s: {
        "rows": [("name", s.name)], "gt_findings": list(findings), "sign": sign,
        "kind": kind, "counts": None})
    monkeypatch.setattr(insp, "speed_from_doppler", lambda s: {"seq": s})
    monkeypatch.setattr(insp, "clock_offset_lines",
                        lambda s, speeds: [("green", f"clock of {speeds['seq'].name} [ok]")])
    monkeypatch.setattr(estimate, "rotation_check",
                        lambda s: calls.setdefault("rotation", rotation))
    monkeypatch.setattr(estimate, "rotation_consistent_text", lambda cal: f"consistent {cal}")

    def plotted(s, path):
        assert s is seq
        calls["plot"] = path
        return path

    monkeypatch.setattr(insp, "plot_speed", plotted)
    console = Recorder()
    insp.inspect_path(tmp_path / "x.h5", None, console, plot)
    return console, calls


RADIAL = KindCheck("radial", 10, 0.9, 0.0, "radial")
CONFIRMED = SignCheck(10, 1.0, 1.0, "confirmed")


def _with_gt(doppler=True):
    return MemorySequence("g", SensorInfo("radar", PERIOD), _scans(doppler=doppler), _gt(6))


def test_agreeing_checks_are_green_and_the_gt_checks_follow(monkeypatch, tmp_path):
    console, calls = _show(monkeypatch, tmp_path, _with_gt(), RADIAL, CONFIRMED,
                           findings=["3 gaps"], warn="12 NaN points dropped",
                           rotation=("CAL", None))
    assert console.lines == [
        "[yellow]warning:[/] 12 NaN points dropped", "<Table>", "  [yellow]GT:[/] 3 gaps",
        f"[green]{RADIAL.describe()}[/]", f"[green]{CONFIRMED.describe()}[/]",
        "consistent CAL", "[green]clock of g \\[ok][/]"]
    assert console.kwargs[-2] == {"highlight": False, "markup": False}
    # the warning and the clock line are printed as they are, no number highlighted
    assert console.kwargs[0] == console.kwargs[-1] == {"highlight": False}
    assert "plot" not in calls


@pytest.mark.parametrize("kind, style", [
    (KindCheck("radial", 10, 0.1, 0.9, "ego-compensated"), "yellow"),
    (KindCheck("ego-compensated", 10, 0.1, 0.9, "ego-compensated"), "yellow"),
    (KindCheck("ego-compensated", 10, 0.9, 0.1, "radial"), "yellow"),
    (KindCheck("radial", 10, 0.4, 0.4, "inconclusive"), "yellow"),
    (KindCheck("radial", 0, np.nan, np.nan, "not checked (no ground truth)"), "yellow"),
    (KindCheck("gt-reconstructed", 10, 0.9, 0.0, "radial"), "green"),
])
def test_the_kind_is_green_only_when_measured_radial_and_agreeing(monkeypatch, tmp_path, kind,
                                                                  style):
    seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())
    console, _ = _show(monkeypatch, tmp_path, seq, kind, CONFIRMED)
    assert console.lines[1] == f"[{style}]{kind.describe()}[/]"


@pytest.mark.parametrize("verdict", ["appears FLIPPED", "inconclusive",
                                     "not checked (no ground truth)"])
def test_a_sign_not_confirmed_is_yellow(monkeypatch, tmp_path, verdict):
    seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())
    sign = SignCheck(0, np.nan, np.nan, verdict)
    console, _ = _show(monkeypatch, tmp_path, seq, None, sign)
    assert console.lines == ["<Table>", f"[yellow]{sign.describe()}[/]"]


def test_a_rotation_warning_and_the_plot(monkeypatch, tmp_path):
    plot = tmp_path / "speed.png"
    console, calls = _show(monkeypatch, tmp_path, _with_gt(), RADIAL, CONFIRMED, plot=plot,
                           rotation=("CAL", "rotated [by] 3 deg"))
    assert "[yellow]warning:[/] rotated \\[by] 3 deg" in console.lines
    assert not any(line.startswith("consistent") for line in console.lines)
    assert console.lines[-1] == f"speed from Doppler vs GT: {plot}"
    assert console.kwargs[-1] == {"markup": False}  # a path is no markup
    assert calls["plot"] == plot
    # no calibration could be made and no warning: nothing about the rotation
    console, _ = _show(monkeypatch, tmp_path, _with_gt(), RADIAL, CONFIRMED)
    assert not any("consistent" in line or "warning" in line for line in console.lines)


@pytest.mark.parametrize("case", ["compensated", "no gt", "no doppler", "no scans"])
def test_the_gt_checks_need_gt_and_raw_doppler(monkeypatch, tmp_path, case):
    kind = RADIAL
    seq = _with_gt()
    if case == "compensated":
        kind = KindCheck("radial", 10, 0.1, 0.9, "ego-compensated")
    elif case == "no gt":
        seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())
    elif case == "no doppler":
        seq = _with_gt(doppler=False)
    else:
        seq = MemorySequence("n", SensorInfo("radar", PERIOD), [], _gt(6))
    console, calls = _show(monkeypatch, tmp_path, seq, kind, CONFIRMED,
                           plot=tmp_path / "speed.png", rotation=("CAL", None))
    assert calls == {}
    assert not any("clock" in line or "consistent" in line for line in console.lines)


def test_an_existing_file_is_not_taken_for_the_plot(monkeypatch, tmp_path):
    mine = tmp_path / "notes.png"
    mine.write_bytes(b"not a plot of ours")
    with pytest.raises(guard.Refused, match="--plot"):
        insp.inspect_path(tmp_path / "x.h5", None, Recorder(), mine)


def test_the_speed_plot_is_a_png_marked_as_ours(monkeypatch, tmp_path):
    t = np.arange(20) * PERIOD
    monkeypatch.setattr(insp, "speed_from_doppler", lambda s: {
        "stamps": t + 100, "speed_gt": 4 + 0 * t, "speed_doppler": 4 + 0.1 * np.sin(t)})
    seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())
    out = insp.plot_speed(seq, str(tmp_path / "speed.png"))
    assert out == tmp_path / "speed.png"
    with Image.open(out) as image:
        assert image.format == "PNG"
        assert image.info["Software"] == f"{guard.MARK} (bench inspect)"
        assert image.size == (960, 384)  # 8 x 3.2 in at 120 dpi


def test_the_plot_may_not_be_the_input_and_its_refusal_names_the_option(tmp_path):
    store = tmp_path / "x.h5"
    store.write_bytes(b"\x89HDF\r\n\x1a\n")
    with pytest.raises(guard.Refused, match=rf"^--plot {store}: is an input of this command"):
        insp.inspect_path(store, None, Recorder(), store)
    mine = tmp_path / "notes.png"
    mine.write_bytes(b"not a plot of ours")
    with pytest.raises(guard.Refused) as err:
        insp.inspect_path(store, None, Recorder(), mine)
    assert str(err.value) == (f"--plot {mine}: exists and is not a speed plot this command "
                              "wrote; it is left as it is: choose another --plot")


def test_the_table_is_titled_by_the_input_and_the_period_is_passed_on(monkeypatch, tmp_path):
    seen = {}
    seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())

    def opened(path, period_s):
        seen["args"] = (path, period_s)
        return seq

    monkeypatch.setattr(insp, "open_sequence", opened)
    monkeypatch.setattr(insp, "inspect_sequence", lambda s: {
        "rows": [("name", "n"), ("frames", "6")], "gt_findings": ["a gap"], "sign": CONFIRMED,
        "kind": RADIAL, "counts": None})
    printed = []

    class Keep:
        def print(self, what="", **kwargs):
            printed.append((what, kwargs))

    insp.inspect_path(tmp_path / "x.h5", 0.25, Keep())
    assert seen["args"] == (tmp_path / "x.h5", 0.25)
    table, kwargs = printed[0]
    assert table.title == str(tmp_path / "x.h5") and table.title_justify == "left"
    assert table.show_header is False and kwargs == {}
    assert [c._cells for c in table.columns] == [["[bold]name[/]", "[bold]frames[/]"],
                                                 ["n", "6"]]
    # the findings and verdicts are printed as they are, no number highlighted
    assert all(kwargs == {"highlight": False} for _, kwargs in printed[1:])


def test_the_speed_plot_shows_both_speeds_against_time_from_the_first_scan(monkeypatch,
                                                                         tmp_path):
    t = np.arange(20) * PERIOD
    seq = MemorySequence("drive", SensorInfo("radar", PERIOD), _scans())
    given = []

    def speeds(s):
        given.append(s)
        return {"stamps": t + 100, "speed_gt": 4 + 0 * t, "speed_doppler": 4 + 0.1 * np.sin(t)}

    monkeypatch.setattr(insp, "speed_from_doppler", speeds)
    figures = []
    save = guard.savefig

    def keep(fig, *args, **kwargs):
        ax = fig.axes[0]
        figures.append({
            "lines": [(line.get_xdata(), line.get_ydata(), line.get_label(), line.get_marker())
                      for line in ax.lines],
            "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(), "title": ax.get_title(),
            "legend": [x.get_text() for x in ax.get_legend().get_texts()]})
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(insp.guard, "savefig", keep)
    insp.plot_speed(seq, tmp_path / "speed.png")
    assert given == [seq]
    (fig,) = figures
    (x_gt, y_gt, label_gt, _), (x_d, y_d, label_d, marker) = fig["lines"]
    np.testing.assert_allclose(x_gt, t, atol=1e-12)
    np.testing.assert_allclose(x_d, t, atol=1e-12)
    np.testing.assert_allclose(y_gt, 4.0)
    np.testing.assert_allclose(y_d, 4 + 0.1 * np.sin(t))
    assert (label_gt, label_d, marker) == ("ground truth", "Doppler ego velocity", ".")
    assert fig["legend"] == ["ground truth", "Doppler ego velocity"]
    assert (fig["xlabel"], fig["ylabel"]) == ("time [s]", "speed [m/s]")
    assert fig["title"] == "drive: speed from Doppler vs ground truth"


def test_a_single_scan_with_gt_and_doppler_gets_the_gt_checks(monkeypatch, tmp_path):
    seq = MemorySequence("one", SensorInfo("radar", PERIOD), _scans(n=1), _gt(6))
    console, calls = _show(monkeypatch, tmp_path, seq, RADIAL, CONFIRMED,
                           rotation=("CAL", None))
    assert calls == {"rotation": ("CAL", None)}
    assert console.lines[-2:] == ["consistent CAL", "[green]clock of one \\[ok][/]"]


def test_a_frame_folder_is_opened_with_the_period_given(sample_dir):
    with pytest.warns(UserWarning, match="GT rows repeat the previous pose"):  # the sample's
        seq = insp.open_sequence(sample_dir, 0.125)
    assert type(seq).__name__ == "NpyFramesSequence" and len(seq) == 60
    np.testing.assert_allclose(np.diff(seq.stamps), 0.125)


def test_the_plot_is_not_written_over_a_file_of_someone_elses(monkeypatch, tmp_path):
    t = np.arange(20) * PERIOD
    monkeypatch.setattr(insp, "speed_from_doppler", lambda s: {
        "stamps": t, "speed_gt": 4 + 0 * t, "speed_doppler": 4 + 0 * t})
    theirs = tmp_path / "speed.png"
    theirs.write_bytes(b"a photo")
    seq = MemorySequence("n", SensorInfo("radar", PERIOD), _scans())
    with pytest.raises(guard.Refused) as err:
        insp.plot_speed(seq, theirs)
    assert str(err.value) == (f"{theirs}: exists and is not a speed plot the harness wrote; it "
                              "is left as it is: choose another output")
    assert theirs.read_bytes() == b"a photo"


def test_ground_truth_without_poses_is_a_finding_not_a_crash():
    """A store whose ground truth has no poses: inspect says so (it raised KeyError)."""
    empty = Trajectory(np.zeros(0), np.zeros((0, 4, 4)))
    seq = MemorySequence("e", SensorInfo("lidar", PERIOD), _scans(), empty)
    report = insp.inspect_sequence(seq)
    rows = dict(report["rows"])
    assert rows["ground truth"] == "0 poses, path length 0.00 m"
    assert rows["GT coverage of scans"] == "0.0 % (no poses)"
    assert rows["frames scored"] == "0 of 6 have ground truth (the others run, unscored)"
    assert report["gt_findings"] == ["ground truth has no poses"]
    assert report["sign"].verdict == "inconclusive (no moving frames)"


def test_the_duration_is_from_the_first_scan_to_the_last():
    scans = [Scan(100.0 + k * PERIOD, np.ones((3, 3)) * (k + 2)) for k in range(6)]
    seq = MemorySequence("late", SensorInfo("lidar", PERIOD), scans)
    assert dict(insp.inspect_sequence(seq)["rows"])["duration"] == "0.625 s"
