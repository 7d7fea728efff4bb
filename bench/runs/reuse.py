"""Reusing a finished run under the names an experiment asks for.

A run is reused when its run key matches (``bench.runs.identity``: the store's SHA-256 and
frame range, the method and its parameters, the seed option, the scoring and the code), which
is the sequence's identity; its sequence *names* (name, display name, sensor class) are not
part of the key. A run made by hand and then named by an experiment is therefore the same
run: its records take the experiment's names, and one line says what was reused under which
name, so its table row joins its sequence instead of standing alone as another sequence.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

from bench import guard
from bench.runs.folders import is_finished
from bench.runs.result import RunResult
from loaders.yamlio import read_yaml

#: the names a run record carries of its sequence (config.yaml ``sequence`` / metrics.json)
SEQUENCE_NAMES = ("name", "display_name", "sensor_class")


def rename_reused(run_dir: Path, key: str, sequence: dict) -> str | None:
    """A finished run of the same inputs (``key``: the store's SHA-256, its frame range, the
    method, its parameters, the scoring and the code) that is reused under other sequence names
    than it was made with (e.g. a run made by hand, then named by an experiment): its records
    take the names asked for now (so its table row joins its sequence) and the returned line
    says what was reused under which name; None when there is nothing to rename."""
    if not is_finished(run_dir, key):
        return None
    config = read_yaml(run_dir / "config.yaml") or {}
    old = config.get("sequence") or {}
    if all(old.get(k) == sequence.get(k) for k in SEQUENCE_NAMES):
        return None
    raw = json.loads((run_dir / "metrics.json").read_text())
    raw.update({"sequence": sequence["name"], "display_name": sequence["display_name"],
                "sensor_class": sequence["sensor_class"]})
    config["sequence"] = {**old, **{k: sequence[k] for k in SEQUENCE_NAMES}}
    guard.write_text(run_dir / "config.yaml", yaml.safe_dump(config, sort_keys=False),
                     guard.in_a_run, "a run's file")
    guard.write_text(run_dir / "metrics.json", RunResult.model_validate(raw).dump(),
                     guard.in_a_run, "a run's file")
    was = old.get("display_name") or old.get("name")
    return (f"reused {run_dir} (made as sequence {was!r}; the same store, frames and "
            f"settings) under the name {sequence['display_name']!r}; `bench run --force` "
            "runs it again")
