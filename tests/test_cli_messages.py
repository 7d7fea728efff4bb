"""What a new user trips over on the command line: conflicting options, silent no-ops,
misspellings and an unscorable segment length are each answered with one clear line (and the
right exit code) before any job runs."""

import numpy as np
import pytest
import yaml
from helpers_cli import run_bench as _bench
from typer.testing import CliRunner

from bench.cli import app
from conftest import constant_twist_sequence
from loaders.store import write_store


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=30, n_points=800, max_range_m=60)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def _experiment(tmp_path, store, **extra):
    path = tmp_path / "e.yaml"
    path.write_text(yaml.safe_dump({"name": "e", "out": str(tmp_path / "out"),
                                    "sequences": [{"path": str(store), "name": "twist"}],
                                    "methods": [{"name": "doppler"}], **extra}))
    return path


def test_single_run_options_beside_an_experiment_are_refused(store, tmp_path, capsys,
                                                             monkeypatch):
    exp = _experiment(tmp_path, store)
    for extra in (["--method", "icp-p2p"], ["--no-seed"], ["-p", "tau_doppler=3"]):
        code, out = _bench(["run", str(exp), *extra], capsys, monkeypatch)
        assert code == 2 and "would be ignored" in out and "e.yaml" in out, out
    assert not (tmp_path / "out").exists()  # nothing ran


def test_no_seed_on_a_method_without_a_guess_says_so(store, tmp_path, capsys, monkeypatch):
    code, out = _bench(["run", "--method", "doppler", "--data", str(store), "--no-seed",
                        "--out", str(tmp_path / "r")], capsys, monkeypatch)
    assert code == 0 and "doppler takes no initial guess: --no-seed changes nothing" in out


def test_a_segment_length_longer_than_the_path_is_an_error_before_any_job(
        store, tmp_path, capsys, monkeypatch):
    exp = _experiment(tmp_path, store, lengths_m=[100])  # the path is ~24 m
    code, out = _bench(["run", str(exp)], capsys, monkeypatch)
    assert code == 2 and out.count("too short for the shortest segment length 100 m") == 1
    assert not (tmp_path / "out").exists()
    # some lengths too long: a warning, the run goes on and those cells stay empty
    exp = _experiment(tmp_path, store, lengths_m=[8, 100])
    code, out = _bench(["run", str(exp)], capsys, monkeypatch)
    assert code == 0 and "no segments of 100 m" in out


def test_misspellings_get_did_you_mean(store, tmp_path, capsys, monkeypatch):
    code, out = _bench(["run", "--method", "dopler", "--data", str(store)], capsys, monkeypatch)
    assert code == 2 and "did you mean 'doppler'?" in out
    # an unknown name may be a plugin method whose module is not named yet
    assert "DOPPLER_BENCH_METHODS=my_module" in out and "PYTHONPATH" in out
    code, out = _bench(["run", "--method", "doppler", "--data", str(store), "-p",
                        "tau_spatail_m=2"], capsys, monkeypatch)
    assert code == 2 and "unknown parameter 'tau_spatail_m'" in out
    assert "did you mean 'tau_spatial_m'?" in out and "known parameters: tau_spatial_m" in out
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"name": "b", "sequences": [{"path": str(store), "nmae": "x"}],
                                   "methods": [{"name": "icpp2p"}]}))
    code, out = _bench(["run", str(bad)], capsys, monkeypatch)
    assert code == 2
    assert "sequences[0]: unknown key 'nmae' (did you mean 'name'?)" in out
    assert "unknown method 'icpp2p' (did you mean 'icp-p2p'?)" in out
    assert "pydantic" not in out and "Extra inputs" not in out  # no library internals


def test_npy_frames_needs_the_period_or_an_explicit_choice(tmp_path, capsys, monkeypatch):
    folder = tmp_path / "f"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(5):
        np.save(folder / f"frame_{i:03d}.npy", rng.uniform(-9, 9, (30, 3)))
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(0, 1, 30))
    rows = "".join(f"{0.1 * i:.1f} {i} 0 0 0 0 0 1\n" for i in range(5))
    (folder / "gt.txt").write_text(rows)
    code, out = _bench(["convert", "npy-frames", str(folder), "--out", str(tmp_path / "a.h5")],
                       capsys, monkeypatch)
    assert code == 2 and "--period SECONDS" in out and "--stamps-from-gt" in out
    assert not (tmp_path / "a.h5").exists()
    code, out = _bench(["convert", "npy-frames", str(folder), "--stamps-from-gt", "--out",
                        str(tmp_path / "b.h5")], capsys, monkeypatch)
    assert code == 0 and (tmp_path / "b.h5").exists()


def test_version_and_help_without_python_types(capsys, monkeypatch):
    code, out = _bench(["--version"], capsys, monkeypatch)
    assert code == 0 and out.startswith("doppler-bench ")
    code, out = _bench(["run", "--help"], capsys, monkeypatch)
    assert code == 0 and "--param KEY=VALUE" in out and "<" not in out, out
    code, out = _bench(["--help"], capsys, monkeypatch)
    commands = out.split("Commands:")[1]
    assert code == 0 and "..." not in commands  # command summaries are whole
    code, out = _bench(["convert", "--help"], capsys, monkeypatch)
    assert code == 0 and "..." not in out.split("Commands:")[1]


def test_cli_runner_still_runs_the_app(store, tmp_path):
    res = CliRunner().invoke(app, ["run", "--method", "doppler", "--data", str(store),
                                   "--out", str(tmp_path / "r")])
    assert res.exit_code == 0, res.output


def _store_without_doppler(folder, doppler_kind="radial", drop_doppler=True):
    from loaders.scan import MemorySequence, Scan, SensorInfo

    seq = constant_twist_sequence(n_frames=20, n_points=600, max_range_m=60)
    scans = [Scan(s.stamp, s.points, None if drop_doppler else s.doppler) for s in seq]
    sensor = SensorInfo("lidar", seq.sensor.period_s, model="test", doppler_kind=doppler_kind)
    out = MemorySequence("plain", sensor, scans, seq.ground_truth, {"loader": "ntu4dradlm"})
    return write_store(out, folder / f"{doppler_kind}-{drop_doppler}.h5")


@pytest.mark.parametrize("method", ["doppler", "dicp", "doppler-icp", "doppler-ego"])
def test_a_doppler_method_on_a_store_without_doppler_is_refused_before_any_job(
        tmp_path, capsys, monkeypatch, method):
    plain = _store_without_doppler(tmp_path)
    code, out = _bench(["run", "--method", method, "--data", str(plain), "--out",
                        str(tmp_path / "r")], capsys, monkeypatch)
    assert code == 2, out
    assert f"{plain}: {method} needs Doppler, but the store has no Doppler values" in out
    # the store's loader (ntu4dradlm) names its Doppler field with --doppler-field
    assert "bench convert ntu4dradlm ... --doppler-field NAME" in out
    assert "Traceback" not in out and not (tmp_path / "r").exists()


def test_an_experiment_with_a_doppler_method_on_compensated_doppler_refuses_that_pair(
        tmp_path, capsys, monkeypatch):
    compensated = _store_without_doppler(tmp_path, "ego-compensated", drop_doppler=False)
    exp = tmp_path / "e.yaml"
    exp.write_text(yaml.safe_dump({
        "name": "e", "out": str(tmp_path / "out"),
        "sequences": [{"path": str(compensated), "name": "comp"}],
        "methods": [{"name": "icp-p2p"}, {"name": "doppler"}]}))
    code, out = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 1, out  # the refused pair is no success; the others ran
    assert f"{compensated}: doppler needs the raw radial Doppler velocity" in out
    assert "ego-compensated" in out and "1 run(s) refused" in out
    assert (tmp_path / "out" / "comp" / "icp-p2p_seed" / "metrics.json").exists()
    assert not (tmp_path / "out" / "comp" / "doppler" / "metrics.json").exists()
    # a method that needs no Doppler runs on it
    code, out = _bench(["run", "--method", "icp-p2p", "--data", str(compensated), "--out",
                        str(tmp_path / "r")], capsys, monkeypatch)
    assert code == 0, out


def test_ground_truth_hours_off_suggests_the_time_offset():
    """GT stamped in UTC+8 against scans in UTC: the error names --time-offset -28800."""
    from loaders.errors import DataError
    from loaders.gt import associate

    twist = constant_twist_sequence(n_frames=10, n_points=100)
    gt = twist.ground_truth
    late = type(gt)(gt.stamps + 1.7e9 + 8 * 3600 + 2.5, gt.poses)
    with pytest.raises(DataError, match=r"try --time-offset -28800 \(the ground truth's clock "
                                        r"is 8 h ahead of the scans'"):
        associate(late, gt.stamps + 1.7e9)
    with pytest.raises(DataError, match=r"try --time-offset -1000 \(this lines up"):
        associate(type(gt)(gt.stamps + 1000, gt.poses), gt.stamps)


def test_bench_speed_bad_options_are_one_message_before_any_timing(tmp_path, capsys,
                                                                     monkeypatch):
    """`bench speed` with sizes that are not point counts, an unknown method or an --out that
    is a file: one message naming the option, exit 2, no traceback (were a ValueError, a
    KeyError and a FileExistsError), and nothing written."""
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    out = tmp_path / "speed"
    for args, says in ((["--sizes", "abc"], "--sizes 'abc': expected point counts"),
                       (["--sizes", "1000,0"], "--sizes '1000,0'"),
                       (["--sizes", "1000", "--methods", "dopler"], "unknown method 'dopler'"),
                       (["--sizes", "1000", "--out", str(notes)], "is a file")):
        extra = [] if "--out" in args else ["--out", str(out)]
        code, text = _bench(["speed", "--no-memory", "--repeats", "1", *args, *extra], capsys,
                            monkeypatch)
        assert code == 2 and says in text and "Traceback" not in text, text
    assert notes.read_text() == "mine" and not out.exists()
