"""configs/methods/*.yaml: one per registered method, valid, and equal to the code's defaults
(the published values documented there are the values a run uses)."""

from pathlib import Path

import pytest
import yaml

from methods.registry import METHODS

CONFIGS = Path(__file__).resolve().parents[1] / "configs" / "methods"
BUILT_IN = sorted(n for n in METHODS if not n.startswith("test-"))


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_method_has_a_config_equal_to_its_defaults(name):
    path = CONFIGS / f"{name}.yaml"
    assert path.exists(), f"{path} missing"
    cfg = yaml.safe_load(path.read_text())
    assert cfg["name"] == name
    Params = METHODS[name].Params
    assert Params.model_validate(cfg["params"]) == Params()
    assert "#" in path.read_text().split("params:")[1]  # each value carries its source


def test_no_config_for_an_unknown_method():
    assert {p.stem for p in CONFIGS.glob("*.yaml")} <= set(METHODS)
