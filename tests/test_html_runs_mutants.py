"""bench/report/html/runs.py, in-process and fast: what the page reads of run folders (status,
message, names, identity, counts, the folder's damaged files, content tags)."""

import json
import os
from pathlib import Path

from bench.report.html.runs import file_problems, read_json, read_page_runs

METRICS = {"sequence": "rec_seq", "method": "doppler", "seed": None, "frames": 12,
           "frames_scored": 12, "diverged": False, "clock": "wall", "threads": 2}


def run_folder(root: Path, rel: str, metrics=None, failed=None, config=None, meta=None,
               gt: str | None = None) -> Path:
    d = root / rel
    d.mkdir(parents=True)
    if metrics is not None:
        (d / "metrics.json").write_text(metrics if isinstance(metrics, str)
                                        else json.dumps(metrics))
    if failed is not None:
        (d / "failed.json").write_text(failed if isinstance(failed, str) else json.dumps(failed))
    if config is not None:
        (d / "config.yaml").write_text(config if isinstance(config, str) else json.dumps(config))
    if meta is not None:
        (d / "meta.json").write_text(meta)
    if gt is not None:
        (d / "gt_tum.txt").write_text(gt)
    return d


def by_folder(root: Path) -> dict:
    return {r.folder: r for r in read_page_runs(root)}


def test_read_json(tmp_path):
    assert read_json(tmp_path / "none.json") == {}
    (tmp_path / "a.json").write_text("{bad")
    assert read_json(tmp_path / "a.json") == {}
    (tmp_path / "b.json").write_text("[1]")
    assert read_json(tmp_path / "b.json") == {}
    (tmp_path / "c.json").write_text('{"x": 1}')
    assert read_json(tmp_path / "c.json") == {"x": 1}
    (tmp_path / "d.json").mkdir()
    assert read_json(tmp_path / "d.json") == {}


def test_a_finished_run_shows_its_record_and_config(tmp_path):
    config = {"run_key": "k", "sequence": {"name": "seq", "display_name": "Seq One",
                                           "store": "/data/s.h5", "frames": 99},
              "identity": {"store_sha256": "abc", "code_sha256": "def"}}
    d = run_folder(tmp_path, "data/seq/orb", metrics={**METRICS, "frames_replaced": 3,
                                                      "frames_unconverged": 2},
                   config=config, meta='{"host": "h1"}', gt="")
    os.utime(d / "metrics.json", (1000.0, 1000.0))
    [r] = read_page_runs(tmp_path)
    assert r.folder == "data/seq/orb"
    assert r.sequence == "Seq One"
    assert r.run == "orb"
    assert (r.status, r.message) == ("finished", "")
    assert r.store == "/data/s.h5"
    assert r.store_sha256 == "abc"
    assert r.code_sha256 == "def"
    assert r.frames == 12
    assert r.has_gt is True
    assert r.diverged is False
    assert r.clock == "wall"
    assert r.threads == 2
    assert r.meta == {"host": "h1"}
    assert r.mtime == 1000.0
    assert (r.frames_replaced, r.frames_unconverged) == (3, 2)


def test_names_fall_back(tmp_path):
    run_folder(tmp_path, "a/p1/r", metrics=METRICS,
               config={"run_key": "k", "sequence": {"name": "plain", "display_name": ""}})
    run_folder(tmp_path, "b/p2/r", metrics=METRICS, config={"run_key": "k"})
    run_folder(tmp_path, "c/p3/r", metrics={k: v for k, v in METRICS.items()
                                            if k != "sequence"})
    run_folder(tmp_path, "d/p4/r", metrics=METRICS,
               config={"run_key": "k", "sequence": "not a mapping", "identity": [1]})
    runs = by_folder(tmp_path)
    assert runs["a/p1/r"].sequence == "plain"
    assert runs["b/p2/r"].sequence == "rec_seq"
    assert runs["c/p3/r"].sequence == "p3"
    assert runs["d/p4/r"].sequence == "rec_seq"
    assert runs["d/p4/r"].store is None and runs["d/p4/r"].store_sha256 is None
    assert runs["c/p3/r"].has_gt is False
    assert runs["c/p3/r"].frames_replaced == 0 and runs["c/p3/r"].frames_unconverged == 0


def test_failed_and_unfinished_runs(tmp_path):
    run_folder(tmp_path, "s/f1", failed={"status": "timeout", "error": "took 9 s"},
               config={"run_key": "k", "sequence": {"name": "s", "frames": 40}})
    run_folder(tmp_path, "s/f2", failed={"error": "boom"})
    d3 = run_folder(tmp_path, "s/f3", failed="not json")
    d4 = run_folder(tmp_path, "s/f4", failed="{}")
    run_folder(tmp_path, "s/u", config={"run_key": "k"})
    run_folder(tmp_path, "exp", config={"experiment": "x"})  # no run: not listed
    run_folder(tmp_path, "s/e", metrics="{}", config={"experiment": "x"})
    runs = by_folder(tmp_path)
    assert (runs["s/f1"].status, runs["s/f1"].message) == ("timeout", "took 9 s")
    assert runs["s/f1"].frames == 40
    assert runs["s/f1"].mtime == (tmp_path / "s/f1/failed.json").stat().st_mtime
    assert (runs["s/f2"].status, runs["s/f2"].message) == ("failed", "boom")
    assert (runs["s/f3"].status, runs["s/f3"].message) == (
        "failed", f"{d3 / 'failed.json'}: not a readable failure record")
    assert (runs["s/f4"].status, runs["s/f4"].message) == (
        "failed", f"{d4 / 'failed.json'}: not a readable failure record")
    assert (runs["s/u"].status, runs["s/u"].message) == (
        "unfinished", "no metrics.json and no failed.json")
    assert runs["s/u"].mtime == 0.0
    assert "exp" not in runs
    assert runs["s/u"].frames is None


def test_failure_message_without_error_is_empty(tmp_path):
    run_folder(tmp_path, "s/f", failed={"status": "crashed"})
    [r] = read_page_runs(tmp_path)
    assert (r.status, r.message) == ("crashed", "")


def test_a_broken_record_is_broken_not_finished(tmp_path):
    d = run_folder(tmp_path, "s/b", metrics="[1, 2]", failed={"status": "timeout"},
                   config={"run_key": "k", "sequence": {"name": "s", "frames": 7}})
    [r] = read_page_runs(tmp_path)
    assert r.status == "broken"
    assert str(d / "metrics.json") in r.message and "list" in r.message
    assert r.frames == 7  # the broken record's fields are not read
    assert r.diverged is None and r.clock is None


def test_broken_metrics_fields_are_not_shown(tmp_path):
    run_folder(tmp_path, "s/b", metrics='{"schema": "x", "frames": 5, "clock": "cpu"}')
    [r] = read_page_runs(tmp_path)
    assert r.status == "broken"
    assert r.frames is None and r.clock is None and r.sequence == "s"


def test_mtime_is_the_newest_record(tmp_path):
    d = run_folder(tmp_path, "s/r", metrics=METRICS, failed={"status": "failed"})
    os.utime(d / "metrics.json", (500.0, 500.0))
    os.utime(d / "failed.json", (700.0, 700.0))
    (d / "meta.json").write_text("{}")
    os.utime(d / "meta.json", (900.0, 900.0))
    [r] = read_page_runs(tmp_path)
    assert r.mtime == 700.0
    assert r.status == "finished"


def test_unreadable_config_is_listed_as_damaged(tmp_path):
    d = run_folder(tmp_path, "s/r", metrics=METRICS, config="a: [unclosed\n")
    [r] = read_page_runs(tmp_path)
    assert r.sequence == "rec_seq"
    assert len(r.damaged) == 1
    assert r.damaged[0].startswith(f"{d / 'config.yaml'}: not readable (")
    assert "\n" not in r.damaged[0]


def test_file_problems(tmp_path):
    d = tmp_path / "r"
    d.mkdir()
    assert file_problems(d, True) == []
    (d / "config.yaml").write_text("- 1\n- 2\n")
    (d / "meta.json").write_text('"text"')
    assert file_problems(d, False) == [
        f"{d / 'config.yaml'}: expected a mapping, found list",
        f"{d / 'meta.json'}: expected a mapping, found str"]
    (d / "meta.json").write_text("{oops")
    (d / "config.yaml").write_text("a: 1\n")
    [p] = file_problems(d, False)
    assert p.startswith(f"{d / 'meta.json'}: not readable (Expecting")
    (d / "meta.json").write_text("{}")
    (d / "gt_tum.txt").write_text("1 2 3\n")
    (d / "est_tum.txt").write_text("garbage line\n")
    assert file_problems(d, False) == []
    probs = file_problems(d, True)
    assert len(probs) == 2
    assert str(d / "gt_tum.txt") in probs[0] and str(d / "est_tum.txt") in probs[1]
    for p in probs:
        assert p.count(str(d)) == 1  # the path named once, not twice
        assert "\n" not in p


def test_file_problems_of_a_good_trajectory(tmp_path):
    d = tmp_path / "r"
    d.mkdir()
    (d / "est_tum.txt").write_text("0.0 0 0 0 0 0 0 1\n1.0 1 0 0 0 0 0 1\n")
    assert file_problems(d, True) == []


def test_two_contents_under_one_name_are_tagged(tmp_path):
    def cfg(sha, frames):
        return {"run_key": "k", "sequence": {"name": "s", "content_sha256": sha,
                                             "frames": frames}}
    run_folder(tmp_path, "x/s/a", metrics={**METRICS, "frames": 10}, config=cfg("aaa", 10))
    run_folder(tmp_path, "y/s/a", metrics={**METRICS, "frames": 20}, config=cfg("bbb", 20))
    run_folder(tmp_path, "z/s/a", metrics=METRICS,
               config={"run_key": "k", "sequence": {"name": "other"}})
    runs = by_folder(tmp_path)
    a, b = runs["x/s/a"].sequence, runs["y/s/a"].sequence
    assert a != b
    assert a.startswith("s [") and b.startswith("s [")
    assert runs["z/s/a"].sequence == "other"


def test_a_config_that_is_not_a_mapping_is_left_out(tmp_path):
    run_folder(tmp_path, "s/r", metrics=METRICS, config="- 1\n- 2\n")
    [r] = read_page_runs(tmp_path)
    assert r.sequence == "rec_seq" and r.status == "finished"
    assert r.damaged == (f"{tmp_path / 's/r/config.yaml'}: expected a mapping, found list",)


def test_trajectory_files_are_checked_for_finished_runs_only(tmp_path):
    run_folder(tmp_path, "s/fin", metrics=METRICS, gt="garbage line\n")
    run_folder(tmp_path, "s/fail", failed={"status": "failed"}, gt="garbage line\n")
    runs = by_folder(tmp_path)
    assert runs["s/fail"].damaged == ()
    [p] = runs["s/fin"].damaged
    assert str(tmp_path / "s/fin/gt_tum.txt") in p
    assert not p.endswith(": None")
