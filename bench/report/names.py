"""How runs and sequences are named in every table and figure: a method's display name, colour
and row order are declared with its class (``Odometry.presentation``, read through
``methods.registry``), the seed tag comes from ``methods.registry.Seed``; this module adds the
paper's sequence order and the row label of a run.

A method that is not registered shows its registry name.
"""

from __future__ import annotations

import re

from bench.runs.result import EXTERNAL_MARK
from methods.registry import SEED_NOTE, Seed, display_name, order_key

__all__ = ["GT_ASSISTED", "SEED_NOTE", "display_name", "gt_assisted_note", "hosts_note",
           "is_gt_assisted", "order_key", "overrides_note", "run_label", "seed_tag", "sequence_key",
           "synthetic_note"]

#: the paper's sequences in the order of its tables (Table III: sparse radar, semi-dense radar,
#: then LiDAR: the two CARLA walls before the Baker-Barry tunnels; Loop1_1 is only in Table IV),
#: each as (sequence name, display name)
PAPER_SEQUENCES = [("Campus1", "Campus1"), ("Campus2", "Campus2"),
                   ("Loop1_0", "Loop1_0"), ("Loop1_1", "Loop1_1"), ("Loop1_2", "Loop1_2"),
                   ("Loop1_3", "Loop1_3"), ("Loop1_4", "Loop1_4"),
                   ("StraightWall", "Straight Wall"), ("CurvedWall", "Curved Wall"),
                   ("Tunnel_Empty", "Baker-Barry Tunnel (Empty)"),
                   ("Tunnel_Vehicles", "Baker-Barry Tunnel (Vehicles)")]

def synthetic_note(sequence_names) -> str:
    """A caption's first words when any sequence shown is synthetic (its display name carries
    loaders.sensor_classes.SYNTHETIC_MARK), else ""."""
    from loaders.sensor_classes import SYNTHETIC_MARK

    if any(SYNTHETIC_MARK in name for name in sequence_names):
        return ("SYNTHETIC DATA: sequences marked (synthetic) are made by this repository's "
                "generator to imitate the paper's sequences; they are not the paper's data. ")
    return ""


#: the mark of a run made from a store whose Doppler was reconstructed from the ground truth's
#: ego motion (``SensorInfo.doppler_kind == "gt-reconstructed"``, recorded in the run's config)
GT_ASSISTED = "GT-assisted"
GT_ASSISTED_NOTE = ("GT-ASSISTED: rows marked [GT-assisted] ran on Doppler reconstructed from "
                    "the ground truth's ego motion (the dataset released ego-compensated "
                    "velocities); they are not independent of the ground truth they are scored "
                    "against. ")


def is_gt_assisted(doppler_kind: str | None) -> bool:
    """A store's Doppler kind that makes every result from it GT-assisted."""
    return doppler_kind == "gt-reconstructed"


def gt_assisted_note(labels) -> str:
    """A caption's first words when any row label shown carries the GT-assisted mark."""
    return GT_ASSISTED_NOTE if any(f"[{GT_ASSISTED}]" in label for label in labels) else ""


def hosts_note(cpus) -> str:
    """A caption's note when the times shown were measured on different CPU models (each run's
    metrics.json ``cpu``; a run without the record counts as unknown), else ""."""
    models = sorted({cpu or "not recorded" for cpu in cpus})
    if len(models) < 2:
        return ""
    return (f"MIXED HOSTS: these times come from runs on different CPUs ({'; '.join(models)}); "
            "times from different CPUs are not comparable. ")


def seed_tag(method: str, seed) -> str:
    """Which motion prior a run used (``Seed.tag``): "With Seed", "With Seed, own model",
    "No Seed" or "No initial guess"."""
    return Seed.of(seed).tag(method)


def run_label(method: str, seed, label: str | None = None,
              doppler_kind: str | None = None) -> str:
    """A run's row / legend name, e.g. "(With Seed) DICP"; a labelled variant shows its label
    after the tag; an external run (``bench score``) its label alone, "NAME (external)"; a run
    on GT-reconstructed Doppler ends in "[GT-assisted]"."""
    mark = f" [{GT_ASSISTED}]" if is_gt_assisted(doppler_kind) else ""
    if label and label.endswith(EXTERNAL_MARK):  # no motion prior of the harness's to name
        return f"{label}{mark}"
    return f"({seed_tag(method, seed)}) {label or display_name(method)}{mark}"


def overrides_note(config: dict) -> str:
    """The parameters a run was asked to change from its method's defaults (config.yaml's
    ``method.given``: ``bench run -p``, an experiment's ``params:``) as a label suffix,
    " [max_iterations=3]"; "" when none were given, when the run has a variant ``label`` of its
    own (which names what it changes), or for a run made before they were recorded."""
    method = config.get("method") if isinstance(config.get("method"), dict) else {}
    given = method.get("given")
    if not isinstance(given, dict) or not given or config.get("label"):
        return ""
    text = ", ".join(f"{k}={_param_text(v)}" for k, v in sorted(given.items()))
    return f" [{text}]"


def _param_text(value) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list | tuple):
        return ",".join(_param_text(v) for v in value)
    return str(value)


def sequence_key(name: str) -> tuple:
    """Sort key of a sequence (its name or display name): the paper's sequences in the order
    of its tables, then every other sequence in natural order ("run2" before "run10"). A display
    name that extends a paper name ("Loop1_0 (GT calibrated ...)") sorts with that name."""
    for i, names in enumerate(PAPER_SEQUENCES):
        if any(name == n or name.startswith(n + " ") for n in names):
            return (i, _natural(name))
    return (len(PAPER_SEQUENCES), _natural(name))


def _natural(text: str) -> tuple:
    return tuple(int(part) if part.isdigit() else part.lower()
                 for part in re.split(r"(\d+)", text))
