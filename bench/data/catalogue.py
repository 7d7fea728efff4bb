"""The dataset catalogue: ``bench datasets`` and the README's real-data table, both made from
the loader table (``loaders.registry.catalogue``), so they cannot disagree.

The README holds the generated block between ``<!-- datasets -->`` and ``<!-- /datasets -->``;
``python -m bench.data.catalogue`` rewrites it and ``tests/test_catalogue.py`` fails while it
is out of date.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rich.console import Console

from loaders.registry import LOADERS, LoaderEntry, catalogue

BEGIN, END = "<!-- datasets -->", "<!-- /datasets -->"
README = Path(__file__).resolve().parents[2] / "README.md"

#: which of the paper's real sequences can be had (REFERENCE.md; Doppler-ICP issue #4)
PAPER_SEQUENCES = (
    "Of the paper's real sequences, **NTU4DRadLM** (Loop1_0 ... Loop1_4; all six of its routes "
    "are public) and the two **Doppler-ICP CARLA** sequences (Straight Wall, Curved Wall) are "
    "public downloads. The **Aeva tunnel** sequences (Baker-Barry Tunnel Empty / Vehicles) were "
    "never released by Aeva (only the CARLA sequences of Doppler-ICP are public), and the "
    "**Campus** recordings are not a public download; their rows in the paper's tables can be "
    "reproduced only by whoever holds copies, and otherwise only on the synthetic suite.")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _command(row: LoaderEntry) -> str:
    return row.example or f"bench convert {row.name} INPUT --out data/real/NAME.h5"


def render_markdown() -> str:
    """The README's real-data block (without the markers)."""
    lines = [
        "Generated from the loader table (`loaders/registry.py`) by `python -m "
        "bench.data.catalogue`; `bench datasets` prints the same. The harness never downloads "
        "data: get each dataset from where its owners publish it, under their licence. A "
        "missing or half-extracted folder gets one message naming what is missing.",
        "",
        "| dataset | sensor | sensor class | Doppler | licence | published at | layout the "
        "loader expects | convert |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in catalogue():
        lines.append("| " + " | ".join(_cell(c) for c in (
            row.dataset, row.sensor, row.sensor_class, row.doppler_kind, row.licence,
            row.published_at, row.layout)) + f" | `{_cell(_command(row))}` |")
    lines += ["", "Doppler `radial` = the raw range rate relative to the moving sensor (what the "
              "Doppler methods need); `ego-compensated` = the sensor's own motion already "
              "removed by the dataset (static points read about 0 m/s), not usable as radial "
              "velocity.", "", PAPER_SEQUENCES]
    return "\n".join(lines)


def readme_block(text: str) -> str | None:
    """The generated block of a README text, or None without markers."""
    if BEGIN not in text or END not in text:
        return None
    return text.split(BEGIN, 1)[1].split(END, 1)[0].strip("\n")


def write_readme(path: Path = README) -> bool:
    """Rewrite the README's block; True when it changed."""
    text = path.read_text()
    if readme_block(text) is None:
        raise SystemExit(f"{path}: no {BEGIN} ... {END} markers")
    head, rest = text.split(BEGIN, 1)
    tail = rest.split(END, 1)[1]
    new = f"{head}{BEGIN}\n{render_markdown()}\n{END}{tail}"
    if new != text:
        path.write_text(new)
    return new != text


def print_catalogue(console: Console, markdown: bool = False) -> None:
    """``bench datasets``: one block per dataset (sensor, class, Doppler kind, licence, where
    it is published, the layout, the exact command and the dataset configs that use it)."""
    if markdown:
        console.print(render_markdown(), markup=False, soft_wrap=True)
        return
    from rich.markup import escape

    from bench.data.datasets import dataset_configs

    by_loader: dict[str, list[str]] = {}
    for cfg in dataset_configs():
        by_loader.setdefault(cfg.loader, []).append(cfg.name)
    for row in catalogue():
        state = "" if LOADERS[row.name].available else "  [yellow](loader not installed)[/]"
        console.print(f"[bold]{escape(row.dataset)}[/]  loader [cyan]{row.name}[/]{state}")
        for label, value in (
                ("sensor", f"{row.sensor} ({row.sensor_class}); Doppler: {row.doppler_kind}"),
                ("licence", row.licence), ("published at", row.published_at),
                ("layout", row.layout), ("convert", _command(row))):
            console.print(f"  {label + ':':<14}{escape(value)}", highlight=False)
        configs = by_loader.pop(row.name, None)
        if configs:
            console.print(f"  {'or:':<14}bench convert dataset NAME..., NAME one of "
                          f"{', '.join(configs)}", highlight=False)
        console.print()
    console.print(escape(PAPER_SEQUENCES.replace("**", "")), highlight=False)


if __name__ == "__main__":
    changed = write_readme()
    print(f"{README}: {'updated' if changed else 'up to date'}")
    sys.exit(0)
