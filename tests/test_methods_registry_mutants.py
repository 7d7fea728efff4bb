"""methods/registry.py's rules, fast and in-process: the lookup and its error, plugins loaded
once per value of the variable, a method made with its parameters, seed and sensor, the seed
options and their tags, styles and ranks, and each method's presentation (names, row order,
colours distinct while spares last)."""

from __future__ import annotations

import importlib
import textwrap

import numpy as np
import pytest
from pydantic import Field, ValidationError

from loaders.errors import DataError
from loaders.scan import SensorInfo
from methods import registry
from methods.base import MethodParams, Odometry, Presentation, Registration
from methods.plugins import PLUGINS_ENV
from methods.registry import (
    METHODS,
    Seed,
    color,
    display_name,
    get_method,
    make_method,
    order_key,
    seed_option,
    seed_options,
)


class _Params(MethodParams):
    gate: float = Field(1.0, gt=0)
    kind: str = "none"


class _Mine(Registration):
    """A method whose seed and sensor choices show in its parameters."""

    name = "mine"
    Params = _Params
    presentation = Presentation(None, None, None)

    def for_seed(self, seed):
        return self if seed is not False else _Mine(self.params, gate=9.0)

    def configured_for(self, sensor):
        return _Mine(self.params, kind=sensor.kind)

    def register(self, source, target, init):  # pragma: no cover - not run
        raise NotImplementedError


class _Bare(Odometry):
    """A method without parameters, declaring a colour that is also the first spare one."""

    name = "bare"
    presentation = Presentation("Bare one", registry._SPARE_COLORS[0], 2.5)

    def run(self, sequence, seed, on_frame=None):  # pragma: no cover - not run
        raise NotImplementedError


@pytest.fixture
def extra(monkeypatch):
    """METHODS with two more methods (restored after the test), colours assigned afresh."""
    monkeypatch.setitem(METHODS, "mine", _Mine)
    monkeypatch.setitem(METHODS, "bare", _Bare)
    monkeypatch.setattr(registry, "_assigned", {})
    monkeypatch.delenv(PLUGINS_ENV, raising=False)
    return METHODS


def test_get_method_and_its_error(monkeypatch):
    monkeypatch.delenv(PLUGINS_ENV, raising=False)
    assert get_method("doppler").name == "doppler" and get_method("dicp").name == "dicp"
    with pytest.raises(DataError) as err:
        get_method("dopler")
    text = str(err.value)
    assert text.startswith("unknown method 'dopler' (did you mean 'doppler'?); registered: "
                           + ", ".join(METHODS) + "; a method of your own: name its module in "
                           f"{PLUGINS_ENV}=my_module")
    assert text.endswith(f"{PLUGINS_ENV}=my_module (on PYTHONPATH; it lists its classes in "
                         "METHODS), see docs/extending.md")
    monkeypatch.setenv(PLUGINS_ENV, " my_plugins ")
    with pytest.raises(DataError, match=r"'zzz'; registered: .*; plugin modules loaded from "
                                        rf"{PLUGINS_ENV}=my_plugins$"):
        get_method("zzz")
    assert err.value.__cause__ is None and err.value.__suppress_context__


def test_plugins_load_once_per_value(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / "registry_mutants_plugin.py").write_text(textwrap.dedent("""
        from methods.base import Registration

        class Theirs(Registration):
            name = "theirs"

        METHODS = [Theirs]
        """))
    importlib.invalidate_caches()
    calls = []
    real = registry.load
    monkeypatch.setattr(registry, "load", lambda spec, builtin: calls.append(spec)
                        or real(spec, builtin))
    try:
        registry.load_plugins("registry_mutants_plugin")
        assert "theirs" in METHODS and set(METHODS) - {"theirs"} == set(registry.BUILTIN)
        registry.load_plugins("registry_mutants_plugin")  # the same value: not again
        assert calls == ["registry_mutants_plugin"]
        monkeypatch.setenv(PLUGINS_ENV, "")
        registry.load_plugins()  # the variable's value (empty): the built-ins only
        assert calls == ["registry_mutants_plugin", ""] and METHODS == registry.BUILTIN
        monkeypatch.setenv(PLUGINS_ENV, "registry_mutants_plugin")
        registry.load_plugins()
        assert "theirs" in METHODS and calls[-1] == "registry_mutants_plugin"
        monkeypatch.delenv(PLUGINS_ENV)
        registry.load_plugins()  # unset: the built-ins only, as an empty value
        assert calls[-1] == "" and METHODS == registry.BUILTIN
    finally:
        registry.load_plugins("")
    assert "theirs" not in METHODS


def test_make_method_validates_and_resolves(extra):
    m = make_method("mine", {"gate": 2.0})
    assert isinstance(m, _Mine) and m.params.gate == 2.0 and m.params.kind == "none"
    assert make_method("mine").params.gate == 1.0
    assert make_method("mine", None, seed=None).params.gate == 1.0
    assert make_method("mine", {"gate": 2.0}, seed=False).params.gate == 9.0
    sensor = SensorInfo("radar", 0.1)
    resolved = make_method("mine", {}, sensor, seed=False)
    assert (resolved.params.gate, resolved.params.kind) == (9.0, "radar")
    with pytest.raises(ValidationError):
        make_method("mine", {"gate": -1.0})
    with pytest.raises(ValidationError):
        make_method("mine", {"nope": 1})
    assert isinstance(make_method("bare", {"ignored": 1}), _Bare)  # no Params: no parameters
    with pytest.raises(DataError, match="unknown method 'nothing'"):
        make_method("nothing")


def test_dicp_takes_the_sensor_extrinsic():
    T = np.eye(4)
    T[:3, 3] = [1.0, 2.0, 3.0]
    m = make_method("dicp", {}, SensorInfo("radar", 0.1, T_body_sensor=T))
    np.testing.assert_allclose(m.T_vehicle_sensor, T)


def test_seed_options():
    assert seed_options("doppler") == [None] and seed_options("doppler", [True]) == [None]
    assert seed_options("icp-p2p") == [True, False]
    assert seed_options("icp-p2p", [False]) == [False]
    assert seed_options("icp-p2p", []) == []
    assert seed_option("icp-p2p", False) is False and seed_option("icp-p2p", True) is True
    assert seed_option("doppler", True) is None


def test_seed_values():
    assert [Seed.of(x) for x in (True, False, None)] == [Seed.WITH, Seed.WITHOUT, Seed.NONE]
    assert Seed.of(Seed.WITHOUT) is Seed.WITHOUT
    assert [s.option for s in Seed] == [True, False, None]
    assert [s.suffix for s in Seed] == ["_seed", "_noseed", ""]
    assert [s.rank for s in Seed] == [0, 1, 0]
    assert [s.value for s in Seed] == ["with", "without", "none"]


def test_seed_tags_and_styles(extra):
    assert Seed.NONE.tag("doppler") == "No initial guess"
    assert Seed.WITHOUT.tag("kiss-icp") == "No Seed"
    assert Seed.WITH.tag("icp-p2p") == "With Seed"
    assert Seed.WITH.tag("kiss-icp") == "With Seed, own model"
    assert Seed.WITH.tag("unknown-method") == "With Seed"
    assert Seed.WITH.style("icp-p2p") == ("-", "o", "")
    assert Seed.WITH.style("kiss-icp") == ("-", "D", "")
    assert Seed.WITHOUT.style("icp-p2p") == ("--", "x", "//////")
    assert Seed.NONE.style("doppler") == ("-", "s", "")
    with_, without = Seed.WITH.style("mine"), Seed.WITHOUT.style("mine")
    assert all(a != b for a, b in zip(with_, without, strict=True))


def test_presentation(extra):
    assert display_name("doppler") == "Doppler Correspondence (Ours)"
    assert display_name("mine") == "mine"  # declares none
    assert display_name("bare") == "Bare one"
    assert display_name("elsewhere") == "elsewhere"
    assert order_key("icp-p2p") == 0.0 and order_key("dicp") == 4.0
    assert order_key("bare") == 2.5
    assert order_key("mine") == float("inf") and order_key("elsewhere") == float("inf")
    assert isinstance(order_key("dicp"), float)


def test_colours_are_distinct_while_spares_last(extra):
    declared = {n: c.presentation.color for n, c in METHODS.items() if c.presentation.color}
    assert color("doppler") == "#d62728" and color("dicp") == "#9467bd"
    assert color("bare") == registry._SPARE_COLORS[0]
    spares = [c for c in registry._SPARE_COLORS if c not in declared.values()]
    assert spares[0] == registry._SPARE_COLORS[1]  # the declared one is not handed out again
    # the registered methods without a colour first (registry order), then others as used
    assert color("other") == spares[1]
    assert color("mine") == spares[0]
    assert color("more") == spares[2]
    assert color("other") == spares[1]  # the same colour again
    names = [f"x{i}" for i in range(len(spares) - 3)]
    got = [color(n) for n in names]
    assert got == spares[3:]
    # spares exhausted: cycling through them by the count assigned
    n = len(registry._assigned)
    assert color("late") == registry._SPARE_COLORS[n % len(registry._SPARE_COLORS)]
