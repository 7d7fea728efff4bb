"""Command-line option types shared by the ``bench convert`` commands."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

Start = Annotated[int, typer.Option(help="first frame")]
Frames = Annotated[int | None, typer.Option(help="number of frames (default: all)")]
Stride = Annotated[int, typer.Option(help="keep every k-th frame (period scaled by k)")]
Out = Annotated[Path, typer.Option(help="store to write (.h5)")]
