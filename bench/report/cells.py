"""Cell formatting shared by every table: ranks (best, second), their markdown and LaTeX marks,
LaTeX escaping, and writing a table's formats to files."""

from __future__ import annotations

import math
from pathlib import Path

from loaders.fileio import atomic_write_text


def ranks(values: list[float]) -> list[int]:
    """0 for the best (lowest) finite value, 1 for the second, 2 otherwise (ties share)."""
    finite = sorted({v for v in values if math.isfinite(v)})
    return [finite.index(v) if math.isfinite(v) and finite.index(v) < 2 else 2 for v in values]


def md_mark(text: str, rank: int) -> str:
    """Markdown emphasis by rank: best bold, second underlined ("-" stays plain)."""
    return {0: f"**{text}**", 1: f"<u>{text}</u>"}.get(rank, text) if text != "-" else text


def tex_mark(text: str, rank: int) -> str:
    """LaTeX emphasis by rank: best bold, second underlined."""
    return {0: rf"\textbf{{{text}}}", 1: rf"\underline{{{text}}}"}.get(rank, text)


def tex_escape(s: str) -> str:
    return s.replace("_", r"\_").replace("&", r"\&").replace("%", r"\%")


def save_formats(out_dir: Path, stem: str, texts: dict[str, str]) -> dict[str, str]:
    """Write ``<stem>.<format>`` for every text (atomically) and return the texts."""
    for fmt, text in texts.items():
        atomic_write_text(Path(out_dir) / f"{stem}.{fmt}", text)
    return texts
