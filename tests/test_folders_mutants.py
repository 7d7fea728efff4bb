"""bench.runs.folders: what the mutation run (``tools/mutate.py``) found untested.

Runs are written with ``write_run`` / ``write_failure`` from records made here (no method
runs), and read back; trajectories are checked against SciPy's rotations and NumPy's own
reading of the files."""

from __future__ import annotations

import csv
import io
import json
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from bench.runs import folders
from bench.runs.folders import (
    BROKEN,
    FRAME_COLUMNS,
    BrokenRecord,
    _rows,
    check_record,
    clear_run,
    frames_csv,
    is_finished,
    load_runs,
    metrics_raw,
    read_run,
    read_run_tum,
    run_dir_name,
    write_failure,
    write_run,
)
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult
from methods.registry import Seed

# ---- folder names ---------------------------------------------------------------------------

@pytest.mark.parametrize("method, seed, label, expected", [
    ("doppler", None, None, "doppler"),
    ("icp-p2p", True, None, "icp-p2p_seed"),
    ("icp-p2p", False, None, "icp-p2p_noseed"),
    ("icp-p2p", Seed.WITH, "", "icp-p2p_seed"),
    ("doppler", None, "  tau = 1.0 / fast+ ", "tau-1.0-fast+"),
    ("icp-p2p", False, "a_b.c", "a_b.c_noseed"),
])
def test_a_run_folder_is_named_by_method_or_label_and_seed(method, seed, label, expected):
    assert run_dir_name(method, seed, label) == expected


# ---- writing a run --------------------------------------------------------------------------

N = 12


def _poses(n: int = N) -> np.ndarray:
    rot = Rotation.from_euler("zyx", np.column_stack([np.linspace(0, 1.3, n),
                                                      np.linspace(0, 0.2, n),
                                                      np.linspace(0, -0.1, n)]))
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = rot.as_matrix()
    poses[:, :3, 3] = np.column_stack([np.arange(n) / 3.0, np.sqrt(np.arange(n)),
                                       np.full(n, 0.1)])
    return poses


def _result(n: int = N) -> OdometryResult:
    frames = [FrameRecord(i, 100.0 + i / 7, 1.0 / 3 + i, 1000 + i, 500 + i, 3, i % 4 != 1,
                          register_ms=0.25 * i, wall_ms=2.0 / 3 * i, replaced=i % 5 == 4)
              for i in range(n)]
    return OdometryResult(100.0 + np.arange(n) / 7, _poses(n), frames)


def _config(**extra) -> dict:
    return {"run_key": "k1", "label": None, "method": {"name": "doppler", "params": {}},
            "sequence": {"name": "seq", "display_name": "Seq One", "sensor_class": "radar",
                         "store": "/data/seq.h5"}, **extra}


def _metrics(n: int = N, **extra) -> dict:
    return {"sequence": "seq", "method": "doppler", "seed": None, "frames": n,
            "frames_scored": n, "diverged": False, **extra}


def _write(run_dir: Path, gt: Trajectory | None, config=None, metrics=None, warnings=None):
    result = _result()
    write_run(run_dir, result, gt, config or _config(), metrics or _metrics(), warnings)
    return result


def test_a_run_with_ground_truth_for_some_frames(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    result = _result()
    keep = np.r_[0:4, 7:N]
    gt = Trajectory(result.stamps[keep], result.poses[keep] + 0.0)
    _write(run_dir, gt, warnings=["few points", "few points again"])
    every = np.loadtxt(run_dir / "est_all_tum.txt")
    assert len(every) == N
    np.testing.assert_array_equal(every[:, 0], result.stamps)
    for name in ("est_tum.txt", "gt_tum.txt"):
        rows = np.loadtxt(run_dir / name)
        np.testing.assert_array_equal(rows[:, 0], result.stamps[keep])  # 17 digits: exact
        np.testing.assert_array_equal(rows[:, 1:4], result.poses[keep][:, :3, 3])
        quat = Rotation.from_matrix(result.poses[keep][:, :3, :3]).as_quat()  # x y z w
        sign = np.sign(np.sum(rows[:, 4:] * quat, axis=1))[:, None]
        np.testing.assert_allclose(rows[:, 4:] * sign, quat, atol=1e-12)
    for name in ("est_kitti.txt", "gt_kitti.txt"):
        rows = np.loadtxt(run_dir / name)
        np.testing.assert_array_equal(rows, result.poses[keep][:, :3, :].reshape(-1, 12))
    record = json.loads((run_dir / "metrics.json").read_text())
    assert record["display_name"] == "Seq One" and record["sensor_class"] == "radar"
    assert record["notes"] == ["few points", "few points again"]
    assert record["label"] is None and record["frames"] == N
    meta = json.loads((run_dir / "meta.json").read_text())
    assert meta["warnings"] == ["few points", "few points again"] and "git" in meta
    config = (run_dir / "config.yaml").read_text()
    assert list(yaml.safe_load(config)) == ["run_key", "label", "method", "sequence"]


def test_a_run_without_ground_truth_replaces_an_older_runs_files(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    result = _result()
    gt = Trajectory(result.stamps[2:], result.poses[2:])
    _write(run_dir, gt)
    write_failure(run_dir, _config(), "boom")
    assert (run_dir / "failed.json").exists()
    _write(run_dir, None, config=_config(label="L"), warnings=None)
    names = sorted(p.name for p in run_dir.iterdir())
    assert names == ["config.yaml", "est_kitti.txt", "est_tum.txt", "frames.csv", "meta.json",
                     "metrics.json"]
    assert len(np.loadtxt(run_dir / "est_tum.txt")) == N
    record = json.loads((run_dir / "metrics.json").read_text())
    assert record["label"] == "L" and record["notes"] == []
    assert json.loads((run_dir / "meta.json").read_text())["warnings"] == []


def test_a_run_whose_config_has_no_sequence_part(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None, config={"run_key": "k", "method": {"name": "doppler"}})
    record = json.loads((run_dir / "metrics.json").read_text())
    assert record["display_name"] is None and record["sensor_class"] is None


def test_every_frame_is_a_row_of_frames_csv():
    result = _result(3)
    rows = list(csv.reader(io.StringIO(frames_csv(result))))
    assert rows[0] == FRAME_COLUMNS == ["index", "stamp", "time_ms", "register_ms", "wall_ms",
                                        "points", "correspondences", "iterations",
                                        "converged", "replaced"]
    assert rows[1:] == [
        ["0", "100.000000000", "0.333333", "0.000000", "0.000000", "1000", "500", "3", "1",
         "0"],
        ["1", "100.142857143", "1.333333", "0.250000", "0.666667", "1001", "501", "3", "0",
         "0"],
        ["2", "100.285714286", "2.333333", "0.500000", "1.333333", "1002", "502", "3", "1",
         "0"]]
    assert frames_csv(_result(5)).splitlines()[-1].endswith(",1,1")  # frame 4 replaced


def test_rows_are_exact_and_empty_for_no_values():
    values = np.array([[0.1, 1 / 3, -2e-300], [np.pi, 1e17 + 2, 5.0]])
    text = _rows(values)
    assert text.endswith("\n") and len(text.splitlines()) == 2
    np.testing.assert_array_equal(np.loadtxt(io.StringIO(text)), values)
    assert _rows(np.zeros((0, 3))) == ""


def test_a_failure_is_recorded_and_the_finished_record_removed(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    write_failure(run_dir, None, "it broke", "Traceback ...", status="timeout")
    assert not (run_dir / "metrics.json").exists()
    info = json.loads((run_dir / "failed.json").read_text())
    assert {k: info[k] for k in ("status", "error", "traceback")} == {
        "status": "timeout", "error": "it broke", "traceback": "Traceback ..."}
    assert abs(time.time() - _epoch(info["date"])) < 60
    assert yaml.safe_load((run_dir / "config.yaml").read_text())["run_key"] == "k1"  # kept
    write_failure(run_dir, _config(run_key="k2"), "again")
    info = json.loads((run_dir / "failed.json").read_text())
    assert info["status"] == "failed" and info["traceback"] == ""
    config = yaml.safe_load((run_dir / "config.yaml").read_text())
    assert config["run_key"] == "k2"
    assert list(config) == ["run_key", "label", "method", "sequence"]  # the order given


def _epoch(date: str) -> float:
    from datetime import datetime

    parsed = datetime.fromisoformat(date)
    assert parsed.utcoffset().total_seconds() == 0 and parsed.microsecond == 0
    return parsed.timestamp()


def test_clear_run_removes_the_records_only(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    (run_dir / "failed.json").write_text("{}")
    clear_run(run_dir)
    assert not (run_dir / "metrics.json").exists() and not (run_dir / "failed.json").exists()
    assert (run_dir / "est_tum.txt").exists() and (run_dir / "config.yaml").exists()


# ---- is_finished ----------------------------------------------------------------------------

def test_a_run_is_finished_with_its_key_clean_timing_and_libraries(tmp_path):
    from importlib import metadata

    run_dir = tmp_path / "seq" / "doppler"
    assert not is_finished(run_dir) and not is_finished(run_dir, "k1")
    numpy = metadata.version("numpy")
    _write(run_dir, None, config=_config(libraries={"numpy": numpy}))
    assert is_finished(run_dir) and is_finished(run_dir, "k1")
    assert not is_finished(run_dir, "k2")
    _write(run_dir, None, config=_config(libraries={"numpy": "0.0.1"}))
    assert is_finished(run_dir) and not is_finished(run_dir, "k1")
    _write(run_dir, None, metrics=_metrics(timing_clean=False))
    assert is_finished(run_dir) and not is_finished(run_dir, "k1")
    _write(run_dir, None, metrics=_metrics(timing_clean=True))
    assert is_finished(run_dir, "k1")


@pytest.mark.parametrize("config", ["run_key: [unclosed", "- a list\n", ""])
def test_a_run_whose_config_is_unreadable_is_not_finished(tmp_path, config):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    (run_dir / "config.yaml").write_text(config)
    assert not is_finished(run_dir, "k1")


def test_a_run_whose_config_is_missing_or_metrics_broken_is_not_finished(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    (run_dir / "metrics.json").write_text('{"schema": 2, "frames": "many"}')
    assert not is_finished(run_dir) and not is_finished(run_dir, "k1")
    (run_dir / "metrics.json").write_text("[1, 2]")
    assert not is_finished(run_dir) and not is_finished(run_dir, "k1")
    _write(run_dir, None)
    (run_dir / "config.yaml").unlink()
    assert not is_finished(run_dir, "k1") and is_finished(run_dir)


# ---- reading a run --------------------------------------------------------------------------

def test_a_run_read_back_names_its_sequence_method_and_seed(tmp_path):
    run_dir = tmp_path / "seq" / "icp_seed"
    result = _result()
    _write(run_dir, Trajectory(result.stamps[1:], result.poses[1:]),
           config=_config(label="from-config", sequence={"name": "seq", "doppler_kind": "ego"}),
           metrics=_metrics(method="icp", seed=True))
    run = read_run(run_dir)
    assert run.method == "icp" and run.seed is Seed.WITH and run.label == "from-config"
    assert run.sequence == "seq" and run.display_name == "seq" and run.base_display_name == "seq"
    assert run.sensor_class == "4D sensor" and run.doppler_kind == "ego"
    assert run.diverged is False and run.has_gt
    np.testing.assert_array_equal(run.stamps, result.stamps[1:])
    np.testing.assert_allclose(run.gt, result.poses[1:], atol=1e-12)
    np.testing.assert_allclose(run.est, result.poses[1:], atol=1e-12)
    tagged = folders.replace(run, sequence_tag="frames 1-11")
    assert tagged.sequence == "seq [frames 1-11]" and tagged.display_name == "seq [frames 1-11]"


def test_the_display_names_fall_back_from_the_record_to_the_config(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    run = read_run(run_dir)
    assert run.display_name == "Seq One" and run.sensor_class == "radar"
    assert run.doppler_kind == "radial" and not run.has_gt and run.label is None
    record = json.loads((run_dir / "metrics.json").read_text())
    record.update(display_name=None, sensor_class=None)
    (run_dir / "metrics.json").write_text(json.dumps(record))
    run = read_run(run_dir)
    assert run.base_display_name == "Seq One" and run.sensor_class == "radar"


def test_the_estimate_is_paired_with_the_ground_truth_by_stamp(tmp_path):
    """gt_tum.txt may hold stamps est_tum.txt lacks (an edited folder): only stamps within
    1 microsecond pair."""
    run_dir = tmp_path / "seq" / "doppler"
    result = _result()
    _write(run_dir, Trajectory(result.stamps, result.poses))
    assert not (run_dir / "est_all_tum.txt").exists()  # every frame has ground truth
    est = np.loadtxt(run_dir / "est_tum.txt")
    est[3, 0] += 5e-7  # still the same frame
    est = np.delete(est, 6, axis=0)
    (run_dir / "est_tum.txt").write_text("".join(" ".join(f"{v:.17g}" for v in row) + "\n"
                                                 for row in est))
    run = read_run(run_dir)
    expected = np.delete(result.stamps, 6)
    np.testing.assert_array_equal(run.stamps, expected)
    np.testing.assert_allclose(run.est[:, :3, 3], np.delete(result.poses, 6, axis=0)[:, :3, 3])


def test_a_trajectory_file_is_read_once_per_version_and_given_as_a_copy(tmp_path):
    path = tmp_path / "t.txt"
    path.write_text("0 1 2 3 0 0 0 1\n1 2 3 4 0 0 0 1\n")
    first = read_run_tum(path)
    first.poses[:] = 0.0
    again = read_run_tum(path)
    np.testing.assert_array_equal(again.poses[:, :3, 3], [[1, 2, 3], [2, 3, 4]])
    mtime = path.stat().st_mtime_ns
    path.write_text("0 7 7 7 0 0 0 1\n1 8 8 8 0 0 0 1\n")  # the same size, a later time
    os.utime(path, ns=(mtime, mtime + 10**9))
    np.testing.assert_array_equal(read_run_tum(path).poses[:, :3, 3], [[7, 7, 7], [8, 8, 8]])
    path.write_text("0 9 9 9 0 0 0 1\n")  # another size, the same time
    os.utime(path, ns=(mtime, mtime + 10**9))
    np.testing.assert_array_equal(read_run_tum(path).poses[:, :3, 3], [[9, 9, 9]])


def test_a_config_with_parts_of_the_wrong_kind_reads_without_them(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    (run_dir / "config.yaml").write_text(yaml.safe_dump(
        {"sequence": "just a name", "method": ["a"], "identity": 3, "label": "kept",
         "lengths_m": [1.0]}))
    run = read_run(run_dir)
    assert run.config == {"label": "kept", "lengths_m": [1.0]}
    (run_dir / "config.yaml").write_text("- not\n- a mapping\n")
    assert read_run(run_dir).config == {}
    (run_dir / "config.yaml").write_text("a: [broken")
    assert read_run(run_dir).config == {}


# ---- runs that did not finish ---------------------------------------------------------------

@pytest.mark.parametrize("name, seed, method", [
    ("icp_noseed", Seed.WITHOUT, "icp"), ("icp_seed", Seed.WITH, "icp"),
    ("doppler", Seed.NONE, "doppler")])
def test_a_failed_run_without_config_is_named_by_its_folders(tmp_path, name, seed, method):
    run_dir = tmp_path / "the-seq" / name
    run_dir.mkdir(parents=True)
    (run_dir / "failed.json").write_text(json.dumps({"status": "crashed", "error": "oom"}))
    assert read_run(run_dir) is None
    run = read_run(run_dir, failed=True)
    assert (run.result.status, run.result.error) == ("crashed", "oom")
    assert run.result.sequence == "the-seq" and run.method == method and run.seed is seed


def test_a_run_that_failed_after_an_older_run_has_no_ground_truth_to_show(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    result = _result()
    _write(run_dir, Trajectory(result.stamps, result.poses))
    assert read_run(run_dir).has_gt
    write_failure(run_dir, None, "broke")
    run = read_run(run_dir, failed=True)
    assert (run_dir / "gt_tum.txt").exists() and not run.has_gt


def test_a_failed_run_with_config_is_named_by_it(tmp_path):
    run_dir = tmp_path / "folder" / "x_seed"
    write_failure(run_dir, _config(seed=False, label="L"), "bad", status="done")
    run = read_run(run_dir, failed=True)
    assert run.result.status == "failed"  # a failure record never reads as finished
    assert run.result.sequence == "seq" and run.method == "doppler"
    assert run.seed is Seed.WITHOUT and run.label == run.result.label == "L"
    assert run.result.display_name == "Seq One" and run.result.sensor_class == "radar"


@pytest.mark.parametrize("text", ["not json", "[1]", json.dumps({"status": None})])
def test_an_unreadable_failure_record_is_a_failed_run(tmp_path, text):
    run_dir = tmp_path / "seq" / "doppler"
    run_dir.mkdir(parents=True)
    (run_dir / "failed.json").write_text(text)
    result = read_run(run_dir, failed=True).result
    assert result.status == "failed"
    if text != json.dumps({"status": None}):
        assert result.error == f"{run_dir / 'failed.json'}: unreadable"
    else:
        assert result.error == ""


# ---- broken records -------------------------------------------------------------------------

@pytest.mark.parametrize("text, message", [
    ("{truncated", r"metrics\.json: not valid JSON \(.*\); expected the record a finished run "
                   r"writes \(`bench run` runs it again\)$"),
    ("[1, 2]", r"metrics\.json: expected a JSON object \(a run's record\), found list$"),
    ('{"schema": true}', r"metrics\.json: not a valid run record: field schema: should be an "
                         r"integer \(got True\)$"),
    ('{"schema": "2"}', r"field schema: should be an integer \(got '2'\)$"),
])
def test_a_broken_metrics_file_is_named_with_what_was_expected(tmp_path, text, message):
    path = tmp_path / "metrics.json"
    path.write_text(text)
    with pytest.raises(BrokenRecord, match=message):
        metrics_raw(path)
    assert check_record(path) is not None


def test_an_unreadable_metrics_file_says_so(tmp_path):
    with pytest.raises(BrokenRecord, match=r"metrics\.json: cannot be read \(.+\)$"):
        metrics_raw(tmp_path / "metrics.json")
    assert metrics_raw(_ok(tmp_path)) == json.loads(_ok(tmp_path).read_text())


def _ok(tmp_path: Path) -> Path:
    path = tmp_path / "ok" / "metrics.json"
    if not path.exists():
        path.parent.mkdir(exist_ok=True)
        path.write_text(json.dumps({"schema": 2, "sequence": "s", "method": "m"}))
    return path


def test_a_broken_record_is_a_broken_row_when_failures_are_read(tmp_path):
    run_dir = tmp_path / "seq" / "doppler"
    _write(run_dir, None)
    (run_dir / "metrics.json").write_text('{"schema": 2, "sequence": "seq", "method": "d", '
                                          '"frames": "many"}')
    with pytest.raises(BrokenRecord, match="not a valid run record: field frames"):
        read_run(run_dir)
    run = read_run(run_dir, failed=True)
    assert run.result.status == BROKEN == "broken"
    assert "not a valid run record: field frames" in run.result.error
    assert check_record(run_dir / "metrics.json") == run.result.error
    (run_dir / "metrics.json").write_text("{")
    assert "not valid JSON" in read_run(run_dir, failed=True).result.error
    with pytest.raises(BrokenRecord):
        read_run(run_dir)


# ---- older records --------------------------------------------------------------------------

def _old_run(run_dir: Path, with_files: bool = True, lengths=(2.0,), **fields) -> dict:
    result = _result(40)
    gt = Trajectory(result.stamps, result.poses)
    est_poses = result.poses.copy()
    est_poses[:, 0, 3] *= 1.05
    est = OdometryResult(result.stamps, est_poses, result.frames)
    config = _config(lengths_m=list(lengths)) if lengths else _config()
    write_run(run_dir, est, gt, config, _metrics(40))
    old = {"sequence": "seq", "method": "doppler", "seed": None, "diverged": True,
           "frames": 40, "time_ms": {"median": 4.0, "mean": 4.0, "p95": 5.0},
           "wall_ms": {"median": 6.0},
           "relative_error": {"3.0": {"trans_m_mean": 99.0}}, **fields}
    (run_dir / "metrics.json").write_text(json.dumps(old))
    if not with_files:
        (run_dir / "gt_tum.txt").unlink()
    return old


def test_an_older_record_is_re_scored_from_its_trajectory_files(tmp_path, capsys):
    from metrics import relative_errors

    _old_run(tmp_path / "r" / "seq" / "doppler")
    (run,) = load_runs(tmp_path / "r")
    result = _result(40)
    est = result.poses.copy()
    est[:, 0, 3] *= 1.05
    expected = relative_errors(result.poses, est, (2.0,))[2.0]
    (rel,) = run.result.relative_error
    assert rel.length_m == 2.0 and rel.trans_m_mean == pytest.approx(expected.trans_m_mean)
    assert run.result.diverged is True  # kept: it looked at every frame
    assert run.result.frames_scored == 40 and run.result.time_ms.median == 4.0
    assert run.result.wall_ms.median == 6.0 and run.result.register_ms.median is None  # absent
    assert run.result.schema_version == 2 and run.result.kitti is not None
    assert run.result.velocity is not None and run.result.ape.requested == "se3"
    err = capsys.readouterr().err
    assert err == (f"note: 1 run folder(s) under {tmp_path / 'r'} were written by an older "
                   "version of the harness: 1 re-scored from their trajectory files (methods "
                   "not re-run); `bench run` re-runs them\n")
    load_runs(tmp_path / "r")
    assert capsys.readouterr().err == ""  # once per results folder


def test_an_older_record_without_trajectory_files_is_read_as_it_is(tmp_path, capsys):
    _old_run(tmp_path / "r" / "seq" / "doppler", with_files=False)
    _old_run(tmp_path / "r" / "seq2" / "doppler")
    runs = load_runs(tmp_path / "r")
    assert len(runs) == 2
    assert runs[0].result.relative_error[0].length_m == 3.0
    assert runs[0].result.relative_error[0].trans_m_mean == 99.0
    err = capsys.readouterr().err
    assert ("2 run folder(s) under" in err and "1 re-scored from their trajectory files "
            "(methods not re-run); 1 read as they are (no trajectory files to re-score: no "
            "KITTI drift or velocity error)" in err)


def test_an_older_record_read_alone_is_announced_once(tmp_path, capsys):
    run_dir = tmp_path / "alone" / "doppler"
    _old_run(run_dir)
    assert check_record(run_dir / "metrics.json") is None
    assert capsys.readouterr().err == ""  # checking a record says nothing
    assert read_run(run_dir).result.schema_version == 2
    assert f"under {run_dir} were written by an older" in capsys.readouterr().err
    read_run(run_dir)
    assert capsys.readouterr().err == ""
    assert check_record(run_dir / "metrics.json") is None
    assert capsys.readouterr().err == ""  # checking a record says nothing


def test_an_older_record_takes_its_lengths_from_its_figures_without_a_config_and_keeps_its_count(
        tmp_path):
    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir, lengths=(), frames_scored=17)
    run = read_run(run_dir)
    assert [r.length_m for r in run.result.relative_error] == [3.0]
    assert run.result.relative_error[0].trans_m_mean != 99.0  # re-scored
    assert run.result.frames_scored == 17


def test_an_older_record_pairs_its_files_by_stamp(tmp_path):
    """Frames 20 and 39 (the last) are missing from est_tum.txt: the 38 others are scored."""
    from metrics import relative_errors

    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir)
    lines = (run_dir / "est_tum.txt").read_text().splitlines(keepends=True)
    (run_dir / "est_tum.txt").write_text("".join(lines[:20] + lines[21:39]))
    run = read_run(run_dir)
    assert run.result.frames_scored == 38
    result = _result(40)
    keep = np.r_[0:20, 21:39]
    est = result.poses.copy()
    est[:, 0, 3] *= 1.05
    expected = relative_errors(result.poses[keep], est[keep], (2.0,))[2.0]
    assert run.result.relative_error[0].n == expected.n
    assert run.result.relative_error[0].trans_m_mean == pytest.approx(expected.trans_m_mean)


def test_an_older_record_with_no_frame_to_pair_is_broken_naming_its_folder(tmp_path):
    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir)
    rows = np.loadtxt(run_dir / "est_tum.txt")
    rows[:, 0] += 1000.0
    (run_dir / "est_tum.txt").write_text("".join(" ".join(f"{v:.17g}" for v in row) + "\n"
                                                 for row in rows))
    with pytest.raises(BrokenRecord) as raised:
        read_run(run_dir)
    assert str(raised.value) == (f"{run_dir / 'metrics.json'}: an older record that cannot be "
                                 f"re-scored ({run_dir}: no frame has ground truth; nothing to "
                                 "score)")


def test_an_older_record_failing_without_a_message_names_the_error(tmp_path, monkeypatch):
    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir)

    def fail(*args, **kwargs):
        raise ZeroDivisionError

    monkeypatch.setattr(folders, "read_tum", fail)
    with pytest.raises(BrokenRecord, match=r"cannot be re-scored \(ZeroDivisionError\(\)\)$"):
        read_run(run_dir)


def test_an_older_record_of_a_run_without_a_verdict_is_read_as_it_is(tmp_path, capsys):
    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir, diverged=None)
    run = read_run(run_dir)
    assert run.result.relative_error[0].trans_m_mean == 99.0 and run.result.kitti is None
    assert "1 read as they are" in capsys.readouterr().err


def test_an_older_record_that_cannot_be_re_scored_is_broken(tmp_path):
    run_dir = tmp_path / "r" / "seq" / "doppler"
    _old_run(run_dir)
    (run_dir / "est_tum.txt").write_text("0 nonsense\n")
    with pytest.raises(BrokenRecord, match="an older record that cannot be re-scored"):
        read_run(run_dir)
    run = read_run(run_dir, failed=True)
    assert run.result.status == BROKEN and "cannot be re-scored" in run.result.error


# ---- load_runs ------------------------------------------------------------------------------

def test_load_runs_reads_every_run_or_those_asked_for_in_path_order(tmp_path):
    for name in ("b", "a", "c"):
        _write(tmp_path / "seq" / name, None, metrics=_metrics(method=name))
    write_failure(tmp_path / "seq" / "d", _config(), "bad")
    assert [r.method for r in load_runs(tmp_path)] == ["a", "b", "c"]
    assert [r.dir.name for r in load_runs(tmp_path, failed=True)] == ["a", "b", "c", "d"]
    only = {tmp_path / "seq" / "c", tmp_path / "seq" / "d"}
    assert [r.method for r in load_runs(tmp_path, only=only)] == ["c"]
    assert [r.dir.name for r in load_runs(tmp_path, only=only, failed=True)] == ["c", "d"]
    assert load_runs(tmp_path, only=set()) == []


def test_runs_of_two_contents_under_one_name_are_told_apart(tmp_path):
    for name, frame_range in (("a", [0, 10]), ("b", [5, 5])):
        config = _config()
        config["sequence"].update(frame_range=frame_range, frames=frame_range[1])
        config["identity"] = {"store_sha256": "same"}
        _write(tmp_path / name / "doppler", None, config=config)
    runs = load_runs(tmp_path)
    assert [r.display_name for r in runs] == ["Seq One [frames 0-9]", "Seq One [frames 5-9]"]
    assert [r.sequence for r in runs] == ["seq [frames 0-9]", "seq [frames 5-9]"]


# ---- what a refusal says --------------------------------------------------------------------

def test_a_run_folder_under_a_file_is_refused_naming_it_as_the_run_folder(tmp_path):
    from bench.guard import Refused

    (tmp_path / "file").write_text("not a folder")
    run_dir = tmp_path / "file" / "doppler"
    with pytest.raises(Refused, match=rf"^run folder {run_dir}: {tmp_path / 'file'} is a file"):
        write_failure(run_dir, None, "x")
    with pytest.raises(Refused, match=rf"^run folder {run_dir}: {tmp_path / 'file'} is a file"):
        _write(run_dir, None)


def test_a_record_in_a_folder_that_is_no_run_is_left_alone_naming_it(tmp_path):
    from bench.guard import Refused

    run_dir = tmp_path / "seq" / "doppler"
    run_dir.mkdir(parents=True)
    (run_dir / "config.yaml").write_text("- someone else's list\n")
    (run_dir / "metrics.json").write_text("{}")
    with pytest.raises(Refused, match=r"metrics\.json: exists and is not a run's record the "
                                      r"harness wrote"):
        write_failure(run_dir, None, "x")
    with pytest.raises(Refused, match=r"metrics\.json: exists and is not a run's record the "
                                      r"harness wrote"):
        clear_run(run_dir)
    assert (run_dir / "metrics.json").read_text() == "{}"
