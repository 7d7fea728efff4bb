"""Parameter sweeps of an experiment: a method entry's grid expanded into labelled variants
(``expand``), and the index of a finished sweep (``sweep_index``: which run folder holds which
point, what the method's default is there, and the experiment's criterion), written to
``<out>/sweeps.json`` so that ``bench table RESULTS --sweep`` (bench/report/tables/sweep.py)
can show the sweep and its best point without the YAML.

Syntax (bench/runs/experiment.py): a list in ``params`` for a parameter that takes one value
is a sweep over that list; ``sweep: {key: [values]}`` sweeps any parameter, including one whose
value is itself a list. Several swept keys form a grid (every combination, in the order given:
the first key varies slowest). Each point is the variant ``"<label or method> k1=v1 k2=v2"``.
"""

from __future__ import annotations

import itertools
import json
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path

from bench import guard
from loaders.errors import DataError
from methods.registry import get_method

INDEX = "sweeps.json"


@dataclass(frozen=True)
class Variant:
    """One run configuration of a method entry: its label, its parameters and, for a sweep
    point, the swept values (``point``) and the sweep's name (``group``)."""

    label: str | None
    params: dict
    point: dict = field(default_factory=dict)
    group: str | None = None


def takes_a_list(method: str, key: str) -> bool:
    """True when parameter ``key`` of ``method`` takes a list (or tuple) as its value."""
    Params = getattr(get_method(method), "Params", None)
    info = None if Params is None else Params.model_fields.get(key)
    return info is not None and _admits_sequence(info.annotation)


def _admits_sequence(annotation) -> bool:
    origin = typing.get_origin(annotation)
    if origin in (list, tuple, set, frozenset) or annotation in (list, tuple, set, frozenset):
        return True
    if origin in (typing.Union, types.UnionType, typing.Annotated):
        return any(_admits_sequence(a) for a in typing.get_args(annotation))
    return False


def format_value(value) -> str:
    """A swept value as it appears in a label (YAML/JSON spelling: 3.0, true, [0.4, 2.6])."""
    return json.dumps(value)


def expand(entry) -> list[Variant]:
    """The variants of a method entry (``bench.runs.experiment.MethodEntry``): the entry itself
    when it sweeps nothing, else one per point of its grid."""
    fixed, axes = {}, {}
    for key, value in entry.params.items():
        if isinstance(value, list) and not takes_a_list(entry.name, key):
            axes[key] = value
        else:
            fixed[key] = value
    for key, values in (entry.sweep or {}).items():
        if key in entry.params:
            raise ValueError(f"{entry.name}: {key!r} is both in params and in sweep")
        axes[key] = values
    if not axes:
        return [Variant(entry.label, dict(entry.params))]
    for key, values in axes.items():
        if not values:
            raise ValueError(f"{entry.name}: the sweep over {key!r} lists no values")
        if len({format_value(v) for v in values}) != len(values):
            raise ValueError(f"{entry.name}: the sweep over {key!r} lists a value twice")
    group = entry.label or entry.name
    variants = []
    for values in itertools.product(*axes.values()):
        point = dict(zip(axes, values, strict=True))
        label = group + " " + " ".join(f"{k}={format_value(v)}" for k, v in point.items())
        variants.append(Variant(label, {**fixed, **point}, point, group))
    return variants


def sweep_index(exp, jobs) -> dict | None:
    """The index of ``exp``'s sweeps over the planned ``jobs`` (None without sweeps): per sweep
    its method, keys, the method's resolved default for those keys on each sequence's sensor,
    and per point its run folders (relative to the experiment's out folder). ``exp`` is a
    ``bench.runs.experiment.Experiment``; this module imports nothing of it (the experiment
    model imports the expansion, so the sweep stays below it)."""
    from loaders.store import StoreSequence
    from methods.registry import make_method

    out = Path(exp.out_dir)
    sweeps: dict[str, dict] = {}
    for m in exp.methods:
        for v in m.variants():
            if v.group is None:
                continue
            s = sweeps.setdefault(v.group, {"method": m.name, "group": v.group,
                                             "keys": list(v.point), "defaults": {},
                                             "points": []})
            runs = [{"sequence": j.name or j.store.stem, "seed": j.seed,
                     "dir": str(Path(j.run_dir_override).relative_to(out))}
                    for j in jobs if j.method == m.name and j.label == v.label]
            s["points"].append({"label": v.label, "point": v.point, "runs": runs})
            for j in jobs:
                if j.method == m.name and j.label == v.label:
                    name = j.name or j.store.stem
                    if name not in s["defaults"]:
                        store = StoreSequence(j.store)
                        try:
                            fixed = {k: val for k, val in v.params.items() if k not in v.point}
                            # the default of the seed option swept (a no-seed run may
                            # have its own, ``Odometry.for_seed``)
                            params = make_method(m.name, fixed, store.sensor,
                                                 j.seed).params
                        finally:
                            store.close()
                        s["defaults"][name] = {k: _plain(getattr(params, k)) for k in v.point}
    if not sweeps:
        return None
    return {"experiment": exp.name,
            "criterion": exp.criterion.model_dump() if exp.criterion else None,
            "default_differs": exp.default_differs, "sweeps": list(sweeps.values())}


def _plain(value):
    """A parameter value as JSON has it (tuples as lists)."""
    return json.loads(json.dumps(value, default=list))


def write_sweep_index(out_dir: Path, index: dict) -> Path:
    path = Path(out_dir) / INDEX
    guard.write_text(path, json.dumps(index, indent=1) + "\n", guard.derived,
                     "an experiment's sweep index")
    return path


def read_sweep_index(results_dir: Path) -> dict:
    path = Path(results_dir) / INDEX
    if not path.exists():
        raise DataError(f"{results_dir}: no {INDEX} here (written by `bench run` for an "
                        "experiment with a parameter sweep)")
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise DataError(f"{path}: not a readable sweep index: {err}") from None
