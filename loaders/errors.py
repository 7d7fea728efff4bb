"""One error type for bad input, with a message that names the file, the frame and what was
expected. Catch ``DataError`` at the CLI to print it without a traceback."""

from __future__ import annotations

from pathlib import Path


class DataError(ValueError):
    """Bad or unexpected input data (a scan, a bag, a ground-truth file, a store)."""


def where(file: str | Path | None = None, frame: int | None = None) -> str:
    """Location prefix for messages: ``"run.bag, frame 12: "`` (empty when nothing is known)."""
    parts = []
    if file is not None:
        parts.append(str(file))
    if frame is not None:
        parts.append(f"frame {frame}")
    return ", ".join(parts) + ": " if parts else ""


class GroundTruthWarning(UserWarning):
    """Ground truth was usable but not clean (duplicate rows dropped, scans without ground truth
    kept but excluded from scoring); the message says what and how many."""
