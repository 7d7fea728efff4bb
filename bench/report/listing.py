"""``bench list``: the registered methods (with the motion prior each uses with seed),
loaders, synthetic scenes and sensors."""

from __future__ import annotations

from rich.console import Console
from rich.markup import escape
from rich.table import Table


def _prior(cls) -> str:
    from methods.base import CONSTANT_VELOCITY

    if not cls.uses_initial_guess:
        return "none (runs once)"
    if cls.motion_prior == CONSTANT_VELOCITY:
        return "with seed: constant velocity (the previous step's motion); no seed: identity"
    return f"with seed: {cls.motion_prior}; no seed: identity, priors reset"


def print_registries(console: Console) -> None:
    from loaders.registry import LOADERS
    from loaders.synthetic import list_scenes, list_sensors
    from methods.registry import METHODS

    methods = Table(title="Methods", title_justify="left")
    for column in ("name", "what it is", "motion prior", "Doppler"):
        methods.add_column(column)
    for name, cls in METHODS.items():
        methods.add_row(f"[bold]{name}[/]", escape(cls.description), _prior(cls),
                        "needed" if getattr(cls, "needs_doppler", False) else "-")
    console.print(methods)
    for title, items in (
        ("Loaders (bench convert LOADER; bench datasets for the datasets they read)",
         {k: e.description + ("" if e.available else " (not installed)")
          for k, e in LOADERS.items()}),
        ("Synthetic scenes (bench synth SCENE)", list_scenes()),
        ("Synthetic sensors (--sensor)", list_sensors()),
    ):
        table = Table(title=title, title_justify="left", show_header=False)
        for name, text in items.items():
            table.add_row(f"[bold]{name}[/]", text)
        console.print(table)
