"""bench/runs/job.py: a job's folder and labels, what ``prepare`` records of it (config.yaml and
the run key's inputs), ``run_job``'s outcomes and the summary line (the mutation run of
tools/mutate.py over bench/runs/job.py; the runs are a few frames of the sample store, in
process)."""

from __future__ import annotations

import hashlib
import json
import sys
import warnings
from pathlib import Path
from types import SimpleNamespace

import h5py
import numpy as np
import pytest
import yaml

from bench.runs import job as jobmod
from bench.runs.evaluate import Scoring
from bench.runs.identity import run_key
from bench.runs.job import (
    GT_EXTRINSIC_MARK,
    MIN_POINTS,
    FewPointsWarning,
    Job,
    JobOutcome,
    _method_error,
    _outside_files,
    _record_failure,
    calibration_frames,
    expected_cost,
    extrinsic_from_gt,
    prepare,
    record_unfinished,
    run_job,
    sequence_folder,
    sequence_labels,
    summarize,
    warn_few_points,
)
from conftest import SAMPLE_STORE
from loaders.errors import DataError
from loaders.scan import FrameRange, MemorySequence, Scan, SensorInfo
from loaders.sensor_classes import DENSE_LIDAR
from methods.registry import get_method, make_method
from metrics.kitti import KITTI_LENGTHS_M
from metrics.relative import DEFAULT_LENGTHS_M

SHORT = dict(lengths_m=(1.0,), kitti_lengths_m=(1.0,), frame_range=(0, 10))


def memory(n=8, provenance=None, model="", kind="radar"):
    scans = [Scan(0.1 * i, np.zeros((4, 3))) for i in range(n)]
    return MemorySequence("mem", SensorInfo(kind, 0.1, model=model), scans,
                          provenance=provenance)


def sample_sha256() -> str:
    return hashlib.sha256(Path(SAMPLE_STORE).read_bytes()).hexdigest()


# ---- the job itself -------------------------------------------------------------------------

def test_a_jobs_defaults_and_scoring(tmp_path):
    j = Job(Path("a/loop.h5"), "doppler", None, tmp_path)
    assert j.lengths_m == DEFAULT_LENGTHS_M and j.kitti_lengths_m == KITTI_LENGTHS_M
    assert j.alignment == "se3" and j.params == {}
    assert j.scoring == Scoring(DEFAULT_LENGTHS_M, KITTI_LENGTHS_M, "se3")
    other = Job(Path("a/loop.h5"), "doppler", None, tmp_path, lengths_m=(4.0,),
                kitti_lengths_m=(50.0,), alignment="sim3")
    assert other.scoring == Scoring((4.0,), (50.0,), "sim3")


def test_a_jobs_title_and_folder(tmp_path):
    j = Job(Path("a/loop.h5"), "icp-p2p", True, tmp_path)
    assert j.title == "loop / icp-p2p_seed"
    named = Job(Path("a/loop.h5"), "icp-p2p", False, tmp_path, name="L1", label="fast")
    assert named.title == "L1 / fast_noseed"
    assert j.run_dir("a/b") == tmp_path / "a_b" / "icp-p2p_seed"
    assert Job(Path("x.h5"), "doppler", None, tmp_path).run_dir("s") == tmp_path / "s" / "doppler"
    fixed = Job(Path("x.h5"), "doppler", None, tmp_path, run_dir_override=tmp_path / "here")
    assert fixed.run_dir("s") == tmp_path / "here"


def test_a_sequence_name_is_one_folder():
    assert sequence_folder("a/b\\c") == "a_b_c"
    assert sequence_folder("..") == "_.."
    assert sequence_folder(".") == "_."
    assert sequence_folder("v1.2") == "v1.2"
    assert sequence_folder(".hidden") == ".hidden"


# ---- labels, calibration frames, extrinsic --------------------------------------------------

def test_sequence_labels_from_the_job_else_the_store(tmp_path):
    seq = memory(model="", kind="lidar")
    bare = Job(Path("x.h5"), "doppler", None, tmp_path)
    assert sequence_labels(seq, bare) == ("mem", "mem", DENSE_LIDAR)
    assert sequence_labels(memory(), bare) == ("mem", "mem", "4D Radar")
    given = Job(Path("x.h5"), "doppler", None, tmp_path, name="n", display_name="D",
                sensor_class="C")
    assert sequence_labels(memory(provenance={"display_name": "P", "sensor_class": "PC"}),
                           given) == ("n", "D", "C")
    assert sequence_labels(memory(provenance={"display_name": "P", "sensor_class": "PC",
                                              "class": "old"}), bare) == ("mem", "P", "PC")
    assert sequence_labels(memory(provenance={"class": "old"}), bare)[2] == "old"
    named = Job(Path("x.h5"), "doppler", None, tmp_path, name="n")
    assert sequence_labels(memory(), named)[:2] == ("n", "n")


def test_a_calibrated_or_synthetic_store_says_so_in_its_display_name(tmp_path):
    bare = Job(Path("x.h5"), "doppler", None, tmp_path)
    calibrated = memory(provenance={"calibration": {"frames": [5, 20]}})
    assert sequence_labels(calibrated, bare)[1] == (
        "mem (GT calibrated on frames 5-19, not scored)")
    synthetic = memory(provenance={"source": "synthetic"})
    assert sequence_labels(synthetic, bare)[1] == "mem (synthetic)"
    marked = memory(provenance={"notice": "generated", "display_name": "x (synthetic)"})
    assert sequence_labels(marked, bare)[1] == "x (synthetic)"
    assert sequence_labels(memory(provenance={"calibration": {}}), bare)[1] == "mem"


def test_calibration_frames_by_store_index():
    assert calibration_frames(memory()) is None
    assert calibration_frames(memory(provenance={"calibration": {"frames": None}})) is None
    seq = memory(8, provenance={"calibration": {"frames": [2, 5]}})
    np.testing.assert_array_equal(calibration_frames(seq),
                                  [False, False, True, True, True, False, False, False])
    part = FrameRange(seq, 3, 4)  # store frames 3..6
    np.testing.assert_array_equal(calibration_frames(part), [True, True, False, False])


def test_an_extrinsic_fitted_to_the_gt():
    calibrated = memory(provenance={"calibration": {"frames": [0, 3]}})

    class Uses:
        uses_sensor_extrinsic = True
        extrinsic_param = "extrinsic"

    class Ignores:
        uses_sensor_extrinsic = False

    class NoParam:
        uses_sensor_extrinsic = True

    assert extrinsic_from_gt(calibrated, Uses, None)
    assert extrinsic_from_gt(calibrated, Uses, {"extrinsic": None})
    assert not extrinsic_from_gt(calibrated, Uses, {"extrinsic": [1, 0, 0]})
    assert extrinsic_from_gt(calibrated, NoParam, {"extrinsic": [1, 0, 0]})
    assert not extrinsic_from_gt(calibrated, Ignores, None)
    assert not extrinsic_from_gt(memory(), Uses, None)
    assert not extrinsic_from_gt(memory(provenance={"calibration": {"frames": []}}), Uses, None)


def test_a_method_error_names_the_method_and_the_parameter(tmp_path):
    given = {"tau_spatail_m": 2.0, "tau_doppler": "x"}
    j = Job(Path("x.h5"), "doppler", None, tmp_path, params=given)
    try:
        make_method("doppler", given, SensorInfo("radar", 0.1), None)
    except Exception as err:  # noqa: BLE001 - the pydantic error, whatever its class
        text = str(_method_error(j, err))
    head = f"method 'doppler': invalid parameters {given}: "
    assert text.startswith(head)
    known = ", ".join(get_method("doppler").Params.model_fields)
    unknown = (f"unknown parameter 'tau_spatail_m' (did you mean 'tau_spatial_m'?); "
               f"known parameters: {known}")
    # two problems, one after the other: the bad value, then the unknown name
    bad, _, rest = text[len(head):].partition("; ")
    assert bad.startswith("tau_doppler: ") and bad.endswith("(got 'x')")
    assert rest == unknown
    other = _method_error(j, ValueError("bad"))
    assert isinstance(other, DataError) and str(other) == "method 'doppler': bad"


# ---- prepare and run ------------------------------------------------------------------------

def test_prepare_records_the_sequence_the_method_and_the_key(tmp_path):
    j = Job(SAMPLE_STORE, "doppler", None, tmp_path, params={"tau_spatial_m": 2},
            name="loop", label="tight", **SHORT)
    prep = prepare(j)
    try:
        config = prep.config
        assert len(prep.sequence) == 10
        assert prep.run_dir == tmp_path / "loop" / "tight"
        seq = config["sequence"]
        assert seq["name"] == "loop" and seq["display_name"] == "loop"
        assert seq["sensor_class"] == "Semi-Dense 4D Radar"
        assert seq["store"] == str(SAMPLE_STORE) and seq["frames"] == 10
        assert seq["frame_range"] == [0, 10] and seq["store_frame_range"] is None
        assert len(seq["content_sha256"]) == 64
        assert seq["sensor_kind"] == "radar" and seq["doppler_kind"] == "radial"
        assert seq["period_s"] == pytest.approx(1 / 12)
        assert seq["sensor_model"] == prep.sequence.sensor.model
        method = config["method"]
        assert method["name"] == "doppler" and method["uses_initial_guess"] is False
        assert method["description"].startswith("Doppler Correspondence")
        assert method["params"]["tau_spatial_m"] == 2.0
        assert method["params"]["tau_doppler"] == 5.0
        assert method["given"] == {"tau_spatial_m": 2}
        assert "extrinsic_from_gt" not in method
        assert config["label"] == "tight" and config["seed"] is None
        assert config["lengths_m"] == [1.0] and config["kitti_lengths_m"] == [1.0]
        assert config["alignment"] == "se3"
        ident = config["identity"]
        assert ident["store_sha256"] == sample_sha256()
        assert ident["method"] == "doppler" and ident["frame_range"] == (0, 10)
        assert ident["params"] == method["params"] and ident["seed"] is None
        assert ident["lengths_m"] == [1.0]
        assert ident["scoring"] == {"kitti_lengths_m": [1.0], "alignment": "se3"}
        assert ident["code_sha256"] and ident["host"]
        assert config["run_key"] == prep.key == run_key(ident)
        assert prep.method.params.tau_spatial_m == 2.0
    finally:
        prep.sequence.close()


def test_the_key_follows_what_changes_the_result(tmp_path):
    def key(**changes):
        prep = prepare(Job(SAMPLE_STORE, "doppler", None, tmp_path,
                           store_sha256="s" * 64, code_sha256="c" * 64, **{**SHORT, **changes}))
        prep.sequence.close()
        assert prep.config["identity"]["store_sha256"] == "s" * 64
        assert prep.config["identity"]["code_sha256"] == "c" * 64
        return prep.key

    base = key()
    assert key(name="other", label="x") == base  # names are not part of the key
    assert key(params={"tau_spatial_m": 2.5}) != base
    assert key(frame_range=(1, 9)) != base
    assert key(kitti_lengths_m=(2.0,)) != base
    assert key(alignment="sim3") != base
    assert key(lengths_m=(2.0,)) != base


def test_bad_parameters_fail_with_the_run_folder(tmp_path):
    j = Job(SAMPLE_STORE, "doppler", None, tmp_path, params={"tau_spatial_m": "wide"},
            name="loop", **SHORT)
    with pytest.raises(DataError) as caught:
        prepare(j)
    err = caught.value
    assert str(err).startswith("method 'doppler': invalid parameters")
    assert err.run_dir == tmp_path / "loop" / "doppler"
    assert err.config["sequence"]["name"] == "loop"
    outcome = run_job(j)
    assert outcome.status == "failed" and outcome.run_dir == tmp_path / "loop" / "doppler"
    assert outcome.message == str(err)
    failed = json.loads((outcome.run_dir / "failed.json").read_text())
    assert failed["status"] == "failed" and failed["error"] == str(err)
    assert yaml.safe_load((outcome.run_dir / "config.yaml").read_text())["sequence"]["name"] \
        == "loop"


def test_a_store_that_does_not_open_fails_without_a_folder(tmp_path):
    outcome = run_job(Job(tmp_path / "none.h5", "doppler", None, tmp_path))
    assert outcome.status == "failed" and outcome.run_dir is None and outcome.message
    assert list(tmp_path.iterdir()) == []


def test_a_run_is_done_then_skipped_then_forced(tmp_path):
    j = Job(SAMPLE_STORE, "doppler", None, tmp_path, name="loop", **SHORT)
    seen = []
    done = run_job(j, on_frame=lambda i, n: seen.append((i, n)))
    assert done.status == "done", done.message
    assert done.message == str(tmp_path / "loop" / "doppler") and done.frames == 10
    assert done.run_dir == tmp_path / "loop" / "doppler" and done.wall_s > 0
    assert seen[-1] == (10, 10) and all(n == 10 for _, n in seen)
    assert [i for i, _ in seen] == sorted(i for i, _ in seen) and seen[0][0] >= 1
    config = yaml.safe_load((done.run_dir / "config.yaml").read_text())
    assert config["libraries"]["numpy"] == np.__version__
    metrics = json.loads((done.run_dir / "metrics.json").read_text())
    assert (metrics["sequence"], metrics["method"], metrics["seed"], metrics["frames"]) == (
        "loop", "doppler", None, 10)
    again = run_job(j)
    assert again.status == "skipped" and again.message == str(done.run_dir)
    assert again.run_dir == done.run_dir
    forced = run_job(j, force=True)
    assert forced.status == "done"


def test_a_failing_run_is_recorded(tmp_path):
    # no relative-error segment of 50 m on a few metres of path: the scoring fails
    j = Job(SAMPLE_STORE, "doppler", None, tmp_path, name="loop", lengths_m=(50.0,),
            frame_range=(0, 6))
    outcome = run_job(j)
    assert outcome.status == "failed" and outcome.run_dir == tmp_path / "loop" / "doppler"
    assert "no relative-error segment" in outcome.message
    assert not outcome.message.startswith("DataError")  # a DataError is said as it is
    failed = json.loads((outcome.run_dir / "failed.json").read_text())
    assert failed["error"] == outcome.message and "Traceback" in failed["traceback"]


def test_an_unexpected_error_is_named_by_its_type(tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("kaput")

    monkeypatch.setattr(jobmod, "timed_run", boom)
    outcome = run_job(Job(SAMPLE_STORE, "doppler", None, tmp_path, name="loop", **SHORT))
    assert outcome.status == "failed" and outcome.message == "RuntimeError: kaput"
    assert json.loads((outcome.run_dir / "failed.json").read_text())["error"] == \
        "RuntimeError: kaput"


# ---- helpers --------------------------------------------------------------------------------

def test_a_plugins_module_is_outside_the_repository(tmp_path, monkeypatch):
    seq = memory()
    assert _outside_files(make_method("doppler", {}, seq.sensor, None)) == []
    (tmp_path / "my_plugin_mod.py").write_text("class M:\n    pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import my_plugin_mod

    try:
        assert _outside_files(my_plugin_mod.M()) == [tmp_path / "my_plugin_mod.py"]
    finally:
        sys.modules.pop("my_plugin_mod", None)


def test_few_points_are_warned_about_once_by_name():
    assert MIN_POINTS == 3
    j = SimpleNamespace(store=Path("s.h5"), method="doppler")
    frames = [SimpleNamespace(index=i, points=p) for i, p in enumerate([10, 3, 2, 0, 5])]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        warn_few_points(SimpleNamespace(frames=frames), j)
        warn_few_points(SimpleNamespace(frames=frames[:2]), j)
    assert len(said) == 1 and said[0].category is FewPointsWarning
    assert str(said[0].message) == (
        "s.h5, frame 2: 2 point(s) to register after doppler's preparation (at least 3 "
        "needed); 2 such frame(s) kept their motion prior")


def test_recording_a_failure_never_raises(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _record_failure(blocker / "run", None, "m", "")  # a file where the folder should be
    assert blocker.read_text() == "x"
    _record_failure(tmp_path / "run", {"a": 1}, "m", "t", "timeout")
    failed = json.loads((tmp_path / "run" / "failed.json").read_text())
    assert (failed["status"], failed["error"], failed["traceback"]) == ("timeout", "m", "t")


def test_an_unfinished_job_is_recorded_only_in_its_own_folder(tmp_path):
    record_unfinished(Job(Path("x.h5"), "doppler", None, tmp_path), "ended", "interrupted")
    assert list(tmp_path.iterdir()) == []
    j = Job(Path("x.h5"), "doppler", None, tmp_path, run_dir_override=tmp_path / "r")
    record_unfinished(j, "ended", "interrupted")
    failed = json.loads((tmp_path / "r" / "failed.json").read_text())
    assert (failed["status"], failed["error"], failed["traceback"]) == ("interrupted", "ended",
                                                                         "")
    assert not (tmp_path / "r" / "config.yaml").exists()


def test_expected_cost_weighs_a_seeded_method(tmp_path):
    size = Path(SAMPLE_STORE).stat().st_size
    assert expected_cost(Job(SAMPLE_STORE, "doppler", None, tmp_path)) == size
    assert expected_cost(Job(SAMPLE_STORE, "icp-p2p", True, tmp_path)) == 20.0 * size
    assert expected_cost(Job(tmp_path / "none.h5", "icp-p2p", True, tmp_path)) == 0


def test_the_summary_counts_and_names_what_did_not_finish(tmp_path):
    def out(status, message="", store=SAMPLE_STORE, name="loop"):
        return JobOutcome(Job(store, "doppler", None, tmp_path, name=name), status, message)

    assert summarize([out("done"), out("done"), out("skipped")]) == "2 done, 1 skipped, 0 failed"
    assert summarize([]) == "0 failed"
    text = summarize([out("done"), out("failed", "bad input\nmore"),
                      out("interrupted", ""), out("failed", "x", name="b")])
    assert text == ("1 done, 2 failed, 1 interrupted"
                    "\n  failed: loop / doppler: bad input"
                    "\n  interrupted: loop / doppler: "
                    "\n  failed: b / doppler: x")
    bare = tmp_path / "nogt.h5"
    with h5py.File(bare, "w") as h5:
        h5.create_group("frames")
    text = summarize([out("done", store=bare, name="n"), out("skipped", store=bare),
                      out("done", store=tmp_path / "t.tum")])
    assert text == ("2 done, 1 skipped, 0 failed"
                    f"\n  not scored: n / doppler: {bare} has no ground truth (the "
                    "trajectory is written, no error is computed)")


def test_the_gt_extrinsic_mark():
    assert GT_EXTRINSIC_MARK == "(extrinsic fitted to GT)"
