"""bench/report/html/page.py, in-process and fast: the page's sections built from ``PageRun``
records and small folders (stale notes, table files' order, figures, provenance counts, failed
runs, fall-backs, missing data, the summary line and banners)."""

import json
import os
import re
from pathlib import Path

from bench.report.html import page as P
from bench.report.html.runs import PageRun
from bench.runs.result import FALLBACK_LIMIT, REPORTED_CLOCK


def run(folder="s/r", status="finished", **kw) -> PageRun:
    kw.setdefault("has_gt", True)
    return PageRun(folder=folder, sequence=kw.pop("sequence", "s"), run="r", status=status,
                   **kw)


def text(html: str) -> str:
    return re.sub(r"<[^>]+>", "", html)


def test_stale_note(tmp_path):
    f = tmp_path / "t.md"
    f.write_text("x")
    os.utime(f, (100.0, 100.0))
    assert P._stale_note(f, 0.0) == ""
    assert P._stale_note(f, 100.0) == ""
    assert P._stale_note(f, 100.0005) == ""  # within the 1 ms tolerance
    note = P._stale_note(f, 100.01)
    assert note.startswith('<p class="stale">Written before the latest run record')
    assert P._stale_note(f, 50.0) == ""


def test_table_files_order(tmp_path):
    for name in ("zeta.md", "pivot.md", "table3.md", "alpha.md", "table_ape.md"):
        (tmp_path / name).write_text("x")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "b.md").write_text("x")
    (tmp_path / "sub" / "a.md").write_text("x")
    got = [str(p.relative_to(tmp_path)) for p in P.table_files(tmp_path)]
    assert got == ["table3.md", "table_ape.md", "pivot.md", "alpha.md", "zeta.md", "sub/a.md",
                   "sub/b.md"]


def test_figures_section(tmp_path):
    figs = tmp_path / "figures"
    assert P._figures_section(figs, 0.0) == (
        "<p>No figures in this folder (<code>bench figures RESULTS_DIR</code> draws them).</p>", 0)
    (figs / "forest").mkdir(parents=True)
    (figs / "zzz").mkdir()
    (figs / "forest" / "b.png").write_bytes(b"BB")
    (figs / "zzz" / "a.png").write_bytes(b"AA")
    (figs / "trajectories.png").write_bytes(b"\x00\x01")
    os.utime(figs / "zzz" / "a.png", (10.0, 10.0))
    html, n = P._figures_section(figs, 20.0)
    assert n == 3
    heads = re.findall(r"<h3>(.*?)</h3>", html)
    assert heads == ["trajectories", "forest", "zzz"]  # known kinds first, in their order
    assert f'<p class="caption">{P.esc(P.FIGURE_KINDS["forest"])}</p>' in html
    assert html.count('<p class="caption">') == 2  # an unknown kind has no caption
    assert 'src="data:image/png;base64,QkI="' in html
    assert 'src="data:image/png;base64,AAE="' in html
    assert 'alt="figures/zzz/a.png"' in html
    assert "<figcaption><code>figures/forest/b.png</code>" in html
    assert html.count('class="stale"') == 1  # only a.png is older than the newest run
    assert P._figures_section(figs, 0.0)[0].count('class="stale"') == 0
    (figs / "empty").mkdir()
    assert P._figures_section(figs / "empty", 0.0)[1] == 0


def test_counts():
    assert P._counts([None, ""]) == "not recorded"
    assert P._counts(["a", "b", "a", None]) == "a (2 runs); b (1 run)"
    assert P._counts(["<x>"]) == "&lt;x&gt; (1 run)"


def test_provenance_empty():
    assert P._provenance_section([]) == "<p>No run records.</p>"


def test_provenance_items():
    meta1 = {"git": {"commit": "0123456789abcdef", "dirty": True},
             "packages": {"doppler-bench": "1.2"}, "date": "2024-05-02",
             "cpu": "Xeon", "cpu_count": 8, "host": "h1", "python": "3.11",
             "timing_lock": "/tmp/lock"}
    meta2 = {"git": {"commit": "fedcba9876543210"}, "date": "2024-01-09", "host": "h2"}
    runs = [run("a", meta=meta1, code_sha256="c" * 40, clock="cpu", threads=1,
                store="/d/x.h5", store_sha256=None, sequence="s1"),
            run("b", meta=meta2, clock=REPORTED_CLOCK, threads=4, store="/d/x.h5",
                store_sha256="abc", sequence="s0"),
            run("c", clock="wall", threads=None, store="/d/<y>.h5", sequence="s2"),
            run("d")]
    html = P._provenance_section(runs)
    items = dict(re.findall(r"<dt>(.*?)</dt><dd>(.*?)</dd>", html))
    assert items["code (git commit)"] == (
        "0123456789ab (uncommitted changes) (1 run); fedcba987654 (1 run)")
    assert items["doppler-bench version"] == "1.2 (1 run)"
    assert items["code hash (loaders, methods, metrics, scoring)"] == "cccccccccccccccc (1 run)"
    assert items["machine"] == ("Xeon, 8 cores, host h1, Python 3.11 (1 run); "
                                "?, ? cores, host h2, Python ? (1 run)")
    assert items["clock"] == (f"cpu time, 1 thread(s) (1 run); {REPORTED_CLOCK} (1 run); "
                              "wall time, 1 thread(s) (1 run)")
    assert items["timing lock"] == "/tmp/lock (1 run); default (1 run)"
    assert items["run dates"] == "2024-01-09 to 2024-05-02"
    rows = re.findall(r"<tr><td><code>(.*?)</code></td><td>(.*?)</td><td><code>(.*?)</code>",
                      html)
    assert rows == [("/d/&lt;y&gt;.h5", "s2", "not recorded"), ("/d/x.h5", "s0, s1", "abc")]
    assert "<h3>Data</h3><table>" in html
    assert f'<p class="caption">{P.esc(P.TIMING_NOTE)}</p>' in html


def test_provenance_without_dates_or_stores():
    html = P._provenance_section([run(meta={"host": "h"})])
    items = dict(re.findall(r"<dt>(.*?)</dt><dd>(.*?)</dd>", html))
    assert items["run dates"] == "not recorded"
    assert items["code (git commit)"] == "not recorded"
    assert items["clock"] == "not recorded"
    assert "<h3>Data</h3><h3>" in html
    assert "<table>" not in html


def test_problems_all_finished():
    assert P._problems_section([run()], {}) == "<p>Every run finished.</p>"


def test_problems_failed_and_broken():
    runs = [run("a", "failed", message="first line\nsecond"), run("b", "broken", message="m<"),
            run("c", "timeout"), run("ok")]
    html = P._problems_section(runs, {})
    assert "<h3>Runs that did not finish (3)</h3>" in html
    assert ('<p class="caption">1 with a broken record (its metrics.json is no valid run '
            "record") in html
    assert ("<tr><td><code>a</code></td><td class=\"failed\">failed</td><td>first line</td>"
            "</tr>") in html
    assert "<td>m&lt;</td>" in html
    assert '<td class="failed">timeout</td><td></td>' in html
    assert "second" not in html
    assert "<code>ok</code>" not in html
    html2 = P._problems_section([run("a", "failed")], {})
    assert 'class="caption"' not in html2
    assert "<h3>Runs that did not finish (1)</h3><table>" in html2


def test_problems_damaged_and_warnings():
    runs = [run("a", damaged=("p1", "p<2")), run("b", damaged=()),
            *[run(f"w{i}", meta={"warnings": ["slow", "odd"] if i == 0 else ["slow"]})
              for i in range(5)]]
    html = P._problems_section(runs, {})
    assert "<h3>Runs with unreadable files (1)</h3>" in html
    assert "<tr><td><code>a</code></td><td>p1</td></tr><tr><td><code>a</code></td><td>p&lt;2" \
           in html
    assert "<h3>Warnings while the runs ran (2)</h3>" in html
    assert "<li>slow <span class=\"caption\">(5 run(s): w0, w1, w2, ...)</span></li>" in html
    assert "<li>odd <span class=\"caption\">(1 run(s): w0)</span></li>" in html
    three = [run(f"v{i}", meta={"warnings": ["x"]}) for i in range(3)]
    assert "(3 run(s): v0, v1, v2)</span>" in P._problems_section(three, {})


def test_problems_fell_back():
    limit = FALLBACK_LIMIT
    high = int(limit * 100) + 5   # replaced+unconverged of 100 registered frames: above
    runs = [run("hi", frames=101, frames_replaced=high - 1, frames_unconverged=1),
            run("lo", frames=101, frames_replaced=0, frames_unconverged=1),
            run("none", frames=None, frames_replaced=2),
            run("f", "failed", frames=10, frames_replaced=5),
            run("clean", frames=50)]
    html = P._problems_section(runs, {})
    assert "<h3>Runs whose frames fell back (3)</h3>" in html
    assert f"Above {100 * limit:g} % (in red)" in html
    assert ('<tr><td><code>hi</code></td><td class="num">' + str(high - 1) +
            '</td><td class="num">1</td><td class="num">100</td>'
            f'<td class="failed">{float(high):.1f} %</td></tr>') in html
    assert ('<tr><td><code>lo</code></td><td class="num">0</td><td class="num">1</td>'
            '<td class="num">100</td><td>1.0 %</td></tr>') in html
    # no frame count: no registered frame, the share over one
    assert ('<tr><td><code>none</code></td><td class="num">2</td><td class="num">0</td>'
            '<td class="num">0</td><td class="failed">200.0 %</td></tr>') in html
    assert "<code>f</code></td><td class=\"num\">" not in html
    assert "<code>clean</code>" not in html


def test_share_at_the_limit_is_not_red():
    frames = 1001
    at = round(FALLBACK_LIMIT * (frames - 1))
    assert at / (frames - 1) == FALLBACK_LIMIT
    html = P._problems_section([run("x", frames=frames, frames_replaced=at)], {})
    assert 'class="failed"' not in html


def test_problems_no_ground_truth_and_coverage():
    runs = [run("g", has_gt=True), run("n<1", has_gt=False), run("f", "failed", has_gt=False)]
    cov = {"data": "ds<", "found": ["a", "b"], "missing": ["c"], "notes": ["note <1>"]}
    html = P._problems_section(runs, cov)
    assert "<h3>Runs without ground truth (in no table)</h3><ul><li><code>n&lt;1</code></li>" \
           "</ul>" in html
    assert "<li><code>f</code></li>" not in html
    assert "<h3>The paper's sequences (ds&lt;)</h3>" in html
    assert "<p>Found (2): a, b</p>" in html
    assert '<p class="failed">Missing (1): c</p>' in html
    assert '<p class="caption">note &lt;1&gt;</p>' in html
    html = P._problems_section([run(has_gt=True)], {"found": [], "data": "d"})
    assert "<p>Found (0): none</p>" in html and "Missing (0): none" in html
    html = P._problems_section([run(has_gt=True)], {"notes": ["only"]})
    assert "<h3>The paper's sequences ()</h3>" in html
    assert "Found" not in html and '<p class="caption">only</p>' in html


def _record(d: Path, metrics=None, failed=None, config=None):
    d.mkdir(parents=True)
    if metrics is not None:
        (d / "metrics.json").write_text(json.dumps(metrics))
    if failed is not None:
        (d / "failed.json").write_text(json.dumps(failed))
    if config is not None:
        (d / "config.yaml").write_text(json.dumps(config))


def test_render_page_summary_banners_and_counts(tmp_path):
    res = tmp_path / "res<1>"
    _record(res / "syn" / "a", failed={"status": "failed", "error": "e"},
            config={"run_key": "k", "sequence": {"name": "s", "display_name": "s (synthetic)"}})
    (res / "syn" / "b").mkdir(parents=True)
    (res / "syn" / "b" / "metrics.json").write_text("[1]")
    (res / "syn" / "b" / "meta.json").write_text("{bad")
    (res / "reproduction.json").write_text(json.dumps({"missing": ["x", "y"], "found": []}))
    page, counts = P.render_page(res)
    n = counts.pop("tables")
    assert counts == {"figures": 0, "runs": 2, "failed": 2, "broken": 1, "damaged": 1}
    assert f"2 run folder(s): 0 finished, 2 not; {n} table(s), 0 figure(s)." in page
    # a failed run is a row of the tables made for the page
    assert "<p>Tables of the folder&#x27;s finished runs, made for this page" in page \
        or "<p>Tables of the folder's finished runs, made for this page" in page
    assert "<strong>Synthetic data.</strong>" in page
    assert '<p class="banner">2 of the paper\'s sequences are missing' in page
    assert "<title>doppler-bench results: res&lt;1&gt;</title>" in page
    assert "<h1>doppler-bench results: res&lt;1&gt;</h1>" in page
    assert f"Folder <code>{P.esc(res)}</code>" in page
    assert f'content="{P._CSP}"' in page
    assert re.search(r"page written \d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00 by", page)


def test_render_page_without_banners_and_unreadable_coverage(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    (res / "reproduction.json").write_text("[]")
    page, counts = P.render_page(res)
    assert 'class="banner"' not in page
    assert counts["broken"] == 0 and counts["damaged"] == 0
    assert (f"{P.esc(res / 'reproduction.json')} is not readable (not a JSON object): the "
            "paper&#x27;s coverage of this folder is unknown") in page
    (res / "reproduction.json").write_text('{"missing": []}')
    page, _ = P.render_page(res)
    assert 'class="banner"' not in page and "not readable" not in page and "XX" not in page


def test_render_page_without_any_table(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", config={"run_key": "k"})  # unfinished: no table at all
    page, counts = P.render_page(res)
    assert counts["tables"] == 0 and counts["failed"] == 1
    assert "<p>No table: no finished run with ground truth.</p>" in page
    assert "made for this page" not in page and "as written" not in page


def test_render_page_tables_written_into_the_folder(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    made = P.render_page(res)[1]["tables"]
    (res / "pivot.md").write_text("| a |\n|---|\n| 1 |\n")
    (res / "sub").mkdir()
    (res / "sub" / "x.md").write_text("| b |\n|---|\n| 2 |\n| 3 |\n")
    os.utime(res / "pivot.md", (1.0, 1.0))
    page, counts = P.render_page(res)
    assert counts["tables"] == made + 2  # one table in each file
    assert "<p>Tables written into this folder, as written:</p>" in page
    assert '<h3 id="pivot">pivot.md</h3><p class="stale">' in page
    assert '<h3 id="x">sub/x.md</h3><div class="scroll">' in page
    assert "No table:" not in page


def test_write_page_refuses_an_empty_or_missing_folder(tmp_path):
    from loaders.errors import DataError

    for folder, said in ((tmp_path / "none", "no such results folder"),
                         (tmp_path, "no run records in this folder")):
        try:
            P.write_page(folder)
        except DataError as err:
            assert said in str(err)
        else:
            raise AssertionError("no error")


def test_write_page_writes_the_page(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    path, counts = P.write_page(res)
    assert path == res / "report.html"
    assert counts["runs"] == 1
    assert path.read_text().startswith("<!DOCTYPE html>")
    other = tmp_path / "out.html"
    assert P.write_page(res, other)[0] == other and other.exists()


def test_table_files_known_names_in_the_pages_order(tmp_path):
    names = ["table3.md", "table4.md", "table5.md", "table.md", "table_ape.md", "pivot.md",
             "fidelity.md"]
    for name in reversed(names):
        (tmp_path / name).write_text("x")
    (tmp_path / "a.md").write_text("x")
    assert [p.name for p in P.table_files(tmp_path)] == [*names, "a.md"]


def test_page_loads_nothing_and_links_its_sections(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", config={"run_key": "k"})
    page, _ = P.render_page(res)
    csp = re.search(r'http-equiv="Content-Security-Policy" content="([^"]*)"', page).group(1)
    rules = {r.split()[0]: r.split()[1:] for r in csp.split("; ")}
    assert rules == {"default-src": ["'none'"], "img-src": ["data:"],
                     "style-src": ["'unsafe-inline'"], "base-uri": ["'none'"],
                     "form-action": ["'none'"]}
    for anchor in ("tables", "figures", "problems", "provenance"):
        assert f'<a href="#{anchor}">' in page
        assert f'<section id="{anchor}"><h2>' in page
    assert "<script" not in page
    assert page.startswith("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">")


def test_made_tables_have_their_titles(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    page, _ = P.render_page(res)
    for title in ("Relative error per segment length (Table III)", "KITTI drift",
                  "Absolute pose error (Tables IV / V)", "Ego-velocity error"):
        assert f"<h3>{title}</h3>" in page


def test_sections_have_no_stray_text_and_exact_captions(tmp_path):
    bad = [run("a", "failed", message="m"), run("b", "broken", message="n"),
           run("c", damaged=("p",)),
           *[run(f"w{i}", meta={"warnings": ["one", "two"]}, has_gt=False) for i in range(4)],
           run("fb", frames=11, frames_replaced=1), run("fc", frames=11, frames_unconverged=2)]
    html = P._problems_section(bad, {"data": "d", "missing": ["m1", "m2"]})
    assert "XX" not in html
    assert "(4 run(s): w0, w1, w2, ...)" in html
    assert ("1 with a broken record (its metrics.json is no valid run record: shown as a failed "
            "row in every table, never as a result; `bench run` runs it again)") in html
    assert ("A finished run keeps its row (its figures come from metrics.json), but without "
            "readable trajectory files its per-segment errors, and so its significance marks "
            "and figures, are missing.</p><table><thead><tr><th>run folder</th><th>problem</th>"
            "</tr></thead>") in html
    assert ("Replaced: the registration gave no usable transform and the step was replaced by "
            "the motion prior (the identity without a seed); not converged: the registration "
            "stopped before converging and its last iterate was kept.") in html
    assert ("table.</p><table><thead><tr><th>run folder</th><th>replaced</th>"
            "<th>not converged</th><th>registered frames</th><th>share</th></tr></thead>") in html
    # only "missing" recorded: both lines are shown
    assert "<p>Found (0): none</p>" in html
    assert '<p class="failed">Missing (2): m1, m2</p>' in html
    prov = P._provenance_section([
        run("x", meta={"git": {"dirty": True}, "date": "2024-03-01"}, store="/s1",
            clock="cpu", threads=1),
        run("y", meta={"date": "2024-01-01", "cpu": "c"}, store="/s2", clock="cpu"),
        run("z", meta={"date": "2024-02-01"})])
    assert "XX" not in prov
    items = dict(re.findall(r"<dt>(.*?)</dt><dd>(.*?)</dd>", prov))
    assert items["code (git commit)"] == "not recorded"  # dirty without a commit: no code
    assert items["run dates"] == "2024-01-01 to 2024-03-01"
    assert items["machine"].startswith("?, ? cores, host ?, Python ? (2 runs)")
    assert "<th>SHA-256 of the store</th>" in prov
    figs = tmp_path / "figures"
    (figs / "boxplots").mkdir(parents=True)
    (figs / "boxplots" / "a.png").write_bytes(b"A")
    (figs / "boxplots" / "b.png").write_bytes(b"B")
    assert "XX" not in P._figures_section(figs, 0.0)[0]


def test_stale_note_text(tmp_path):
    f = tmp_path / "t.md"
    f.write_text("x")
    os.utime(f, (1.0, 1.0))
    assert P._stale_note(f, 5.0) == (
        '<p class="stale">Written before the latest run record of this folder: it may not show '
        "every run (<code>bench table</code> / <code>bench figures</code> rewrite it).</p>")


def test_tables_section_of_a_failed_run(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    long = "This long caption sentence is shared by both written tables of the folder."
    (res / "pivot.md").write_text(f"| a |\n|---|\n| 1 |\n\n{long}\n")
    (res / "sub").mkdir()
    (res / "sub" / "x.md").write_bytes(f"| b \xff |\n|---|\n| 2 |\n\n{long}\n".encode("latin-1"))
    html, n = P._tables_section(res, 0.0)
    assert "XX" not in html
    assert n == 4 + 2  # the four metrics' tables (each with the failed row) and the two files
    assert "No table" not in html
    assert "<th>b \ufffd</th>" in html
    assert 'given once, under &quot;pivot.md&quot; above.' in html
    # the made tables share the marking rule: said once, under the first made table
    assert 'under &quot;Relative error per segment length (Table III)&quot; above.' in html
    assert ("<p>Tables of the folder's finished runs, made for this page: every figure with its "
            "95 % confidence interval [low, high]; bold / underlined read from the printed "
            "intervals alone (the caption states the rule: check any mark against the "
            "cells).</p>") in html
    empty = tmp_path / "e"
    _record(empty / "s" / "a", config={"run_key": "k"})
    assert P._tables_section(empty, 0.0) == (
        "<p>No table: no finished run with ground truth.</p>", 0)


def test_render_page_counts_figures_banner_and_provenance(tmp_path, monkeypatch):
    res = tmp_path / "r"
    _record(res / "s" / "fin", metrics={"sequence": "s (synthetic)", "method": "m",
                                        "seed": None, "frames": 3, "frames_scored": 3,
                                        "diverged": False, "clock": "cpu", "threads": 1})
    (res / "figures" / "speed").mkdir(parents=True)
    png = res / "figures" / "speed" / "a.png"
    png.write_bytes(b"P")
    os.utime(png, (1.0, 1.0))
    (res / "reproduction.json").write_text('{"missing": ["q"]}')
    page, counts = P.render_page(res)
    assert (counts["figures"], counts["failed"], counts["runs"]) == (1, 0, 1)
    assert "1 run folder(s): 1 finished, 0 not;" in page
    assert 'class="stale"' in page  # the figure is older than the run record
    assert "XX" not in page
    assert ('<p class="banner"><strong>Synthetic data.</strong> Sequences marked (synthetic) '
            "were made by this repository&#x27;s generator") in page or (
        "were made by this repository's generator to imitate the paper's sequences; they are "
        "not the paper's data.</p>") in page
    assert ('<p class="banner">1 of the paper\'s sequences are missing from this reproduction '
            "(listed under Failed runs and missing data).</p>") in page
    assert "<dt>clock</dt><dd>cpu time, 1 thread(s) (1 run)</dd>" in page
    monkeypatch.chdir(res)
    page, _ = P.render_page(Path("."))
    assert "<title>doppler-bench results: r</title>" in page


def test_render_page_of_a_folder_without_runs(tmp_path):
    page, counts = P.render_page(tmp_path)
    assert counts["runs"] == 0
    assert "<p>No run records.</p>" in page


def test_write_page_never_replaces_a_file_it_did_not_write(tmp_path):
    from bench.guard import Refused

    res = tmp_path / "r"
    _record(res / "s" / "a", failed={"status": "failed"}, config={"run_key": "k"})
    mine = tmp_path / "notes.html"
    mine.write_text("my notes")
    try:
        P.write_page(res, mine)
    except Refused as err:
        assert "exists and is not a report page this command wrote" in str(err)
    else:
        raise AssertionError("replaced a file it did not write")
    assert mine.read_text() == "my notes"
    first, _ = P.write_page(res)
    again, _ = P.write_page(res)  # its own page is replaced
    assert first == again and again.read_text().startswith("<!DOCTYPE html>")


def test_written_tables_without_made_ones_and_exact_texts(tmp_path):
    res = tmp_path / "r"
    _record(res / "s" / "a", config={"run_key": "k"})  # unfinished: no made table
    (res / "pivot.md").write_text("| a |\n|---|\n| 1 |\n")
    page, counts = P.render_page(res)
    assert counts["tables"] == 1
    assert "No table" not in page and "XX" not in page
    html = P._problems_section([run(meta={"warnings": ["w"]})], {})
    assert html.endswith("(1 run(s): s/r)</span></li></ul>")
    empty = tmp_path / "empty"
    empty.mkdir()
    from loaders.errors import DataError
    try:
        P.write_page(empty)
    except DataError as err:
        assert str(err) == (
            f"{empty}: no run records in this folder (no metrics.json, failed.json or run "
            "config.yaml under it); expected a results folder of `bench run` or "
            "`bench reproduce`")
    else:
        raise AssertionError("no error")
