"""Telling apart table rows that would carry the same label: two runs of one sequence with the
same method, seed option and label (e.g. made with different ``--alignment``, segment lengths,
method parameters or code) each get what differs between their configurations appended to
their label, ``(No initial guess) Doppler ... [alignment=sim3]``, so no row is dropped or
shown twice without saying which run it is.

What differs is read from each run's config.yaml ``identity`` (the inputs of its run key,
``bench.runs.identity``): method parameters by name, ``alignment``, ``lengths_m``,
``kitti_lengths_m``, ``frame_range``, the store (its file name, or its SHA-256 when the names
agree), the code hash and the host. Runs whose configurations agree on all of these are told
apart by their run folder's name.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")


def _text(value) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list | tuple):
        return ",".join(_text(v) for v in value)
    if value is None:
        return "none"
    return str(value)


def config_items(config: dict) -> dict[str, str]:
    """A run configuration's determining items as ``name -> text`` (see the module's doc)."""
    identity = config.get("identity") or {}
    method = config.get("method") or {}
    seq = config.get("sequence") or {}
    items: dict[str, str] = {}
    for name, value in (identity.get("params") or method.get("params") or {}).items():
        items[str(name)] = _text(value)
    scoring = identity.get("scoring") or {}
    items["alignment"] = _text(scoring.get("alignment", config.get("alignment", "se3")))
    items["lengths_m"] = _text(identity.get("lengths_m", config.get("lengths_m")))
    items["kitti_lengths_m"] = _text(scoring.get("kitti_lengths_m",
                                                 config.get("kitti_lengths_m")))
    items["frame_range"] = _text(identity.get("frame_range", seq.get("frame_range")))
    items["store"] = Path(str(seq.get("store") or "")).name or "not recorded"
    items["store_sha256"] = str(identity.get("store_sha256") or "not recorded")[:12]
    items["code"] = str(identity.get("code_sha256") or "not recorded")[:12]
    for name, value in (identity.get("host") or {}).items():
        items[f"host.{name}"] = _text(value)
    return items


def differences(configs: Sequence[dict]) -> list[str]:
    """Per configuration, the items in which it differs from the others ("alignment=sim3,
    lengths_m=8,16"); "" for every one when they agree on all."""
    flat = [config_items(c) for c in configs]
    names = list(dict.fromkeys(k for f in flat for k in f))
    differ = [k for k in names if len({f.get(k, "not recorded") for f in flat}) > 1]
    if "store" in differ and "store_sha256" in differ:
        differ.remove("store_sha256")  # the file names already tell them apart
    return [", ".join(f"{k}={f.get(k, 'not recorded')}" for k in differ) for f in flat]


def distinct_labels(items: Sequence[T], label: Callable[[T], str],
                    group: Callable[[T], Hashable], config: Callable[[T], dict],
                    folder: Callable[[T], Path]) -> list[str]:
    """The labels of ``items``, each item whose ``(group, label)`` is shared with another made
    distinct by what differs in its configuration (else its run folder's name), in brackets."""
    clashes: dict[tuple, list[int]] = {}
    for i, item in enumerate(items):
        clashes.setdefault((group(item), label(item)), []).append(i)
    out = [label(item) for item in items]
    for members in clashes.values():
        if len(members) < 2:
            continue
        diffs = dict(zip(members, differences([config(items[i]) for i in members]),
                         strict=True))
        seen = [diffs[i] for i in members]
        for i in members:
            what = diffs[i]
            if seen.count(what) > 1:  # the same items as another: its run folder tells
                what = f"{what}, run folder {folder(items[i]).name}" if what else \
                    f"run folder {folder(items[i]).name}"
            out[i] = f"{out[i]} [{what}]"
    return out
