"""Checking that a dataset folder holds what its loader expects, before anything is read.

The harness never downloads data; a missing or half-extracted folder gets ONE ``DataError``
that names every missing piece (not a traceback from the first file that fails to open).
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from loaders.errors import DataError


def _present(root: Path, entry: str) -> bool:
    """``entry`` (relative to ``root``; glob patterns allowed; a trailing ``/`` means a folder
    that must not be empty) exists."""
    folder = entry.endswith("/")
    pattern = entry.rstrip("/")
    if any(c in pattern for c in "*?["):
        matches = list(root.glob(pattern))
    else:
        matches = [root / pattern] if (root / pattern).exists() else []
    if folder:
        return any(m.is_dir() and any(m.iterdir()) for m in matches)
    return bool(matches)


def missing_paths(root: str | Path, expected: Iterable[str]) -> list[str]:
    """The entries of ``expected`` that ``root`` lacks (see ``require_paths``)."""
    root = Path(root)
    if not root.is_dir():
        return [str(root)]
    return [e for e in expected if not _present(root, e)]


def require_paths(root: str | Path, expected: Iterable[str], dataset: str = "",
                  layout: str = "") -> Path:
    """``root`` as a ``Path`` when it holds every entry of ``expected``; otherwise one
    ``DataError`` naming the folder, every missing entry and (``layout``) what the folder
    should look like. Entries are relative to ``root``: ``"gt_odom.txt"``, ``"frames/"`` (a
    non-empty folder), ``"*.bag"`` (at least one match)."""
    root = Path(root)
    expected = list(expected)
    what = f"{dataset} " if dataset else ""
    hint = f"; expected layout: {layout}" if layout else ""
    if not root.exists():
        raise DataError(f"{root}: {what}folder not found (the harness never downloads data; "
                        f"get it from the dataset's owners){hint}")
    if not root.is_dir():
        raise DataError(f"{root}: expected a {what}folder, found a file{hint}")
    missing = missing_paths(root, expected)
    if missing:
        raise DataError(f"{root}: incomplete {what}folder (missing or half-extracted): missing "
                        f"{', '.join(missing)}{hint}")
    return root


def require_files(paths: Iterable[str | Path], what: str = "input") -> list[Path]:
    """Every path of ``paths`` as a ``Path``; one ``DataError`` naming all that do not exist."""
    paths = [Path(p) for p in paths]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise DataError(f"{what} not found: {', '.join(missing)}")
    return paths
