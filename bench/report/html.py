"""``bench report RESULTS_DIR``: one self-contained HTML page of a results folder.

The page holds every table the harness wrote into the folder (``table*.md``, ``pivot.md``,
``fidelity.md``; the Table III of the folder's runs, made in memory, when none was written),
with the paper's marking (best bold, second underlined, as in the markdown), every figure under
``figures/`` embedded as a base64 PNG with its caption, the provenance of the runs (code
version, store hashes, machine, how times were taken), the failed runs and the missing data
(runs without ground truth, paper sequences a reproduction did not find: ``reproduction.json``).

It is readable offline and loads nothing: no script, no external style, font or image; its
Content-Security-Policy forbids any load but the embedded ``data:`` images. Every string that
comes from data or configuration (sequence, method and store names, labels, paths, messages) is
HTML-escaped, so a store named ``<script>alert(1)</script>`` shows as that text.

Run folders are read by one function, ``read_page_runs`` (the documented files of a run folder,
README "Results layout"); everything else works on its ``PageRun`` records.
"""

from __future__ import annotations

import base64
import html
import json
import re
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import yaml

from loaders.fileio import atomic_write_text

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


def esc(text) -> str:
    """HTML-escaped text (quotes included): every string from data or configuration."""
    return html.escape(str(text), quote=True)


@dataclass(frozen=True)
class PageRun:
    """What the page shows of one run folder."""

    folder: str                    # relative to the results folder
    sequence: str                  # display name
    run: str                       # the run folder's name (method, label, seed option)
    status: str                    # finished, failed, crashed, timeout, interrupted, unfinished
    message: str = ""
    store: str | None = None
    store_sha256: str | None = None
    frames: int | None = None
    has_gt: bool = False
    diverged: bool | None = None
    clock: str | None = None
    threads: int | None = None
    code_sha256: str | None = None
    meta: dict = field(default_factory=dict)
    mtime: float = 0.0


def _read_json(path: Path) -> dict:
    try:
        return json.loads(path.read_text()) if path.exists() else {}
    except (OSError, ValueError):
        return {}


def read_page_runs(results_dir: Path) -> list[PageRun]:
    """Every run folder under ``results_dir`` (a folder holding ``config.yaml`` with a
    ``run_key``, ``metrics.json`` or ``failed.json``): the page's one reader of run records."""
    results_dir = Path(results_dir)
    folders = sorted({p.parent for name in ("metrics.json", "failed.json", "config.yaml")
                      for p in results_dir.rglob(name)})
    runs = []
    for d in folders:
        config = {}
        if (d / "config.yaml").exists():
            try:
                config = yaml.safe_load((d / "config.yaml").read_text()) or {}
            except (OSError, yaml.YAMLError):
                pass
        config = config if isinstance(config, dict) else {}
        metrics, failed = _read_json(d / "metrics.json"), _read_json(d / "failed.json")
        if not (metrics or failed or "run_key" in config):
            continue  # a config.yaml of something else (an experiment)
        seq = config.get("sequence") or {}
        identity = config.get("identity") or {}
        if metrics:
            status, message = "finished", ""
        elif failed:
            status, message = failed.get("status", "failed"), failed.get("error", "")
        else:
            status, message = "unfinished", "no metrics.json and no failed.json"
        records = [d / n for n in ("metrics.json", "failed.json") if (d / n).exists()]
        runs.append(PageRun(
            folder=str(d.relative_to(results_dir)),
            sequence=str(seq.get("display_name") or seq.get("name") or metrics.get("sequence")
                         or d.parent.name),
            run=d.name, status=status, message=str(message), store=seq.get("store"),
            store_sha256=identity.get("store_sha256"),
            frames=metrics.get("frames", seq.get("frames")),
            has_gt=(d / "gt_tum.txt").exists(), diverged=metrics.get("diverged"),
            clock=metrics.get("clock"), threads=metrics.get("threads"),
            code_sha256=identity.get("code_sha256"), meta=_read_json(d / "meta.json"),
            mtime=max((p.stat().st_mtime for p in records), default=0.0)))
    return runs


# ---------------------------------------------------------------- markdown -> HTML (tables)

_BOLD = re.compile(r"\*\*(.+?)\*\*")
_UNDER = re.compile(r"&lt;u&gt;(.+?)&lt;/u&gt;")
_CODE = re.compile(r"`([^`]+)`")
_NUMBER = re.compile(r"^[-+]?[\d.]+(e[-+]?\d+)?( / [-+]?[\d.]+(e[-+]?\d+)?)?( \[\d+ thr\.\])?$")


def inline(text: str) -> str:
    """One markdown cell or line as HTML: escaped first, then the harness's own marks (``**``
    bold, ``<u>`` underline, backticks) turned into tags around the escaped text."""
    out = esc(text)
    out = _CODE.sub(r"<code>\1</code>", out)
    out = _BOLD.sub(r"<strong>\1</strong>", out)
    return _UNDER.sub(r"<u>\1</u>", out)


def _split_row(line: str) -> list[str]:
    body = line.strip()
    body = body[1:] if body.startswith("|") else body
    body = body[:-1] if body.endswith("|") else body
    return [c.strip() for c in body.split(" | ")] if " | " in body or body else [""]


def _is_rule(line: str) -> bool:
    return bool(re.fullmatch(r"\|?(\s*:?-{3,}:?\s*\|)+\s*:?(-{3,}:?)?\s*\|?", line.strip()))


def _plain(cell: str) -> str:
    return re.sub(r"\*\*|</?u>", "", cell).strip()


def _td(cell: str) -> str:
    num = ' class="num"' if _NUMBER.match(_plain(cell)) else ""
    return f"<td{num}>{inline(cell)}</td>"


def markdown_html(text: str) -> tuple[str, int]:
    """A markdown report (the harness's tables, captions, headings and lists) as HTML, and
    the number of tables in it."""
    lines, out, i, tables = text.splitlines(), [], 0, 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("|") and i + 1 < len(lines) and _is_rule(lines[i + 1]):
            header = _split_row(line)
            rows = []
            i += 2
            while i < len(lines) and lines[i].startswith("|"):
                rows.append(_split_row(lines[i]))
                i += 1
            tables += 1
            head = "".join(f"<th>{inline(c)}</th>" for c in header)
            body = "".join("<tr>" + "".join(_td(c) for c in row) + "</tr>" for row in rows)
            out.append(f'<div class="scroll"><table><thead><tr>{head}</tr></thead>'
                       f"<tbody>{body}</tbody></table></div>")
            continue
        if line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")) + 2, 5)
            out.append(f"<h{level}>{inline(line.lstrip('#').strip())}</h{level}>")
        elif line.lstrip().startswith(("- ", "* ")):
            items = []
            while i < len(lines) and lines[i].lstrip().startswith(("- ", "* ")):
                items.append(f"<li>{inline(lines[i].lstrip()[2:])}</li>")
                i += 1
            out.append(f"<ul>{''.join(items)}</ul>")
            continue
        elif line.strip():
            para = [line.strip()]
            while i + 1 < len(lines) and lines[i + 1].strip() and not lines[i + 1].startswith(
                    ("|", "#", "- ", "* ")):
                i += 1
                para.append(lines[i].strip())
            out.append(f'<p class="caption">{inline(" ".join(para))}</p>')
        i += 1
    return "\n".join(out), tables


# ---------------------------------------------------------------- sections


def _stale_note(path: Path, newest_run: float) -> str:
    if newest_run and path.stat().st_mtime < newest_run - 1e-3:
        return ('<p class="stale">Written before the latest run record of this folder: it may '
                "not show every run (<code>bench table</code> / <code>bench figures</code> "
                "rewrite it).</p>")
    return ""


def _tables_section(results_dir: Path, newest_run: float) -> tuple[str, int]:
    parts, count = [], 0
    files = [results_dir / n for n in TABLE_FILES if (results_dir / n).exists()]
    for path in files:
        body, n = markdown_html(path.read_text(errors="replace"))
        count += n
        parts.append(f'<h3 id="{esc(path.stem)}">{esc(path.name)}</h3>'
                     f"{_stale_note(path, newest_run)}{body}")
    if not files:
        text = _table_in_memory(results_dir)
        if text:
            body, n = markdown_html(text)
            count += n
            parts.append("<p>No table was written into this folder; Table III of its finished "
                         "runs, made for this page:</p>" + body)
        else:
            parts.append("<p>No table: no finished run with ground truth.</p>")
    return "\n".join(parts), count


def _table_in_memory(results_dir: Path) -> str:
    """Table III of the folder's runs as markdown (empty when there are none)."""
    from bench.report.tables import FORMATS, select_rows

    try:
        rows, lengths = select_rows(results_dir)
    except (FileNotFoundError, ValueError):
        return ""
    return FORMATS["md"](rows, lengths)


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
        ("clock", _counts(f"{r.clock} time, {r.threads or 1} thread(s)" if r.clock else None
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
        parts.append(f"<h3>Runs that did not finish ({len(bad)})</h3><table><thead><tr>"
                     f"<th>run folder</th><th>status</th><th>error</th></tr></thead>"
                     f"<tbody>{rows}</tbody></table>")
    else:
        parts.append("<p>Every run finished.</p>")
    said: dict[str, list[str]] = {}
    for r in runs:
        for w in r.meta.get("warnings") or []:
            said.setdefault(str(w), []).append(r.folder)
    if said:
        parts.append(f"<h3>Warnings while the runs ran ({len(said)})</h3><ul>" + "".join(
            f"<li>{esc(w)} <span class=\"caption\">({len(where)} run(s): "
            f"{esc(', '.join(where[:3]))}{', ...' if len(where) > 3 else ''})</span></li>"
            for w, where in said.items()) + "</ul>")
    no_gt = [r for r in runs if r.status == "finished" and not r.has_gt]
    if no_gt:
        parts.append("<h3>Runs without ground truth (in no table)</h3><ul>" + "".join(
            f"<li><code>{esc(r.folder)}</code></li>" for r in no_gt) + "</ul>")
    if coverage:
        found, missing = coverage.get("found") or [], coverage.get("missing") or []
        parts.append(f"<h3>The paper's sequences ({esc(coverage.get('data', ''))})</h3>"
                     f"<p>Found ({len(found)}): {esc(', '.join(found) or 'none')}</p>"
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
    coverage = _read_json(results_dir / "reproduction.json")
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
    return page, {"tables": n_tables, "figures": n_figures, "runs": len(runs), "failed": failed}


def write_page(results_dir: Path, out: Path | None = None) -> tuple[Path, dict]:
    """Write the page (default ``RESULTS_DIR/report.html``) atomically; returns its path and
    what it holds."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        from loaders.errors import DataError

        raise DataError(f"{results_dir}: no such results folder")
    page, counts = render_page(results_dir)
    path = Path(out) if out is not None else results_dir / PAGE_NAME
    atomic_write_text(path, page)
    return path, counts
