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


def did_you_mean(word: str, choices) -> str:
    """" (did you mean 'x'?)" for the closest of ``choices``, or "" when none is close."""
    import difflib

    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _dotted(loc) -> str:
    return "".join(f"[{x}]" if isinstance(x, int) else f".{x}" for x in loc).lstrip(".")


def validation_problems(err, known_keys=None, noun: str = "key") -> list[str]:
    """A pydantic ``ValidationError`` as plain lines, one per problem: where (``a.b[0].c``), what
    was wrong and, for an unknown ``noun`` (key, parameter), the closest known one and the known
    ones (``known_keys(loc)`` gives the keys of the model at ``loc``, or None)."""
    lines = []
    for e in err.errors():
        path = _dotted(e["loc"])
        if e["type"] == "extra_forbidden":
            key, parent = str(e["loc"][-1]), tuple(e["loc"][:-1])
            keys = known_keys(parent) if known_keys else None
            hint = did_you_mean(key, keys) if keys else ""
            known = f"; known {noun}s: {', '.join(keys)}" if keys else ""
            where_ = f"{_dotted(parent)}: " if parent else ""
            lines.append(f"{where_}unknown {noun} {key!r}{hint}{known}")
            continue
        msg = e["msg"].removeprefix("Value error, ")
        if msg.startswith("Input should"):
            msg = "should" + msg[len("Input should"):] + f" (got {e.get('input')!r})"
        lines.append(f"{path}: {msg}" if path else msg)
    return lines
