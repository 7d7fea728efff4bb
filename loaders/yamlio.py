"""Reading YAML: the safe loader, in libyaml's C implementation where PyYAML has it.

PyYAML's pure-Python parser takes about 3.4 ms for a run's config.yaml, libyaml's 0.4 ms, and
planning an experiment reads every run's config several times (85 runs: hundreds of reads).
Both build the same objects through the same safe constructor (only the scanner and parser
differ), so what is read does not depend on which is installed; neither builds Python objects
from tags (``!!python/...`` is an error, as with ``yaml.safe_load``)."""

from __future__ import annotations

from pathlib import Path

import yaml

from loaders.errors import DataError

#: the safe loader in C (libyaml), or PyYAML's own where it was built without libyaml
SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def load_yaml(text: str):
    """``yaml.safe_load(text)``, faster."""
    return yaml.load(text, Loader=SAFE_LOADER)


class NotYamlText(DataError, yaml.YAMLError):
    """A file that is not text at all (a binary): a DataError naming it, and a YAMLError to
    the callers that treat an unreadable YAML file as one that is not theirs."""


def read_yaml(path: str | Path):
    """The YAML document in the file ``path`` (``yaml.safe_load`` of its text)."""
    try:
        text = Path(path).read_text()
    except UnicodeDecodeError:
        raise NotYamlText(f"{path}: not a text file; expected YAML") from None
    return load_yaml(text)
