"""The loader table as the one place a loader is declared: the dataset catalogue (`bench
datasets`, the manual's datasets page and the README's short table), `bench convert LOADER`
built from each loader's Options model, dataset configs validated by the same model, loaders
listed before their module exists, and one message for a missing or half-extracted dataset
folder."""

import shlex

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from bench.cli import app
from bench.data.catalogue import (
    BEGIN,
    LOADERS_BEGIN,
    PAGE,
    README,
    SUMMARY_BEGIN,
    page_block,
    render_loader_sections,
    render_markdown,
    render_summary,
)
from bench.data.convert import loader_command
from loaders.errors import DataError
from loaders.layout import require_paths
from loaders.options import cli_flag
from loaders.registry import LOADERS, LoaderEntry, catalogue
from loaders.store import StoreSequence

runner = CliRunner()


def test_catalogue_lists_the_public_doppler_datasets_and_the_papers():
    rows = catalogue()
    text = " ".join(r.dataset for r in rows)
    for name in ("NTU4DRadLM", "Campus", "Doppler-ICP CARLA", "NumPy frames", "Snail-Radar",
                 "View-of-Delft", "ColoRadar", "HeLiPR", "ROS bag", "Aeva Aeries I tunnels"):
        assert name in text, name
    snail = [r for r in rows if r.name == "snail-radar"]
    assert {r.sensor.split()[1] for r in snail} == {"Eagle", "ARS548"}
    assert {r.sensor_class for r in snail} == {"Semi-Dense 4D Radar", "Sparse 4D Radar"}
    for r in rows:  # every row says everything the catalogue promises
        for field in ("dataset", "sensor", "sensor_class", "licence", "published_at", "layout",
                      "example"):
            assert getattr(r, field), (r.name, field)
        assert r.example.startswith(f"bench convert {r.name} "), r.example
        assert r.doppler_kind in ("radial", "ego-compensated")
    assert next(r for r in rows if r.name == "helipr").doppler_kind == "ego-compensated"
    assert "never released" in next(r for r in rows if "tunnels" in r.dataset).licence
    assert "not" in next(r for r in rows if r.name == "campus").published_at


def test_catalogue_examples_use_options_the_loaders_have():
    """Each example command parses against its loader's generated command (loaders whose module
    is not there yet are skipped here; their rows are checked once they exist)."""
    for row in catalogue():
        entry = LOADERS[row.name]
        if not entry.available:
            continue
        command = loader_command(entry)
        args = shlex.split(row.example)[3:]
        ctx = command.make_context(row.name, args, resilient_parsing=True)
        assert ctx.params["out"] is not None, row.example
        flags = {o for p in command.params for o in getattr(p, "opts", [])}
        used = [a for a in args if a.startswith("--")]
        assert set(used) <= flags, (row.name, set(used) - flags)


def test_datasets_page_and_readme_table_are_generated_from_the_loader_table():
    block = page_block(PAGE.read_text(), BEGIN)
    assert block is not None, "docs/datasets.md lacks the <!-- datasets --> markers"
    assert block == render_markdown(), \
        "docs/datasets.md out of date: run python -m bench.data.catalogue"
    for row in catalogue():
        assert row.example in block
    assert "never released by Aeva" in block and "Campus** recordings are not" in block
    sections = page_block(PAGE.read_text(), LOADERS_BEGIN)
    assert sections == render_loader_sections(), \
        "docs/datasets.md's loader sections out of date: run python -m bench.data.catalogue"
    summary = page_block(README.read_text(), SUMMARY_BEGIN)
    assert summary == render_summary(), \
        "README's dataset table out of date: run python -m bench.data.catalogue"
    assert summary.count("\n") == len(catalogue()) + 1  # header, rule, one line per row


def test_each_loader_has_a_section_with_every_option_of_its_command():
    """One section per loader: its datasets' layouts and commands, and each option of
    `bench convert LOADER` (from its Options model) but the four every loader shares."""
    sections = render_loader_sections()
    for name, entry in LOADERS.items():
        part = sections.split(f"(loader `{name}`)", 1)[1].split("\n### ", 1)[0]
        for row in entry.rows():
            assert row.layout in part and row.example in part, name
        if not entry.available:
            continue
        command = loader_command(entry)
        for p in command.params:
            flags = set(getattr(p, "opts", ())) - {"--out", "--start", "--frames", "--stride"}
            if p.param_type_name == "option" and flags:
                assert any(f"`{f}" in part for f in flags), (name, flags)


def test_bench_datasets_lists_every_row_even_without_the_loader_module(monkeypatch):
    ghost = LoaderEntry("ghost", "a loader not written yet", "loaders.no_such_module", "Ghost",
                        dataset="Ghost Dataset", sensor="s", sensor_class="Sparse 4D Radar",
                        licence="l", published_at="p", layout="x/",
                        example="bench convert ghost x --out y.h5")
    monkeypatch.setitem(LOADERS, "ghost", ghost)
    assert not ghost.available
    res = runner.invoke(app, ["datasets"])
    assert res.exit_code == 0, res.output
    assert "Ghost Dataset" in res.output and "(loader not installed)" in res.output
    assert "bench convert ghost x --out y.h5" in res.output
    for r in catalogue():
        assert r.dataset in res.output
    res = runner.invoke(app, ["convert", "--help"])
    assert res.exit_code == 0 and "ghost" in res.output and "[unavailable]" in res.output
    res = runner.invoke(app, ["convert", "ghost", "x", "--out", "y.h5"])
    assert isinstance(res.exception, DataError)
    assert "unavailable" in str(res.exception) and "loaders.no_such_module" in str(res.exception)


def test_every_available_loader_gets_a_command_from_its_options_model():
    for entry in LOADERS.values():
        if not entry.available:
            continue
        Loader = entry.load_class()
        command = loader_command(entry)
        opts = {o for p in command.params for o in getattr(p, "opts", [])}
        for name, field in Loader.Options.model_fields.items():
            assert field.description, (entry.name, name)  # the help text
            flag = cli_flag(name, field)
            if flag:
                assert f"--{flag.partition('/')[0]}" in opts, (entry.name, name)
        assert {"--out", "--start", "--frames", "--stride", "--name"} <= opts
        inputs = command.params[0]
        assert inputs.param_type_name == "argument" and inputs.required
        assert (inputs.nargs == -1) == Loader.many_inputs


def test_generated_help_keeps_the_old_option_names():
    res = runner.invoke(app, ["convert", "npy-frames", "--help"])
    assert res.exit_code == 0
    for text in ("--period SECONDS", "--stamps-from-gt", "--kind radar|lidar",
                 "--associate order|time", "--gt PATH", "--out STORE.h5", "--stride K"):
        assert text in res.output, text
    res = runner.invoke(app, ["convert", "ntu4dradlm", "--help"])
    for text in ("--doppler-field", "--time-offset SECONDS", "--max-gap SECONDS", "--extrinsic",
                 "--uncovered keep|trim|error", "INPUT..."):
        assert text in res.output, text
    res = runner.invoke(app, ["convert", "aeva", "--help"])
    assert "--no-gt " in res.output and "--no-no-gt" not in res.output
    assert "--kind lidar|radar" in res.output


def _frames(folder, n=6, points=40, seed=0):
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    pts = [rng.uniform(-20, 20, (points, 3)) for _ in range(n)]
    for i, p in enumerate(pts):
        np.save(folder / f"frame_{i:03d}.npy", p)
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(0, 2, points))
    (folder / "gt.txt").write_text("".join(f"{0.1 * i:.1f} {i} 0 0 0 0 0 1\n" for i in range(n)))
    return pts


def test_a_real_conversion_through_the_generated_command(tmp_path):
    pts = _frames(tmp_path / "f")
    out = tmp_path / "s.h5"
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--period", "0.05",
                              "--kind", "lidar", "--name", "tiny", "--start", "1", "--frames",
                              "4", "--out", str(out)])
    assert res.exit_code == 0, res.output
    st = StoreSequence(out)
    try:
        assert (st.name, len(st), st.sensor.kind) == ("tiny", 4, "lidar")
        assert st.sensor.period_s == pytest.approx(0.05)
        np.testing.assert_allclose(st.stamps, [0.05, 0.10, 0.15, 0.20])
        np.testing.assert_allclose(st.scan(0).points, pts[1], atol=1e-5)
        np.testing.assert_allclose(st.ground_truth.poses[0][:3, 3], [1, 0, 0])
    finally:
        st.close()
    # the model's constraints are the command's: a period must be positive, kinds are listed
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--period", "-1",
                              "--out", str(tmp_path / "bad.h5")])
    assert isinstance(res.exception, DataError) and "--period" in str(res.exception)
    res = runner.invoke(app, ["convert", "npy-frames", str(tmp_path / "f"), "--kind", "sonar",
                              "--out", str(tmp_path / "bad.h5")])
    assert res.exit_code == 2 and "sonar" in res.output
    assert not (tmp_path / "bad.h5").exists()


def test_dataset_config_options_are_validated_by_the_loader_model(tmp_path):
    from bench.data.datasets import read_dataset_config

    _frames(tmp_path / "raw")
    cfg = {"name": "Tiny", "display_name": "Tiny", "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(tmp_path / "raw"),
           "raw_files": ["frame_000.npy", "gt.txt"], "options": {"period_s": 0.1, "gt": "gt.txt"},
           "store": "Tiny.h5"}
    path = tmp_path / "Tiny.yaml"
    path.write_text(yaml.safe_dump(cfg))
    seq = read_dataset_config(path).open()
    assert seq.name == "Tiny" and len(seq) == 6
    assert seq.provenance["gt"] == str(tmp_path / "raw" / "gt.txt")  # relative to raw_dir
    path.write_text(yaml.safe_dump({**cfg, "options": {"period": 0.1}}))
    with pytest.raises(DataError, match=r"unknown option 'period' \(did you mean 'period_s'"):
        read_dataset_config(path).open()


def test_a_missing_or_half_extracted_folder_is_one_message(tmp_path):
    with pytest.raises(DataError, match="folder not found .*never downloads"):
        require_paths(tmp_path / "nope", ["a.bag"], "NTU4DRadLM")
    root = tmp_path / "seq"
    (root / "frames").mkdir(parents=True)
    (root / "gt_odom.txt").write_text("")
    with pytest.raises(DataError) as err:
        require_paths(root, ["gt_odom.txt", "frames/", "*.bag", "calib/"], "X", "SEQ/*.bag")
    message = str(err.value)
    assert "missing frames/, *.bag, calib/" in message and "gt_odom.txt" not in message
    assert message.count("\n") == 0 and "expected layout: SEQ/*.bag" in message
    (root / "frames" / "0.bin").write_bytes(b"")
    (root / "a.bag").write_bytes(b"")
    (root / "calib").mkdir()
    (root / "calib" / "t.txt").write_text("")
    assert require_paths(root, ["gt_odom.txt", "frames/", "*.bag", "calib/"]) == root


def test_bench_convert_dataset_names_what_is_missing(tmp_path, capsys, monkeypatch):
    from bench.cli import main

    cfg = {"name": "Gone", "display_name": "Gone", "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(tmp_path / "raw"),
           "raw_files": ["frame_000.npy", "gt.txt"], "store": "Gone.h5"}
    (tmp_path / "raw").mkdir()
    (tmp_path / "raw" / "gt.txt").write_text("0 0 0 0 0 0 0 1\n")
    path = tmp_path / "Gone.yaml"
    path.write_text(yaml.safe_dump(cfg))
    monkeypatch.setattr("sys.argv", ["bench", "convert", "dataset", str(path), "--data-dir",
                                     str(tmp_path / "data")])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    assert exit_.value.code == 2
    assert "incomplete" in out.err and "missing frame_000.npy" in out.err
    assert "Traceback" not in out.err + out.out
