"""``bench convert LOADER ...``: any loader's input -> an HDF5 store, with a progress bar.

There is no hand-written command per loader: ``ConvertGroup`` lists the loader table
(``loaders/registry.py``) and builds ``bench convert LOADER`` on first use from the loader's
typed ``Options`` model (``loader_command``): the positional input(s) (``inputs``,
``many_inputs``), one option per model field (``loaders.options.cli_flag``), then ``--out``,
``--start``, ``--frames`` and ``--stride``. Only the loader asked for is imported, so ``bench``
starts without the bag readers. A listed loader whose module is missing gets a command that
says so (exit 2). ``bench convert dataset NAME...`` converts from ``configs/datasets/*.yaml``
(``bench.data.convert_batch``).
"""

from __future__ import annotations

import time
import types
import typing
from pathlib import Path
from typing import Annotated, Any

import click
import typer
import typer.core
from rich.console import Console

from loaders.errors import DataError
from loaders.registry import LOADERS, LoaderEntry

console = Console()


class ConvertGroup(typer.core.TyperGroup):
    """The ``convert`` group: its own commands (``dataset``) plus one per loader table entry,
    built when asked for; the command list is written from the table without importing any
    loader."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [*super().list_commands(ctx), *LOADERS]

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        command = super().get_command(ctx, name)
        if command is None and name in LOADERS:
            command = loader_command(LOADERS[name])
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, cmd.get_short_help_str(limit=200))
                for name, cmd in self.commands.items() if not cmd.hidden]
        rows += [(name, e.description + ("" if e.available else " [unavailable]"))
                 for name, e in LOADERS.items()]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


convert_app = typer.Typer(cls=ConvertGroup, no_args_is_help=True, rich_markup_mode=None,
                          help="Convert a dataset to an HDF5 store: bench convert LOADER "
                               "INPUT... --out STORE.h5, or bench convert dataset NAME... "
                               "(see `bench datasets`).")


def write_with_progress(sequence, out: Path, quiet: bool = False) -> Path:
    """Write ``sequence`` to the store ``out`` with a progress bar, then print the throughput."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from loaders.store import write_store

    n = len(sequence)
    t0 = time.perf_counter()
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[fps]} frames/s"), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=console, disable=quiet) as progress:
        task = progress.add_task(f"{sequence.name} -> {Path(out).name}", total=n, fps="-")

        def report(i: int) -> None:
            if i % 10 == 0 or i == n - 1:
                fps = (i + 1) / max(time.perf_counter() - t0, 1e-9)
                progress.update(task, completed=i + 1, fps=f"{fps:.0f}")

        write_store(sequence, out, progress=report)
    wall = time.perf_counter() - t0
    size_mb = Path(out).stat().st_size / 1e6
    if not quiet:
        console.print(f"[green]wrote[/] {out}: {n} frames in {wall:.1f} s "
                      f"({n / max(wall, 1e-9):.0f} frames/s), {size_mb:.1f} MB")
    return Path(out)


# ---- the command of one loader, from its Options model -------------------------------------

def _unwrap(annotation) -> tuple[Any, bool]:
    """(the type without ``None``, whether ``None`` was allowed)."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return (rest[0] if len(rest) == 1 else typing.Union[tuple(rest)]), True  # noqa: UP007
    return annotation, False


def _click_type(tp) -> tuple[Any, bool] | None:
    """(click type, multiple) for a field type, or None when it has no command-line form."""
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        values = typing.get_args(tp)
        if all(isinstance(v, str) for v in values):
            return click.Choice(list(values)), False
        return (click.FLOAT if any(isinstance(v, float) for v in values) else click.INT), False
    if origin in (list, tuple):
        inner = _click_type(typing.get_args(tp)[0])
        return (inner[0], True) if inner and not inner[1] else None
    if tp is Path:
        return click.Path(path_type=Path), False
    return {str: (click.STRING, False), int: (click.INT, False),
            float: (click.FLOAT, False)}.get(tp)


def _metavar(name: str, flag: str, tp, ctype) -> str:
    if isinstance(ctype, click.Choice):
        return "|".join(ctype.choices)
    if tp is Path:
        return "PATH"
    if name.endswith("_s"):
        return "SECONDS"
    return flag.upper().replace("-", "_")


def option_params(Options) -> tuple[list[click.Parameter], dict[str, str]]:
    """The click options of an Options model and {field name: flag shown} (for messages)."""
    from loaders.options import cli_flag
    from loaders.options import GroundTruthTimeOptions

    params, flags = [], {}
    shared = set(GroundTruthTimeOptions.model_fields)  # the loader's own options come first
    fields = sorted(Options.model_fields.items(), key=lambda kv: kv[0] in shared)
    for name, field in fields:
        flag = cli_flag(name, field)
        if flag is None:
            continue
        tp, _ = _unwrap(field.annotation)
        help_ = field.description or ""
        if tp is bool:
            on, _, off = flag.partition("/")
            if field.default is True:
                decl = f"--{on}/--{off or 'no-' + on}"
                help_ += " [default: on]"
            else:
                decl = f"--{on}"
            params.append(click.Option([decl, name], is_flag=True, default=None, help=help_))
            flags[name] = f"--{on}"
            continue
        converted = _click_type(tp)
        if converted is None:
            continue  # a dataset-config-only value (a mapping, ...)
        ctype, multiple = converted
        default = field.default
        if default is not None and not multiple and str(default) != "":
            help_ += f" [default: {default}]"
        params.append(click.Option([f"--{flag}", name], type=ctype, multiple=multiple,
                                   default=None, help=help_,
                                   metavar=_metavar(name, flag, tp, ctype)))
        flags[name] = f"--{flag}"
    return params, flags


def validate_options(Options, values: dict, flags: dict[str, str] | None = None,
                     where: str = "options"):
    """``values`` validated by the loader's Options model; one DataError listing every
    problem (by command-line flag when ``flags`` names them)."""
    from pydantic import ValidationError

    from loaders.errors import validation_problems

    try:
        return Options.model_validate(values)
    except ValidationError as err:
        problems = validation_problems(err, lambda loc: list(Options.model_fields), "option")
        if flags:
            for key, flag in flags.items():
                problems = [p.replace(f"{key}: ", f"{flag}: ", 1) if p.startswith(f"{key}: ")
                            else p for p in problems]
        raise DataError(f"{where}:\n  " + "\n  ".join(problems)) from None


def _frame_params() -> list[click.Parameter]:
    return [
        click.Option(["--out"], type=click.Path(path_type=Path), required=True,
                     metavar="STORE.h5", help="store to write, e.g. data/real/NAME.h5"),
        click.Option(["--start"], type=click.IntRange(min=0), default=0, metavar="FRAME",
                     help="first frame [default: 0]"),
        click.Option(["--frames"], type=click.IntRange(min=1), default=None, metavar="N",
                     help="number of frames (default: all)"),
        click.Option(["--stride"], type=click.IntRange(min=1), default=1, metavar="K",
                     help="keep every k-th frame (period scaled by k) [default: 1]"),
    ]


def loader_command(entry: LoaderEntry) -> click.Command:
    """``bench convert <entry.name>`` built from the loader's Options model."""
    if not entry.available:
        def unavailable(**_):
            raise DataError(f"loader {entry.name!r} ({entry.dataset or entry.description}) is "
                            f"listed but unavailable in this installation: module "
                            f"{entry.module} not found")
        return click.Command(entry.name, callback=unavailable, help=entry.description,
                             short_help=entry.description, context_settings={
                                 "ignore_unknown_options": True, "allow_extra_args": True},
                             params=[click.Argument(["args"], nargs=-1)])
    Loader = entry.load_class()
    params, flags = option_params(Loader.Options)
    many = getattr(Loader, "many_inputs", False)
    inputs = click.Argument(["inputs"], nargs=-1 if many else 1, required=True,
                            type=click.Path(path_type=Path),
                            metavar="INPUT..." if many else "INPUT")

    def run(inputs, out: Path, start: int, frames: int | None, stride: int, **values) -> None:
        from loaders.scan import select_frames

        given = {k: v for k, v in values.items() if v is not None and v != ()}
        options = validate_options(Loader.Options, given, flags, f"bench convert {entry.name}")
        paths = list(inputs) if many else [inputs]
        sequence = Loader.open(paths, options)
        write_with_progress(select_frames(sequence, start, frames, stride), out)

    doc = (f"{entry.description}.\n\nINPUT: {Loader.inputs}."
           + (f"\n\nLayout: {entry.layout}." if entry.layout else ""))
    return click.Command(entry.name, callback=run, params=[inputs, *params, *_frame_params()],
                         help=doc, short_help=entry.description)


# ---- bench convert dataset NAME... ---------------------------------------------------------

@convert_app.command("dataset", short_help="sequences from their dataset configs (resumable)")
def dataset(
    names: Annotated[list[str], typer.Argument(
        help="sequence name(s) (e.g. Loop1_0, 'NTU4DRadLM_*') or configs/datasets/*.yaml "
             "path(s)", metavar="NAME...")],
    raw_dir: Annotated[Path | None, typer.Option(help="folder with the raw files (default: "
                                                 "the config's raw_dir; one NAME only)")]
    = None,
    data_dir: Annotated[Path, typer.Option(help="the stores go to DATA_DIR/real/")]
    = Path("data"),
    out: Annotated[Path | None, typer.Option(help="store path (default: "
                                             "DATA_DIR/real/<store>; one NAME only)")] = None,
    jobs: Annotated[int, typer.Option(min=1, help="sequences converted at once")] = 1,
    executor: Annotated[str, typer.Option(help="local (in this process), process (one "
                                          "worker process per sequence) or dask")] = "process",
    scheduler: Annotated[str | None, typer.Option(
        help="dask scheduler address (default: a LocalCluster)")] = None,
    force: Annotated[bool, typer.Option(help="convert again even when the store is up to "
                                        "date")] = False,
) -> None:
    """Sequences from configs/datasets/<Name>.yaml -> DATA_DIR/real/<store>. A store whose
    inputs (file sizes and times) and options are unchanged is skipped; several sequences run
    as jobs (--jobs N) with progress."""
    from bench.data.convert_batch import convert_datasets

    raise typer.Exit(convert_datasets(names, data_dir, raw_dir, out, jobs, executor, force,
                                      console, scheduler))


__all__ = ["convert_app", "write_with_progress", "loader_command", "validate_options"]
