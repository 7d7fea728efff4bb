"""The generator's identity: a hash of its code, so that stores made by another generator are
never taken for current ones (no hand-bumped version string)."""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

GENERATOR_DIR = Path(__file__).resolve().parent


def generator_code_hash(directory: Path = GENERATOR_DIR) -> str:
    """SHA-256 (16 hex digits) of the names and bytes of every ``*.py`` file in ``directory``
    (default: loaders/synthetic, the generator), in name order."""
    h = hashlib.sha256()
    for path in sorted(Path(directory).glob("*.py")):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()[:16]


@lru_cache(maxsize=1)
def current_code_hash() -> str:
    """``generator_code_hash()`` of the installed generator (computed once per process)."""
    return generator_code_hash()
