"""bench/runs/reuse.py: a finished run reused under other sequence names takes those names in
both its records, and says so in one line (the mutation run of tools/mutate.py over
bench/runs/reuse.py; the run folders here are written by hand, as a finished run leaves them).
"""

from __future__ import annotations

import json

import yaml

from bench.runs.result import RunResult
from bench.runs.reuse import SEQUENCE_NAMES, rename_reused

KEY = "k" * 64
ASKED = {"name": "loop", "display_name": "Loop 1", "sensor_class": "4D Radar"}


def finished_run(folder, sequence=None, key=KEY, **config):
    """A run folder as ``bench run`` leaves a finished run: config.yaml with its key and
    sequence, metrics.json with its names."""
    folder.mkdir(parents=True)
    seq = sequence if sequence is not None else {
        "name": "hand", "display_name": "By hand", "sensor_class": "Radar",
        "store": "data/x.h5", "frames": 40}
    cfg = {"run_key": key, "method": {"name": "doppler"}, "libraries": {}, **config}
    if sequence is not False:
        cfg["sequence"] = seq
    (folder / "config.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
    names = seq if sequence is not False else {"name": "hand"}
    result = RunResult(sequence=names["name"], method="doppler", frames=40,
                       display_name=names.get("display_name"),
                       sensor_class=names.get("sensor_class"), threads=3)
    (folder / "metrics.json").write_text(result.dump())
    return folder


def records(folder):
    return (yaml.safe_load((folder / "config.yaml").read_text()),
            json.loads((folder / "metrics.json").read_text()))


def test_the_names_a_record_carries():
    assert SEQUENCE_NAMES == ("name", "display_name", "sensor_class")


def test_a_run_reused_under_other_names_takes_them(tmp_path):
    run = finished_run(tmp_path / "run")
    said = rename_reused(run, KEY, {**ASKED, "store": "elsewhere.h5"})
    assert said == (f"reused {run} (made as sequence 'By hand'; the same store, frames and "
                    "settings) under the name 'Loop 1'; `bench run --force` runs it again")
    config, metrics = records(run)
    # the names change, nothing else of the sequence
    assert config["sequence"] == {"name": "loop", "display_name": "Loop 1",
                                  "sensor_class": "4D Radar", "store": "data/x.h5",
                                  "frames": 40}
    assert list(config) == ["run_key", "method", "libraries", "sequence"]
    assert config["run_key"] == KEY
    assert (metrics["sequence"], metrics["display_name"], metrics["sensor_class"]) == (
        "loop", "Loop 1", "4D Radar")
    assert metrics["method"] == "doppler" and metrics["frames"] == 40
    assert metrics["threads"] == 3 and metrics["schema"] == 2
    assert RunResult.model_validate(metrics).sequence == "loop"
    # renamed once: the same names again are nothing to rename
    assert rename_reused(run, KEY, ASKED) is None


def test_one_name_differing_is_enough(tmp_path):
    for i, key in enumerate(SEQUENCE_NAMES):
        same = {"name": "hand", "display_name": "By hand", "sensor_class": "Radar"}
        run = finished_run(tmp_path / str(i))
        said = rename_reused(run, KEY, {**same, key: "other"})
        assert said is not None and "made as sequence 'By hand'" in said
        assert records(run)[0]["sequence"][key] == "other"


def test_the_same_names_leave_the_records_as_they_are(tmp_path):
    run = finished_run(tmp_path / "run")
    before = [(run / n).read_bytes() for n in ("config.yaml", "metrics.json")]
    same = {"name": "hand", "display_name": "By hand", "sensor_class": "Radar", "extra": 1}
    assert rename_reused(run, KEY, same) is None
    assert [(run / n).read_bytes() for n in ("config.yaml", "metrics.json")] == before


def test_an_unfinished_or_other_run_is_not_reused(tmp_path):
    run = finished_run(tmp_path / "run", key="other")
    before = (run / "metrics.json").read_bytes()
    assert rename_reused(run, KEY, ASKED) is None
    assert (run / "metrics.json").read_bytes() == before
    assert rename_reused(tmp_path / "none", KEY, ASKED) is None


def test_the_old_name_is_the_display_name_else_the_name(tmp_path):
    run = finished_run(tmp_path / "a", {"name": "hand", "display_name": None,
                                        "sensor_class": "Radar"})
    assert "(made as sequence 'hand';" in rename_reused(run, KEY, ASKED)
    bare = finished_run(tmp_path / "b", sequence=False)
    said = rename_reused(bare, KEY, ASKED)
    assert "(made as sequence None;" in said
    assert records(bare)[0]["sequence"] == ASKED
