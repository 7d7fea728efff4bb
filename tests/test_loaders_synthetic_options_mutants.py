"""loaders/synthetic_options.py: ``bench synth -o key=value`` values checked before anything is
generated. The ranges are the documented contract (the module's table, which the error message
states to the user): each bound is accepted and the next float beyond it refused, with one
``ValueError`` naming the option and the range."""

from __future__ import annotations

import math

import pytest

from loaders.synthetic import OPTIONS
from loaders.synthetic_options import _number, _text, check_options

#: the documented ranges: name -> (low, high, integer, the range as the message states it)
RANGES = {
    "points": (1, 1_000_000, True, "a whole number from 1 to 1,000,000"),
    "road_radius": (1.0, 100_000.0, False, "a number from 1 to 100,000"),
    "rib_spacing": (0.0, 1_000.0, False, "a number from 0 to 1,000"),
    "attitude_deg": (0.0, 45.0, False, "a number from 0 to 45"),
    "jitter_s": (0.0, 1.0, False, "a number from 0 to 1"),
    "t0": (-1e10, 1e10, False, "a number from -10,000,000,000 to 10,000,000,000"),
}


def refused(options: dict) -> str:
    with pytest.raises(ValueError) as err:
        check_options(options)
    return str(err.value)


def test_every_generator_option_is_checked():
    checked = set(RANGES) | {"uturn", "one_lane", "sweep", "edge_band", "gt", "speed"}
    assert checked == set(OPTIONS)


@pytest.mark.parametrize("name", sorted(RANGES))
def test_each_bound_is_accepted_and_the_next_value_beyond_it_refused(name):
    low, high, integer, _ = RANGES[name]
    check_options({name: low})
    check_options({name: high})
    below = low - 1 if integer else math.nextafter(low, -math.inf)
    above = high + 1 if integer else math.nextafter(high, math.inf)
    for value in (below, above):
        assert refused({name: value}).startswith(f"--option {name}={value!r}: expected ")


@pytest.mark.parametrize("name", sorted(RANGES))
def test_the_message_names_the_option_what_it_is_and_its_range(name):
    _, _, _, text = RANGES[name]
    message = refused({name: math.inf})
    assert message.startswith(f"--option {name}=inf: expected ")
    assert message.endswith(f"({text})")


def test_the_message_says_what_the_value_is():
    assert refused({"points": 0}) == ("--option points=0: expected a number of points per frame "
                                      "(a whole number from 1 to 1,000,000)")
    assert refused({"jitter_s": 2}) == ("--option jitter_s=2: expected a standard deviation in "
                                        "seconds (a number from 0 to 1)")


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, "3", None, True, False, [2]])
def test_a_value_that_is_not_a_finite_number_is_refused(value):
    assert refused({"attitude_deg": value}).startswith(f"--option attitude_deg={value!r}")


def test_points_must_be_whole_but_may_be_a_whole_float():
    check_options({"points": 2.0})
    check_options({"points": 500})
    assert "a whole number" in refused({"points": 2.5})
    check_options({"road_radius": 2.5})  # the other numeric options take fractions


@pytest.mark.parametrize("flag", ["uturn", "one_lane", "sweep", "edge_band"])
def test_a_flag_takes_true_or_false_only(flag):
    check_options({flag: True})
    check_options({flag: False})
    for value in (1, 0, "true", None):
        assert refused({flag: value}) == f"--option {flag}={value!r}: expected true or false"


def test_gt_names_one_of_the_pipelines():
    for name in ("exact", "ntu4dradlm", "campus"):
        check_options({"gt": name})
    assert refused({"gt": "kitti"}) == ("--option gt='kitti': expected one of exact, "
                                        "ntu4dradlm, campus")


@pytest.mark.parametrize("pair", [[5, 10], (5, 10), [0.5, 0.5], [1e-9, 100], [100, 100.0]])
def test_a_speed_range_within_zero_and_100_m_s_is_accepted(pair):
    check_options({"speed": pair})


@pytest.mark.parametrize("pair", [[0, 10], [-1, 10], [10, 5], [5, math.nextafter(100, 200)],
                                  [5], [1, 2, 3], [], "5,10", 7, [True, 5], [5, None],
                                  [5, math.nan], [math.inf, math.inf], ["5", "10"]])
def test_a_speed_range_outside_or_malformed_is_refused(pair):
    assert refused({"speed": pair}) == (f"--option speed={pair!r}: expected [low, high] in m/s "
                                        "with 0 < low <= high <= 100, e.g. [5, 10]")


def test_the_first_bad_option_is_named_and_unknown_keys_are_left_to_the_generator():
    check_options({})
    check_options({"no_such_option": object()})
    assert refused({"points": 10, "gt": "x", "uturn": 3}).startswith("--option gt=")


def test_numbers_and_their_text():
    assert _number(3) == 3.0 and isinstance(_number(3), float)
    assert _number(2.5) == 2.5
    assert _number(True) is None and _number("1") is None and _number(None) is None
    assert _text(1_000_000) == "1,000,000"
    assert _text(45.0) == "45"
    assert _text(0.5) == "0.5"
    assert _text(-1e10) == "-10,000,000,000"
