"""The catalogue's generated blocks on pages of our own (``write_pages``, ``page_block``) and
``bench datasets``' text (``print_catalogue``). Written against the surviving mutants of
``make mutate`` on bench/data/catalogue.py."""

from __future__ import annotations

import pytest
from rich.console import Console

from bench.data import catalogue
from bench.data.catalogue import (
    BEGIN,
    END,
    LOADERS_BEGIN,
    LOADERS_END,
    SUMMARY_BEGIN,
    SUMMARY_END,
    page_block,
)
from loaders.errors import DataError
from loaders.registry import LOADERS, LoaderEntry
from loaders.registry import catalogue as rows_of


@pytest.fixture
def pages(tmp_path, monkeypatch):
    """A datasets page with two blocks and a README with one, rendered as "one", "two" and
    "three"."""
    page, readme = tmp_path / "datasets.md", tmp_path / "README.md"
    page.write_text(f"head\n{BEGIN}\nold one\n{END}\nmiddle\n{LOADERS_BEGIN}\nold two\n"
                    f"{LOADERS_END}\ntail\n")
    readme.write_text(f"intro\n{SUMMARY_BEGIN}\n{SUMMARY_END}\nend\n")
    monkeypatch.setattr(catalogue, "FILES", {BEGIN: page, LOADERS_BEGIN: page,
                                             SUMMARY_BEGIN: readme})
    monkeypatch.setattr(catalogue, "BLOCKS", {BEGIN: (END, lambda: "one"),
                                              LOADERS_BEGIN: (LOADERS_END, lambda: "two"),
                                              SUMMARY_BEGIN: (SUMMARY_END, lambda: "three")})
    return page, readme


def test_write_pages_replaces_each_block_between_its_markers(pages):
    page, readme = pages
    assert catalogue.write_pages() == [page, readme]
    assert page.read_text() == (f"head\n{BEGIN}\none\n{END}\nmiddle\n{LOADERS_BEGIN}\ntwo\n"
                                f"{LOADERS_END}\ntail\n")
    assert readme.read_text() == f"intro\n{SUMMARY_BEGIN}\nthree\n{SUMMARY_END}\nend\n"
    stamps = [(p.stat().st_mtime_ns, p.stat().st_ino) for p in pages]
    assert catalogue.write_pages() == []  # current: nothing written again
    assert [(p.stat().st_mtime_ns, p.stat().st_ino) for p in pages] == stamps


def test_write_pages_names_only_the_pages_that_changed(pages):
    page, readme = pages
    readme.write_text(f"intro\n{SUMMARY_BEGIN}\nthree\n{SUMMARY_END}\nend\n")
    before = readme.stat().st_ino
    assert catalogue.write_pages() == [page]
    assert readme.stat().st_ino == before


def test_a_page_without_its_markers_stops_with_their_names(pages):
    page, readme = pages
    readme.write_text(f"intro\n{SUMMARY_BEGIN}\nno end marker\n")
    with pytest.raises(SystemExit) as stop:
        catalogue.write_pages()
    assert str(stop.value) == f"{readme}: no {SUMMARY_BEGIN} ... {SUMMARY_END} markers"
    assert readme.read_text() == f"intro\n{SUMMARY_BEGIN}\nno end marker\n"


def test_a_page_edited_meanwhile_is_left_alone(pages, monkeypatch):
    page, _ = pages

    def render_and_edit():
        page.write_text(page.read_text() + "edited\n")  # between the read and the write
        return "two"

    monkeypatch.setitem(catalogue.BLOCKS, LOADERS_BEGIN, (LOADERS_END, render_and_edit))
    with pytest.raises(DataError, match="is not a page with generated blocks the harness wrote"):
        catalogue.write_pages()
    assert page.read_text().endswith("tail\nedited\n") and "old one" in page.read_text()


@pytest.mark.parametrize("text, block", [
    (f"a{BEGIN}\n\n x \n\n{END}b", " x "),
    (f"{BEGIN}{END}", ""),
    (f"{BEGIN}\nfirst\n{END} {BEGIN}\nsecond\n{END}", "first"),
    (f"a{BEGIN}\nx\n", None),
    (f"a\nx\n{END}", None),
    ("plain", None),
])
def test_page_block_is_the_text_between_the_first_markers(text, block):
    assert page_block(text) == block
    assert page_block(text, BEGIN) == block


def test_page_block_of_the_other_blocks_uses_their_own_end():
    text = f"{LOADERS_BEGIN}\nL\n{LOADERS_END}{SUMMARY_BEGIN}\nS\n{SUMMARY_END}"
    assert page_block(text, LOADERS_BEGIN) == "L" and page_block(text, SUMMARY_BEGIN) == "S"
    assert page_block(text) is None


def _printed(markdown: bool) -> str:
    console = Console(record=True, width=2000, force_terminal=False)
    catalogue.print_catalogue(console, markdown)
    return console.export_text()


def test_bench_datasets_markdown_is_the_pages_table():
    assert _printed(True) == catalogue.render_markdown() + "\n"


def test_bench_datasets_prints_one_block_per_row_with_aligned_labels():
    text = _printed(False)
    lines = text.splitlines()
    rows = rows_of()
    for row in rows:
        head = f"{row.dataset}  loader {row.name}"
        assert any(line.startswith(head) for line in lines), head
    # each label padded to 14 columns, two spaces in
    assert f"  {'licence:':<14}{rows[0].licence}" in lines
    assert f"  {'convert:':<14}{rows[0].example}" in lines
    assert f"  {'sensor:':<14}{rows[0].sensor} ({rows[0].sensor_class}); Doppler: " \
        f"{rows[0].doppler_kind}" in lines
    assert sum(line.startswith("  published at: ") for line in lines) == len(rows)
    assert sum(line.startswith("  layout:       ") for line in lines) == len(rows)
    assert lines.count("") >= len(rows)  # a blank line after each block
    assert lines[-1] == catalogue.PAPER_SEQUENCES.replace("**", "")
    ntu = [line for line in lines if line.startswith("  or:")]
    assert ntu and all(line.startswith(f"  {'or:':<14}bench convert dataset NAME..., NAME one "
                                       "of ") for line in ntu)
    assert any("Loop1_0" in line for line in ntu)
    installed = [e.name for e in LOADERS.values() if e.available]
    for name in installed:
        assert not any(line.startswith(f"{r.dataset}  loader {name}  (loader not installed)")
                       for r in rows for line in lines), name


def test_configs_are_listed_under_their_loader_only():
    from bench.data.datasets import dataset_configs

    text = _printed(False)
    blocks = text.split("\n\n")
    by_loader = {}
    for cfg in dataset_configs():
        by_loader.setdefault(cfg.loader, []).append(cfg.name)
    for loader, names in by_loader.items():
        # the first row of a loader lists them; its later rows (same loader) do not
        holding = [b for b in blocks if b.splitlines()[0].endswith(f"loader {loader}")
                   and "  or:" in b]
        assert len(holding) == 1, loader
        assert holding[0].split("NAME one of ", 1)[1].split("\n")[0] == ", ".join(names)


# -- cells, titles, anchors and an unavailable loader's section ---------------------------------


def test_a_cell_escapes_pipes_and_joins_lines():
    assert catalogue._cell("a|b\nc\nd") == "a\\|b c d"


def test_a_section_title_is_the_dataset_without_its_note_or_else_the_loader():
    entry = LoaderEntry("x", "d", "m", "C", dataset="Foo Set (Bar et al., 2020)")
    assert catalogue.section_title(entry) == "Foo Set (loader `x`)"
    assert catalogue.section_title(LoaderEntry("x", "d", "m", "C")) == "x (loader `x`)"


@pytest.mark.parametrize("title, slug", [
    ("Café Überfahrt (loader `x-y`)", "cafe-uberfahrt-loader-x-y"),
    ("NTU4DRadLM (loader `ntu4dradlm`)", "ntu4dradlm-loader-ntu4dradlm"),
    ("a  --  b", "a-b"),
])
def test_slug_as_mkdocs_makes_it(title, slug):
    assert catalogue._slug(title) == slug


def test_an_unavailable_loader_has_its_rows_and_a_note_instead_of_options(monkeypatch):
    ghost = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost",
                        dataset="Ghost Set (someone, 2030)", sensor="s",
                        sensor_class="Sparse 4D Radar", licence="l", published_at="p",
                        layout="x/", example="bench convert ghost x --out y.h5")
    before = catalogue.render_loader_sections()
    monkeypatch.setattr(catalogue, "LOADERS", {"ghost": ghost, **LOADERS})
    after = catalogue.render_loader_sections()
    section = ("### Ghost Set (loader `ghost`)\n\n`bench convert ghost`: a loader not written "
               "yet.\n\n- **Ghost Set (someone, 2030)**: s (Sparse 4D Radar); Doppler radial\n"
               "    - licence: l; published at: p\n    - layout: x/\n"
               "    - convert: `bench convert ghost x --out y.h5`\n\n(module "
               "`loaders.no_such_module` not installed: its options are not listed)\n\n")
    assert section in after
    assert after.replace(section, "") == before  # the other loaders' sections as they were


def test_text_after_a_block_that_names_its_markers_is_kept(pages):
    page, readme = pages
    page.write_text(f"{BEGIN}\nold\n{END}\nsee {BEGIN} and {END} above; {END} again\n"
                    f"{LOADERS_BEGIN}\n{LOADERS_END}\n")
    catalogue.write_pages()
    assert page.read_text() == (f"{BEGIN}\none\n{END}\nsee {BEGIN} and {END} above; {END} "
                                f"again\n{LOADERS_BEGIN}\ntwo\n{LOADERS_END}\n")


@pytest.mark.parametrize("text, block", [
    (f"{BEGIN}\na {BEGIN} b\n{END}", f"a {BEGIN} b"),
    (f"{BEGIN}\nXbX\n{END}", "XbX"),
])
def test_page_block_keeps_what_lies_between_the_first_begin_and_the_next_end(text, block):
    assert page_block(text) == block


def test_bench_datasets_markdown_keeps_each_row_whole_on_a_narrow_terminal():
    console = Console(record=True, width=60, force_terminal=False)
    catalogue.print_catalogue(console, True)
    assert console.export_text() == catalogue.render_markdown() + "\n"


def test_a_row_whose_loader_is_not_installed_says_so_after_its_name(monkeypatch):
    ghost = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost",
                        dataset="Ghost Dataset", sensor="s", sensor_class="Sparse 4D Radar",
                        licence="l", published_at="p", layout="x/",
                        example="bench convert ghost x --out y.h5")
    monkeypatch.setitem(LOADERS, "ghost", ghost)
    lines = _printed(False).splitlines()
    assert "Ghost Dataset  loader ghost  (loader not installed)" in lines
    assert f"  {'convert:':<14}bench convert ghost x --out y.h5" in lines
