"""The pieces of bench.runs.external.score that need no store: the file hashes of its identity,
the options' bounds, the frame of the poses, each scan's reported time, the notes of a run, and
what an estimate too short to score is told."""

import hashlib

import numpy as np
import pytest

from bench.runs.evaluate import Scoring
from bench.runs.external import score
from bench.runs.external.match import Matched
from bench.runs.external.score import (
    NOT_TIMED,
    ExternalSpec,
    _frame_times,
    _notes,
    _str,
    check_options_of,
    file_sha256,
    frame_transform,
)
from loaders.errors import DataError


def test_a_file_hashes_to_its_sha256_and_a_folder_to_its_files_with_their_names(tmp_path):
    f = tmp_path / "a.tum"
    f.write_bytes(b"0 1 2 3\n" * 1000)
    assert file_sha256(f) == hashlib.sha256(b"0 1 2 3\n" * 1000).hexdigest()
    assert file_sha256(None) is None
    bag = tmp_path / "bag"
    (bag / "sub").mkdir(parents=True)
    (bag / "x.db3").write_bytes(b"xx")
    (bag / "sub" / "meta.yaml").write_bytes(b"m")
    want = hashlib.sha256(b"sub/meta.yaml\0" + b"m" + b"x.db3\0" + b"xx").hexdigest()
    assert file_sha256(bag) == want
    (bag / "x.db3").rename(bag / "y.db3")  # a renamed file changes the folder's hash
    assert file_sha256(bag) != want


def test_a_file_larger_than_a_read_hashes_whole(tmp_path):
    data = np.random.default_rng(0).bytes((1 << 20) + 17)
    f = tmp_path / "big.bin"
    f.write_bytes(data)
    assert file_sha256(f) == hashlib.sha256(data).hexdigest()


def test_the_scoring_codes_hash_is_of_the_external_modules():
    h = hashlib.sha256()
    folder = score.Path(score.__file__).parent
    for path in sorted(folder.glob("*.py")):
        h.update(path.read_bytes())
    assert score._own_code() == h.hexdigest()[:16]


def test_the_minimum_coverage_is_a_share_from_0_to_1():
    for share in (0.0, 0.5, 1.0):
        check_options_of(ExternalSpec("e.tum", "e", min_coverage=share))
    for share in (-0.01, 1.01, float("nan"), float("inf")):
        with pytest.raises(DataError, match=r"--min-coverage .*: expected a share in \[0, 1\] "
                                            r"of the scans with ground truth"):
            check_options_of(ExternalSpec("e.tum", "e", min_coverage=share))
    with pytest.raises(DataError, match="--tolerance -1"):  # the association's options too
        check_options_of(ExternalSpec("e.tum", "e", tolerance_s=-1.0))
    with pytest.raises(DataError, match="--max-gap 0"):
        check_options_of(ExternalSpec("e.tum", "e", max_gap_s=0.0))


def test_the_frame_of_the_poses():
    T_body_sensor = np.eye(4)
    T_body_sensor[:3, 3] = [1.0, 2.0, 3.0]
    T, how = frame_transform(ExternalSpec("e", "e"), T_body_sensor)
    np.testing.assert_array_equal(T, np.eye(4))
    assert how == "identity (poses of the sensor)"
    T, how = frame_transform(ExternalSpec("e", "e", pose_frame="body"), T_body_sensor)
    np.testing.assert_array_equal(T, T_body_sensor)
    assert how == "the store's T_body_sensor"
    T, how = frame_transform(ExternalSpec("e", "e", pose_frame="body", extrinsic="4 5 6 0 0 0 1"),
                             T_body_sensor)  # an extrinsic given wins
    np.testing.assert_array_equal(T[:3, 3], [4.0, 5.0, 6.0])
    assert how == "given (--extrinsic)"
    with pytest.raises(DataError, match="--pose-frame 'world': expected sensor or body"):
        frame_transform(ExternalSpec("e", "e", pose_frame="world"), T_body_sensor)


def test_each_scan_has_the_reported_time_of_the_pose_it_matched():
    m = Matched(np.zeros((4, 4, 4)), np.array([True, True, True, False]),
                np.array([True, False, True, False]), {}, np.array([2, -1, 0, -1]))
    np.testing.assert_array_equal(_frame_times(np.array([10.0, 11.0, 12.0]), 4, m),
                                  [12.0, np.nan, 10.0, np.nan])
    assert np.isnan(_frame_times(None, 4, m)).all()
    none = Matched(np.zeros((4, 4, 4)), np.zeros(4, bool), np.zeros(4, bool), {},
                   np.full(4, -1))
    assert np.isnan(_frame_times(np.array([10.0]), 4, none)).all()


def test_the_notes_say_what_was_scored_and_how():
    coverage = {"share_scored": 0.75, "max_gap_s": None, "scored": 3, "scans_with_gt": 4,
                "matched": 3, "tolerance_s": 0.01, "interpolated": 0}
    assert _notes(coverage, False) == [
        "external trajectory: 3 of the 4 scans with ground truth scored (75.0 %): 3 matched "
        "within 0.01 s, 0 interpolated (no --max-gap: no interpolation)", NOT_TIMED]
    bridged = {**coverage, "max_gap_s": 0.5, "widest_bridged_s": 0.25, "interpolated": 1}
    assert _notes(bridged, True) == [
        "external trajectory: 3 of the 4 scans with ground truth scored (75.0 %): 3 matched "
        "within 0.01 s, 1 interpolated (--max-gap 0.5 s; the widest gap bridged 0.25 s)"]
    assert _notes({k: v for k, v in bridged.items() if k != "widest_bridged_s"}, True)[0] \
        .endswith("the widest gap bridged 0 s)")
    assert NOT_TIMED.startswith("not timed: ")
    assert _str(None) is None and _str(score.Path("a/b")) == "a/b"


def test_an_estimate_too_short_is_told_its_coverage_and_path(monkeypatch):
    """evaluate_run finds no segment: the estimate is named with its scored share and the
    length of its path over the scans with ground truth (3 + 4 m), not the store."""
    def no_segment(*a, **k):
        raise DataError("store.h5: no relative-error segment of 10 m")

    monkeypatch.setattr(score, "evaluate_run", no_segment)
    poses = np.repeat(np.eye(4)[None], 4, 0)
    poses[:, :3, 3] = [[0, 0, 0], [3, 0, 0], [3, 4, 0], [100, 100, 0]]
    result = score.OdometryResult(np.arange(4.0), poses, [])
    with_gt = np.array([True, True, True, False, True])
    idx = np.array([0, 1, 2, 3])
    coverage = {"scored": 3, "scans_with_gt": 4, "share_scored": 0.75}
    with pytest.raises(DataError) as e:
        score._evaluate(None, result, Scoring(lengths_m=(10.0, 20.0)), with_gt, idx, coverage,
                        "e.tum", "store.h5")
    assert str(e.value) == ("e.tum is too short to score: it covers 3 of the 4 scans with ground "
                            "truth (75.0 %), about 7.000 m of path, shorter than the shortest "
                            "segment (10 m)")
    one = np.array([True, False, False, False, False])
    with pytest.raises(DataError, match="about 0.000 m of path"):
        score._evaluate(None, result, Scoring(lengths_m=(10.0,)), one, idx, coverage, "e", "s")
    two = np.array([True, True, False, False, False])
    with pytest.raises(DataError, match="about 3.000 m of path"):
        score._evaluate(None, result, Scoring(lengths_m=(10.0,)), two, idx, coverage, "e", "s")

    seen = {}

    def other(*a, **k):
        seen.update(k)
        raise DataError("store.h5: something else")

    monkeypatch.setattr(score, "evaluate_run", other)
    scoring = Scoring()
    with pytest.raises(DataError, match="^store.h5: something else$"):
        score._evaluate(None, result, scoring, with_gt, idx, coverage, "e", "store.h5")
    # scored as a run is: named by the store, its scoring, the scans without ground truth out
    assert seen["name"] == "store.h5" and seen["scoring"] is scoring
    np.testing.assert_array_equal(seen["excluded"], [False, False, False, True])
