"""How methods and runs are named in every table and figure: one display name per method, the
paper's row order, the seed tag that says which motion prior a run used, and the GT-assisted
mark of a run whose store's Doppler was rebuilt from the ground truth (``run_label``).

A method that is not listed shows its registry name.
"""

from __future__ import annotations

import re

#: registry name -> display name (the paper's Tables IV/V names)
_NAMES: dict[str, str] = {
    "icp-p2p": "ICP point-to-point",
    "icp-p2plane": "ICP point-to-plane",
    "gicp": "Generalized-ICP",
    "vgicp": "VGICP",
    "dicp": "DICP",
    "kiss-icp": "KISS-ICP",
    "doppler": "Doppler Correspondence (Ours)",
    "doppler-icp": "Doppler 4D-ICP (Ours)",
    "doppler-ego": "Doppler-Ego (this harness)",
}

# the paper lists the baselines first and its own methods last (Tables III-V); methods beyond
# the paper follow (a baseline, then this harness's own)
PAPER_ORDER = ["icp-p2p", "icp-p2plane", "gicp", "vgicp", "dicp", "doppler", "doppler-icp",
               "kiss-icp", "doppler-ego"]

#: the paper's sequences in the order of its tables (Table III: sparse radar, semi-dense radar,
#: then LiDAR: the two CARLA walls before the Baker-Barry tunnels; Loop1_1 is only in Table IV),
#: each as (sequence name, display name)
PAPER_SEQUENCES = [("Campus1", "Campus1"), ("Campus2", "Campus2"),
                   ("Loop1_0", "Loop1_0"), ("Loop1_1", "Loop1_1"), ("Loop1_2", "Loop1_2"),
                   ("Loop1_3", "Loop1_3"), ("Loop1_4", "Loop1_4"),
                   ("StraightWall", "Straight Wall"), ("CurvedWall", "Curved Wall"),
                   ("Tunnel_Empty", "Baker-Barry Tunnel (Empty)"),
                   ("Tunnel_Vehicles", "Baker-Barry Tunnel (Vehicles)")]

#: what the seed tags mean (table captions and figure notes)
SEED_NOTE = ("With Seed: each step starts from the previous step's motion (constant velocity); "
             "With Seed, own model: from the method's own motion prediction instead; No Seed: "
             "from the identity, with every internal prior reset; No initial guess: a method "
             "that takes none.")


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


def synthetic_note(sequence_names) -> str:
    """A caption's first words when any sequence shown is synthetic (its display name carries
    loaders.sensor_classes.SYNTHETIC_MARK), else ""."""
    from loaders.sensor_classes import SYNTHETIC_MARK

    if any(SYNTHETIC_MARK in name for name in sequence_names):
        return ("SYNTHETIC DATA: sequences marked (synthetic) are made by this repository's "
                "generator to imitate the paper's sequences; they are not the paper's data. ")
    return ""


def hosts_note(cpus) -> str:
    """A caption's note when the times shown were measured on different CPU models (each run's
    metrics.json ``cpu``; a run without the record counts as unknown), else ""."""
    models = sorted({cpu or "not recorded" for cpu in cpus})
    if len(models) < 2:
        return ""
    return (f"MIXED HOSTS: these times come from runs on different CPUs ({'; '.join(models)}); "
            "times from different CPUs are not comparable. ")


def display_name(method: str) -> str:
    """The method's name in every table and figure, e.g. "Generalized-ICP"."""
    return _NAMES.get(method, method)


def seed_tag(method: str, seed: bool | None) -> str:
    """Which motion prior a run used: "With Seed" (the harness's constant-velocity guess),
    "With Seed, own model" (the method's own prior), "No Seed" or "No initial guess"."""
    if seed is None:
        return "No initial guess"
    if not seed:
        return "No Seed"
    from methods.base import CONSTANT_VELOCITY
    from methods.registry import METHODS

    cls = METHODS.get(method)
    own = cls is not None and cls.motion_prior not in (None, CONSTANT_VELOCITY)
    return "With Seed, own model" if own else "With Seed"


def run_label(method: str, seed: bool | None, label: str | None = None,
              doppler_kind: str | None = None) -> str:
    """A run's row / legend name, e.g. "(With Seed) DICP"; a labelled variant shows its label
    after the tag; a run on a store whose Doppler was reconstructed from the ground truth
    (``doppler_kind`` "gt-reconstructed") ends with "[GT-assisted]"."""
    text = f"({seed_tag(method, seed)}) {label or display_name(method)}"
    return f"{text} [{GT_ASSISTED}]" if is_gt_assisted(doppler_kind) else text


def order_key(method: str) -> int:
    """Position of a method in the paper's row order (unknown methods after the known ones)."""
    return PAPER_ORDER.index(method) if method in PAPER_ORDER else len(PAPER_ORDER)


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
