"""What bench.runs.external.score.score_external records and returns, on a tiny synthetic store
(40 scans 0.1 s apart on a straight drive, so poses interpolated across a gap are exact): the
outcome, the run folder's config (the store, the trajectory file and its hash, the options as
given, the scoring), metrics and notes; a re-score of the same file is its own run (reused,
or done again when forced), another file, topic or store into that folder is refused naming
what it holds; a harness run there is replaced only when asked; the output is checked before
the estimate is read; and an experiment's external entries (score_experiment_external)."""

import hashlib
import json
import shutil
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from bench.data.export import export_store
from bench.runs.evaluate import Scoring
from bench.runs.external import score
from bench.runs.external.score import NOT_TIMED, ExternalSpec, score_external
from bench.runs.folders import read_run
from bench.runs.identity import code_identity, run_key
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.scan import MemorySequence, SensorInfo
from loaders.se3 import inv_T, tum_from_T
from loaders.store import StoreSequence, write_store

N = 40
GAP = slice(10, 15)  # the scans without a pose of their own: 0.6 s between scans 9 and 15
SCORING = Scoring(lengths_m=(2.0, 4.0), kitti_lengths_m=(3.0, 6.0), alignment="se3",
                  velocity_window_s=0.5)


def write_tum(path: Path, stamps, poses, times=None) -> Path:
    xyz, quat = tum_from_T(np.asarray(poses))
    cols = [stamps, xyz, quat] + ([] if times is None else [times])
    np.savetxt(path, np.column_stack(cols), fmt="%.17g")
    return path


#: the store's sensor in its body frame
T_BS = np.array([[0, -1, 0, 1.2], [1, 0, 0, 0.1], [0, 0, 1, 1.5], [0, 0, 0, 1.0]])


def make_store(path: Path, with_gt: bool = True) -> tuple[Path, object]:
    base = constant_twist_sequence(n_frames=N, n_points=60, w=(0.0, 0.0, 0.0), max_range_m=70)
    seq = MemorySequence("twist", SensorInfo("lidar", 0.1, T_BS, "test"), list(base),
                         base.ground_truth if with_gt else None,
                         {"display_name": "Twist drive", "sensor_class": "lidar-test"})
    return write_store(seq, path), base.ground_truth


def reused(scored):
    """The fixture's run scored again (each test that reads it calls score_external itself, so
    mutation testing runs it on score_external's mutants): the same run, reused."""
    again = score_external(scored.store, scored.spec, scored.out, SCORING)
    assert again.status == "skipped" and again.run_dir == scored.outcome.run_dir
    return again


@pytest.fixture(scope="module")
def scored(tmp_path_factory):
    """The ground truth with 5 poses left out, scored with --max-gap 1 and per-row times."""
    root = tmp_path_factory.mktemp("record")
    store, gt = make_store(root / "twist.h5")
    keep = np.ones(N, bool)
    keep[GAP] = False
    path = write_tum(root / "est.tum", gt.stamps[keep], gt.poses[keep])
    times = np.linspace(2.0, 5.0, keep.sum())
    times_file = root / "times.txt"
    times_file.write_text("".join(f"{t:.17g}\n" for t in times))
    spec = ExternalSpec(path, "mine", fmt="tum", frame_times=times_file, tolerance_s=0.02,
                        max_gap_s=1.0, stamp_unit="s", min_coverage=0.5)
    out = root / "out"
    outcome = score_external(store, spec, out, SCORING)
    return SimpleNamespace(root=root, store=store, gt=gt, path=path, times=times,
                           times_file=times_file, spec=spec, out=out, outcome=outcome)


def test_the_outcome_says_what_was_scored(scored):
    reused(scored)
    o = scored.outcome
    assert o.status == "done" and o.run_dir == scored.out / "twist" / "mine"
    c = o.coverage
    assert (c["scans"], c["scans_with_gt"], c["matched"], c["interpolated"], c["scored"]) == \
        (N, N, N - 5, 5, N)
    assert c["share_scored"] == 1.0
    assert o.frame == "identity (poses of the sensor)"
    assert o.clock.startswith("the clock could not be checked")  # a constant motion
    assert o.convention.startswith("wxyz: as read")
    # the gap bridged is 6 scan periods: scored anyway, with a warning naming the file
    assert len(o.warnings) == 1 and o.warnings[0].startswith(f"{scored.path}: --max-gap 1 "
                                                             "bridged a gap of 0.6 s")


def test_the_config_records_the_store_the_file_and_the_options_as_given(scored):
    reused(scored)
    config = read_run(scored.outcome.run_dir).config
    seq = StoreSequence(scored.store, fields=())
    sensor = seq.sensor
    seq.close()
    assert config["sequence"] == {
        "name": "twist", "display_name": "Twist drive", "sensor_class": "lidar-test",
        "store": str(scored.store), "frames": N, "frame_range": None,
        "sensor_kind": sensor.kind, "sensor_model": "test", "period_s": pytest.approx(0.1),
        "doppler_kind": sensor.doppler_kind}
    assert config["method"] == {"name": "mine", "description": f"external trajectory "
                                f"{scored.path}", "uses_initial_guess": False, "params": {}}
    assert config["label"] == "mine (external)" and config["seed"] is None
    assert config["lengths_m"] == [2.0, 4.0] and config["kitti_lengths_m"] == [3.0, 6.0]
    assert config["alignment"] == "se3"
    ext = config["external"]
    assert ext["trajectory"] == str(scored.path) and ext["format"] == "tum"
    assert ext["topic"] is None and ext["stamps"] is None
    assert ext["frame_times"] == str(scored.times_file)
    assert ext["pose_frame"] == "sensor" and ext["stamp_unit"] == "s"
    np.testing.assert_array_equal(ext["T_frame_sensor"], np.eye(4))
    assert ext["T_frame_sensor_from"] == "identity (poses of the sensor)"
    assert ext["timing"] == "reported by the method"
    assert ext["clock_check"] == scored.outcome.clock
    assert ext["convention_check"] == scored.outcome.convention
    assert ext["coverage"] == scored.outcome.coverage


def test_the_identity_holds_the_hashes_of_the_files_and_every_setting(scored):
    reused(scored)
    config = read_run(scored.outcome.run_dir).config
    ident = config["identity"]
    assert ident["kind"] == "external"
    assert ident["store_sha256"] == hashlib.sha256(scored.store.read_bytes()).hexdigest()
    assert ident["trajectory_sha256"] == hashlib.sha256(scored.path.read_bytes()).hexdigest()
    assert ident["frame_times_sha256"] == \
        hashlib.sha256(scored.times_file.read_bytes()).hexdigest()
    assert ident["stamps_sha256"] is None
    assert ident["format"] == "tum" and ident["topic"] is None and ident["stamp_unit"] == "s"
    np.testing.assert_array_equal(ident["T_frame_sensor"], np.eye(4))
    assert ident["association"] == {"time_offset_s": 0.0, "tolerance_s": 0.02,
                                    "max_gap_s": 1.0}
    assert ident["lengths_m"] == [2.0, 4.0]
    assert ident["scoring"] == {"kitti_lengths_m": [3.0, 6.0], "alignment": "se3",
                                "velocity_window_s": 0.5}
    assert ident["code_sha256"] == code_identity()
    assert ident["external_code_sha256"] == score._own_code()
    assert set(ident) == {"kind", "store_sha256", "trajectory_sha256", "stamps_sha256",
                          "frame_times_sha256", "format", "topic", "T_frame_sensor",
                          "stamp_unit", "association", "lengths_m", "scoring", "code_sha256",
                          "external_code_sha256"}
    assert config["run_key"] == run_key(ident)  # the key is of what is recorded


def test_the_metrics_of_the_ground_truth_are_zero_and_its_times_are_the_methods(scored):
    reused(scored)
    run_dir = scored.outcome.run_dir
    res = read_run(run_dir).result
    assert res.method == "mine" and res.sequence == "twist" and res.frames == N
    assert res.frames_scored == N
    assert [r.length_m for r in res.relative_error] == [2.0, 4.0]
    for r in res.relative_error:  # poses of the ground truth, interpolated on a straight line
        assert r.n > 0 and r.trans_m_mean < 1e-9 and r.rot_deg_mean < 1e-6
    assert res.ape.trans_rmse_m < 1e-9
    gt = np.loadtxt(run_dir / "gt_tum.txt")  # the ground truth at the scored scans
    np.testing.assert_allclose(gt[:, 0], scored.gt.stamps, atol=1e-9)
    np.testing.assert_allclose(gt[:, 1:4], scored.gt.poses[:, :3, 3], atol=1e-9)
    raw = json.loads((run_dir / "metrics.json").read_text())
    assert raw["seed"] is None and raw["frames"] == N
    assert res.clock == "reported by the method"
    assert res.clock_note == (f"reported by the method: per-frame times from "
                              f"{scored.times_file}, not measured by the harness")
    assert res.time_ms.mean == pytest.approx(scored.times.mean(), rel=1e-9)
    assert res.register_ms.mean is None
    # each matched scan has its pose's time; the 5 interpolated ones none
    rows = (run_dir / "frames.csv").read_text().splitlines()[1:]
    ms = np.array([float(r.split(",")[2]) if r.split(",")[2] else np.nan for r in rows])
    keep = np.ones(N, bool)
    keep[GAP] = False
    np.testing.assert_allclose(ms[keep], scored.times, atol=1e-6)
    assert np.isnan(ms[GAP]).all()
    # no points, correspondences or iterations of the harness; every pose is the method's own
    header = (run_dir / "frames.csv").read_text().splitlines()[0].split(",")
    table = [dict(zip(header, r.split(","), strict=True)) for r in rows]
    assert [int(r["index"]) for r in table] == list(range(N))
    for r in table:
        assert (r["points"], r["correspondences"], r["iterations"]) == ("0", "0", "0")
        assert (r["converged"], r["replaced"]) == ("1", "0")


def test_the_notes_say_the_coverage_and_each_warning(scored):
    reused(scored)
    notes = read_run(scored.outcome.run_dir).result.notes
    assert notes == [
        f"external trajectory: {N} of the {N} scans with ground truth scored (100.0 %): "
        f"{N - 5} matched within 0.02 s, 5 interpolated (--max-gap 1 s; the widest gap "
        "bridged 0.6 s)", f"warning: {scored.outcome.warnings[0]}"]
    assert NOT_TIMED not in notes  # timed by the method


def test_a_rescore_of_the_same_file_is_its_own_run(scored, tmp_path):
    """Reused unchanged (with the same outcome), done again when forced; another file, topic
    or store under the name is refused, naming what the folder holds."""
    out = tmp_path / "out"
    shutil.copytree(scored.out, out)  # the fixture's folder is left as it is
    first = scored.outcome
    again = score_external(scored.store, scored.spec, out, SCORING)
    assert again.status == "skipped" and again.run_dir == out / "twist" / "mine"
    assert (again.coverage, again.frame, again.clock, again.warnings, again.convention) == \
        (first.coverage, first.frame, first.clock, first.warnings, first.convention)
    other_scoring = score_external(scored.store, scored.spec, out)  # a setting: rescored
    assert other_scoring.status == "done"
    assert read_run(again.run_dir).config["lengths_m"] == list(Scoring().lengths_m)
    forced = score_external(scored.store, scored.spec, out, force=True)
    assert forced.status == "done"
    assert forced.coverage == first.coverage and forced.warnings == first.warnings

    copy = Path(shutil.copy(scored.path, scored.root / "copy.tum"))
    with pytest.raises(DataError) as err:
        score_external(scored.store, ExternalSpec(copy, "mine"), out)
    text = str(err.value)
    assert f"holds another run (trajectory '{scored.path}')" in text
    assert f"bench score would replace it with trajectory '{copy}'" in text
    with pytest.raises(DataError, match=r"holds another run .*with topic '/odom'"):
        score_external(scored.store, ExternalSpec(scored.path, "mine", topic="/odom"),
                       out)
    elsewhere = scored.root / "elsewhere"
    elsewhere.mkdir()
    store2 = Path(shutil.copy(scored.store, elsewhere / "twist.h5"))  # same name, another store
    with pytest.raises(DataError, match=r"holds another run .*with store '.*elsewhere"):
        score_external(store2, scored.spec, out)


def _as_harness_run(folder: Path, method: str = "icp-p2p") -> None:
    """An external run's folder made to look like a harness run's (its run key kept)."""
    config = yaml.safe_load((folder / "config.yaml").read_text())
    del config["external"]
    config["identity"] = {k: v for k, v in config["identity"].items() if k != "kind"}
    config["method"] = {"name": method, "params": {}}
    (folder / "config.yaml").write_text(yaml.safe_dump(config))


def test_a_harness_run_is_replaced_only_when_asked_and_then_with_a_warning(scored, tmp_path):
    """A harness run under the name (even one whose run key is the external run's own): refused
    (before the estimate is read: an unreadable file is not what is said); with
    --replace-run replaced and said so."""
    out = tmp_path / "out"
    shutil.copytree(scored.outcome.run_dir, out / "twist" / "theirs")
    _as_harness_run(out / "twist" / "theirs")
    garbage = tmp_path / "garbage.tum"
    garbage.write_text("not a trajectory\n")
    with pytest.raises(DataError, match=r"theirs holds a harness run \(method icp-p2p\); bench "
                                        r"score does not replace it"):
        score_external(scored.store, ExternalSpec(garbage, "theirs"), out)
    spec = ExternalSpec(scored.path, "theirs", fmt="tum", frame_times=scored.times_file,
                        tolerance_s=0.02, max_gap_s=1.0, stamp_unit="s", min_coverage=0.5,
                        replace_run=True)
    with pytest.warns(UserWarning) as caught:
        o = score_external(scored.store, spec, out, SCORING)
    assert o.status == "done"
    said = [str(w.message) for w in caught]
    assert f"{o.run_dir}: replaced a harness run (method icp-p2p) by the external run theirs " \
        "(--replace-run)" in said
    # said of the caller's line, not of score.py's
    assert all(Path(w.filename).name != "score.py" for w in caught)
    run = read_run(o.run_dir)
    assert run.result.label == "theirs (external)" and run.config["identity"]["kind"] == \
        "external"
    # now the folder holds an external run: re-scored without --replace-run
    assert score_external(scored.store, spec, out, SCORING).status == "skipped"


def test_the_output_is_checked_before_the_estimate_is_read(scored, tmp_path):
    """The run folder is an input (the trajectory, its stamps or times as an empty folder
    there, or the store itself): refused as such, not as an unreadable estimate."""
    out = tmp_path / "out"
    run_dir = out / "twist" / "mine"
    run_dir.mkdir(parents=True)
    for spec in (ExternalSpec(run_dir, "mine"),
                 ExternalSpec(scored.path, "mine", fmt="kitti", stamps=run_dir),
                 ExternalSpec(scored.path, "mine", frame_times=run_dir)):
        with pytest.raises(DataError, match="is an input of this command"):
            score_external(scored.store, spec, out)
    run_dir.rmdir()
    store = make_store(run_dir)[0]  # the store at the run folder's place
    assert store == run_dir
    with pytest.raises(DataError, match="is an input of this command"):
        score_external(store, ExternalSpec(scored.path, "mine"), out)


def test_without_out_the_run_goes_under_results_external(scored, tmp_path, monkeypatch):
    """And times in a 9th TUM column are the trajectory file's: the time of the run is of every
    row the method reported, the rows between the scans (matched to none) too."""
    extra = scored.gt.interpolate(scored.gt.stamps[:-1] + 0.05)  # halfway between the scans
    stamps = np.concatenate([scored.gt.stamps, extra.stamps])
    order = np.argsort(stamps)
    poses = np.concatenate([scored.gt.poses, extra.poses])[order]
    times = np.concatenate([np.linspace(1.0, 3.0, N), np.full(N - 1, 100.0)])[order]
    path = write_tum(tmp_path / "timed.tum", stamps[order], poses, times)
    monkeypatch.chdir(tmp_path)
    o = score_external(scored.store, ExternalSpec(path, "mine"))
    assert o.status == "done" and o.run_dir == Path("results/external/twist/mine")
    assert (tmp_path / "results" / "external" / "twist" / "mine" / "metrics.json").exists()
    run = read_run(tmp_path / o.run_dir)
    assert run.result.clock == "reported by the method"
    assert run.result.clock_note == (f"reported by the method: per-frame times from {path}, "
                                     "not measured by the harness")
    assert run.result.time_ms.mean == pytest.approx(times.mean(), rel=1e-9)
    assert run.config["external"]["frame_times"] is None
    assert run.config["lengths_m"] == list(Scoring().lengths_m)


def test_a_kitti_file_of_body_poses_with_stamps_in_ms_untimed(scored, tmp_path):
    """Its stamps file is hashed and recorded, its unit and frame as given; the body poses of
    the ground truth through the store's T_body_sensor score zero; no times: not timed."""
    body = scored.gt.poses @ inv_T(T_BS)
    kitti = tmp_path / "est.kitti"
    np.savetxt(kitti, body[:, :3, :].reshape(N, 12), fmt="%.17g")
    stamps = tmp_path / "stamps_ms.txt"
    stamps.write_text("".join(f"{t * 1000:.17g}\n" for t in scored.gt.stamps))
    spec = ExternalSpec(kitti, "body", fmt="kitti", stamps=stamps, stamp_unit="ms",
                        pose_frame="body")
    o = score_external(scored.store, spec, tmp_path / "out", SCORING)
    assert o.frame == "the store's T_body_sensor" and o.coverage["matched"] == N
    run = read_run(o.run_dir)
    ext, ident = run.config["external"], run.config["identity"]
    assert ext["stamps"] == str(stamps) and ext["format"] == "kitti"
    assert ext["stamp_unit"] == "ms" and ext["pose_frame"] == "body"
    assert ident["stamps_sha256"] == hashlib.sha256(stamps.read_bytes()).hexdigest()
    assert ident["frame_times_sha256"] is None and ident["stamp_unit"] == "ms"
    np.testing.assert_allclose(ext["T_frame_sensor"], T_BS)
    np.testing.assert_allclose(ident["T_frame_sensor"], T_BS)
    assert ext["T_frame_sensor_from"] == "the store's T_body_sensor"
    res = run.result
    for r in res.relative_error:
        assert r.n > 0 and r.trans_m_mean < 1e-9 and r.rot_deg_mean < 1e-6
    assert res.clock is None and res.clock_note == NOT_TIMED and res.time_ms.mean is None
    assert ext["timing"] == "not timed"
    assert res.notes == [f"external trajectory: {N} of the {N} scans with ground truth scored "
                         f"(100.0 %): {N} matched within 0.01 s, 0 interpolated (no --max-gap: "
                         "no interpolation)", NOT_TIMED]


def test_a_store_without_ground_truth_and_an_estimate_too_short_are_refused(scored, tmp_path):
    store = make_store(tmp_path / "nogt.h5", with_gt=False)[0]
    with pytest.raises(DataError) as err:
        score_external(store, ExternalSpec(scored.path, "mine"), tmp_path / "out")
    assert str(err.value) == (f"{store}: the store has no ground truth; nothing to score "
                              f"{scored.path} against")
    # 2 poses 0.1 s apart at 8 m/s: 0.8 m of path, below the shortest segment of 2 m
    two = write_tum(tmp_path / "two.tum", scored.gt.stamps[:2], scored.gt.poses[:2])
    with pytest.raises(DataError) as err:
        score_external(scored.store, ExternalSpec(two, "two", min_coverage=0.0),
                       tmp_path / "out", SCORING)
    assert str(err.value) == (f"{two} is too short to score: it covers 2 of the {N} scans with "
                              "ground truth (5.0 %), about 0.800 m of path, shorter than the "
                              "shortest segment (2 m)")
    assert not (tmp_path / "out").exists()


def test_an_experiment_scores_each_entry_and_reports_the_failing_one(scored, tmp_path):
    """Filed under the sequence entry of the same store, scored with the experiment's settings
    and the entry's options; an entry that fails is reported, the next still scored; an
    optional sequence whose store is absent is not said again (the plan says it)."""
    def entry(name, **options):
        given = {"name": name, "trajectory": scored.path, "store": scored.store,
                 "format": "tum", "stamps": None, "topic": None, "frame_times": None,
                 "time_offset_s": 0.0, "tolerance_s": 0.02, "max_gap_s": 1.0,
                 "pose_frame": "sensor", "extrinsic": None, "stamp_unit": "s",
                 "min_coverage": 0.5, "trust_clock": True}
        return SimpleNamespace(**{**given, **options})

    # 30 body poses as KITTI, its stamps and times files, the extrinsic given
    body = scored.gt.poses[:30] @ inv_T(T_BS)
    kitti = tmp_path / "part.kitti"
    np.savetxt(kitti, body[:, :3, :].reshape(30, 12), fmt="%.17g")
    stamps = tmp_path / "part_stamps.txt"
    stamps.write_text("".join(f"{t:.17g}\n" for t in scored.gt.stamps[:30]))
    times = tmp_path / "part_times.txt"
    times.write_text("".join(f"{t:.17g}\n" for t in np.linspace(1.0, 2.0, 30)))
    extrinsic = "1.2 0.1 1.5 0 0 0.7071067811865476 0.7071067811865476"  # T_BS
    # the ground truth as a ROS1 bag's nav_msgs/Odometry topic (T_world_body)
    bag = export_store(scored.store, "ros1", tmp_path / "gt.bag").path
    sequence = SimpleNamespace(path=scored.store, name="twist-exp", display_name="Twist exp",
                               sensor_class="exp-class", is_glob=False, optional=False)
    absent = SimpleNamespace(path=tmp_path / "absent.h5", name="absent", display_name=None,
                             sensor_class=None, is_glob=False, optional=True, dataset=None)
    exp = SimpleNamespace(sequences=[absent, sequence], lengths_m=[2.0], kitti_lengths_m=[6.0],
                          alignment="sim3", out_dir=tmp_path / "exp",
                          external=[entry("bad", min_coverage=1.0, max_gap_s=None),
                                    entry("good"),
                                    entry("part", trajectory=kitti, format="kitti",
                                          stamps=stamps, frame_times=times, max_gap_s=None,
                                          extrinsic=extrinsic),
                                    entry("odom", trajectory=bag, format="auto",
                                          topic="/ground_truth", pose_frame="body",
                                          max_gap_s=None, stamp_unit=None)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        done = score.score_experiment_external(exp)
    assert [d[:2] for d in done] == [("bad", "failed"), ("good", "done"), ("part", "done"),
                                     ("odom", "done")]
    assert f"covers 35 of the 40 scans of {scored.store} with ground truth" in done[0][2]
    assert "below --min-coverage 1" in done[0][2]
    run_dir = tmp_path / "exp" / "twist-exp" / "good"
    assert done[1][2] == (f"{run_dir}: {N} of the {N} scans with ground truth scored "
                          "(100.0 %); warning: " + f"{scored.path}: --max-gap 1 bridged a gap "
                          "of 0.6 s (6.0 scan periods) between two of its poses: the scans "
                          "inside are scored on poses interpolated across it, not estimated")
    part_dir = tmp_path / "exp" / "twist-exp" / "part"
    assert done[2][2] == f"{part_dir}: 30 of the {N} scans with ground truth scored (75.0 %)"
    config = read_run(run_dir).config
    assert config["sequence"]["name"] == "twist-exp"
    assert config["sequence"]["display_name"] == "Twist exp"
    assert config["sequence"]["sensor_class"] == "exp-class"
    assert config["lengths_m"] == [2.0] and config["kitti_lengths_m"] == [6.0]
    assert config["alignment"] == "sim3"
    ext = config["external"]
    assert (ext["format"], ext["stamp_unit"], ext["pose_frame"]) == ("tum", "s", "sensor")
    assert config["identity"]["association"] == {"time_offset_s": 0.0, "tolerance_s": 0.02,
                                                 "max_gap_s": 1.0}
    assert ext["clock_check"] == "not checked (--trust-clock)"
    part = read_run(part_dir)
    ext = part.config["external"]
    assert (ext["format"], ext["stamps"], ext["frame_times"]) == ("kitti", str(stamps),
                                                                 str(times))
    assert ext["T_frame_sensor_from"] == "given (--extrinsic)"
    np.testing.assert_allclose(ext["T_frame_sensor"], T_BS, atol=1e-12)
    assert ext["timing"] == "reported by the method"
    assert part.result.relative(2.0).trans_m_mean < 1e-9  # the ground truth's own poses
    odom = read_run(tmp_path / "exp" / "twist-exp" / "odom").config
    assert odom["method"]["description"] == f"external trajectory {bag}:/ground_truth"
    assert odom["external"]["topic"] == odom["identity"]["topic"] == "/ground_truth"
    assert odom["identity"]["trajectory_sha256"] == hashlib.sha256(bag.read_bytes()).hexdigest()
    assert score.score_experiment_external(exp)[1][1] == "skipped"
    assert score.score_experiment_external(exp, force=True)[1][1] == "done"
    # a store with no sequence entry: filed under the store's own name
    exp.sequences = []
    exp.external = [entry("good")]
    assert score.score_experiment_external(exp)[0][1] == "done"
    assert read_run(tmp_path / "exp" / "twist" / "good").config["sequence"]["display_name"] \
        == "Twist drive"
