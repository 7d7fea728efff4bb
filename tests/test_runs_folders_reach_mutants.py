"""bench.runs.folders: what the mutation run (``tools/mutate.py``) left alive after
tests/test_folders_mutants.py. Expected names and records are worked out by hand from the
rules the module states."""

from __future__ import annotations

import re

import pytest

from bench.runs.folders import run_dir_name

# ---- folder names ---------------------------------------------------------------------------


@pytest.mark.parametrize("label, expected", [
    ("Tau ZZ", "Tau-ZZ_seed"),  # capitals are file-name safe: kept
    ("X-ray", "X-ray_seed"),  # only the dashes at either end are stripped, never a letter
    ("-X-", "X_seed"),
])
def test_a_labels_capitals_are_kept_and_only_its_dashes_stripped(label, expected):
    assert run_dir_name("icp-p2p", True, label) == expected


# ---- is_finished ----------------------------------------------------------------------------


def test_a_record_that_does_not_say_its_timing_is_clean_is_finished(tmp_path):
    """Only ``timing_clean: false`` runs again; a record without the field (written before it
    existed) is a finished run."""
    import json

    import yaml

    from bench.runs.folders import is_finished

    run_dir = tmp_path / "seq" / "doppler"
    run_dir.mkdir(parents=True)
    (run_dir / "config.yaml").write_text(yaml.safe_dump({"run_key": "k1"}))
    record = {"schema": 2, "sequence": "seq", "method": "doppler", "frames": 3}
    (run_dir / "metrics.json").write_text(json.dumps(record))
    assert is_finished(run_dir, "k1") and not is_finished(run_dir, "k2")
    (run_dir / "metrics.json").write_text(json.dumps({**record, "timing_clean": False}))
    assert not is_finished(run_dir, "k1")


# ---- broken records -------------------------------------------------------------------------


def test_a_missing_metrics_file_is_named_with_the_systems_reason(tmp_path):
    import errno
    import os

    from bench.runs.folders import BrokenRecord, metrics_raw

    path = tmp_path / "metrics.json"
    with pytest.raises(BrokenRecord) as raised:
        metrics_raw(path)
    # the reason alone ("No such file or directory"), not the exception's "[Errno 2] ..."
    assert str(raised.value) == f"{path}: cannot be read ({os.strerror(errno.ENOENT)})"


_GT = "0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n"
_BROKEN = {
    # not JSON
    "json": ({"metrics.json": "{truncated"}, r"metrics\.json: not valid JSON"),
    # an older record (no schema) whose trajectory files cannot be re-scored
    "older": ({"metrics.json": '{"sequence": "seq", "method": "doppler", "diverged": false}',
               "gt_tum.txt": _GT, "est_tum.txt": "0 nonsense\n"},
              r"metrics\.json: an older record that cannot be re-scored \("),
    # two fields of the wrong type: both named, one after the other
    "fields": ({"metrics.json": '{"schema": 2, "sequence": "seq", "method": "doppler", '
                                '"frames": "many", "frames_scored": "few"}'},
               r"metrics\.json: not a valid run record: field frames: [^;]*\(got 'many'\); "
               r"field frames_scored: [^;]*\(got 'few'\)$"),
}


@pytest.mark.parametrize("kind", sorted(_BROKEN))
def test_a_broken_record_read_as_a_failed_run_keeps_its_folder_and_config(tmp_path, kind):
    import yaml

    from bench.runs.folders import BrokenRecord, read_run

    files, message = _BROKEN[kind]
    run_dir = tmp_path / "seq" / "doppler"
    run_dir.mkdir(parents=True)
    config = {"run_key": "k1", "label": "L", "sequence": {"name": "seq"}}
    (run_dir / "config.yaml").write_text(yaml.safe_dump(config))
    for name, text in files.items():
        (run_dir / name).write_text(text)
    with pytest.raises(BrokenRecord, match=message):
        read_run(run_dir)
    run = read_run(run_dir, failed=True)
    assert run.dir == run_dir and run.config == config
    assert run.result.status == "broken" and run.label == "L" and run.sequence == "seq"
    assert re.search(message, run.result.error)


# ---- the text of a run's files --------------------------------------------------------------


def test_a_single_value_is_a_row_and_exponents_are_lowercase():
    import numpy as np

    from bench.runs.folders import _rows

    assert _rows(np.array([[2.5]])) == "2.5\n"
    text = _rows(np.array([[2.0**-40, -(2.0**1000)]]))
    # 17 significant digits, C's %g: a lowercase exponent
    assert text == "9.0949470177292824e-13 -1.0715086071862673e+301\n"


def test_frames_csv_rows_end_with_a_newline_only():
    import numpy as np

    from bench.runs.folders import frames_csv
    from methods.base import FrameRecord, OdometryResult

    frames = [FrameRecord(i, 0.1 * i, 1.0, 10, 5, 2, True) for i in range(2)]
    text = frames_csv(OdometryResult(0.1 * np.arange(2), np.tile(np.eye(4), (2, 1, 1)), frames))
    assert "\r" not in text and text.count("\n") == 3 and text.endswith("\n")


@pytest.mark.parametrize("name, what", [
    ("gt_tum.txt", "a run's file"),  # removed as stale
    ("est_tum.txt", "a run's file"),  # written
    ("failed.json", "a run's record"),  # removed
])
def test_a_folder_where_a_runs_file_would_be_is_refused_naming_it(tmp_path, name, what):
    import numpy as np

    from bench.guard import Refused
    from bench.runs.folders import write_run
    from methods.base import OdometryResult

    run_dir = tmp_path / "seq" / "doppler"
    (run_dir / name).mkdir(parents=True)
    result = OdometryResult(0.1 * np.arange(2), np.tile(np.eye(4), (2, 1, 1)), [])
    with pytest.raises(Refused) as raised:
        write_run(run_dir, result, None, {"run_key": "k"}, {"sequence": "seq", "method": "m"})
    assert str(raised.value) == f"{run_dir / name}: is a folder; expected the file name of {what}"
    assert (run_dir / name).is_dir() and not (run_dir / "metrics.json").exists()


# ---- older records --------------------------------------------------------------------------


def test_an_older_record_saying_schema_1_is_re_scored_as_schema_2(tmp_path):
    """A metrics.json that names its schema 1 (not only one without the field) reads, once
    re-scored, as today's record."""
    import json

    import numpy as np

    from bench.runs.folders import read_run, write_run
    from loaders.trajectory import Trajectory
    from methods.base import OdometryResult

    run_dir = tmp_path / "seq" / "doppler"
    n = 30
    gt = np.tile(np.eye(4), (n, 1, 1))
    gt[:, 0, 3] = np.arange(n) * 0.5  # a 14.5 m straight line
    est = gt.copy()
    est[:, 0, 3] *= 1.1
    write_run(run_dir, OdometryResult(0.1 * np.arange(n), est, []),
              Trajectory(0.1 * np.arange(n), gt), {"lengths_m": [2.0]},
              {"sequence": "seq", "method": "doppler", "seed": None, "frames": n,
               "diverged": False})
    (run_dir / "metrics.json").write_text(json.dumps(
        {"schema": 1, "sequence": "seq", "method": "doppler", "seed": None, "frames": n,
         "diverged": False, "relative_error": {"2.0": {"trans_m_mean": 99.0}}}))
    result = read_run(run_dir).result
    assert result.schema_version == 2
    (rel,) = result.relative_error
    # every 2 m of ground truth is 2.2 m of estimate: 0.2 m of error per segment
    assert rel.length_m == 2.0
    np.testing.assert_allclose(rel.trans_m_mean, 0.2, atol=1e-9)


# ---- the layout of the JSON files a user opens ----------------------------------------------


def test_failed_json_and_meta_json_are_indented_by_two_spaces(tmp_path):
    """One key per line, indented by two spaces (read by hand when a run failed)."""
    import numpy as np

    from bench.runs.folders import write_failure, write_run
    from methods.base import OdometryResult

    def indents(path):
        lines = path.read_text().splitlines()
        assert lines[0] == "{" and lines[-1] == "}" and len(lines) > 3
        return {len(line) - len(line.lstrip(" ")) for line in lines[1:-1]
                if line.lstrip(" ").startswith('"')}

    run_dir = tmp_path / "seq" / "doppler"
    write_failure(run_dir, None, "it broke")
    assert indents(run_dir / "failed.json") == {2}
    write_run(run_dir, OdometryResult(0.1 * np.arange(2), np.tile(np.eye(4), (2, 1, 1)), []),
              None, {"run_key": "k"}, {"sequence": "seq", "method": "m"})
    assert 2 in indents(run_dir / "meta.json") and min(indents(run_dir / "meta.json")) == 2
