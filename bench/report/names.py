"""Display names of the methods as the paper's tables print them, and the paper's row order.

One place for every table and figure, so a method reads the same everywhere. A method that is
not listed shows its registry name.
"""

from __future__ import annotations

# registry name -> (Table III name, Tables IV/V name)
_NAMES: dict[str, tuple[str, str]] = {
    "icp-p2p": ("point-to-point", "ICP point-to-point"),
    "icp-p2plane": ("point-to-plane", "ICP point-to-plane"),
    "gicp": ("GICP", "Generalized-ICP"),
    "vgicp": ("VGICP", "VGICP"),
    "dicp": ("DICP", "DICP"),
    "kiss-icp": ("KISS-ICP", "KISS-ICP"),
    "doppler": ("Ours", "Doppler Correspondence (Ours)"),
    "doppler-icp": ("Doppler 4D-ICP", "Doppler 4D-ICP (Ours)"),
    "doppler-ego": ("Doppler-Ego", "Doppler-Ego (this harness)"),
}

# the paper lists the baselines first and its own methods last; methods beyond the paper follow
PAPER_ORDER = ["icp-p2p", "icp-p2plane", "gicp", "vgicp", "dicp", "kiss-icp", "doppler",
               "doppler-icp", "doppler-ego"]


def short_name(method: str) -> str:
    """The name in Table III's rows, e.g. "(With Seed)DICP"'s "DICP"."""
    return _NAMES.get(method, (method, method))[0]


def long_name(method: str) -> str:
    """The name in Tables IV/V's rows, e.g. "Generalized-ICP"."""
    return _NAMES.get(method, (method, method))[1]


def order_key(method: str) -> int:
    """Position of a method in the paper's row order (unknown methods after the known ones)."""
    return PAPER_ORDER.index(method) if method in PAPER_ORDER else len(PAPER_ORDER)
