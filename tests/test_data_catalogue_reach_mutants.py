"""bench/data/catalogue.py, second round: ``print_catalogue``'s default form is the terminal
one (a block per dataset), not the markdown table (survivor print_catalogue 1)."""

from rich.console import Console

from bench.data import catalogue
from loaders.registry import LOADERS


def _printed(*markdown: bool) -> str:
    console = Console(record=True, width=2000, force_terminal=False)
    catalogue.print_catalogue(console, *markdown)
    return console.export_text()


def test_the_default_form_is_one_block_per_dataset_not_the_table():
    text = _printed()
    assert text == _printed(False)
    assert catalogue.render_markdown() not in text
    assert "| dataset | sensor |" not in text
    for name in LOADERS:
        assert f"  loader {name}" in text, name
