"""``bench convert LOADER ...``: any loadable sequence -> an HDF5 store, with a progress bar."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from bench.data.convert_options import Frames, Out, Start, Stride
from loaders.scan import Sequence, select_frames
from loaders.store import write_store

console = Console()
convert_app = typer.Typer(no_args_is_help=True, help="Convert a dataset to an HDF5 store.")

def write_with_progress(sequence: Sequence, out: Path) -> Path:
    """Write ``sequence`` to the store ``out`` with a progress bar, then print the throughput."""
    n = len(sequence)
    t0 = time.perf_counter()
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[fps]} frames/s"), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=console) as progress:
        task = progress.add_task(f"{sequence.name} -> {out.name}", total=n, fps="-")

        def report(i: int) -> None:
            if i % 10 == 0 or i == n - 1:
                fps = (i + 1) / max(time.perf_counter() - t0, 1e-9)
                progress.update(task, completed=i + 1, fps=f"{fps:.0f}")

        write_store(sequence, out, progress=report)
    wall = time.perf_counter() - t0
    size_mb = Path(out).stat().st_size / 1e6
    console.print(f"[green]wrote[/] {out}: {n} frames in {wall:.1f} s "
                  f"({n / max(wall, 1e-9):.0f} frames/s), {size_mb:.1f} MB")
    return Path(out)




@convert_app.command("npy-frames", short_help="NumPy frame folders (frame_XXX.npy)")
def npy_frames(
    folder: Annotated[Path, typer.Argument(help="folder with frame_XXX.npy (or its frames/)")],
    out: Out,
    gt: Annotated[Path | None, typer.Option(help="TUM ground truth (default: the one .txt "
                                            "in FOLDER)")] = None,
    period: Annotated[float | None, typer.Option(help="scan period [s]: stamps = index x "
                                                 "period")] = None,
    kind: Annotated[str, typer.Option(help="radar or lidar")] = "radar",
    name: Annotated[str | None, typer.Option(help="sequence name")] = None,
    associate: Annotated[str, typer.Option(help="GT association: order or time")] = "order",
    stamps_from_gt: Annotated[bool, typer.Option(
        help="stamp the frames with the TUM file's stamps (only when they are the sensor "
             "clock; else give --period)")] = False,
    start: Start = 0, frames: Frames = None, stride: Stride = 1,
) -> None:
    """NumPy frame folders (the reference code's example format)."""
    from loaders.npy_frames import NpyFramesSequence

    seq = NpyFramesSequence(folder, gt=gt, period_s=period, kind=kind, name=name,
                            associate=associate, stamps_from_gt=stamps_from_gt)
    write_with_progress(select_frames(seq, start, frames, stride), out)


def _register_real_loaders() -> None:
    from bench.data.convert_real import register

    register(convert_app, write_with_progress)


_register_real_loaders()
__all__ = ["convert_app", "write_with_progress"]
