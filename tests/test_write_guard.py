"""The one write rule end to end through the command line (issue 46): a run folder holding
another run is never replaced (``--force`` included), a user's own table, figure or page of
the harness's file name is left as it is, nothing is written into a run folder by another
command, every --out / --name passes one name check, and an output is checked before the
long work. Exit 2 with one message naming the path, no traceback, everything as it was."""

import os
import shutil
import time
from pathlib import Path

import pytest
from helpers_cli import bench_main
from test_guard import digest

from bench import guard
from conftest import SAMPLE_STORE, constant_twist_sequence
from loaders.errors import DataError
from loaders.scan import MemorySequence
from loaders.store import write_store


@pytest.fixture(scope="module")
def twist(tmp_path_factory):
    """A small store, a results folder with the harness's doppler run and icp-p2p (seed) run
    in it, and two different TUM trajectories (the doppler run's and the icp run's)."""
    root = tmp_path_factory.mktemp("write")
    base = constant_twist_sequence(n_frames=30, n_points=800, noise_m=0.02, max_range_m=70)
    store = write_store(MemorySequence("twist", base.sensor, list(base), base.ground_truth),
                        root / "twist.h5")
    from bench.runs.plan import run_single

    results = root / "results"
    for method, seed, folder in (("doppler", False, "doppler"),
                                 ("icp-p2p", True, "icp-p2p_seed")):
        run_single(method, store, seed, out=results / "twist" / folder)
    tums = [Path(shutil.copy(results / "twist" / name / "est_tum.txt", root / f"{name}.tum"))
            for name in ("doppler", "icp-p2p_seed")]
    return store, results, tums


@pytest.fixture
def work(twist, tmp_path):
    """A copy of the results folder to change."""
    _, results, _ = twist
    return Path(shutil.copytree(results, tmp_path / "results"))


# -- run folders: another run is never the command's own --------------------------------------

@pytest.mark.parametrize("args, holds", [
    (["--method", "icp-p2p", "--seed"], "method 'doppler'"),  # another method
    (["--method", "doppler", "-p", "tau_spatial_m=2.0"], "parameters"),  # other parameters
])
def test_run_never_replaces_another_run_in_its_out_folder(twist, work, monkeypatch, capsys,
                                                          args, holds):
    store, _, _ = twist
    run = work / "twist" / "doppler"
    before = digest(run)
    link = work / "link"
    link.symlink_to(run, target_is_directory=True)
    for out in (run, link):
        for extra in ([], ["--force"]):
            code, text = bench_main(monkeypatch, capsys, "run", *args, "--data", store, "--out",
                                    out, "--executor", "local", *extra)
            assert code == 2 and "holds another run" in text and holds in text, text
            assert "Traceback" not in text
    assert digest(run) == before


def test_run_never_replaces_a_run_of_another_store_path(twist, work, monkeypatch, capsys):
    """A copy of the store at another path (the same content): another run's input, refused
    with or without --force; the store changed in place at its own path runs again."""
    store, _, _ = twist
    run = work / "twist" / "doppler"
    before = digest(run)
    copy = shutil.copy(store, work.parent / "copy.h5")
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data",
                                copy, "--out", run, "--executor", "local", *extra)
        assert code == 2 and "holds another run" in text and str(store) in text, text
    assert digest(run) == before
    moved = work.parent / "moved"
    moved.mkdir()
    changed = moved / "twist.h5"
    base = constant_twist_sequence(n_frames=30, n_points=800, noise_m=0.02, max_range_m=70)
    write_store(MemorySequence("twist", base.sensor, list(base), base.ground_truth), changed)
    out = work / "twist" / "again"
    code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data",
                            changed, "--out", out, "--executor", "local")
    assert code == 0, text
    other = constant_twist_sequence(n_frames=30, n_points=800, noise_m=0.02, max_range_m=70,
                                    seed=7)
    write_store(MemorySequence("twist", other.sensor, list(other), other.ground_truth), changed)
    stamp = (out / "metrics.json").stat().st_mtime_ns
    code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data",
                            changed, "--out", out, "--executor", "local")
    assert code == 0 and (out / "metrics.json").stat().st_mtime_ns != stamp, text


def test_run_never_replaces_a_run_of_the_other_seed_option(twist, work, monkeypatch, capsys):
    store, _, _ = twist
    run = work / "twist" / "icp-p2p_seed"
    before = digest(run)
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "run", "--method", "icp-p2p", "--no-seed",
                                "--data", store, "--out", run, "--executor", "local", *extra)
        assert code == 2 and "seed option True" in text, text
    assert digest(run) == before


def test_force_re_does_the_commands_own_run(twist, work, monkeypatch, capsys):
    store, _, _ = twist
    run = work / "twist" / "doppler"
    stamp = (run / "metrics.json").stat().st_mtime_ns
    code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data", store,
                            "--out", run, "--executor", "local", "--force")
    assert code == 0, text
    assert (run / "metrics.json").stat().st_mtime_ns != stamp


def test_score_never_replaces_a_run_of_another_trajectory(twist, work, monkeypatch, capsys):
    store, _, (first, second) = twist
    args = ["score", "--store", store, "--name", "mine", "--out", work]
    code, text = bench_main(monkeypatch, capsys, *args[:1], first, *args[1:])
    assert code == 0, text
    mine = work / "twist" / "mine"
    before = digest(mine)
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "score", second, *args[1:], *extra)
        assert code == 2 and "holds another run" in text and str(first) in text, text
    assert digest(mine) == before
    code, text = bench_main(monkeypatch, capsys, "score", first, *args[1:], "--force")
    assert code == 0, text  # its own run, again


# -- derived files: only the harness's own are replaced ----------------------------------------

def test_table_never_overwrites_a_users_table(work, tmp_path, monkeypatch, capsys):
    mine = work / "table.md"
    mine.write_text("my own table")
    code, text = bench_main(monkeypatch, capsys, "table", work)
    assert code == 2 and "table.md" in text and "not a table" in text, text
    assert mine.read_text() == "my own table" and not (work / "table.csv").exists()
    out = tmp_path / "tables"
    out.mkdir()
    (out / "table.tex").write_text("% mine")
    code, text = bench_main(monkeypatch, capsys, "table", work, "--out", out)
    assert code == 2 and "table.tex" in text, text
    assert sorted(p.name for p in out.iterdir()) == ["table.tex"]
    (out / "table.tex").unlink()
    for _ in range(2):  # its own tables: made again
        code, text = bench_main(monkeypatch, capsys, "table", work, "--out", out)
        assert code == 0, text
    assert all(guard.derived(out / f"table.{fmt}") for fmt in ("md", "tex", "csv"))
    (out / "table.csv").write_text("edited by hand")  # no longer what the harness wrote
    code, text = bench_main(monkeypatch, capsys, "table", work, "--out", out)
    assert code == 2 and "table.csv" in text, text
    assert (out / "table.csv").read_text() == "edited by hand"


def test_figures_and_report_never_overwrite_a_users_plot(work, tmp_path, monkeypatch, capsys):
    out = tmp_path / "figs"
    code, text = bench_main(monkeypatch, capsys, "figures", work, "--out", out)
    assert code == 0, text
    pngs = sorted(out.rglob("*.png"))
    pdfs = sorted(out.rglob("*.pdf"))
    assert pngs and pdfs and all(guard.derived(p) for p in pngs + pdfs)
    for victim in (pngs[0], pdfs[-1]):
        victim.write_bytes(b"\x89PNG\r\n\x1a\nmy own plot")
        code, text = bench_main(monkeypatch, capsys, "figures", work, "--out", out)
        assert code == 2 and victim.name in text and "not a figure" in text, text
        assert victim.read_bytes() == b"\x89PNG\r\n\x1a\nmy own plot"
        victim.unlink()
    assert bench_main(monkeypatch, capsys, "figures", work, "--out", out)[0] == 0
    # the report's figures: a user's PNG in RESULTS/figures is left as it is
    figures = work / "figures"
    code, text = bench_main(monkeypatch, capsys, "report", work)
    assert code == 0, text
    png = sorted(figures.rglob("*.png"))[0]
    png.write_bytes(b"mine")
    os.utime(work / "twist" / "doppler" / "metrics.json")  # figures older than a record
    time.sleep(0.01)
    code, text = bench_main(monkeypatch, capsys, "report", work)
    assert code == 2 and png.name in text and "not a figure" in text, text
    assert png.read_bytes() == b"mine"
    page = work / "report.html"
    page.write_text("<html>my page</html>")
    code, text = bench_main(monkeypatch, capsys, "report", work)
    assert code == 2 and "not a report page" in text and "drew" not in text, text
    assert page.read_text() == "<html>my page</html>"


def test_figures_into_a_folder_whose_subfolder_is_a_file(work, tmp_path, monkeypatch, capsys):
    out = tmp_path / "d"
    out.mkdir()
    (out / "trajectories").write_text("mine")
    code, text = bench_main(monkeypatch, capsys, "figures", work, "--out", out)
    assert code == 2 and "trajectories is a file" in text and "Traceback" not in text, text
    assert (out / "trajectories").read_text() == "mine"
    code, text = bench_main(monkeypatch, capsys, "report", work, "--out",
                            out / "trajectories" / "page.html")
    assert code == 2 and "trajectories is a file" in text and "drew" not in text, text


# -- nothing written into a run folder by another command --------------------------------------

def test_no_command_writes_into_a_run_folder(twist, work, monkeypatch, capsys):
    store, _, _ = twist
    run = work / "twist" / "doppler"
    before = digest(run)
    folder = _npy_folder(work.parent)
    for args in (["convert", "npy-frames", folder, "--period", "0.1", "--out", run / "s.h5"],
                 ["export", store, "--format", "ros1", "--out", run / "s.bag"],
                 ["report", work, "--out", run / "page.html"],
                 ["table", work, "--out", run / "tables"],
                 ["figures", work, "--out", run],
                 ["run", "--method", "doppler", "--data", store, "--out", run / "sub"],
                 ["score", run / "est_tum.txt", "--store", store, "--name", "n", "--out", run],
                 ["synth", "loop", "--frames", "3", "--out", run / "s.h5"],
                 ["speed", "--out", run, "--sizes", "100", "--no-memory"]):
        code, text = bench_main(monkeypatch, capsys, *args)
        assert code == 2 and "run folder" in text and "Traceback" not in text, (args, text)
    code, text = bench_main(monkeypatch, capsys, "table", run)  # printed, not written there
    assert code == 0 and "printed, not written" in text, text
    assert digest(run) == before


def test_a_scored_run_folder_is_a_run_folder_too(twist, work, monkeypatch, capsys):
    """The output-folder check knows bench score's runs as well as bench run's."""
    store, _, (first, _) = twist
    code, text = bench_main(monkeypatch, capsys, "score", first, "--store", store, "--name",
                            "ext", "--out", work)
    assert code == 0, text
    scored = work / "twist" / "ext"
    assert guard.run_kind(scored) == guard.EXTERNAL
    with pytest.raises(DataError, match=r"is a run folder \(made by bench score\)"):
        guard.output_folder(scored)
    before = digest(scored)
    code, text = bench_main(monkeypatch, capsys, "figures", work, "--out", scored)
    assert code == 2 and "run folder" in text, text
    assert digest(scored) == before


def _npy_folder(root: Path) -> Path:
    from helpers_public import write_npy_frames

    base = constant_twist_sequence(n_frames=5, n_points=200)
    return write_npy_frames(root / "frames", [s.points for s in base],
                            [s.doppler for s in base], base.stamps, base.ground_truth.poses)


# -- names and paths ---------------------------------------------------------------------------

def test_every_out_and_name_passes_one_name_check(twist, tmp_path, monkeypatch, capsys):
    store, _, (first, _) = twist
    folder = _npy_folder(tmp_path)
    long = "x" * 300
    cases = [
        (["convert", "npy-frames", folder, "--period", "0.1", "--out", tmp_path / long],
         "at most 239 bytes"),
        (["convert", "npy-frames", folder, "--period", "0.1", "--name", long,
          "--out", tmp_path / "s.h5"], "--name"),
        (["run", "--method", "doppler", "--data", store, "--out", tmp_path / long / "r"],
         "at most 239 bytes"),
        (["score", first, "--store", store, "--name", long, "--out", tmp_path / "r"],
         "--name"),
        (["score", first, "--store", store, "--name", "ok", "--out", tmp_path / long],
         "at most 239 bytes"),
        (["export", store, "--format", "ros1", "--out", ""], "empty"),
        (["table", tmp_path, "--out", ""], "empty"),
        (["inspect", store, "--plot", tmp_path / (long + ".png")], "at most 239 bytes"),
        (["synth", "--suite", "synthetic-ci", "--data-dir", tmp_path / long],
         "at most 239 bytes"),
        # a name the file system takes (250 bytes) but not with the atomic write's temporary
        (["synth", "loop", "--frames", "3", "--out", tmp_path / ("z" * 246 + ".h5")],
         "at most 239 bytes"),
        (["score", first, "--store", store, "--name", "", "--out", tmp_path / "r"],
         "one path component"),
    ]
    for args, says in cases:
        code, text = bench_main(monkeypatch, capsys, *args)
        assert code == 2 and says in text and "Traceback" not in text, (args, text)
        assert "OSError" not in text and "ValueError" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames"]


def test_guard_writes_check_the_name_too(tmp_path):
    """The guard's own writers turn a name too long into one DataError (the API path)."""
    with pytest.raises(DataError, match="cannot"):
        guard.write_text(tmp_path / ("y" * 300) / "f.txt", "x")
    with pytest.raises(DataError, match="at most 239 bytes"):
        guard.check_out(tmp_path / ("y" * 300))


def test_reproduce_refuses_a_file_as_out_at_once(tmp_path, monkeypatch, capsys):
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    t0 = time.perf_counter()
    code, text = bench_main(monkeypatch, capsys, "reproduce", "--out", notes, "--data-dir",
                            tmp_path / "data", "--synthetic-only", "--executor", "local")
    assert code == 2 and "is a file" in text, text
    assert time.perf_counter() - t0 < 10
    assert not (tmp_path / "data").exists() and notes.read_text() == "mine"
    out = tmp_path / "paper"
    out.mkdir()
    (out / "table5.md").write_text("my table5")  # a user's: neither replaced nor removed
    code, text = bench_main(monkeypatch, capsys, "reproduce", "--out", out, "--data-dir",
                            tmp_path / "data", "--synthetic-only", "--executor", "local")
    assert code == 2 and "table5.md" in text and "not a table" in text, text
    assert (out / "table5.md").read_text() == "my table5" and not (tmp_path / "data").exists()


# -- the guard's writers -----------------------------------------------------------------------

def test_the_guards_writers_replace_only_their_own(tmp_path):
    mine = tmp_path / "notes.md"
    mine.write_text("mine")
    with pytest.raises(DataError, match="exists and is not a table"):
        guard.write_text(mine, "x", guard.derived, "a table")
    with pytest.raises(DataError, match="exists"):
        guard.write_text(mine, "x")  # no owner: only a new file
    with pytest.raises(DataError, match="is not"):
        guard.remove(mine, guard.derived)
    assert mine.read_text() == "mine"
    ours = guard.write_text(tmp_path / "t.md", "a", guard.derived, "a table")
    assert guard.derived(ours)
    guard.write_text(ours, "b", guard.derived, "a table")  # its own: made again
    assert ours.read_text() == "b" and guard.derived(ours)
    ours.write_text("edited")
    assert not guard.derived(ours)
    with pytest.raises(DataError):  # every file checked before any is written
        guard.write_texts({tmp_path / "a.md": "a", mine: "b"}, guard.derived, "a table")
    assert not (tmp_path / "a.md").exists()


def test_calibrate_write_force_never_replaces_another_store(tmp_path, monkeypatch, capsys):
    """--force replaces a store bench calibrate wrote, never a converted store."""
    store = shutil.copy(SAMPLE_STORE, tmp_path / "S.h5")
    other = Path(shutil.copy(SAMPLE_STORE, tmp_path / "other.h5"))
    before = digest(other)
    args = ["calibrate", store, "--frames", "30", "--bootstrap", "10"]
    code, text = bench_main(monkeypatch, capsys, *args, "--write", other, "--force")
    assert code == 2 and "not a store bench calibrate wrote" in text, text
    assert digest(other) == before
    mine = tmp_path / "cal.h5"
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, *args, "--write", mine, *extra)
        assert code == 0, text


def test_a_suite_never_replaces_a_file_of_its_name(tmp_path, monkeypatch, capsys):
    """`bench synth --suite`: a store of the suite's file name that is not a synthetic store
    (a user's file) is left as it is; the suite's own stores are made."""
    import loaders.synthetic.suite as suite

    first = suite.SuiteEntry("A", "A", suite.SPARSE, "campus", "radar-sparse", 4, 1)
    monkeypatch.setitem(suite.SUITES, "tiny", [first])
    mine = tmp_path / "tiny" / f"{first.name}.h5"
    mine.parent.mkdir()
    mine.write_text("mine")
    code, text = bench_main(monkeypatch, capsys, "synth", "--suite", "tiny", "--data-dir",
                            tmp_path)
    assert code == 2 and "not a synthetic store" in text and "Traceback" not in text, text
    assert mine.read_text() == "mine"
    mine.unlink()
    code, text = bench_main(monkeypatch, capsys, "synth", "--suite", "tiny", "--data-dir",
                            tmp_path)
    assert code == 0 and guard.is_synthetic_store(mine), text


def test_speed_and_an_experiment_check_their_files_before_any_work(twist, tmp_path,
                                                                   monkeypatch, capsys):
    """A user's own speed.csv / table.md in the output folder: refused at once, before any
    timing or run (no run folder made)."""
    store, _, _ = twist
    out = tmp_path / "speed"
    out.mkdir()
    (out / "speed.csv").write_text("mine")
    t0 = time.perf_counter()
    code, text = bench_main(monkeypatch, capsys, "speed", "--out", out, "--sizes", "100",
                            "--no-memory")
    assert code == 2 and "speed.csv" in text, text
    assert time.perf_counter() - t0 < 10 and (out / "speed.csv").read_text() == "mine"
    results = tmp_path / "exp_results"
    results.mkdir()
    (results / "table.md").write_text("mine")
    exp = tmp_path / "exp.yaml"
    exp.write_text(f"name: x\nout: {results}\nsequences: [{{path: {store}}}]\n"
                   "methods: [{name: doppler}]\n")
    code, text = bench_main(monkeypatch, capsys, "run", exp, "--executor", "local")
    assert code == 2 and "table.md" in text, text
    assert sorted(p.name for p in results.iterdir()) == ["table.md"]


def test_a_users_text_naming_the_project_is_not_the_harnesss(tmp_path):
    """Only a figure's metadata or a page carries the mark: a user's notes.md that mentions
    doppler-bench is not a derived file the harness may replace."""
    notes = tmp_path / "table.md"
    notes.write_text(f"my notes on {guard.MARK}\n")
    assert not guard.derived(notes)
    with pytest.raises(DataError, match="exists and is not a table"):
        guard.write_text(notes, "x", guard.derived, "a table")
    page = tmp_path / "report.html"
    page.write_text(f"<!-- {guard.MARK} -->")
    assert guard.derived(page)
