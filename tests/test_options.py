"""Options and environment variables are checked before any work (bench/options.py): the cases
of issue 46 each pinned, and every numeric option of every command (convert's loaders
included) with a range of its own."""

from __future__ import annotations

import textwrap

import pytest
import typer
from strategies import bench, tree_digest

from bench import options
from bench.cli import app
from conftest import constant_twist_sequence
from loaders.registry import LOADERS
from loaders.store import write_store


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=12, n_points=300, max_range_m=60)
    return write_store(seq, tmp_path_factory.mktemp("store") / "twist.h5")


def _all_numeric_params():
    from bench.data.convert import loader_command

    command = typer.main.get_command(app)
    found = list(options.numeric_params(command))
    for name, entry in LOADERS.items():
        found += [(("convert", name, *p), q) for p, q in
                  options.numeric_params(loader_command(entry))]
    return found


def test_every_numeric_option_has_a_range():
    found = _all_numeric_params()
    assert len(found) > 60  # the walk reached convert's loader commands
    missing = sorted({f"{' '.join(path)} --{p.name}" for path, p in found
                      if options.number_rule(path[-1] if path else "", p.name) is None
                      and (path[-1], p.name) not in options.OWN_CHECKS})
    assert not missing, f"numeric options without a rule in bench/options.py: {missing}"


def _one_error(code, text, *says):
    lines = [line for line in text.splitlines() if line.startswith("error:")]
    assert code == 2 and len(lines) == 1 and "Traceback" not in text, text
    for s in says:
        assert s in lines[0], text


@pytest.mark.parametrize("value", ["-1", "nan", "inf", "1e9"])
def test_calibrate_min_speed_is_checked_before_the_store_is_read(store, value):
    out = bench(["calibrate", store, "--min-speed", value])
    _one_error(out.code, out.text, f"--min-speed {float(value)!r}", "a speed in m/s")
    assert "estimating on frames" not in out.text  # nothing ran


def _stores_without_raw_doppler(folder):
    from loaders.scan import MemorySequence, Scan, SensorInfo

    seq = constant_twist_sequence(n_frames=12, n_points=300, max_range_m=60)
    sensor = SensorInfo("lidar", seq.sensor.period_s, model="test",
                        doppler_kind="ego-compensated")
    comp = write_store(MemorySequence("comp", sensor, list(seq), seq.ground_truth,
                                      {"loader": "helipr"}), folder / "comp.h5")
    plain = write_store(MemorySequence("plain", seq.sensor,
                                       [Scan(s.stamp, s.points, None) for s in seq],
                                       seq.ground_truth, {"loader": "ntu4dradlm"}),
                        folder / "plain.h5")
    return comp, plain


def test_commands_that_use_doppler_refuse_a_store_without_raw_doppler_as_run_does(tmp_path):
    comp, plain = _stores_without_raw_doppler(tmp_path)
    for store, says in ((comp, "needs the raw radial Doppler velocity, but the store's Doppler "
                               "is ego-compensated"),
                        (plain, "needs Doppler, but the store has no Doppler values; convert "
                                "it again naming the Doppler field (bench convert ntu4dradlm "
                                "... --doppler-field NAME)")):
        out = bench(["calibrate", store])
        _one_error(out.code, out.text, f"{store}: calibration from Doppler {says}")
        assert "only 0 frames" not in out.text and "estimating on" not in out.text
        out = bench(["figures", "--pair", store, "2", "--out", tmp_path / "f"])
        _one_error(out.code, out.text, f"{store}: Doppler Correspondence's pairs {says}")
        run = bench(["run", "--method", "doppler", "--data", store, "--out", tmp_path / "r"])
        _one_error(run.code, run.text, f"{store}: doppler {says}")
    assert not (tmp_path / "f").exists() and not (tmp_path / "r").exists()


def test_speed_scale_refuses_absurd_pose_counts(tmp_path):
    out = bench(["speed", "--scale", "--poses", "2000000000", "--out", tmp_path / "s"])
    _one_error(out.code, out.text, "--poses '2000000000'", "200,000")
    assert not (tmp_path / "s").exists()


def _plugin(folder, name, body):
    (folder / f"{name}.py").write_text(textwrap.dedent(body))
    return name


@pytest.fixture
def plugin_dir(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    from methods import registry

    registry.load_plugins("")  # the built-in methods only, for the tests after this one


def test_a_plugin_with_a_syntax_error_is_one_error_naming_it(plugin_dir, tmp_path):
    name = _plugin(plugin_dir, "broken_syntax_plugin", "def oops(:\n")
    out = bench(["list"], env={"DOPPLER_BENCH_METHODS": name})
    _one_error(out.code, out.text, "DOPPLER_BENCH_METHODS", name, "SyntaxError")


def test_a_plugin_cannot_shadow_a_built_in_method(plugin_dir, store, tmp_path):
    name = _plugin(plugin_dir, "shadowing_plugin", """
        from methods.icp import PointToPointIcp

        class Fake(PointToPointIcp):
            name = "doppler"

        METHODS = [Fake]
        """)
    before = tree_digest(tmp_path)
    out = bench(["run", "--method", "doppler", "--data", store, "--out", tmp_path / "r"],
                env={"DOPPLER_BENCH_METHODS": name})
    _one_error(out.code, out.text, "DOPPLER_BENCH_METHODS", f"{name}.Fake is named 'doppler'",
               "cannot replace a built-in method")
    assert tree_digest(tmp_path) == before
    from methods import registry

    assert registry.get_method("doppler").__name__ == "DopplerCorrespondence"


def test_a_good_plugin_still_registers_and_is_forgotten_when_unset(plugin_dir):
    name = _plugin(plugin_dir, "good_plugin_opts", """
        from methods.icp import PointToPointIcp

        class Mine(PointToPointIcp):
            name = "mine-opts"

        METHODS = [Mine]
        """)
    out = bench(["list"], env={"DOPPLER_BENCH_METHODS": name})
    assert out.code == 0 and "mine-opts" in out.text, out.text
    out = bench(["list"], env={"DOPPLER_BENCH_METHODS": None})
    assert out.code == 0 and "mine-opts" not in out.text, out.text


def test_a_timing_lock_in_a_missing_folder_names_the_variable(store, tmp_path):
    lock = tmp_path / "missing" / "timing.lock"
    out = bench(["run", "--method", "doppler", "--data", store, "--out", tmp_path / "r",
                 "--executor", "local"], env={"DOPPLER_BENCH_TIMING_LOCK": str(lock)})
    _one_error(out.code, out.text, f"DOPPLER_BENCH_TIMING_LOCK='{lock}': the folder "
               f"{lock.parent} does not exist")
    assert out.text.count("DOPPLER_BENCH_TIMING_LOCK=") == 1  # said once
    assert not (tmp_path / "r").exists()


def test_the_timing_lock_check_in_methods_names_the_variable(tmp_path):
    from loaders.errors import DataError
    from methods import timing

    for bad, says in ((str(tmp_path), "is a folder"), ("", "expected the path"),
                      (str(tmp_path / "no" / "x.lock"), "does not exist")):
        with pytest.raises(DataError, match=timing.TIMING_LOCK_ENV) as err:
            timing.check_lock_path(bad)
        assert says in str(err.value)
    timing.check_lock_path(str(tmp_path / "ok.lock"))  # a new file in a folder of ours
    assert not (tmp_path / "ok.lock").exists()  # checking creates nothing


@pytest.mark.parametrize("args, says", [
    (["inspect", ""], "expected a path, got an empty one"),
    (["run", "--method", "doppler", "--data", "a\0b"], "NUL byte"),
    (["run", "--method", "doppler", "--data", "/nonexistent/x.h5"], "--data /nonexistent"),
    (["table", "x" * 300], "at most 255 bytes"),
    (["run", "--method", "doppler", "--data", "S", "-p", "tau_spatial_m=.nan"],
     "--param 'tau_spatial_m=.nan': expected finite numbers"),
    (["run", "--method", "doppler", "--data", "S", "-p", "=3"], "--param expects key=value"),
    (["synth", "--option", "speed=[1, .inf]"], "--option 'speed=[1, .inf]'"),
    (["calibrate", "S", "--bootstrap", "5"], "'--bootstrap'"),
    (["view", "S", "--stride", "0"], "'--stride'"),
    (["figures", "--pair", "S", "-2"], "--pair -2: expected a frame index"),
    (["table", ".", "--lengths", "8,inf"], "--lengths '8,inf'"),
    (["convert", "npy-frames", ".", "--period", "-0.1", "--out", "o.h5"], "--period -0.1"),
])
def test_bad_options_are_one_error_naming_them(store, args, says, tmp_path):
    args = [store if a == "S" else a for a in args]
    before = tree_digest(tmp_path)
    out = bench(args)
    _one_error(out.code, out.text, says)
    assert tree_digest(tmp_path) == before


def test_the_frame_limit_variable_is_checked_before_any_command(tmp_path):
    out = bench(["table", tmp_path], env={"BENCH_MAX_FRAME_MB": "nan"})
    _one_error(out.code, out.text, "BENCH_MAX_FRAME_MB='nan'")
