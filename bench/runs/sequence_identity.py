"""Sequences known by their content: a run's sequence is its store's content (SHA-256) and the
frames of it the run covers; the name is only a label.

Two runs whose sequence has the same name but different content (the same Snail-Radar bag
converted in full and with ``--start 60 --frames 190``; a View-of-Delft folder converted with
radial and with compensated Doppler; a store rewritten in place) are never one sequence: each
run's sequence label gets what tells its content apart, in brackets, e.g. ``data1 [frames
60-249]`` beside ``data1 [frames 0-399]``, ``vod_00000-00099 [radial Doppler]``, else the
stores' file names or their SHA-256 prefixes. Every table, figure, summary and the report group
runs by that label (``RunRecord.sequence`` / ``display_name``), so different content is never
paired as one sequence. Runs whose content is not recorded (older runs without
``identity.store_sha256``) keep their name.

A store's content is its numbers, not its name: ``content_digest`` hashes every dataset and
every attribute of the store but its ``name`` and ``provenance`` (which describe it), so one
recording converted twice under two names (``--name a``, ``--name b``) is one content, and so
is one store run under two sequence names. A run records it (``sequence.content_sha256``);
for a run that does not, it is read from the store when that is still there, else the store's
SHA-256 stands for it. ``one_content`` finds the sequence labels of one content, which the
summaries across sequences count once and name.

The frames are those of the store's source: a store cut at conversion (its provenance's
``frame_range``, recorded by the run as ``sequence.store_frame_range``, else read from the store
when it is still there) composed with the run's own frame range.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

#: store attributes that describe a store rather than hold its content
_DESCRIBING = {"name", "provenance"}
#: rows of a dataset hashed at a time (memory stays bounded on a large store)
_ROWS = 1 << 18
_digests: dict[str, str] = {}


def content_digest(path: str | Path) -> str:
    """SHA-256 of a store's content: every dataset (its path, dtype, shape and values) and
    every attribute but ``name`` and ``provenance``, in sorted order. Cached per process by
    resolved path, size, mtime and inode."""
    import h5py

    st = Path(path).stat()
    key = f"{Path(path).resolve()}|{st.st_size}|{st.st_mtime_ns}|{st.st_ino}"
    if key in _digests:
        return _digests[key]
    h = hashlib.sha256()
    with h5py.File(str(path), "r") as f:
        items: list[tuple[str, object]] = []
        f.visititems(lambda name, obj: items.append((name, obj)))
        for name, obj in [("", f), *sorted(items, key=lambda x: x[0])]:
            for attr in sorted(obj.attrs):
                if not (name == "" and attr in _DESCRIBING):
                    h.update(f"@{name}/{attr}={np.asarray(obj.attrs[attr]).tolist()!r}"
                             .encode())
            if isinstance(obj, h5py.Dataset):
                h.update(f"#{name}:{obj.dtype.str}:{obj.shape}".encode())
                if obj.shape == ():
                    h.update(np.asarray(obj[()]).tobytes())
                else:
                    for k in range(0, obj.shape[0], _ROWS):
                        h.update(np.ascontiguousarray(obj[k:k + _ROWS]).tobytes())
    _digests[key] = h.hexdigest()
    return _digests[key]


def content_or_none(path: str | Path) -> str | None:
    """``content_digest``, or None when the store cannot be read whole (the run's own read
    then says what is wrong with it, as a clear error)."""
    try:
        return content_digest(path)
    except (OSError, ValueError, KeyError, RuntimeError):
        return None


def _content(config: dict) -> str | None:
    """The run's store content: recorded, else read from the store, else its SHA-256."""
    seq = config.get("sequence") or {}
    recorded = seq.get("content_sha256")
    if isinstance(recorded, str) and recorded:
        return recorded
    store = seq.get("store")
    sha = (config.get("identity") or {}).get("store_sha256")
    if isinstance(sha, str) and sha and store and Path(str(store)).is_file():
        digest = content_or_none(str(store))
        if digest is not None:
            return digest
    return sha if isinstance(sha, str) and sha else None


def content_key(config: dict) -> tuple | None:
    """What a run's sequence *is*: (its store's content, the run's frame range), or None when
    its configuration does not record the store."""
    identity = config.get("identity") or {}
    seq = config.get("sequence") or {}
    sha = _content(config)
    if sha is None:
        return None
    frame_range = identity.get("frame_range", seq.get("frame_range"))
    return (sha, tuple(frame_range) if isinstance(frame_range, list | tuple) else None)


def one_content(labels: Sequence[str], configs: Sequence[dict]) -> dict[str, str]:
    """Sequence label -> the label it is counted under: the first (sorted) of the labels whose
    runs hold one content (``content_key``); a label alone with its content maps to itself,
    and so does one whose content is not recorded."""
    by_key: dict[tuple, set[str]] = {}
    for label, config in zip(labels, configs, strict=True):
        key = content_key(config)
        if key is not None:
            by_key.setdefault(key, set()).add(label)
    out = {label: label for label in labels}
    for group in by_key.values():
        first = sorted(group)[0]
        for label in group:
            out[label] = first
    return out


def _store_cut(seq: dict) -> dict | None:
    """The frame range the store was cut to at conversion (None: the whole source)."""
    if "store_frame_range" in seq:
        cut = seq.get("store_frame_range")
        return cut if isinstance(cut, dict) else None
    store = seq.get("store")
    if not store or not Path(str(store)).is_file():
        return None
    try:
        import h5py

        with h5py.File(str(store), "r") as f:
            cut = json.loads(f.attrs.get("provenance", "{}")).get("frame_range")
    except (OSError, ValueError, AttributeError):
        return None
    return cut if isinstance(cut, dict) else None


def frames_text(config: dict) -> str | None:
    """The frames of the store's source a run covers, "frames 60-249" (with ", stride 2"
    for a stride), or None when the number of frames is not recorded."""
    seq = config.get("sequence") or {}
    identity = config.get("identity") or {}
    count = seq.get("frames")
    own = identity.get("frame_range", seq.get("frame_range")) or (0, None)
    cut = _store_cut(seq) or {}
    stride = int(cut.get("stride") or 1)
    first = int(cut.get("start") or 0) + int(own[0] or 0) * stride
    if not isinstance(count, int) or count < 1:
        return None
    last = first + (count - 1) * stride
    # a NumPy frame folder's own numbers (frame_061.npy ...): said as such, since a folder may
    # number its drive from 0 or from 1
    what = "frame files" if cut.get("from") == "file numbers" else "frames"
    return f"{what} {first}-{last}" + (f", stride {stride}" if stride > 1 else "")


def _attributes(config: dict) -> dict[str, str]:
    seq = config.get("sequence") or {}
    sha = str((config.get("identity") or {}).get("store_sha256") or "")
    return {"frames": frames_text(config) or "frames not recorded",
            "doppler": f"{seq.get('doppler_kind') or 'radial'} Doppler",
            "store": Path(str(seq.get("store") or "")).name or "store not recorded",
            "sha": f"store {sha[:12]}"}


def sequence_tags(names: Sequence[str], configs: Sequence[dict]) -> list[str]:
    """Per run (its sequence ``names[i]`` and ``configs[i]``), "" or what tells its content
    apart from another content under the same name (see the module's doc)."""
    keys = [content_key(c) for c in configs]
    by_name: dict[str, dict[tuple, dict[str, str]]] = {}
    for name, key, config in zip(names, keys, configs, strict=True):
        if key is not None:
            by_name.setdefault(name, {}).setdefault(key, _attributes(config))
    tags: dict[tuple[str, tuple], str] = {}
    for name, contents in by_name.items():
        if len(contents) < 2:
            continue
        attrs = list(contents.values())
        chosen: list[str] = []
        for what in ("frames", "doppler", "store", "sha"):  # the fewest that tell all apart
            if len({tuple(a[w] for w in chosen) for a in attrs}) == len(attrs):
                break
            if len({a[what] for a in attrs}) > 1:
                chosen.append(what)
        for key, a in contents.items():
            tags[(name, key)] = ", ".join(a[w] for w in chosen)
    return [tags.get((name, key), "") if key is not None else ""
            for name, key in zip(names, keys, strict=True)]


def tagged(name: str, tag: str) -> str:
    """A sequence label with its content tag: "data1 [frames 60-249]"."""
    return f"{name} [{tag}]" if tag else name
