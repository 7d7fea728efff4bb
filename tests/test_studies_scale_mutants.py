"""bench.studies.scale, piece by piece (mutation testing): the child-process probe against what
a tiny command measures of itself (its own CPU, its workers' CPU, user and system time, its
peak memory, its exit status), the synthetic drive against bench.studies.coverage, the
per-pose and per-frame arithmetic with the children replaced by known figures, the printed
tables and the whole command with its parts replaced.

Issue 46's planted bug: the scale benchmark's CPU figure left out the worker processes;
``test_the_probes_cpu_is_the_commands_own_and_its_workers`` pins that it holds them."""

from __future__ import annotations

import ast
import csv
import textwrap
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

import bench
from bench.studies import scale
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.errors import DataError

ROOT = Path(scale.__file__).resolve().parents[2]

#: busy work of ``seconds`` of user time then ``seconds`` of system time (reading /dev/zero)
BURN = textwrap.dedent("""
    import os

    def burn(seconds):
        t = os.times()
        while os.times().user - t.user < seconds:
            pass
        with open("/dev/zero", "rb", buffering=0) as f:
            while os.times().system - t.system < seconds:
                f.read(1 << 22)
    """)


def _entry(folder: Path, name: str, body: str) -> str:
    (folder / f"{name}.py").write_text(BURN + textwrap.dedent(body))
    return name


# ---- the child-process probe --------------------------------------------------------------

def test_the_probes_cpu_is_the_commands_own_and_its_workers(tmp_path, monkeypatch):
    """The command burns 0.2 s of user and 0.2 s of system time itself and waits for a worker
    process that burns as much: the probe's CPU time is all four (as the command's own
    os.times() says at its end, own and children's)."""
    entry = _entry(tmp_path, "burner", f"""
        import subprocess, sys

        def main():
            burn(0.2)
            subprocess.run([sys.executable, "-c", "import burner; burner.burn(0.2)"],
                           check=True)
            t = os.times()
            with open({str(tmp_path / "times")!r}, "w") as f:
                f.write(f"{{t.user}} {{t.system}} {{t.children_user}} {{t.children_system}}")
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    got = scale.child([], entry=entry)
    user, system, kids_user, kids_system = map(float, (tmp_path / "times").read_text().split())
    assert min(user, system, kids_user, kids_system) >= 0.2
    # all four, and nothing twice: the probe reads them a moment after the command's end
    assert user + system + kids_user + kids_system - 0.02 <= got["cpu_s"]
    assert got["cpu_s"] <= user + system + kids_user + kids_system + 0.1
    assert 0.8 <= got["wall_s"] < 120


def test_the_probe_reads_the_commands_peak_memory(tmp_path, monkeypatch):
    entry = _entry(tmp_path, "big", f"""
        def main():
            block = b"x" * (200 << 20)
            hwm = next(ln.split()[1] for ln in open("/proc/self/status")
                       if ln.startswith("VmHWM"))
            with open({str(tmp_path / "hwm")!r}, "w") as f:
                f.write(hwm)
            del block
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    got = scale.child([], entry=entry)
    own_kb = int((tmp_path / "hwm").read_text())
    assert own_kb / 1024 >= 200
    # the high-water mark only grows: the probe's, in MB, is the command's own (the kernel
    # counts resident pages lazily: within 0.3 MB)
    assert own_kb / 1024 - 0.3 <= got["peak_mb"] <= own_kb / 1024 + 50


def test_the_probe_passes_the_arguments_and_imports_this_checkout(tmp_path, monkeypatch):
    """``bench`` in the child is this checkout's even when PYTHONPATH names another one (a
    decoy package ``bench`` first on it); the command sees ``bench ARGV`` as its argv."""
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "__init__.py").write_text("DECOY = True\n")
    entry = _entry(tmp_path, "echo", f"""
        import sys

        def main():
            import bench
            with open({str(tmp_path / "seen")!r}, "w") as f:
                f.write(repr((sys.argv, bench.__file__)))
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    scale.child(["score", "a b", "--x"], entry=entry)
    argv, bench_file = ast.literal_eval((tmp_path / "seen").read_text())
    assert argv == ["bench", "score", "a b", "--x"]
    assert Path(bench_file).resolve() == Path(bench.__file__).resolve()
    assert Path(bench_file).resolve().parents[1] == ROOT


@pytest.mark.parametrize("exit_", ["sys.exit()", "sys.exit(0)", "return None"])
def test_a_command_ending_well_is_no_error(tmp_path, monkeypatch, exit_):
    entry = _entry(tmp_path, "ok", f"""
        import sys

        def main():
            {exit_}
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    got = scale.child([], entry=entry)
    assert set(got) == {"wall_s", "cpu_s", "peak_mb"}
    assert 0 < got["cpu_s"] < 30 and 0 < got["wall_s"] < 60 and 5 < got["peak_mb"] < 500


def test_a_failing_command_is_an_error_naming_it_with_its_output_tails(tmp_path, monkeypatch):
    entry = _entry(tmp_path, "fails", """
        import sys

        def main():
            print("A" * 3000)
            sys.stderr.write("B" * 3000)
            sys.exit(3)
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    with pytest.raises(RuntimeError) as err:
        scale.child(["table", "runs"], entry=entry)
    msg = str(err.value)
    head = "`bench table runs` failed (exit 3):\n"
    assert msg.startswith(head)
    # the last 1500 characters of each of stdout and stderr
    assert len(msg) == len(head) + 1500 + 1500
    out, err = msg[len(head):len(head) + 1500], msg[len(head) + 1500:]
    assert out.startswith("AAA") and out.endswith("\n") and "\nSCALE_PROBE 3 " in out
    assert err == "B" * 1500


def test_a_command_that_cannot_start_is_an_error_with_the_exit_code(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    with pytest.raises(RuntimeError, match=r"(?s)`bench x` failed \(exit 1\):\n.*ModuleNotFound"):
        scale.child(["x"], entry="no_such_module_here")


def test_a_command_running_past_its_timeout_is_stopped(tmp_path, monkeypatch):
    entry = _entry(tmp_path, "slow", """
        import time

        def main():
            time.sleep(30)
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    import subprocess

    with pytest.raises(subprocess.TimeoutExpired):
        scale.child([], timeout_s=1.0, entry=entry)


# ---- the synthetic drive ------------------------------------------------------------------

def test_the_drive_is_a_store_of_the_coverage_drive_and_two_noisy_estimates(tmp_path):
    from loaders.posefile import read_tum
    from loaders.store import StoreSequence

    store, estimates = scale.drive(120, tmp_path)
    assert store == tmp_path / "drive-120.h5"
    assert estimates == [tmp_path / "drive-120-estimate-0.txt",
                         tmp_path / "drive-120-estimate-1.txt"]
    seq = StoreSequence(store)
    try:
        assert len(seq) == 120 and seq.name == "drive-120"
        np.testing.assert_allclose(seq.stamps, np.arange(120) / 10.0, atol=1e-9)
        np.testing.assert_allclose(seq.ground_truth.poses, ground_truth(120), atol=1e-9)
        assert seq.scan(7).points.shape == (3, 3)
        assert seq.sensor.period_s == pytest.approx(0.1)
    finally:
        seq.close()
    gt = ground_truth(120)
    for k, (path, noise) in enumerate(zip(estimates, (NoiseModel(), NoiseModel(0.08, 0.02)),
                                          strict=True)):
        est = read_tum(path)
        np.testing.assert_allclose(est.stamps, np.arange(120) / 10.0, atol=1e-6)
        np.testing.assert_allclose(est.poses, noisy_estimate(gt, noise, 100 + k), atol=1e-5)


# ---- the arithmetic, the children replaced by known figures -------------------------------

def fake_children(monkeypatch, figures: dict) -> list:
    """``scale.child`` replaced: ``figures[argv[0]]`` (a list for repeated commands)."""
    calls = []

    def child(argv, timeout_s=3600, entry="bench.cli"):
        calls.append(argv)
        got = figures[argv[0]]
        return got.pop(0) if isinstance(got, list) else got

    monkeypatch.setattr(scale, "child", child)
    return calls


def test_a_scale_row_is_cpu_per_pose_and_against_the_scorings(tmp_path, monkeypatch):
    store = tmp_path / "s.h5"
    ests = [tmp_path / "e0.txt", tmp_path / "e1.txt"]
    drives = []
    monkeypatch.setattr(scale, "drive", lambda poses, folder: drives.append(
        (poses, folder)) or (store, ests))
    calls = fake_children(monkeypatch, {
        "score": [{"cpu_s": 2.0, "wall_s": 5.0, "peak_mb": 300.0},
                  {"cpu_s": 4.0, "wall_s": 3.0, "peak_mb": 200.0}],
        "table": {"cpu_s": 3.0, "wall_s": 4.0, "peak_mb": 150.0},
        "report": {"cpu_s": 9.0, "wall_s": 12.0, "peak_mb": 400.0}})
    row = scale.scale_row(1000, tmp_path)
    assert drives == [(1000, tmp_path)]
    results = str(tmp_path / "results-1000")
    assert calls == [["score", str(ests[0]), "--store", str(store), "--name", "estimate-0",
                      "--out", results],
                     ["score", str(ests[1]), "--store", str(store), "--name", "estimate-1",
                      "--out", results],
                     ["table", results], ["report", results]]
    want = {"poses": 1000, "score_ms": 3.0, "score_wall_ms": 4.0, "score_mb": 300.0,
            "table_ms": 1.5, "table_wall_ms": 2.0, "table_mb": 150.0, "table_x_scorings": 0.5,
            "report_ms": 4.5, "report_wall_ms": 6.0, "report_mb": 400.0,
            "report_x_scorings": 1.5}
    assert list(row) == list(want)
    for k, v in want.items():
        assert row[k] == pytest.approx(v, rel=1e-12), k


def test_the_marginal_cost_leaves_the_start_up_out():
    # 1 s of start-up and 2 ms a pose: 100 poses cost 12 ms a pose, 1000 poses 3 ms
    rows = [{"poses": 100, "x_ms": 12.0}, {"poses": 500, "x_ms": 99.0},
            {"poses": 1000, "x_ms": 3.0}]
    assert scale.marginal(rows, "x_ms") == pytest.approx(2.0, rel=1e-12)
    assert scale.marginal([{"poses": 10, "y": 5.0}, {"poses": 30, "y": 5.0}], "y") == \
        pytest.approx(5.0)


def _write_frames(folder: Path, times: list) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "frames.csv", "w") as f:
        f.write("frame,time_ms\n" + "".join(f"{i},{t}\n" for i, t in enumerate(times)))


def test_an_executor_row_is_the_commands_cpu_less_the_methods_time(tmp_path, monkeypatch):
    import yaml

    stores = [tmp_path / "long-0.h5", tmp_path / "long-1.h5"]
    asked = []
    monkeypatch.setattr(scale, "long_stores", lambda folder, sequences, frames: asked.append(
        (folder, sequences, frames)) or stores)
    figures = {"process": {"cpu_s": 0.1, "wall_s": 0.4, "peak_mb": 250.0},
               "dask": {"cpu_s": 0.2, "wall_s": 0.8, "peak_mb": 350.0}}
    calls = []

    def child(argv, timeout_s=3600, entry="bench.cli"):
        calls.append(argv)
        executor = argv[argv.index("--executor") + 1]
        out = tmp_path / f"experiment-{executor}"
        # a sequence's first frame is not timed; frames.csv in folders below the experiment
        _write_frames(out / "b" / "run", ["", 10.0, 20.0])
        _write_frames(out / "a" / "run", ["", 30.0, 40.0])
        return figures[executor]

    monkeypatch.setattr(scale, "child", child)
    rows = scale.executor_rows(tmp_path, 2, 3)
    assert asked == [(tmp_path, 2, 3)]
    for executor in ("process", "dask"):
        config = tmp_path / f"experiment-{executor}.yaml"
        assert yaml.safe_load(config.read_text()) == {
            "name": f"scale-{executor}", "methods": [{"name": "doppler"}], "jobs": 2,
            "out": str(tmp_path / f"experiment-{executor}"),
            "sequences": [{"path": str(s)} for s in stores]}
        assert [str(config), "--executor", executor, "--jobs", "2"] == \
            calls[("process", "dask").index(executor)][1:]
    assert [c[0] for c in calls] == ["run", "run"]
    for r, executor in zip(rows, ("process", "dask"), strict=True):
        cpu = figures[executor]["cpu_s"]
        want = {"executor": executor, "sequences": 2, "frames": 6, "timed_frames": 4,
                "method_ms": 25.0, "method_median_ms": 25.0,
                "harness_ms": (1e3 * cpu - 100.0) / 6, "cpu_ms": 1e3 * cpu / 6,
                "wall_ms": 1e3 * figures[executor]["wall_s"] / 6,
                "main_peak_mb": figures[executor]["peak_mb"]}
        assert list(r) == list(want)
        for k, v in want.items():
            assert r[k] == (pytest.approx(v, rel=1e-12) if isinstance(v, float) else v), k


def test_the_median_method_time_is_the_median(tmp_path, monkeypatch):
    monkeypatch.setattr(scale, "long_stores", lambda folder, sequences, frames: [])

    def child(argv, timeout_s=3600, entry="bench.cli"):
        _write_frames(tmp_path / "experiment-dask" / "r", ["", 1.0, 2.0, 9.0])
        return {"cpu_s": 1.0, "wall_s": 1.0, "peak_mb": 1.0}

    monkeypatch.setattr(scale, "child", child)
    (row,) = scale.executor_rows(tmp_path, 1, 4, executors=("dask",))
    assert row["method_ms"] == pytest.approx(4.0) and row["method_median_ms"] == 2.0
    assert row["timed_frames"] == 3 and row["frames"] == 4


def test_frames_missing_from_a_run_are_an_error(tmp_path, monkeypatch):
    monkeypatch.setattr(scale, "long_stores", lambda folder, sequences, frames: [])

    def child(argv, timeout_s=3600, entry="bench.cli"):
        _write_frames(tmp_path / "experiment-process" / "r", [1.0, 2.0, 3.0])
        return {"cpu_s": 1.0, "wall_s": 1.0, "peak_mb": 1.0}

    monkeypatch.setattr(scale, "child", child)
    with pytest.raises(RuntimeError, match="^process: 3 frames recorded, expected 4$"):
        scale.executor_rows(tmp_path, 2, 2, executors=("process",))


# ---- the long stores and the sample -------------------------------------------------------

def _scan(t: float, n: int, tag: float):
    from loaders.scan import Scan

    points = np.c_[np.arange(n, dtype=float), np.full(n, tag), np.ones(n)]
    return Scan(t, points, doppler=np.zeros(n))


def test_the_long_stores_tile_thinned_radar_scans_each_in_its_own_order(tmp_path, monkeypatch):
    """Radar scans of 1500, 10 and 1000 points: the first thinned to 1000 of its points (in
    their order), the others kept whole; store k starts at scan k and cycles."""
    import bench.studies.harness as harness
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.store import StoreSequence

    radar = MemorySequence("radar", SensorInfo("radar", 0.1),
                           [_scan(0.0, 1500, 0.0), _scan(0.1, 10, 1.0), _scan(0.2, 1000, 2.0)])
    monkeypatch.setattr(harness, "synthetic_scenarios",
                        lambda: iter([("radar", radar), ("lidar", None)]))
    paths = scale.long_stores(tmp_path, 2, 5)
    assert paths == [tmp_path / "long-0.h5", tmp_path / "long-1.h5"]
    for k, path in enumerate(paths):
        seq = StoreSequence(path)
        try:
            assert len(seq) == 5 and seq.name == f"long-{k}-tiled"
            scans = [seq.scan(i) for i in range(5)]
        finally:
            seq.close()
        tags = [int(s.points[0, 1]) for s in scans]
        assert tags == [(k + i) % 3 for i in range(5)]
        for s, tag in zip(scans, tags, strict=True):
            x = s.points[:, 0]
            if tag == 0:  # 1000 distinct points of the 1500, in order
                assert len(s) == 1000 and np.all(np.diff(x) > 0) and x.max() < 1500
                assert x.max() > 1000  # drawn from the whole scan, not its first 1000
            else:
                np.testing.assert_array_equal(x, np.arange(1000 if tag == 2 else 10))


def test_doppler_is_timed_on_the_sample_as_bench_speed_times_it(monkeypatch):
    import bench.studies.speed as speed

    seen = []

    def time_method(method, seq):
        seen.append((method, len(seq)))
        return {"median_ms": np.float32(1.25), "mean_ms": 9.0}

    monkeypatch.setattr(speed, "time_method", time_method)
    got = scale.doppler_on_sample(scale.SAMPLE)
    assert got == 1.25 and type(got) is float
    assert seen == [("doppler", 250)]
    assert scale.SAMPLE == ROOT / "samples" / "ntu4dradlm-loop1.h5"


def test_a_missing_sample_is_a_data_error_naming_it(tmp_path):
    missing = tmp_path / "gone.h5"
    with pytest.raises(DataError, match=r"gone\.h5: no such store; the scale benchmark times "
                                        r"doppler on the real radar sample "
                                        r"\(samples/ntu4dradlm-loop1\.h5\)"):
        scale.doppler_on_sample(missing)


# ---- the tables and the command -----------------------------------------------------------

def _text(draw, *args) -> str:
    console = Console(record=True, width=500, force_terminal=False)
    draw(*args, console)
    return console.export_text()


ROWS = [{"poses": 1000, "score_ms": 3.0, "score_wall_ms": 4.25, "score_mb": 300.4,
         "table_ms": 1.5, "table_wall_ms": 2.0, "table_mb": 150.6, "table_x_scorings": 0.5,
         "report_ms": 4.5, "report_wall_ms": 6.0, "report_mb": 400.0,
         "report_x_scorings": 1.5},
        {"poses": 3000, "score_ms": 2.0, "score_wall_ms": 3.0, "score_mb": 310.0,
         "table_ms": 1.0, "table_wall_ms": 1.25, "table_mb": 160.0, "table_x_scorings": 0.25,
         "report_ms": 2.5, "report_wall_ms": 3.5, "report_mb": 410.0,
         "report_x_scorings": 1.25}]


def test_the_scale_table_prints_each_figure_and_the_marginal_costs():
    text = _text(scale.print_scale, ROWS, 0.75)
    lines = [" ".join(ln.replace("│", " ").split()) for ln in text.splitlines()]
    assert "1,000 3.000 (4.250) 300 1.500 (2.000) 151 0.50x 4.500 (6.000) 400 1.50x 0.750" \
        in lines
    assert "3,000 2.000 (3.000) 310 1.000 (1.250) 160 0.25x 2.500 (3.500) 410 1.25x 0.750" \
        in lines
    flat = " ".join(text.split())
    assert ("poses score score peak table table peak table x scorings report report peak "
            "report x scorings doppler / frame") in " ".join(flat.replace("┃", " ").split())
    # marginal per pose: score (6000 - 3000) / 2000 = 1.5 ms, 2x doppler's 0.75 ms;
    # table (3000 - 1500) / 2000 = 0.75 ms; report (7500 - 4500) / 2000 = 1.5 ms
    assert ("marginal per pose 1,000 -> 3,000: scoring 1.500 ms (2.00x doppler's per-frame "
            "time), table 0.750 ms, report 1.500 ms.") in flat
    assert "ntu4dradlm-loop1.h5" in flat
    assert "The harness at dataset scale: CPU time per pose [ms]" in flat
    # one drive: no marginal cost
    assert "marginal" not in _text(scale.print_scale, ROWS[:1], 0.75)


def test_the_executor_table_prints_each_figure():
    rows = [{"executor": "process", "sequences": 3, "frames": 6000, "timed_frames": 5997,
             "method_ms": 2.0, "method_median_ms": 1.9, "harness_ms": 3.0, "cpu_ms": 5.0,
             "wall_ms": 2.5, "main_peak_mb": 200.4}]
    text = _text(scale.print_executors, rows, 1.5)
    lines = [" ".join(ln.replace("│", " ").split()) for ln in text.splitlines()]
    assert "process 6,000 2.000 3.000 1.50x 5.000 2.500 200 1.500" in lines
    flat = " ".join(text.split())
    assert "`bench run` of 3 long synthetic radar sequences with doppler, 2 workers" in flat
    assert "on 2 workers; scans thinned to 1000 points" in flat
    header = " ".join(flat.replace("┃", " ").split())
    assert ("executor frames method (mean) harness CPU harness / method all CPU wall "
            "main peak [MB] doppler on the sample") in header


def test_the_command_runs_its_parts_and_writes_both_tables(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(scale, "doppler_on_sample", lambda sample: calls.append(
        ("sample", sample)) or 0.75)

    def scale_row(n, folder):
        calls.append(("row", n))
        assert folder.is_dir()
        return dict(ROWS[0], poses=n)

    def executor_rows(folder, sequences, frames, executors):
        calls.append(("executors", sequences, frames, executors))
        assert folder.is_dir()
        return [{"executor": e, "sequences": sequences, "frames": frames, "timed_frames": 1,
                 "method_ms": 2.0, "method_median_ms": 2.0, "harness_ms": 1.0, "cpu_ms": 3.0,
                 "wall_ms": 1.0, "main_peak_mb": 9.0} for e in executors]

    monkeypatch.setattr(scale, "scale_row", scale_row)
    monkeypatch.setattr(scale, "executor_rows", executor_rows)
    console = Console(record=True, width=300)
    out = tmp_path / "out"
    rows, ex_rows = scale.run_scale(out, console, poses=(400, 200), frames=7, sequences=2,
                                    sample=tmp_path / "s.h5", executors=("dask",))
    assert calls == [("sample", tmp_path / "s.h5"), ("row", 200), ("row", 400),
                     ("executors", 2, 7, ("dask",))]
    assert [r["poses"] for r in rows] == [200, 400]
    assert all(r["doppler_sample_ms"] == 0.75 for r in rows + ex_rows)
    with open(out / "scale.csv") as f:
        written = list(csv.DictReader(f))
    assert [int(r["poses"]) for r in written] == [200, 400]
    assert list(written[0]) == [*ROWS[0], "doppler_sample_ms"]
    assert float(written[0]["doppler_sample_ms"]) == 0.75
    with open(out / "scale_executors.csv") as f:
        ex_written = list(csv.DictReader(f))
    assert [r["executor"] for r in ex_written] == ["dask"]
    assert float(ex_written[0]["doppler_sample_ms"]) == 0.75
    text = console.export_text()
    assert f"timing doppler on {tmp_path / 's.h5'}" in text
    assert "scoring, table and report at 200 poses" in text
    assert "`bench run` of 2 x 7 frames on dask" in text
    assert f"wrote {out}/scale.csv and scale_executors.csv" in text
    assert "marginal per pose 200 -> 400" in text


def test_the_commands_defaults():
    import inspect

    assert scale.POSES == (2500, 10_000, 40_000) and scale.MIN_POSES == 100
    assert (scale.SEQUENCES, scale.FRAMES, scale.POINTS, scale.METHOD) == (3, 2000, 1000,
                                                                           "doppler")
    assert scale.EXECUTORS == ("process", "dask") and scale.WORKERS == 2
    defaults = {k: v.default for k, v in inspect.signature(scale.run_scale).parameters.items()
                if v.default is not inspect.Parameter.empty}
    assert defaults == {"poses": (2500, 10_000, 40_000), "frames": 2000, "sequences": 3,
                        "sample": ROOT / "samples" / "ntu4dradlm-loop1.h5",
                        "executors": ("process", "dask")}


def test_the_probe_runs_bench_itself_by_default():
    """No ``entry``: the command is ``bench`` (bench.cli's main); its help ends well."""
    got = scale.child(["--help"])
    assert 0 < got["cpu_s"] < 60 and got["peak_mb"] > 10
    with pytest.raises(RuntimeError, match=r"`bench no-such-command` failed \(exit 2\)"):
        scale.child(["no-such-command"])


def test_the_commands_messages_print_paths_and_names_as_they_are(tmp_path, monkeypatch):
    """Paths and executor names holding brackets (rich's markup) are printed verbatim."""
    monkeypatch.setattr(scale, "doppler_on_sample", lambda sample: 0.75)
    monkeypatch.setattr(scale, "scale_row", lambda n, folder: dict(ROWS[0], poses=n))
    monkeypatch.setattr(scale, "executor_rows", lambda folder, sequences, frames, executors: [
        {"executor": e, "sequences": sequences, "frames": frames, "timed_frames": 1,
         "method_ms": 2.0, "method_median_ms": 2.0, "harness_ms": 1.0, "cpu_ms": 3.0,
         "wall_ms": 1.0, "main_peak_mb": 9.0} for e in executors])
    console = Console(record=True, width=300)
    sample, out = tmp_path / "s[bold].h5", tmp_path / "out[red]"
    scale.run_scale(out, console, poses=(200,), frames=7, sequences=2, sample=sample,
                    executors=("[bold]process", "dask"))
    text = console.export_text()
    assert f"timing doppler on {sample}" in text
    assert "`bench run` of 2 x 7 frames on [bold]process, dask" in text
    assert f"wrote {out}/scale.csv and scale_executors.csv" in text


def test_the_long_stores_are_the_same_each_time(tmp_path, monkeypatch):
    """The thinning is seeded: two builds of the stores hold the same points."""
    import bench.studies.harness as harness
    from loaders.scan import MemorySequence, SensorInfo
    from loaders.store import StoreSequence

    radar = MemorySequence("radar", SensorInfo("radar", 0.1), [_scan(0.0, 3000, 0.0)])
    monkeypatch.setattr(harness, "synthetic_scenarios", lambda: iter([("radar", radar)]))
    points = []
    for k in range(2):
        (path,) = scale.long_stores(tmp_path / str(k), 1, 1)
        seq = StoreSequence(path)
        try:
            points.append(seq.scan(0).points)
        finally:
            seq.close()
    np.testing.assert_array_equal(points[0], points[1])


def test_the_tables_titles_and_captions_in_full():
    flat = " ".join(_text(scale.print_scale, ROWS, 0.75).split())
    assert ("The harness at dataset scale: CPU time per pose [ms] (wall in brackets), peak "
            "memory [MB], and the table / report against the scorings that made them") in flat
    assert ("marginal per pose 1,000 -> 3,000: scoring 1.500 ms (2.00x doppler's per-frame "
            "time), table 0.750 ms, report 1.500 ms. Per pose: the command's CPU time (start-up "
            "included) over the poses it covers (two runs: 2N; scoring: the two scorings over "
            "2N); doppler: median per-frame time on the real radar sample "
            "(ntu4dradlm-loop1.h5), measured in this command") in flat
    rows = [{"executor": "dask", "sequences": 3, "frames": 6000, "timed_frames": 5997,
             "method_ms": 2.0, "method_median_ms": 1.9, "harness_ms": 3.0, "cpu_ms": 5.0,
             "wall_ms": 2.5, "main_peak_mb": 200.4}]
    text = _text(scale.print_executors, rows, 1.5)
    flat = " ".join(text.split())
    assert ("An experiment's whole cost per frame: `bench run` of 3 long synthetic radar "
            "sequences with doppler, 2 workers [ms per frame]") in flat
    assert ("harness CPU: the whole command's CPU time (planning, start-up, workers, reading, "
            "scoring, writing) less the method's own time_ms, over every frame; all CPU: the "
            "whole command's CPU time per frame; wall: its wall time per frame on 2 workers; "
            "scans thinned to 1000 points, tiled along a straight path") in flat
    # the executor column is left-justified, the figures right-justified under their headers
    header = next(ln for ln in text.splitlines() if "executor" in ln and "harness" in ln)
    row = next(ln for ln in text.splitlines() if "dask" in ln and "│" in ln)
    heads, cells = header.split("┃")[1:-1], row.split("│")[1:-1]
    assert cells[0].startswith(" dask ") and cells[0].strip() == "dask"
    assert heads[0].strip() == "executor" and len(cells[0]) > len(" dask ")
    for head, cell in zip(heads[1:], cells[1:], strict=True):
        assert cell.endswith(cell.strip() + " "), cell
        if len(head.strip()) > len(cell.strip()):  # padded: on the left
            assert cell.startswith("  "), (head, cell)


# ---- the scratch files go through the guard ------------------------------------------------

def test_a_drive_rebuilt_in_the_same_folder_replaces_its_own_files(tmp_path):
    scale.drive(100, tmp_path)
    store, estimates = scale.drive(100, tmp_path)  # the harness's own files: replaced
    assert store.is_file() and all(p.is_file() for p in estimates)


@pytest.mark.parametrize("name, what", [("drive-100.h5", "a scratch store"),
                                        ("drive-100-estimate-0.txt", "a scratch estimate"),
                                        ("drive-100-estimate-1.txt", "a scratch estimate")])
def test_a_drive_leaves_a_users_file_alone(tmp_path, name, what):
    (tmp_path / name).write_text("mine\n")
    with pytest.raises(DataError, match=f"exists and is not {what} the harness wrote"):
        scale.drive(100, tmp_path)
    assert (tmp_path / name).read_text() == "mine\n"


def _fake_run(tmp_path, monkeypatch):
    monkeypatch.setattr(scale, "long_stores", lambda folder, sequences, frames: [])

    def child(argv, timeout_s=3600, entry="bench.cli"):
        executor = argv[argv.index("--executor") + 1]
        _write_frames(tmp_path / f"experiment-{executor}" / "r", [1.0])
        return {"cpu_s": 1.0, "wall_s": 1.0, "peak_mb": 1.0}

    monkeypatch.setattr(scale, "child", child)


def test_an_experiment_config_is_replaced_but_a_users_file_is_not(tmp_path, monkeypatch):
    _fake_run(tmp_path, monkeypatch)
    scale.executor_rows(tmp_path, 1, 1, executors=("dask",))
    scale.executor_rows(tmp_path, 1, 1, executors=("dask",))  # its own config: replaced
    (tmp_path / "experiment-process.yaml").write_text("mine\n")
    with pytest.raises(DataError, match="exists and is not a scratch experiment the harness"):
        scale.executor_rows(tmp_path, 1, 1, executors=("process",))
    assert (tmp_path / "experiment-process.yaml").read_text() == "mine\n"


def test_the_scale_table_right_justifies_its_figures_and_spans_first_to_last():
    rows = [ROWS[0], dict(ROWS[1], poses=2000), ROWS[1]]
    text = _text(scale.print_scale, rows, 0.75)
    flat = " ".join(text.split())
    # the caption spans the smallest and the largest drive, not the second
    assert "marginal per pose 1,000 -> 3,000: scoring 1.500 ms" in flat
    header = next(ln for ln in text.splitlines() if "poses" in ln and "┃" in ln)
    row = next(ln for ln in text.splitlines() if "1,000" in ln and "│" in ln)
    heads, cells = header.split("┃")[1:-1], row.split("│")[1:-1]
    assert len(heads) == len(cells) == 10
    for head, cell in zip(heads, cells, strict=True):
        assert cell.endswith(cell.strip() + " "), cell
        if len(head.strip()) > len(cell.strip()):
            assert cell.startswith("  "), (head, cell)


def test_a_command_vanishing_without_the_probes_line_is_an_error(tmp_path, monkeypatch):
    """Exit status 0 but no probe line (the command ended the process itself)."""
    entry = _entry(tmp_path, "vanish", """
        def main():
            os._exit(0)
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    with pytest.raises(RuntimeError, match=r"^`bench x` failed \(exit 0\)"):
        scale.child(["x"], entry=entry)


def test_the_peak_memory_is_whole_kibibytes_in_mebibytes(tmp_path, monkeypatch):
    """/proc's VmHWM is whole kB: the figure times 1024 is a whole number."""
    entry = _entry(tmp_path, "small", """
        def main():
            pass
        """)
    monkeypatch.setenv("PYTHONPATH", str(tmp_path))
    kb = scale.child([], entry=entry)["peak_mb"] * 1024
    assert kb == pytest.approx(round(kb), abs=1e-6)
