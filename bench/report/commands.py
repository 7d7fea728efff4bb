"""The report commands: ``bench table``, ``bench compare`` and ``bench figures``."""

from __future__ import annotations

import sys
from pathlib import Path

from rich.console import Console

from bench import guard
from loaders.errors import DataError


def table_command(console: Console, status: Console, results_dirs: list[Path], format: str,
                  out: Path | None, lengths: str | None, pivot: bool, methods: str | None,
                  variants: bool, metric: str = "relative", marks: str = "intervals",
                  ci: bool = False, stability: bool = False) -> int:
    """Print a table of ``metric`` (relative: the paper-shaped Table III; kitti; ape: methods
    x sequences; velocity), or the pivot, and write its files; returns 0 (1 when a run
    record is broken: its row says "failed" and names the file). The results folder's
    own ``table.*`` (``table_<metric>.*``) is the whole table of that one folder: a filtered
    view (lengths, methods, variants, pivot) or a merged one (several folders) is written only
    to ``out``. ``stability``: each half of every sequence scored on its own, and the cells
    whose mark differs on a half flagged (``bench.report.tables.stability``)."""
    from bench.report.tables.ape import collect_ape
    from bench.report.tables.model import MARK_RULES, RENDERERS, render, rule_name
    from bench.report.tables.paper import METRICS, build, select
    from bench.report.tables.pivot import pivot_markdown
    from bench.runs.folders import BROKEN, load_runs

    wanted = None if methods is None else {m.strip() for m in methods.split(",")}

    def keep(row) -> bool:
        return (wanted is None or row.method in wanted) and (variants or not row.is_variant)

    if format not in RENDERERS:
        raise DataError(f"unknown table format {format!r}; choose from {', '.join(RENDERERS)}")
    if metric not in METRICS:
        raise DataError(f"unknown metric {metric!r}; choose from {', '.join(METRICS)}")
    if stability and (metric != "relative" or pivot):
        raise DataError("--stability: for the relative-error table (Table III) only, not "
                        f"{'--pivot' if pivot else '--metric ' + metric}")
    try:
        marks = rule_name(marks)
    except ValueError:
        raise DataError(f"--marks {marks!r}: choose from {', '.join(MARK_RULES)}") from None
    try:
        lengths_m = None if lengths is None else [float(x) for x in lengths.split(",")]
    except ValueError:
        raise DataError(f"--lengths {lengths!r}: expected numbers in metres, e.g. 8,48") from None
    view = pivot or len(results_dirs) > 1 or lengths is not None or methods is not None \
        or not variants
    where = out if out is not None else (None if view else results_dirs[0])
    stem = "pivot" if pivot else ("table" if metric == "relative" else f"table_{metric}")
    if where is not None and out is None and (guard.run_kind(Path(where)) is not None or any(
            guard.run_kind(p) is not None for p in Path(where).resolve().parents)):
        status.print(f"{where} is a run folder: the table is printed, not written into it "
                     "(--out DIR writes it)", style="dim", markup=False)
        where = None  # a run folder holds its run's files only
    if where is not None:  # before any work: a folder, never a run's; only tables of ours
        guard.output_folder(Path(where))
        for fmt in RENDERERS:
            guard.regenerated_file(Path(where) / f"{stem}.{fmt}", guard.derived, "a table")
    try:
        rows, chosen = select(list(results_dirs), lengths_m=lengths_m, keep=keep)
    except ValueError as e:
        raise DataError(str(e)) from None
    if pivot:
        texts = {"md": pivot_markdown(rows, chosen, marks, ci)}
    else:
        if metric == "ape":
            if len(results_dirs) > 1:
                raise DataError("--metric ape: one results folder at a time")
            only = {r.run.dir for r in rows}
            made = collect_ape(results_dirs[0], only=only, marks=marks, ci=ci).table
        else:
            made = build(metric, rows, chosen, marks, ci)
            if stability:
                from bench.report.tables.stability import with_stability

                with_stability(rows, chosen, made, marks)
        if where is not None:  # a caption without the intervals names the CSV written
            made.csv_file = str(Path(where) / f"{stem}.csv")
        texts = render(made)
    sys.stdout.write(texts["md" if pivot else format])  # unwrapped (a pipe gets valid CSV)
    broken = [r for r in rows if r.result.status == BROKEN]
    for r in broken:
        status.print(f"broken run record: {r.result.error}", markup=False)
    for d in results_dirs:  # never left out without a line
        for r in load_runs(d, failed=True):
            if r.result.finished and not r.result.scored:
                status.print(f"not in the table: {r.dir} (no ground truth: nothing to score)",
                             style="dim", markup=False)
    code = 1 if broken else 0  # a broken record is a failed row, never a success
    if where is None:
        if view:
            status.print("a filtered or merged view: not written (--out DIR writes it)",
                         style="dim", markup=False)
        return code
    guard.write_texts({Path(where) / f"{stem}.{fmt}": text for fmt, text in texts.items()},
                      guard.derived, "a table")
    status.print(f"wrote {where}/{stem}.{{{','.join(texts)}}}", style="dim", markup=False)
    return code


def compare_command(console: Console, a: Path, b: Path, threshold: float,
                    fail_on_regression: bool) -> int:
    """Print A, B and the change per cell and the times per run as markdown; returns 1 when
    asked to fail and B regresses."""
    from bench.report.compare import compare, compare_run_metrics, compare_times, to_markdown

    cells, times = compare(a, b, threshold), compare_times(a, b)
    # written as is (not wrapped): `bench compare A B > diff.md` is a valid markdown file
    sys.stdout.write(to_markdown(cells, times, a, b, threshold, compare_run_metrics(a, b)))
    n = int(cells["regression"].sum()) if len(cells) else 0
    return 1 if fail_on_regression and n else 0


def figures_command(console: Console, results_dir: Path | None, out: Path | None,
                    speed_csv: Path | None, pair: tuple[Path, int] | None) -> int:
    """Write the figures asked for and list them; returns 0 (1 when a run record of the
    folder is broken: left out, with a warning naming it)."""
    from bench.report.figures.draw import make_figures
    from bench.report.figures.pair import plot_pair

    paths = []
    if out is not None:
        guard.output_folder(out)  # a folder, never a run's own
    if pair is not None:
        paths += plot_pair(pair[0], pair[1], out or Path("results/figures"))
    if results_dir is not None:
        default_csv = Path("results/speed/speed.csv")
        paths += make_figures(results_dir, out, speed_csv or
                              (default_csv if default_csv.exists() else None))
    if not paths:
        raise DataError("give a RESULTS_DIR with finished runs, or --pair STORE FRAME")
    for p in paths:
        if p.suffix == ".png":
            console.print(f"wrote {p} (+ .pdf)", markup=False)
    if results_dir is not None:
        from bench.runs.folders import BROKEN, load_runs

        # the broken records were named in warnings and left out: no success
        if any(r.result.status == BROKEN for r in load_runs(results_dir, failed=True)):
            return 1
    return 0


def figures_current(results_dir: Path) -> bool:
    """The folder's figures (RESULTS/figures/**.png) exist and none is older than its newest
    run record (metrics.json / failed.json)."""
    figures = list((Path(results_dir) / "figures").rglob("*.png"))
    records = [p for n in ("metrics.json", "failed.json") for p in Path(results_dir).rglob(n)]
    if not figures:
        return False
    newest = max((p.stat().st_mtime for p in records), default=0.0)
    return min(p.stat().st_mtime for p in figures) >= newest


def report_command(console: Console, results_dir: Path, out: Path | None,
                   figures: bool = True) -> int:
    """Write the results folder's HTML page and say what it holds; returns 0, or 1 when some
    run records are broken or run folders hold unreadable files (the page lists them; a
    broken record is never a success). With ``figures`` the figures the page shows are drawn
    first (``bench figures``) unless they are newer than every run record."""
    import warnings

    from bench.report.html.page import PAGE_NAME, write_page

    # the page's path before any drawing: only a page of ours, never into a run folder
    guard.regenerated_file(Path(out) if out is not None else Path(results_dir) / PAGE_NAME,
                           guard.derived, "a report page")
    if figures and not figures_current(results_dir):
        from bench.report.figures.draw import make_figures
        from bench.report.figures.style import for_the_page

        try:
            with warnings.catch_warnings(), for_the_page():  # a broken record: the page
                warnings.simplefilter("ignore")                # lists it
                drawn = [p for p in make_figures(results_dir) if p.suffix == ".png"]
        except guard.Refused:  # a user's own figure of that name: left as it is, said, exit 2
            raise
        except (DataError, OSError, ValueError) as err:  # an unreadable run file: the page
            drawn = []                                     # lists it; the tables still show
            console.print(f"figures not drawn: {str(err).splitlines()[0]}", markup=False)
        if drawn:
            console.print(f"drew {len(drawn)} figure(s) into {Path(results_dir) / 'figures'} "
                          "(PNG, for the page; `bench figures` writes PDF too)", markup=False)
    path, counts = write_page(results_dir, out)
    console.print(f"wrote {path}: {counts['tables']} table(s), {counts['figures']} figure(s), "
                  f"{counts['runs']} run(s), {counts['failed']} not finished", markup=False)
    if counts["broken"]:
        console.print(f"{counts['broken']} run record(s) broken (metrics.json not a valid "
                      "record): listed under \"Failed runs and missing data\" on the page; "
                      "`bench run` runs them again", markup=False)
    if counts["damaged"]:
        console.print(f"{counts['damaged']} run folder(s) with unreadable files (config.yaml, "
                      "meta.json or trajectory files): listed under \"Failed runs and missing "
                      "data\" on the page", markup=False)
    return 1 if counts["broken"] or counts["damaged"] else 0
