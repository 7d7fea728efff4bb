"""``bench report RESULTS_DIR``: one self-contained HTML page of a results folder.

The page holds the tables of the folder's runs made for it (relative error, KITTI drift, APE,
velocity error: every figure with its 95 % confidence interval, marks read from the printed
intervals: ``bench.report.tables.significance``), then every table the harness wrote into the folder
(every ``*.md`` of the folder: ``table*.md`` of any metric, ``pivot.md``, ``fidelity.md`` ...)
as written, every figure under ``figures/`` embedded as a base64 PNG with its caption, the
provenance of the runs (code version, store hashes, machine, how times were taken), the failed
runs, the runs whose frames fell back and the missing data (runs without ground truth, paper
sequences a reproduction did not find: ``reproduction.json``).

It is readable offline and loads nothing: no script, no external style, font or image; its
Content-Security-Policy forbids any load but the embedded ``data:`` images. Every string that
comes from data or configuration (sequence, method and store names, labels, paths, messages) is
HTML-escaped, so a store named ``<script>alert(1)</script>`` shows as that text.

Run folders are read by one function, ``bench.report.html.runs.read_page_runs`` (the documented
files of a run folder); everything else works on its ``PageRun`` records.
"""

from __future__ import annotations

import base64
from collections import Counter
from datetime import UTC, datetime
from pathlib import Path

from bench.report.html.markdown import PageNotes, esc, markdown_html
from bench.report.html.runs import PageRun, read_json, read_page_runs
from bench.report.summary.overview import cross_dataset
from bench.report.tables.model import to_markdown
from bench.runs.folders import BROKEN
from bench.runs.result import REPORTED_CLOCK

#: the page's name inside the results folder
PAGE_NAME = "report.html"
#: the markdown reports the harness writes into a results folder, in the page's order
TABLE_FILES = ("table3.md", "table4.md", "table5.md", "table.md", "table_ape.md", "pivot.md",
               "fidelity.md")
#: figure kinds (subfolders of ``figures/``), in the page's order, with their captions
FIGURE_KINDS = {
    "trajectories": "Top view of every method's trajectory over the ground truth (equal scale "
                    "in x and y; estimates aligned at their first pose; o start, square end); "
                    "a diverged run is drawn until it leaves the axes and marked Div.",
    "error-along-path": "Relative error of 8 m segments along the path (log axis); a diverged "
                        "run is drawn to the top and marked Div.",
    "boxplots": "Relative error per segment length for each sensor class (log axis); "
                "diverged runs are named, not drawn.",
    "forest": "Every method's mean relative error on its 95 % interval at the shortest and "
              "longest length; bold / underlined as in the tables (dashed line U: the smallest "
              "upper end among the ranked figures; bold = every ranked figure at or below it).",
    "frames": "Time per frame and the number of correspondences per frame.",
    "drift": "Drift per axis (roll / pitch / yaw, along / across / vertical) against distance.",
    "speed": "Scaling of the per-frame time with the number of points (bench speed).",
    "pairs": "Closest-point against Doppler correspondences of one scan pair.",
}
#: how the Time columns were measured (README "Metrics" / Timing)
TIMING_NOTE = ("Time per frame covers all per-frame work from a scan in memory to its pose "
               "(downsampling, normals, kd-trees, maps, registration, map update; not file I/O), "
               "after the same untimed warm-up for every method. A one-thread run is timed by "
               "its thread's CPU time (waiting for a core is not counted, so runs side by side "
               "do not inflate it); a run on several threads by the wall clock, its timed "
               "sections holding a machine-wide lock.")

_CSP = ("default-src 'none'; img-src data:; style-src 'unsafe-inline'; base-uri 'none'; "
        "form-action 'none'")
_CSS = """
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0 auto;
max-width:1200px;padding:1em 1.5em;color:#222}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #ccc;margin-top:2em}
h3{font-size:1.05em}
table{border-collapse:collapse;margin:.6em 0;font-size:12px}
th,td{border:1px solid #ccc;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#f3f3f3}td.num{text-align:right;white-space:nowrap}
.scroll{overflow-x:auto}.caption,figcaption{color:#444;font-size:12.5px;max-width:1000px}
.banner{background:#fff3cd;border:1px solid #e0c36a;padding:.6em 1em;margin:1em 0}
.stale{color:#a4420b}.failed{color:#b00020}code{background:#f4f4f4;padding:0 2px}
figure{display:inline-block;margin:.5em 1em 1em 0;vertical-align:top;max-width:520px}
figure img{max-width:100%;height:auto;border:1px solid #eee}
nav ul{columns:2}dl{display:grid;grid-template-columns:max-content auto;gap:2px 1em}
dt{font-weight:600}dd{margin:0}
"""


# ---------------------------------------------------------------- sections


def _stale_note(path: Path, newest_run: float) -> str:
    if newest_run and path.stat().st_mtime < newest_run - 1e-3:
        return ('<p class="stale">Written before the latest run record of this folder: it may '
                "not show every run (<code>bench table</code> / <code>bench figures</code> "
                "rewrite it).</p>")
    return ""


def table_files(results_dir: Path) -> list[Path]:
    """Every markdown table in the folder: ``TABLE_FILES`` first, then any other ``*.md`` of
    the folder, then those of its subfolders (e.g. ``bench table --out RESULTS/sub``)."""
    known = [results_dir / n for n in TABLE_FILES if (results_dir / n).exists()]
    others = sorted(p for p in results_dir.glob("*.md") if p not in known)
    nested = sorted(p for p in results_dir.rglob("*.md") if p.parent != results_dir)
    return known + others + nested


def _tables_section(results_dir: Path, newest_run: float) -> tuple[str, int]:
    parts, count = [], 0
    notes = PageNotes()  # the shared caption notes once per page
    made = _tables_in_memory(results_dir)
    if made:
        parts.append("<p>Tables of the folder's finished runs, made for this page: every "
                     "figure with its 95 % confidence interval [low, high]; bold / underlined "
                     "read from the printed intervals alone (the caption states the rule: "
                     "check any mark against the cells).</p>")
    for title, text in made:
        body, n = markdown_html(text, notes, title)
        count += n
        parts.append(f"<h3>{esc(title)}</h3>{body}")
    for title, table in cross_dataset(results_dir):
        body, n = markdown_html(to_markdown(table), notes, title)
        count += n
        parts.append(f"<h3>{esc(title)}</h3>{body}")
    files = table_files(results_dir)
    if files:
        parts.append("<p>Tables written into this folder, as written:</p>")
    for path in files:
        body, n = markdown_html(path.read_text(errors="replace"), notes,
                                str(path.relative_to(results_dir)))
        count += n
        parts.append(f'<h3 id="{esc(path.stem)}">{esc(path.relative_to(results_dir))}</h3>'
                     f"{_stale_note(path, newest_run)}{body}")
    if not made and not files:
        parts.append("<p>No table: no finished run with ground truth.</p>")
    return "\n".join(parts), count


#: the tables made for the page: (title, metric)
PAGE_TABLES = (("Relative error per segment length (Table III)", "relative"),
               ("KITTI drift", "kitti"), ("Absolute pose error (Tables IV / V)", "ape"),
               ("Ego-velocity error", "velocity"))


def _tables_in_memory(results_dir: Path) -> list[tuple[str, str]]:
    """(title, markdown) of every metric's table of the folder's runs, with intervals (none
    when there is no finished run with ground truth)."""
    from bench.report.tables.ape import collect_ape
    from bench.report.tables.paper import build, select
    from bench.report.tables.stability import with_stability

    try:
        rows, lengths = select(results_dir)
    except (FileNotFoundError, ValueError):
        return []
    out = []
    for title, metric in PAGE_TABLES:
        if metric == "ape":
            table = collect_ape(results_dir, only={r.run.dir for r in rows}, ci=True).table
        else:
            table = build(metric, rows, lengths, ci=True)
            if metric == "relative":  # do the marks hold on both halves of each sequence?
                with_stability(rows, lengths, table)
        # never left out without a line: what is missing and why
        out.append((title, to_markdown(table) if table.rows else
                    "Not made: no run of this folder has this metric (a finished run with "
                    "ground truth and its figure in metrics.json; runs without ground truth "
                    "and runs that did not finish are listed under Failed runs and missing "
                    "data)."))
    return out


def _figures_section(figures_dir: Path, newest_run: float) -> tuple[str, int]:
    pngs = sorted(figures_dir.rglob("*.png")) if figures_dir.is_dir() else []
    if not pngs:
        return ("<p>No figures in this folder (<code>bench figures RESULTS_DIR</code> draws "
                "them).</p>", 0)

    def kind(p: Path) -> str:
        rel = p.relative_to(figures_dir)
        return rel.parts[0] if len(rel.parts) > 1 else p.stem

    order = list(FIGURE_KINDS)
    groups: dict[str, list[Path]] = {}
    for p in sorted(pngs, key=lambda p: (order.index(kind(p)) if kind(p) in order
                                         else len(order), str(p))):
        groups.setdefault(kind(p), []).append(p)
    parts = []
    for k, paths in groups.items():
        parts.append(f"<h3>{esc(k)}</h3>")
        if k in FIGURE_KINDS:
            parts.append(f'<p class="caption">{esc(FIGURE_KINDS[k])}</p>')
        for p in paths:
            data = base64.b64encode(p.read_bytes()).decode("ascii")
            rel = p.relative_to(figures_dir.parent)
            parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{esc(rel)}">'
                         f"<figcaption><code>{esc(rel)}</code>"
                         f"{_stale_note(p, newest_run)}</figcaption></figure>")
    return "\n".join(parts), len(pngs)


def _counts(values) -> str:
    c = Counter(v for v in values if v not in (None, ""))
    if not c:
        return "not recorded"
    return "; ".join(f"{esc(v)} ({n} run{'s' if n > 1 else ''})" for v, n in c.most_common())


def _provenance_section(runs: list[PageRun]) -> str:
    if not runs:
        return "<p>No run records.</p>"
    metas = [r.meta for r in runs]
    commits = [(m.get("git") or {}) for m in metas]
    code = [f"{g.get('commit', '')[:12]}{' (uncommitted changes)' if g.get('dirty') else ''}"
            if g.get("commit") else None for g in commits]
    version = [(m.get("packages") or {}).get("doppler-bench") for m in metas]
    dates = sorted(m["date"] for m in metas if m.get("date"))
    items = [
        ("code (git commit)", _counts(code)),
        ("doppler-bench version", _counts(version)),
        ("code hash (loaders, methods, metrics, scoring)", _counts(
            r.code_sha256[:16] if r.code_sha256 else None for r in runs)),
        ("machine", _counts(f"{m.get('cpu', '?')}, {m.get('cpu_count', '?')} cores, "
                            f"host {m.get('host', '?')}, Python {m.get('python', '?')}"
                            if m else None for m in metas)),
        ("clock", _counts((r.clock if r.clock == REPORTED_CLOCK else
                           f"{r.clock} time, {r.threads or 1} thread(s)") if r.clock else None
                          for r in runs)),
        ("timing lock", _counts(m.get("timing_lock") or "default" for m in metas if m)),
        ("run dates", esc(f"{dates[0]} to {dates[-1]}") if dates else "not recorded"),
    ]
    dl = "".join(f"<dt>{esc(k)}</dt><dd>{v}</dd>" for k, v in items)
    stores: dict[str, tuple[str | None, set]] = {}
    for r in runs:
        if r.store:
            sha, seqs = stores.get(r.store, (r.store_sha256, set()))
            seqs.add(r.sequence)
            stores[r.store] = (sha or r.store_sha256, seqs)
    rows = "".join(f"<tr><td><code>{esc(s)}</code></td><td>{esc(', '.join(sorted(seqs)))}</td>"
                   f"<td><code>{esc(sha or 'not recorded')}</code></td></tr>"
                   for s, (sha, seqs) in sorted(stores.items()))
    data = ("<table><thead><tr><th>store</th><th>sequence</th><th>SHA-256 of the store</th>"
            f"</tr></thead><tbody>{rows}</tbody></table>") if rows else ""
    return (f"<dl>{dl}</dl><h3>Data</h3>{data}<h3>How times were taken</h3>"
            f'<p class="caption">{esc(TIMING_NOTE)}</p>')


def _problems_section(runs: list[PageRun], coverage: dict) -> str:
    parts = []
    bad = [r for r in runs if r.status != "finished"]
    if bad:
        rows = "".join(
            f'<tr><td><code>{esc(r.folder)}</code></td><td class="failed">{esc(r.status)}</td>'
            f"<td>{esc((r.message or '').splitlines()[0] if r.message else '')}</td></tr>"
            for r in bad)
        broken = sum(r.status == BROKEN for r in bad)
        what = (f"; {broken} with a broken record (its metrics.json is no valid run record: "
                "shown as a failed row in every table, never as a result; `bench run` runs it "
                "again)" if broken else "")
        parts.append(f"<h3>Runs that did not finish ({len(bad)})</h3>"
                     + f'<p class="caption">{esc(what.lstrip("; "))}</p>' * bool(broken)
                     + "<table><thead><tr>"
                     f"<th>run folder</th><th>status</th><th>error</th></tr></thead>"
                     f"<tbody>{rows}</tbody></table>")
    else:
        parts.append("<p>Every run finished.</p>")
    damaged = [r for r in runs if r.damaged]
    if damaged:
        rows = "".join(f"<tr><td><code>{esc(r.folder)}</code></td><td>{esc(line)}</td></tr>"
                       for r in damaged for line in r.damaged)
        parts.append(f'<h3>Runs with unreadable files ({len(damaged)})</h3><p class="caption">'
                     "A finished run keeps its row (its figures come from metrics.json), but "
                     "without readable trajectory files its per-segment errors, and so its "
                     "significance marks and figures, are missing.</p><table><thead><tr>"
                     "<th>run folder</th><th>problem</th></tr></thead>"
                     f"<tbody>{rows}</tbody></table>")
    said: dict[str, list[str]] = {}
    for r in runs:
        for w in r.meta.get("warnings") or []:
            said.setdefault(str(w), []).append(r.folder)
    if said:
        parts.append(f"<h3>Warnings while the runs ran ({len(said)})</h3><ul>" + "".join(
            f"<li>{esc(w)} <span class=\"caption\">({len(where)} run(s): "
            f"{esc(', '.join(where[:3]))}{', ...' if len(where) > 3 else ''})</span></li>"
            for w, where in said.items()) + "</ul>")
    fell = [r for r in runs if r.status == "finished"
            and (r.frames_replaced or r.frames_unconverged)]
    if fell:
        from bench.runs.result import FALLBACK_LIMIT

        def share(r: PageRun) -> float:
            return (r.frames_replaced + r.frames_unconverged) / max(1, (r.frames or 1) - 1)

        def line(r: PageRun) -> str:
            red = ' class="failed"' if share(r) > FALLBACK_LIMIT else ""
            return (f'<tr><td><code>{esc(r.folder)}</code></td><td class="num">'
                    f'{r.frames_replaced}</td><td class="num">{r.frames_unconverged}</td>'
                    f'<td class="num">{max(0, (r.frames or 1) - 1)}</td>'
                    f"<td{red}>{100 * share(r):.1f} %</td></tr>")

        rows = "".join(line(r) for r in fell)
        parts.append(
            f"<h3>Runs whose frames fell back ({len(fell)})</h3><p class=\"caption\">Replaced: "
            "the registration gave no usable transform and the step was replaced by the motion "
            "prior (the identity without a seed); not converged: the registration stopped "
            "before converging and its last iterate was kept. Above "
            f"{100 * FALLBACK_LIMIT:g} % (in red) the run is marked [fell back] in every "
            "table.</p><table><thead><tr><th>run folder</th><th>replaced</th>"
            "<th>not converged</th><th>registered frames</th><th>share</th></tr></thead>"
            f"<tbody>{rows}</tbody></table>")
    no_gt = [r for r in runs if r.status == "finished" and not r.has_gt]
    if no_gt:
        parts.append("<h3>Runs without ground truth (in no table)</h3><ul>" + "".join(
            f"<li><code>{esc(r.folder)}</code></li>" for r in no_gt) + "</ul>")
    if coverage:
        found, missing = coverage.get("found") or [], coverage.get("missing") or []
        parts.append(f"<h3>The paper's sequences ({esc(coverage.get('data', ''))})</h3>")
        if "found" in coverage or "missing" in coverage:
            parts.append(f"<p>Found ({len(found)}): {esc(', '.join(found) or 'none')}</p>"
                         f'<p class="failed">Missing ({len(missing)}): '
                         f"{esc(', '.join(missing) or 'none')}</p>")
        for note in coverage.get("notes") or []:
            parts.append(f'<p class="caption">{esc(note)}</p>')
    return "\n".join(parts)


def render_page(results_dir: Path) -> tuple[str, dict]:
    """The page of ``results_dir`` and what it holds ({tables, figures, runs, failed})."""
    results_dir = Path(results_dir)
    runs = read_page_runs(results_dir)
    newest = max((r.mtime for r in runs), default=0.0)
    coverage = read_json(results_dir / "reproduction.json")
    if (results_dir / "reproduction.json").exists() and not coverage:
        coverage = {"notes": [f"{results_dir / 'reproduction.json'} is not readable (not a JSON "
                              "object): the paper's coverage of this folder is unknown"]}
    tables, n_tables = _tables_section(results_dir, newest)
    figures, n_figures = _figures_section(results_dir / "figures", newest)
    failed = sum(r.status != "finished" for r in runs)
    synthetic = any("(synthetic)" in r.sequence for r in runs)
    banner = ('<p class="banner"><strong>Synthetic data.</strong> Sequences marked (synthetic) '
              "were made by this repository's generator to imitate the paper's sequences; they "
              "are not the paper's data.</p>") if synthetic else ""
    if coverage.get("missing"):
        banner += (f'<p class="banner">{len(coverage["missing"])} of the paper\'s sequences are '
                   "missing from this reproduction (listed under Failed runs and missing "
                   "data).</p>")
    title = f"doppler-bench results: {results_dir.name or results_dir.resolve().name}"
    now = datetime.now(UTC).isoformat(timespec="seconds")
    summary = (f"{len(runs)} run folder(s): {len(runs) - failed} finished, {failed} not; "
               f"{n_tables} table(s), {n_figures} figure(s)")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{esc(title)}</title><style>{_CSS}</style></head>
<body>
<h1>{esc(title)}</h1>
<p>Folder <code>{esc(results_dir)}</code>; page written {esc(now)} by <code>bench report</code>.
{esc(summary)}.</p>
{banner}
<nav><ul><li><a href="#tables">Tables</a></li><li><a href="#figures">Figures</a></li>
<li><a href="#problems">Failed runs and missing data</a></li>
<li><a href="#provenance">Provenance</a></li></ul></nav>
<section id="tables"><h2>Tables</h2>
{tables}
</section>
<section id="figures"><h2>Figures</h2>
{figures}
</section>
<section id="problems"><h2>Failed runs and missing data</h2>
{_problems_section(runs, coverage)}
</section>
<section id="provenance"><h2>Provenance</h2>
{_provenance_section(runs)}
</section>
</body></html>
"""
    return page, {"tables": n_tables, "figures": n_figures, "runs": len(runs), "failed": failed,
                  "broken": sum(r.status == BROKEN for r in runs),
                  "damaged": sum(bool(r.damaged) for r in runs)}


def write_page(results_dir: Path, out: Path | None = None) -> tuple[Path, dict]:
    """Write the page (default ``RESULTS_DIR/report.html``) atomically; returns its path and
    what it holds."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        from loaders.errors import DataError

        raise DataError(f"{results_dir}: no such results folder")
    if not read_page_runs(results_dir):
        from loaders.errors import DataError

        raise DataError(f"{results_dir}: no run records in this folder (no metrics.json, "
                        "failed.json or run config.yaml under it); expected a results folder "
                        "of `bench run` or `bench reproduce`")
    from bench import guard

    path = Path(out) if out is not None else results_dir / PAGE_NAME
    # before any drawing: only a page of ours, never into a run folder
    guard.regenerated_file(path, guard.derived, "a report page")
    page, counts = render_page(results_dir)
    guard.write_text(path, page, guard.derived, "a report page")
    return path, counts
