"""The synthetic generator's options (``bench synth -o key=value``) checked before anything is
generated: each value's type and range, so a typo or an absurd value (``points=1000000000000``,
``speed=[1, 1e9]``) is one ``ValueError`` naming the option, not an allocation that exhausts
the machine or a NaN trajectory. (It lives outside loaders/synthetic/, whose code hash is the
generator's identity: checking inputs changes no store.)"""

from __future__ import annotations

import math

#: numeric options: name -> (low, high, what, integer)
NUMERIC = {
    "points": (1, 1_000_000, "a number of points per frame", True),
    "road_radius": (1.0, 100_000.0, "a radius in metres", False),
    "rib_spacing": (0.0, 1_000.0, "a spacing in metres (0: no ribs)", False),
    "attitude_deg": (0.0, 45.0, "an amplitude in degrees", False),
    "jitter_s": (0.0, 1.0, "a standard deviation in seconds", False),
    "t0": (-1e10, 1e10, "a stamp in seconds", False),
}
FLAGS = ("uturn", "one_lane", "sweep", "edge_band")
GT_PIPELINES = ("exact", "ntu4dradlm", "campus")
#: the fastest a synthetic drive goes [m/s]
MAX_SPEED_MPS = 100.0


def _text(x: float) -> str:
    return f"{int(x):,}" if float(x).is_integer() else f"{x:g}"


def _number(value) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


def check_options(options: dict) -> None:
    """A ``ValueError`` naming the first option whose value is of the wrong type or range."""
    for key, value in options.items():
        if key in NUMERIC:
            low, high, what, integer = NUMERIC[key]
            x = _number(value)
            if x is None or not math.isfinite(x) or not low <= x <= high or \
                    (integer and not x.is_integer()):
                kind = "a whole number" if integer else "a number"
                raise ValueError(f"--option {key}={value!r}: expected {what} ({kind} from "
                                 f"{_text(low)} to {_text(high)})")
        elif key in FLAGS and not isinstance(value, bool):
            raise ValueError(f"--option {key}={value!r}: expected true or false")
        elif key == "gt" and value not in GT_PIPELINES:
            raise ValueError(f"--option gt={value!r}: expected one of {', '.join(GT_PIPELINES)}")
        elif key == "speed":
            pair = [_number(v) for v in value] if isinstance(value, (list, tuple)) else []
            if len(pair) != 2 or None in pair or not all(math.isfinite(v) for v in pair) or \
                    not 0 < pair[0] <= pair[1] <= MAX_SPEED_MPS:
                raise ValueError(f"--option speed={value!r}: expected [low, high] in m/s with "
                                 f"0 < low <= high <= {MAX_SPEED_MPS:g}, e.g. [5, 10]")
