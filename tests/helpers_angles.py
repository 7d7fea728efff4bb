"""Points placed exactly on an angular edge, for tests of inclusive field-of-view limits."""

from __future__ import annotations

import numpy as np


def on_azimuth_edge(half_deg: float) -> float:
    """A y with arctan2(y, 1) exactly the radians of ``half_deg`` (stepped by nextafter)."""
    target = np.radians(half_deg)
    y = np.tan(target)
    for _ in range(200):
        got = np.arctan2(y, 1.0)
        if got == target:
            return y
        y = np.nextafter(y, np.inf if got < target else -np.inf)
    raise AssertionError("no exact edge point found")
