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

import inspect
import time
import types
import typing
from pathlib import Path
from typing import Annotated, Any

import typer
import typer.core
from rich.console import Console

from bench.data.loader_options import validate_options
from loaders.errors import DataError
from loaders.registry import LOADERS, LoaderEntry

console = Console()


class ConvertGroup(typer.core.TyperGroup):
    """The ``convert`` group: its own commands (``dataset``) plus one per loader table entry,
    built when asked for; the command list is written from the table without importing any
    loader."""

    def list_commands(self, ctx) -> list[str]:
        return [*super().list_commands(ctx), *LOADERS]

    def get_command(self, ctx, name: str):
        command = super().get_command(ctx, name)
        if command is None and name in LOADERS:
            command = loader_command(LOADERS[name])
            from bench import options

            options.attach(command, name)  # every option checked as it is read
        return command

    def format_commands(self, ctx, formatter) -> None:
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


def write_with_progress(sequence, out: Path, own=None, what: str = "a store") -> Path:
    """Write ``sequence`` to the store ``out`` with a progress bar, then print the throughput;
    an existing ``out`` only when ``own`` recognises it (default ``bench.guard.is_store``; the
    command checked it before)."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    from bench import guard

    n = len(sequence)
    t0 = time.perf_counter()
    with Progress(TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("{task.fields[fps]} frames/s"), TimeElapsedColumn(),
                  TimeRemainingColumn(), console=console) as progress:
        task = progress.add_task(f"{sequence.name} -> {Path(out).name}", total=n, fps="-")

        def report(i: int) -> None:
            if i % 10 == 0 or i == n - 1:
                fps = (i + 1) / max(time.perf_counter() - t0, 1e-9)
                progress.update(task, completed=i + 1, fps=f"{fps:.0f}")

        guard.write_store(sequence, out, own or guard.is_store, what, progress=report)
    wall = time.perf_counter() - t0
    size_mb = Path(out).stat().st_size / 1e6
    console.print(f"[green]wrote[/] {out}: {n} frames in {wall:.1f} s "
                  f"({n / max(wall, 1e-9):.0f} frames/s), {size_mb:.1f} MB")
    return Path(out)


# ---- ground truth: say where it came from, or warn that nothing will be scored ---------------

#: loader options that give ground truth, by command-line flag
GT_OPTIONS = ("gt", "gt_topic")


def gt_flags(flags: dict[str, str]) -> list[str]:
    """The command-line flags of a loader's ground-truth options (``--gt``, ``--gt-topic``)."""
    return [flags[name] for name in GT_OPTIONS if name in flags]


def ground_truth_note(sequence) -> str | None:
    """"ground truth: FILE (N poses ...)" for a sequence with ground truth, else None."""
    gt = sequence.ground_truth
    if gt is None:
        return None
    prov = getattr(sequence, "provenance", {}) or {}
    assoc = prov.get("gt_association")
    assoc = assoc if isinstance(assoc, dict) else {}
    source = prov.get("gt_file") or assoc.get("gt_file") or prov.get("gt") or "from the input"
    scored = (f"{assoc['with_gt']} of {assoc.get('kept', len(sequence))} scans have a pose"
              if "with_gt" in assoc else f"{len(gt)} poses")
    return f"ground truth: {source} ({scored})"


def report_ground_truth(sequence, flags: list[str]) -> None:
    """Print where the ground truth came from; without any, warn (``GroundTruthWarning``) that
    runs on the store will not be scored, naming the loader's ground-truth options."""
    from loaders.errors import GroundTruthWarning

    note = ground_truth_note(sequence)
    if note is not None:
        console.print(note, markup=False, highlight=False, soft_wrap=True)
        return
    how = (f"give it with {' or '.join(flags)}" if flags else
           "this loader reads none from its input")
    import warnings

    warnings.warn(GroundTruthWarning(
        f"{sequence.name}: no ground truth found: the store will hold the scans only, and "
        f"`bench run` on it computes trajectories but scores none ({how})"), stacklevel=2)


# ---- the command of one loader, from its Options model -------------------------------------
# The command is made the public Typer way: a function whose signature (``__signature__``) has
# one annotated parameter per option, registered on a throwaway Typer app.

def _unwrap(annotation) -> tuple[Any, bool]:
    """(the type without ``None``, whether ``None`` was allowed)."""
    args = typing.get_args(annotation)
    if typing.get_origin(annotation) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return (rest[0] if len(rest) == 1 else typing.Union[tuple(rest)]), True  # noqa: UP007
    return annotation, False


def _cli_type(tp) -> Any | None:
    """The command-line type of a field type (numbers for numeric Literals: the model checks
    the value), or None when it has no command-line form (a mapping: config only)."""
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        values = typing.get_args(tp)
        if all(isinstance(v, str) for v in values):
            return tp
        return float if any(isinstance(v, float) for v in values) else int
    if origin is list:
        inner = _cli_type(typing.get_args(tp)[0])
        return list[inner] if inner is not None and typing.get_origin(inner) is None else None
    if origin in (typing.Union, types.UnionType):  # e.g. str | Path: given as text
        members = typing.get_args(tp)
        if all(m in (str, Path, int, float) for m in members):
            return Path if set(members) <= {str, Path} and Path in members else str
        return None
    return tp if tp in (str, int, float, Path, bool) else None


def _metavar(name: str, flag: str, tp) -> str:
    if typing.get_origin(tp) is typing.Literal and all(
            isinstance(v, str) for v in typing.get_args(tp)):
        return "|".join(typing.get_args(tp))
    if tp is Path:
        return "PATH"
    if name.endswith("_s"):
        return "SECONDS"
    return flag.upper().replace("-", "_")


def option_parameters(Options) -> tuple[list[inspect.Parameter], dict[str, str]]:
    """One keyword parameter per command-line field of an Options model (the loader's own
    options first, the shared ground-truth ones last) and {field name: flag} for messages."""
    from loaders.options import GroundTruthTimeOptions, cli_flag

    shared = set(GroundTruthTimeOptions.model_fields)
    fields = sorted(Options.model_fields.items(), key=lambda kv: kv[0] in shared)
    params, flags = [], {}
    for name, field in fields:
        flag = cli_flag(name, field)
        tp = _cli_type(_unwrap(field.annotation)[0])
        if flag is None or tp is None:
            continue
        help_ = field.description or ""
        if tp is bool:
            on, _, off = flag.partition("/")
            decl = f"--{on}/--{off or 'no-' + on}" if field.default is True else f"--{on}"
            if field.default is True:
                help_ += " [default: on]"
            option = typer.Option(decl, help=help_, show_default=False)
        else:
            if field.default is not None and str(field.default) != "":
                help_ += f" [default: {field.default}]"
            option = typer.Option(f"--{flag}", help=help_, show_default=False,
                                  metavar=_metavar(name, flag, tp))
        flags[name] = f"--{flag.partition('/')[0]}"
        params.append(inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=None,
                                        annotation=Annotated[tp | None, option]))
    return params, flags


def _frame_parameters() -> list[inspect.Parameter]:
    kw = inspect.Parameter.KEYWORD_ONLY
    return [
        inspect.Parameter("out", kw, annotation=Annotated[Path, typer.Option(
            "--out", metavar="STORE.h5", help="store to write, e.g. data/real/NAME.h5")]),
        inspect.Parameter("start", kw, default=0, annotation=Annotated[int, typer.Option(
            "--start", min=0, metavar="FRAME", help="first frame")]),
        inspect.Parameter("frames", kw, default=None, annotation=Annotated[int | None, typer.Option(
            "--frames", min=1, metavar="N", help="number of frames (default: all)")]),
        inspect.Parameter("stride", kw, default=1, annotation=Annotated[int, typer.Option(
            "--stride", min=1, metavar="K", help="keep every k-th frame (period scaled by k)")]),
        inspect.Parameter("force", kw, default=False, annotation=Annotated[bool, typer.Option(
            "--force", help="replace an existing store (only a store: never another file)")]),
    ]


def _command_from(name: str, run, params: list[inspect.Parameter], help_: str,
                  short_help: str, **settings):
    run.__signature__ = inspect.Signature(params)
    holder = typer.Typer(add_completion=False, rich_markup_mode=None)
    holder.command(name, help=help_, short_help=short_help, **settings)(run)
    command = typer.main.get_command(holder)
    for param in command.params:  # as bench's tidy_help: the metavar says it, no Python types
        if param.param_type_name == "argument":
            param.display_type_rich = lambda ctx: None
    return command


def loader_command(entry: LoaderEntry):
    """``bench convert <entry.name>`` built from the loader's Options model."""
    if not entry.available:
        def unavailable(args=None) -> None:
            raise DataError(f"loader {entry.name!r} ({entry.dataset or entry.description}) is "
                            f"listed but unavailable in this installation: module "
                            f"{entry.module} not found")
        arg = inspect.Parameter("args", inspect.Parameter.POSITIONAL_OR_KEYWORD, default=None,
                                annotation=Annotated[list[str] | None, typer.Argument()])
        return _command_from(entry.name, unavailable, [arg], entry.description,
                             entry.description, context_settings={
                                 "ignore_unknown_options": True, "allow_extra_args": True})
    Loader = entry.load_class()
    params, flags = option_parameters(Loader.Options)
    many = getattr(Loader, "many_inputs", False)
    inputs = inspect.Parameter(
        "inputs", inspect.Parameter.POSITIONAL_OR_KEYWORD,
        annotation=Annotated[list[Path] if many else Path, typer.Argument(
            metavar="INPUT..." if many else "INPUT", show_default=False)])

    def run(inputs, out: Path, start: int, frames: int | None, stride: int, force: bool,
            **values) -> None:
        from bench import guard
        from loaders.scan import select_frames

        given = {k: v for k, v in values.items() if v is not None}
        options = validate_options(Loader.Options, given, flags, f"bench convert {entry.name}")
        paths = list(inputs) if many else [inputs]
        guard.replaceable(out, force, guard.is_store, "a store", "--out",
                          [*paths, *(v for v in given.values() if isinstance(v, Path))])
        sequence = Loader.open(paths, options)
        report_ground_truth(sequence, gt_flags(flags))
        # a cut is named by its frames unless --name says otherwise: never the whole's name
        write_with_progress(select_frames(sequence, start, frames, stride,
                                          rename="name" not in given), out)

    doc = (f"{entry.description}.\n\nINPUT: {Loader.inputs}."
           + (f"\n\nLayout: {entry.layout}." if entry.layout else ""))
    return _command_from(entry.name, run, [inputs, *params, *_frame_parameters()], doc,
                         entry.description)


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
