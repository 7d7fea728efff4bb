"""The output guard (bench.guard) and every command that writes through it: exit 2 with one
message naming the path, nothing deleted or overwritten that the command did not make, with
and without --force."""

import hashlib
import os
import shutil
from pathlib import Path

import pytest
from helpers_cli import bench_main

from bench import guard
from conftest import SAMPLE_STORE, constant_twist_sequence
from loaders.errors import DataError
from loaders.scan import MemorySequence
from loaders.store import write_store


def digest(path: Path) -> str:
    """A folder's or file's content (names and bytes), to show nothing changed."""
    path = Path(path)
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    h = hashlib.sha256()
    for p in files:
        h.update(str(p.relative_to(path) if path.is_dir() else p.name).encode())
        h.update(p.read_bytes())
    return h.hexdigest()


# -- the rules --------------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["", " ", ".", "..", "a/b", "../../outside", "a\\b", "/abs"])
def test_a_name_is_one_path_component(name):
    with pytest.raises(DataError, match="expected one folder name"):
        guard.one_component(name)


def test_a_name_of_one_component_passes():
    assert guard.one_component("kiss-ext.v2") == "kiss-ext.v2"
    assert guard.one_component("..a") == "..a"  # dots inside a name are no path step


def test_an_input_is_never_an_output_by_any_path(tmp_path):
    src = tmp_path / "d" / "s.h5"
    src.parent.mkdir()
    src.write_bytes(b"x")
    link = tmp_path / "link.h5"
    link.symlink_to(src)
    hard = tmp_path / "hard.h5"
    os.link(src, hard)
    for out in (src, tmp_path / "d" / ".." / "d" / "s.h5", link, hard):
        with pytest.raises(DataError, match="is an input of this command"):
            guard.not_an_input(out, [src])
    for out in (tmp_path / "d", tmp_path):
        with pytest.raises(DataError, match="holds an input of this command"):
            guard.not_an_input(out, [src])
    guard.not_an_input(tmp_path / "d" / "other.h5", [src, None])  # a sibling is fine


def test_replaceable_needs_force_and_a_thing_of_its_own(tmp_path):
    import h5py

    from loaders.store import FORMAT_NAME

    mine = tmp_path / "s.h5"
    with h5py.File(mine, "w") as f:
        f.attrs["format"] = FORMAT_NAME
    other = tmp_path / "notes.h5"
    other.write_text("my notes")
    foreign = tmp_path / "foreign.h5"  # an HDF5 file of someone else's: not a store
    with h5py.File(foreign, "w") as f:
        f["x"] = [1.0, 2.0]
    with pytest.raises(DataError, match="is a file that is not a store this command wrote"):
        guard.replaceable(foreign, True, guard.is_store, "a store")
    assert not guard.is_store(foreign) and guard.is_store(mine)
    assert guard.replaceable(tmp_path / "new.h5", False, guard.is_store, "a store") is False
    with pytest.raises(DataError, match=r"exists \(a store\); give another --out or --force"):
        guard.replaceable(mine, False, guard.is_store, "a store")
    with pytest.raises(DataError, match=r"give another --write \(it is not replaced\)"):
        guard.replaceable(mine, None, guard.is_store, "a store", "--write")
    assert guard.replaceable(mine, True, guard.is_store, "a store") is True
    for force in (False, True, None):
        with pytest.raises(DataError, match="is a file that is not a store this command wrote"):
            guard.replaceable(other, force, guard.is_store, "a store")
    assert other.read_text() == "my notes"


def test_a_rosbag2_folder_is_recognised_only_with_nothing_else_in_it(tmp_path):
    bag = tmp_path / "b"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (bag / "b_0.mcap").write_bytes(b"\x89MCAP")
    assert guard.is_rosbag2_folder(bag)
    (bag / "notes.txt").write_text("mine")
    assert not guard.is_rosbag2_folder(bag)
    assert not guard.is_rosbag2_folder(tmp_path / "absent")


def _run_folder(path: Path, external: bool) -> Path:
    path.mkdir(parents=True)
    (path / "config.yaml").write_text("method: {name: x}\n" + ("external: {}\n" if external
                                                                 else "run_key: k\n"))
    (path / "metrics.json").write_text("{}")
    return path


def test_run_kinds_and_the_run_folder_rule(tmp_path):
    harness = _run_folder(tmp_path / "r" / "seq" / "icp-p2p_seed", external=False)
    ext = _run_folder(tmp_path / "r" / "seq" / "mine", external=True)
    assert guard.run_kind(harness) == guard.HARNESS and guard.run_kind(ext) == guard.EXTERNAL
    assert guard.run_kind(tmp_path) is None
    before = digest(harness)
    with pytest.raises(DataError, match=r"holds a run made by bench run \(harness\); bench "
                       "score does not replace it: choose another name, or --force"):
        guard.run_folder(harness, guard.EXTERNAL, False)
    said = []
    guard.run_folder(harness, guard.EXTERNAL, True, say=said.append, ask="--replace-run")
    assert said and "replacing the harness run" in said[0] and "--replace-run" in said[0]
    with pytest.raises(DataError, match=r"bench run does not replace it: choose another name$"):
        guard.run_folder(ext, guard.HARNESS, None)  # bench run has no such option
    guard.run_folder(ext, guard.EXTERNAL, False)  # its own kind: the command decides
    other = tmp_path / "stuff"
    other.mkdir()
    (other / "a.txt").write_text("x")
    for force in (False, True):
        with pytest.raises(DataError, match="holds files that are not a run's"):
            guard.run_folder(other, guard.EXTERNAL, force)
    with pytest.raises(DataError, match="outside the results root"):
        guard.run_folder(tmp_path / "r" / "seq" / ".." / ".." / ".." / "x", guard.EXTERNAL,
                         root=tmp_path / "r")
    assert digest(harness) == before


def test_derived_files_and_folders(tmp_path):
    page = tmp_path / "report.html"
    page.write_text(f"<title>{guard.MARK} results</title>")
    guard.regenerated_file(page, guard.has_mark, "a page")  # its own: made again
    foreign = tmp_path / "README.md"
    foreign.write_text("mine")
    with pytest.raises(DataError, match="exists and is not a page this command wrote"):
        guard.regenerated_file(foreign, guard.has_mark, "a page")
    with pytest.raises(DataError, match="is a folder"):
        guard.regenerated_file(tmp_path, guard.has_mark, "a page")
    with pytest.raises(DataError, match="is a file; expected a folder"):
        guard.output_folder(foreign)
    run = _run_folder(tmp_path / "seq" / "doppler", external=False)
    with pytest.raises(DataError, match="is a run folder"):
        guard.output_folder(run)
    guard.output_folder(tmp_path / "new")


# -- every writer ------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def twist(tmp_path_factory):
    """A small store, the harness's doppler and icp-p2p (seed) runs on it, and a TUM file of
    the doppler run's trajectory."""
    from bench.runs.job import Job, run_job

    root = tmp_path_factory.mktemp("guard")
    base = constant_twist_sequence(n_frames=30, n_points=800, noise_m=0.02, max_range_m=70)
    store = write_store(MemorySequence("twist", base.sensor, list(base), base.ground_truth),
                        root / "twist.h5")
    results = root / "results"
    for method, seed in (("doppler", None), ("icp-p2p", True)):
        outcome = run_job(Job(store=store, method=method, seed=seed, out_root=results))
        assert outcome.status == "done", outcome.message
    tum = root / "est.txt"
    shutil.copy(results / "twist" / "doppler" / "est_tum.txt", tum)
    return store, results, tum


def test_score_names_stay_inside_the_results_root_and_never_replace_a_harness_run(
        twist, tmp_path, monkeypatch, capsys):
    store, results, tum = twist
    before = digest(results)
    code, text = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name",
                            "../../outside-results", "--out", results)
    assert code == 2 and "one path component" in text and "Traceback" not in text, text
    assert not (results.parent.parent / "outside-results").exists()
    code, text = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name",
                            "icp-p2p_seed", "--out", results)
    assert code == 2 and "run folder of the harness's icp-p2p run" in text, text
    assert digest(results) == before  # the ICP run and everything else as it was
    work = tmp_path / "results"
    shutil.copytree(results, work)
    shutil.copytree(work / "twist" / "doppler", work / "twist" / "custom")  # a harness run
    harness = digest(work / "twist" / "custom")
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name",
                                "custom", "--out", work, *extra)
        assert code == 2 and "holds a harness run" in text, text
    assert digest(work / "twist" / "custom") == harness
    code, text = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name",
                            "custom", "--out", work, "--replace-run")
    assert code == 0 and "replac" in text, text
    assert guard.run_kind(work / "twist" / "custom") == guard.EXTERNAL
    # scoring a run's own trajectory file into that run's folder: its input, refused
    own = work / "twist" / "mine"
    code, _ = bench_main(monkeypatch, capsys, "score", tum, "--store", store, "--name", "mine",
                         "--out", work)
    assert code == 0
    code, text = bench_main(monkeypatch, capsys, "score", own / "est_tum.txt", "--store", store,
                            "--name", "mine", "--out", work, "--force")
    assert code == 2 and "holds an input of this command" in text, text


def test_run_never_writes_into_a_folder_of_other_files_or_onto_its_store(
        twist, tmp_path, monkeypatch, capsys):
    store, _, _ = twist
    folder = tmp_path / "docs"
    folder.mkdir()
    (folder / "thesis.tex").write_text("mine")
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data",
                                store, "--out", folder, *extra)
        assert code == 2 and "holds files that are not a run's" in text, text
    assert sorted(p.name for p in folder.iterdir()) == ["thesis.tex"]
    near = tmp_path / "near"
    near.mkdir()
    copy = shutil.copy(store, near / "s.h5")
    code, text = bench_main(monkeypatch, capsys, "run", "--method", "doppler", "--data", copy,
                            "--out", near)
    assert code == 2 and "holds an input of this command" in text, text


def test_an_experiment_never_replaces_a_score_nor_writes_into_a_folder_of_other_files(
        twist, tmp_path, monkeypatch, capsys):
    """The experiment's run folders RESULTS/twist/doppler: a `bench score` run there is not
    replaced (with or without --force: bench run has no such choice); a folder of other files
    there is left as it is; exit 2 naming the folder."""
    store, results, tum = twist
    out = tmp_path / "exp_results"
    exp = tmp_path / "exp.yaml"
    exp.write_text(f"name: x\nout: {out}\nsequences: [{{path: {store}}}]\n"
                   "methods: [{name: doppler}]\n")
    scored = _run_folder(out / "twist" / "doppler", external=True)
    before = digest(scored)
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, "run", exp, "--executor", "local", *extra)
        assert code == 2 and "holds a run made by bench score (external)" in text, text
    assert digest(scored) == before
    shutil.rmtree(scored)
    scored.mkdir()
    (scored / "plot.png").write_bytes(b"mine")
    code, text = bench_main(monkeypatch, capsys, "run", exp, "--executor", "local")
    assert code == 2 and "holds files that are not a run's" in text, text
    assert (scored / "plot.png").read_bytes() == b"mine"


def test_calibrate_write_never_overwrites_its_input_or_another_file(
        tmp_path, monkeypatch, capsys):
    store = shutil.copy(SAMPLE_STORE, tmp_path / "S.h5")
    before = digest(store)
    args = ["calibrate", store, "--frames", "30", "--bootstrap", "10"]
    for extra in ([], ["--force"]):
        code, text = bench_main(monkeypatch, capsys, *args, "--write", store, *extra)
        assert code == 2 and "never writes onto its own input" in text, text
    assert digest(store) == before
    notes = tmp_path / "notes.h5"
    notes.write_text("mine")
    code, text = bench_main(monkeypatch, capsys, *args, "--write", notes)
    assert code == 2 and "exists; give another path, or --force" in text, text
    code, text = bench_main(monkeypatch, capsys, *args, "--write", notes, "--force")
    assert code == 2 and "not a store bench calibrate wrote" in text, text
    assert notes.read_text() == "mine"


def _npy_folder(tmp_path) -> Path:
    from helpers_public import write_npy_frames

    base = constant_twist_sequence(n_frames=5, n_points=200)
    poses = base.ground_truth.poses
    return write_npy_frames(tmp_path / "frames", [s.points for s in base],
                            [s.doppler for s in base], base.stamps, poses)


def test_convert_replaces_only_a_store_and_only_with_force(tmp_path, monkeypatch, capsys):
    folder = _npy_folder(tmp_path)
    args = ["convert", "npy-frames", folder, "--period", "0.1"]
    out = tmp_path / "s.h5"
    assert bench_main(monkeypatch, capsys, *args, "--out", out)[0] == 0
    before = digest(out)
    code, text = bench_main(monkeypatch, capsys, *args, "--out", out)
    assert code == 2 and "exists (a store); give another --out or --force" in text, text
    assert digest(out) == before
    assert bench_main(monkeypatch, capsys, *args, "--out", out, "--force")[0] == 0
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    code, text = bench_main(monkeypatch, capsys, *args, "--out", notes, "--force")
    assert code == 2 and "not a store this command wrote" in text, text
    gt = folder / "gt.txt"
    gt_before = gt.read_text()
    code, text = bench_main(monkeypatch, capsys, *args, "--gt", gt, "--out", gt, "--force")
    assert code == 2 and "is an input of this command" in text, text
    assert gt.read_text() == gt_before and notes.read_text() == "mine"


def test_table_figures_and_report_write_only_their_own_files(twist, tmp_path, monkeypatch,
                                                             capsys):
    _, results, _ = twist
    work = tmp_path / "results"
    shutil.copytree(results, work)
    run = work / "twist" / "doppler"
    before = digest(run)
    code, text = bench_main(monkeypatch, capsys, "table", work, "--out", run)
    assert code == 2 and "is a run folder" in text, text
    code, text = bench_main(monkeypatch, capsys, "figures", work, "--out", run / "metrics.json")
    assert code == 2 and "is a file; expected a folder" in text, text
    code, text = bench_main(monkeypatch, capsys, "report", work, "--out", run / "metrics.json")
    assert code == 2 and "inside a run folder" in text and "drew" not in text, text
    assert digest(run) == before
    assert bench_main(monkeypatch, capsys, "report", work)[0] == 0
    assert bench_main(monkeypatch, capsys, "report", work)[0] == 0  # its own page: made again
    assert guard.has_mark(work / "report.html")


def test_inspect_plots_next_to_the_store_and_never_onto_an_input(tmp_path, monkeypatch,
                                                                 capsys):
    store = shutil.copy(SAMPLE_STORE, tmp_path / "loop.h5")
    before = digest(store)
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    code, text = bench_main(monkeypatch, capsys, "inspect", store)
    assert code == 0, text
    plot = tmp_path / "loop_speed.png"
    assert plot.exists() and guard.has_mark(plot) and not (elsewhere / "results").exists()
    assert bench_main(monkeypatch, capsys, "inspect", store)[0] == 0  # its own plot: again
    code, text = bench_main(monkeypatch, capsys, "inspect", store, "--plot", store)
    assert code == 2 and "is an input of this command" in text, text
    photo = tmp_path / "photo.png"
    photo.write_bytes(b"\x89PNG\r\n\x1a\nmine")
    code, text = bench_main(monkeypatch, capsys, "inspect", store, "--plot", photo)
    assert code == 2 and "not a speed plot this command wrote" in text, text
    assert photo.read_bytes() == b"\x89PNG\r\n\x1a\nmine" and digest(store) == before


def test_a_results_folder_that_is_a_file_is_one_message_naming_it(
        twist, tmp_path, monkeypatch, capsys):
    """`--out` naming an existing file (or a path through one): `bench score` and `bench run`
    stop with one message naming that file, exit 2, and leave it as it was (was: an OSError
    "Not a directory" from deep inside the writer)."""
    store, _, tum = twist
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    for args in (["score", tum, "--store", store, "--name", "mine", "--out", notes],
                 ["run", "--method", "doppler", "--data", store, "--out", notes / "sub"]):
        code, text = bench_main(monkeypatch, capsys, *args)
        assert code == 2 and f"{notes}: is a file, expected a folder of results" in text, text
        assert "Traceback" not in text and "Errno" not in text
    assert notes.read_text() == "mine"


def test_view_never_writes_onto_its_store_another_file_or_into_a_run_folder(
        twist, tmp_path, monkeypatch, capsys):
    """`bench view --out`: onto its own store (it replaced the store with a recording), onto a
    file that is not a rerun recording, onto a folder or into a run folder: one message,
    exit 2, everything as it was; a recording it wrote is made again."""
    store, results, _ = twist
    copy = Path(shutil.copy(store, tmp_path / "s.h5"))
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    run = results / "twist" / "doppler"
    before = digest(run)
    folder = tmp_path / "recordings"
    folder.mkdir()
    for out, says in ((copy, "is an input of this command"),
                      (notes, "is not a rerun recording this command wrote"),
                      (folder, "is a folder"),
                      (run / "view.rrd", "inside a run folder")):
        code, text = bench_main(monkeypatch, capsys, "view", copy, "--run", run, "--out", out,
                                "--stride", "10")
        assert code == 2 and says in text and "Traceback" not in text, text
    assert guard.is_store(copy) and notes.read_text() == "mine" and digest(run) == before
    rrd = tmp_path / "v.rrd"
    for _ in range(2):
        code, text = bench_main(monkeypatch, capsys, "view", copy, "--out", rrd, "--stride",
                                "10")
        assert code == 0 and guard.is_recording(rrd), text


def test_synth_makes_its_own_store_again_but_never_replaces_a_converted_one(
        twist, tmp_path, monkeypatch, capsys):
    """`bench synth --out S.h5`: a store synth made is made again; a store converted from a
    recording (real data: its provenance is not synthetic) is left as it is (it was replaced
    by a synthetic one without a word), as is any other file."""
    store, _, _ = twist
    real = Path(shutil.copy(store, tmp_path / "real.h5"))
    before = digest(real)
    code, text = bench_main(monkeypatch, capsys, "synth", "loop", "--frames", "3", "--out", real)
    assert code == 2 and "is not a synthetic store" in text, text
    assert digest(real) == before
    mine = tmp_path / "syn.h5"
    for frames in ("3", "4"):
        code, text = bench_main(monkeypatch, capsys, "synth", "loop", "--frames", frames,
                                "--out", mine)
        assert code == 0 and guard.is_synthetic_store(mine), text
    assert not guard.is_synthetic_store(real)
