"""What ``bench report``'s page reads of run folders: ``read_page_runs``, the page's one reader
of run records (the documented files of a run folder, README "Results layout": config.yaml,
metrics.json, failed.json, meta.json, gt_tum.txt), into plain ``PageRun`` records. When the run
folders' reader changes (a typed result), only this module follows."""

from __future__ import annotations

import json
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from bench.runs.folders import BROKEN, check_record
from bench.runs.sequence_identity import sequence_tags, tagged
from loaders.yamlio import read_yaml


@dataclass(frozen=True)
class PageRun:
    """What the page shows of one run folder."""

    folder: str                    # relative to the results folder
    sequence: str                  # display name
    run: str                       # the run folder's name (method, label, seed option)
    status: str                    # finished, failed, crashed, timeout, interrupted, unfinished,
    #                                broken (a metrics.json that is no valid record)
    message: str = ""
    store: str | None = None
    store_sha256: str | None = None
    frames: int | None = None
    has_gt: bool = False
    diverged: bool | None = None
    clock: str | None = None
    threads: int | None = None
    code_sha256: str | None = None
    meta: dict = field(default_factory=dict)
    mtime: float = 0.0
    frames_replaced: int = 0       # registered frames replaced by the motion prior
    frames_unconverged: int = 0    # registered frames that did not converge
    damaged: tuple[str, ...] = ()  # files of the folder that cannot be read (file_problems)


def read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text()) if path.exists() else {}
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def read_page_runs(results_dir: Path) -> list[PageRun]:
    """Every run folder under ``results_dir`` (a folder holding ``config.yaml`` with a
    ``run_key``, ``metrics.json`` or ``failed.json``): the page's one reader of run records."""
    results_dir = Path(results_dir)
    folders = sorted({p.parent for name in ("metrics.json", "failed.json", "config.yaml")
                      for p in results_dir.rglob(name)})
    runs, configs = [], []
    for d in folders:
        config = {}
        if (d / "config.yaml").exists():
            try:
                config = read_yaml(d / "config.yaml") or {}
            except (OSError, yaml.YAMLError):
                pass
        config = config if isinstance(config, dict) else {}
        metrics, failed = read_json(d / "metrics.json"), read_json(d / "failed.json")
        broken = check_record(d / "metrics.json") if (d / "metrics.json").exists() else None
        if broken:
            metrics = {}
        elif not (metrics or (d / "failed.json").exists() or "run_key" in config):
            continue  # a config.yaml of something else (an experiment)
        seq = config.get("sequence") if isinstance(config.get("sequence"), dict) else {}
        identity = config.get("identity") if isinstance(config.get("identity"), dict) else {}
        if broken:
            status, message = BROKEN, broken
        elif metrics:
            status, message = "finished", ""
        elif failed:
            status, message = failed.get("status", "failed"), failed.get("error", "")
        elif (d / "failed.json").exists():
            status, message = "failed", f"{d / 'failed.json'}: not a readable failure record"
        else:
            status, message = "unfinished", "no metrics.json and no failed.json"
        records = [d / n for n in ("metrics.json", "failed.json") if (d / n).exists()]
        runs.append(PageRun(
            folder=str(d.relative_to(results_dir)),
            sequence=str(seq.get("display_name") or seq.get("name") or metrics.get("sequence")
                         or d.parent.name),
            run=d.name, status=status, message=str(message), store=seq.get("store"),
            store_sha256=identity.get("store_sha256"),
            frames=metrics.get("frames", seq.get("frames")),
            has_gt=(d / "gt_tum.txt").exists(), diverged=metrics.get("diverged"),
            clock=metrics.get("clock"), threads=metrics.get("threads"),
            code_sha256=identity.get("code_sha256"), meta=read_json(d / "meta.json"),
            mtime=max((p.stat().st_mtime for p in records), default=0.0),
            frames_replaced=int(metrics.get("frames_replaced") or 0),
            frames_unconverged=int(metrics.get("frames_unconverged") or 0),
            damaged=tuple(file_problems(d, status == "finished"))))
        # a part of the wrong kind is left out, as the run folders' reader does
        configs.append({k: v for k, v in config.items()
                        if k not in ("sequence", "identity") or isinstance(v, dict)})
    # two contents under one name are two sequences here too (bench.runs.sequence_identity)
    tags = sequence_tags([r.sequence for r in runs], configs)
    return [replace(r, sequence=tagged(r.sequence, t)) for r, t in zip(runs, tags, strict=True)]


def file_problems(run_dir: Path, finished: bool) -> list[str]:
    """The run folder's files besides its record that cannot be read (config.yaml, meta.json
    and, of a finished run, its trajectory files), each naming the file and what is wrong:
    the page lists them, never passes over them."""
    from bench.runs.folders import read_run_tum

    out = []
    for name, load in (("config.yaml", yaml.safe_load), ("meta.json", json.loads)):
        path = run_dir / name
        if path.exists():
            try:
                data = load(path.read_text())
                if not isinstance(data, dict):
                    out.append(f"{path}: expected a mapping, found {type(data).__name__}")
            except (OSError, ValueError, yaml.YAMLError) as err:
                out.append(f"{path}: not readable ({str(err).splitlines()[0]})")
    if finished:
        for name in ("gt_tum.txt", "est_tum.txt"):
            path = run_dir / name
            if path.exists():
                try:
                    read_run_tum(path)
                except (OSError, ValueError) as err:
                    text = str(err).splitlines()[0]
                    out.append(text if str(path) in text else f"{path}: {text}")
    return out
