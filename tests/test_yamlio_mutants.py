"""loaders/yamlio.py, what tests/test_yamlio.py leaves open (make mutate's survivors): a file
that is not text is one error that is both a DataError naming the file (reported to the user)
and a YAMLError (callers that skip unreadable YAML files skip it), and a text file is read as
its text."""

import pytest
import yaml

from loaders.errors import DataError
from loaders.yamlio import NotYamlText, read_yaml


def test_a_binary_file_is_a_data_error_and_a_yaml_error_naming_it(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_bytes(b"\xff\xfe\x00\x81 not utf-8")
    with pytest.raises(NotYamlText) as err:
        read_yaml(path)
    assert isinstance(err.value, DataError) and isinstance(err.value, yaml.YAMLError)
    assert str(err.value) == f"{path}: not a text file; expected YAML"
    assert err.value.__cause__ is None and err.value.__suppress_context__


def test_a_path_given_as_text_is_read(tmp_path):
    path = tmp_path / "a.yaml"
    path.write_text("seed: 3\nlengths_m: [8, 16.5]\nname: 'x: y'\n")
    assert read_yaml(str(path)) == {"seed": 3, "lengths_m": [8, 16.5], "name": "x: y"}
