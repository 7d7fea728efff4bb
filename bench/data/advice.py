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
