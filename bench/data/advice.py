"""Advice that names only options that exist: which command-line option of the loader that made
a store (its provenance's ``loader``) sets a given loader option, if any.

A store converted by ``bench convert LOADER`` records the loader's name; its options are the
loader's typed options model (``loaders.options``) or, for a loader without one, the keyword
arguments of its ``Sequence`` class. ``bench convert`` spells an option ``--name-with-dashes``.
"""

from __future__ import annotations

import inspect

from loaders.registry import LOADERS


def loader_options(loader: str | None) -> set[str] | None:
    """The option names of loader ``loader`` (None when the loader is not known here)."""
    entry = LOADERS.get(loader or "")
    if entry is None:
        return None
    try:
        cls = entry.load_class()
    except ImportError:
        return None
    options = getattr(cls, "Options", None)
    names = set(getattr(options, "model_fields", {}) or {})
    try:
        names |= {p for p in inspect.signature(cls.__init__).parameters if p != "self"}
    except (TypeError, ValueError):
        pass
    return names


def option_flag(provenance: dict, option: str) -> str | None:
    """``--option-name`` when the loader that made the store (``provenance["loader"]``) takes
    ``option``, else None."""
    names = loader_options(provenance.get("loader"))
    if not names or option not in names:
        return None
    return "--" + option.replace("_", "-")


def loader_name(provenance: dict) -> str:
    return str(provenance.get("loader") or "its loader")


def doppler_refusal(store, who: str, seq) -> str | None:
    """None when ``seq`` (a store's sequence, or a frame range of one) carries raw radial
    Doppler; else why ``who`` (a method, "calibration from Doppler", ...) cannot use it: no
    Doppler values, or ego-compensated Doppler (``SensorInfo.doppler_kind``: static points read
    about 0 m/s). The words `bench run`, `bench calibrate` and the pair figures refuse with."""
    base = getattr(seq, "base", seq)
    has = getattr(base, "has_doppler", None)
    if has is None:
        has = len(seq) > 0 and seq[0].doppler is not None
    prov = getattr(base, "provenance", {}) or {}
    if not has:
        flag = option_flag(prov, "doppler_field")
        again = (f"convert it again naming the Doppler field (bench convert "
                 f"{loader_name(prov)} ... {flag} NAME)" if flag else
                 "convert it from data with Doppler")
        return f"{store}: {who} needs Doppler, but the store has no Doppler values; {again}"
    if seq.sensor.doppler_kind == "ego-compensated":
        return compensated_doppler(store, who, prov)
    return None


def compensated_doppler(store, who: str, provenance: dict) -> str:
    """Why ``who`` (e.g. "doppler", "calibration from Doppler") cannot use a store whose
    Doppler is ego-compensated, and how to get raw radial Doppler (``bench run`` and ``bench
    calibrate`` refuse such a store with this text)."""
    flag = option_flag(provenance, "reconstruct_doppler_from_gt")
    opt_in = (f"convert it again with `bench convert {loader_name(provenance)} ... {flag}` "
              "(results marked GT-assisted)" if flag else
              "reconstructing the radial velocity from the ground truth's ego motion is "
              "an explicit opt-in of the loader (doppler_kind 'gt-reconstructed')")
    return (f"{store}: {who} needs the raw radial Doppler velocity, but the store's Doppler is "
            "ego-compensated (sensor doppler_kind 'ego-compensated': static points read about 0 "
            f"m/s); {opt_in}")
