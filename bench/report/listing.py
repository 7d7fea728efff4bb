"""``bench list``: the registered methods, loaders, synthetic scenes and sensors."""

from __future__ import annotations

from rich.console import Console
from rich.table import Table


def print_registries(console: Console) -> None:
    from loaders.registry import LOADERS
    from loaders.synthetic import list_scenes, list_sensors
    from methods.registry import METHODS

    for title, items in (
        ("Methods", {name: cls.description for name, cls in METHODS.items()}),
        ("Loaders (bench convert LOADER)", {k: e.description for k, e in LOADERS.items()}),
        ("Synthetic scenes (bench synth SCENE)", list_scenes()),
        ("Synthetic sensors (--sensor)", list_sensors()),
    ):
        table = Table(title=title, title_justify="left", show_header=False)
        for name, text in items.items():
            table.add_row(f"[bold]{name}[/]", text)
        console.print(table)
