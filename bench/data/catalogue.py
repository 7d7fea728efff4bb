"""The dataset catalogue: ``bench datasets`` and the manual's datasets page
(``docs/datasets.md``), both made from the loader table (``loaders.registry.catalogue``), so
they cannot disagree.

The page holds two generated blocks: the real-data table between ``<!-- datasets -->`` and
``<!-- /datasets -->``, and one section per loader (its datasets, layout, Doppler kind,
sources and every option of ``bench convert LOADER``, from its Options model) between
``<!-- loaders -->`` and ``<!-- /loaders -->``. ``python -m bench.data.catalogue`` (``make
docs``) rewrites them and ``tests/test_catalogue.py`` fails while they are out of date.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rich.console import Console

from loaders.registry import LOADERS, LoaderEntry, catalogue

BEGIN, END = "<!-- datasets -->", "<!-- /datasets -->"
LOADERS_BEGIN, LOADERS_END = "<!-- loaders -->", "<!-- /loaders -->"
SUMMARY_BEGIN, SUMMARY_END = "<!-- datasets-summary -->", "<!-- /datasets-summary -->"
PAGE = Path(__file__).resolve().parents[2] / "docs" / "datasets.md"
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
    """The datasets page's real-data table block (without the markers)."""
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


#: the options every ``bench convert LOADER`` has (listed once, not per loader)
FRAME_OPTIONS = ("--out", "--start", "--frames", "--stride")


def section_title(entry: LoaderEntry) -> str:
    """A loader's heading on the datasets page: its dataset and its name."""
    title = entry.dataset.split(" (")[0] if entry.dataset else entry.name
    return f"{title} (loader `{entry.name}`)"


def render_loader_sections() -> str:
    """One section per loader (without the markers): what it reads, each dataset row it
    serves (sensor, class, Doppler kind, licence, sources, layout, the exact command) and the
    options of its ``bench convert`` command, as ``bench convert LOADER --help`` has them."""
    from bench.data.convert import loader_command

    lines = ["Every loader also takes `--out STORE.h5`, `--start FRAME`, `--frames N` and "
             "`--stride K` (a stride of k scales the nominal period by k). Generated from the "
             "loader table and each loader's Options model by `python -m "
             "bench.data.catalogue`.", ""]
    for entry in LOADERS.values():
        lines += [f"### {section_title(entry)}", "", f"`bench convert {entry.name}`: "
                  f"{_cell(entry.description)}.", ""]
        for row in entry.rows():
            lines += [f"- **{_cell(row.dataset)}**: {_cell(row.sensor)} ({row.sensor_class}); "
                      f"Doppler {row.doppler_kind}",
                      f"    - licence: {_cell(row.licence)}; published at: "
                      f"{_cell(row.published_at)}",
                      f"    - layout: {_cell(row.layout)}",
                      f"    - convert: `{_cell(_command(row))}`"]
        lines.append("")
        if not entry.available:
            lines += [f"(module `{entry.module}` not installed: its options are not listed)", ""]
            continue
        command = loader_command(entry)
        ctx = command.context_class(command, info_name=entry.name)
        records = [p.get_help_record(ctx) for p in command.params
                   if p.param_type_name == "option" and not p.hidden
                   and not set(p.opts) & set(FRAME_OPTIONS)]
        inputs = getattr(entry.load_class(), "inputs", "")
        if inputs:
            lines += [f"Input: {_cell(inputs)}.", ""]
        if records:
            lines += ["| option | what it does |", "|---|---|"]
            lines += [f"| `{_cell(spell)}` | {_cell(text)} |" for spell, text in records if spell]
            lines.append("")
    return "\n".join(lines).rstrip("\n")


def render_summary() -> str:
    """The README's short table (without the markers): dataset, sensor, class, Doppler kind and
    the loader, each linked to its section of the datasets page."""
    lines = ["| dataset | sensor | sensor class | Doppler | loader |", "|---|---|---|---|---|"]
    for row in catalogue():
        anchor = _slug(section_title(LOADERS[row.name]))
        lines.append(f"| {_cell(row.dataset)} | {_cell(row.sensor)} | {row.sensor_class} | "
                     f"{row.doppler_kind} | [`{row.name}`](docs/datasets.md#{anchor}) |")
    return "\n".join(lines)


def _slug(text: str) -> str:
    """A heading's anchor as MkDocs makes it (Python-Markdown's toc slugify)."""
    import re
    import unicodedata

    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


BLOCKS = {BEGIN: (END, render_markdown), LOADERS_BEGIN: (LOADERS_END, render_loader_sections),
          SUMMARY_BEGIN: (SUMMARY_END, render_summary)}
#: the file each generated block lives in
FILES = {BEGIN: PAGE, LOADERS_BEGIN: PAGE, SUMMARY_BEGIN: README}


def page_block(text: str, begin: str = BEGIN) -> str | None:
    """The generated block of a page's text after ``begin``, or None without the markers."""
    end = BLOCKS[begin][0]
    if begin not in text or end not in text:
        return None
    return text.split(begin, 1)[1].split(end, 1)[0].strip("\n")


def write_pages() -> list[Path]:
    """Rewrite every generated block (datasets page, README); the files that changed."""
    from bench import guard

    changed = []
    for path in dict.fromkeys(FILES.values()):
        text = new = path.read_text()
        for begin, (end, render) in BLOCKS.items():
            if FILES[begin] != path:
                continue
            if page_block(new, begin) is None:
                raise SystemExit(f"{path}: no {begin} ... {end} markers")
            head, rest = new.split(begin, 1)
            tail = rest.split(end, 1)[1]
            new = f"{head}{begin}\n{render()}\n{end}{tail}"
        if new != text:
            # the page as just read (its generated blocks between their markers) is replaced
            guard.write_text(path, new, lambda p, was=text: p.read_text() == was,
                             "a page with generated blocks")
            changed.append(path)
    return changed


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
    changed = write_pages()
    for path in dict.fromkeys(FILES.values()):
        print(f"{path}: {'updated' if path in changed else 'up to date'}")
    sys.exit(0)
