"""loaders/yamlio.py: YAML read by libyaml's safe loader reads what ``yaml.safe_load`` reads,
and builds no Python object from a tag."""

from pathlib import Path

import pytest
import yaml

from loaders.yamlio import SAFE_LOADER, load_yaml, read_yaml

ROOT = Path(__file__).resolve().parents[1]


def test_every_config_reads_as_safe_load_reads_it():
    paths = sorted((ROOT / "configs").rglob("*.yaml"))
    assert len(paths) >= 20  # methods, datasets, experiments, tuning sweeps, splits
    for path in paths:
        assert read_yaml(path) == yaml.safe_load(path.read_text()), path


def test_a_run_config_with_every_kind_of_value_reads_alike(tmp_path):
    text = yaml.safe_dump({"run_key": "ab" * 32, "seed": None, "lengths_m": [8.0, 16, 1e-3],
                           "flags": [True, False], "when": "2026-12-06", "nested": {"a": {}},
                           "text": "a: b # not a comment", "nan": float("inf")},
                          sort_keys=False)
    (tmp_path / "config.yaml").write_text(text)
    assert read_yaml(tmp_path / "config.yaml") == yaml.safe_load(text)
    assert load_yaml("") is None and load_yaml("x: 1") == {"x": 1}


def test_the_loader_is_safe_and_in_c_where_pyyaml_has_libyaml():
    assert SAFE_LOADER is (yaml.CSafeLoader if yaml.__with_libyaml__ else yaml.SafeLoader)
    with pytest.raises(yaml.YAMLError, match="python/object"):
        load_yaml("!!python/object/apply:os.getcwd []")
    with pytest.raises(yaml.YAMLError):
        load_yaml("a: [1, 2")
