"""`bench report`: one self-contained HTML page per results folder, opened in headless Chromium
(it fails, never skips, without it: `make system-deps` installs it). The page shows every table
and figure without a console error, loads nothing from the network, and shows a store named
``<script>alert(1)</script>`` as text; the failed runs and the provenance are on it."""

import json
import re

import pytest

from bench.cli import main
from bench.report.figures.draw import make_figures
from bench.report.html.markdown import inline, markdown_html
from bench.report.html.page import PAGE_TABLES, render_page, table_files
from bench.report.tables.paper import write_tables
from bench.runs.folders import write_failure
from bench.runs.job import Job, sequence_folder
from bench.runs.plan import plan
from bench.runs.progress import run_jobs
from conftest import constant_twist_sequence
from helpers_browser import open_page
from loaders.store import write_store

EVIL = "<script>alert(1)</script>"
#: what the page's DOM says about itself (evaluated in Chromium after the load)
PROBE = """JSON.stringify({
  tables: document.querySelectorAll('#tables table').length,
  marked: document.querySelectorAll('#tables table strong, #tables table u').length,
  images: Array.from(document.images).map(i => [i.complete, i.naturalWidth]),
  scripts: document.scripts.length,
  links: document.querySelectorAll('link, iframe, object, embed').length,
  text: document.body.innerText,
})"""


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    """Three runs on a store whose sequence is named EVIL (a path separator in it), a failed
    run whose message holds markup, the folder's table and figures."""
    root = tmp_path_factory.mktemp("report")
    seq = constant_twist_sequence(n_frames=30, n_points=1200, noise_m=0.02, max_range_m=60)
    seq.name = EVIL
    store = write_store(seq, root / "evil.h5")
    out = root / "results"
    jobs = [Job(store=store, method=m, seed=s, out_root=out)
            for m, s in (("doppler", None), ("icp-p2p", True), ("icp-p2p", False))]
    assert all(o.status == "done" for o in run_jobs(plan(jobs), executor="local"))
    write_failure(out / sequence_folder(EVIL) / "dicp_seed", None,
                  "DataError: <b>bold</b> problem in evil.h5")
    meta = out / sequence_folder(EVIL) / "doppler" / "meta.json"
    meta.write_text(json.dumps({**json.loads(meta.read_text()),
                                "warnings": ["frame 4: 1 point(s) <to> register"]}))
    write_tables(out)
    make_figures(out)
    return out


def _bench(args, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["bench", *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    captured = capsys.readouterr()
    return exit_.value.code, captured.out + captured.err


def test_a_sequence_name_with_a_slash_stays_one_folder(results):
    folders = [p for p in results.iterdir() if p.is_dir() and p.name != "figures"]
    assert [p.name for p in folders] == [sequence_folder(EVIL)]
    assert "/" not in sequence_folder(EVIL) and sequence_folder("..") == "_.."


def test_the_page_renders_every_table_and_figure_in_chromium(results, capsys, monkeypatch):
    code, out = _bench(["report", str(results)], capsys, monkeypatch)
    assert code == 0, out
    page = results / "report.html"
    assert f"wrote {page}" in " ".join(out.split())
    pngs = sorted((results / "figures").rglob("*.png"))
    assert len(pngs) >= 4
    seen = open_page(page, PROBE)
    dom = json.loads(seen["value"])
    assert seen["console_errors"] == []
    assert seen["requests"] == [] and seen["dialogs"] == []
    # the four metrics' tables made for the page (PAGE_TABLES, with intervals), then every
    # table file as written
    md_tables = sum(markdown_html(p.read_text())[1] for p in table_files(results))
    assert (results / "table.md") in table_files(results)
    assert dom["tables"] == len(PAGE_TABLES) + md_tables
    assert dom["marked"] >= 2  # best bold, second underlined, as in table.md
    assert len(dom["images"]) == len(pngs)
    assert all(complete and width > 100 for complete, width in dom["images"])
    assert dom["scripts"] == 0 and dom["links"] == 0
    assert EVIL in dom["text"]  # the store's name shows as text
    assert "<b>bold</b> problem" in dom["text"] and "failed" in dom["text"]
    assert "frame 4: 1 point(s) <to> register" in dom["text"]  # a run's warning, as text


def test_the_page_loads_nothing_and_escapes_every_name(results):
    page, counts = render_page(results)
    files = sum(markdown_html(p.read_text())[1] for p in table_files(results))
    assert counts == {"tables": len(PAGE_TABLES) + files, "figures": counts["figures"],
                      "runs": 4, "failed": 1, "broken": 0, "damaged": 0}
    assert EVIL not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert "<b>bold</b>" not in page
    # nothing that loads: no script, no external URL; a policy that forbids any load
    assert "<script" not in page.lower()
    assert not re.search(r"(src|href)=\"(https?:)?//", page)
    assert "default-src 'none'" in page and "img-src data:" in page
    # provenance: code version, the store's hash, the machine and the clock
    sha = json.loads(next(results.rglob("metrics.json")).read_text())  # a finished run
    assert sha["clock"] == "cpu" and "cpu time, 1 thread(s)" in page
    assert "SHA-256 of the store" in page and "code (git commit)" in page
    assert "How times were taken" in page


def test_markdown_marks_become_tags_only_around_escaped_text():
    assert inline("**0.083** / <u>0.051</u>") == "<strong>0.083</strong> / <u>0.051</u>"
    assert inline("<img src=x onerror=alert(1)>") == "&lt;img src=x onerror=alert(1)&gt;"
    assert inline("**<script>x</script>**") == "<strong>&lt;script&gt;x&lt;/script&gt;</strong>"
    html, n = markdown_html("# T\n\n| a | b |\n|---|---|\n| **1** | 2 |\n\nnote `x`\n- item\n")
    assert n == 1 and "<h3>T</h3>" in html and "<code>x</code>" in html and "<li>" in html
    assert '<td class="num"><strong>1</strong></td>' in html


def test_a_folder_without_tables_gets_table_three_made_for_the_page(results, tmp_path):
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(results, copy, ignore=shutil.ignore_patterns("table.*", "figures",
                                                                 "report.html"))
    assert table_files(copy) == []
    page, counts = render_page(copy)
    assert counts["tables"] == len(PAGE_TABLES) and counts["figures"] == 0
    assert "made for this page" in page and "bench figures RESULTS_DIR" in page
    assert "Relative error per segment length" in page and "KITTI drift" in page


def test_a_missing_folder_is_exit_2(tmp_path, capsys, monkeypatch):
    code, out = _bench(["report", str(tmp_path / "nope")], capsys, monkeypatch)
    # the option checks name the argument before the command runs (bench.options)
    assert code == 2 and "RESULTS_DIR" in out and "nope: not found" in out
