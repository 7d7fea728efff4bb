"""Many sequences at once: `bench convert dataset A B --jobs 2` runs each conversion as a job,
skips a store whose inputs and options are unchanged (resume), converts again when either
changes, and skips absent raw data with one line; configs/experiments/public.yaml runs on the
stores that exist and skips each absent dataset with one line."""

import os
import shutil

import numpy as np
import pytest
import yaml
from rich.console import Console

from bench.data.convert_batch import convert_datasets, stored_key
from bench.paths import EXPERIMENTS
from bench.runs.experiment import load_experiment
from bench.runs.plan import jobs_for_experiment
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.store import StoreSequence, write_store


def _frames(folder, n=5, points=30, seed=0):
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        np.save(folder / f"frame_{i:03d}.npy", rng.uniform(-20, 20, (points, 3)))
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(0, 2, points))
    (folder / "gt.txt").write_text("".join(f"{0.1 * i:.1f} {i} 0 0 0 0 0 1\n" for i in range(n)))


def _config(tmp_path, name, raw, period=0.1):
    cfg = {"name": name, "display_name": name, "sensor_class": "Sparse 4D Radar",
           "loader": "npy-frames", "raw_dir": str(raw), "raw_files": ["frame_000.npy", "gt.txt"],
           "options": {"period_s": period}, "store": f"{name}.h5"}
    path = tmp_path / "configs" / f"{name}.yaml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(yaml.safe_dump(cfg))
    return path


def _console():
    return Console(record=True, width=200, force_terminal=False)


def test_batch_conversion_resumes_and_redoes_what_changed(tmp_path):
    _frames(tmp_path / "raw_a", seed=1)
    _frames(tmp_path / "raw_b", n=7, seed=2)
    a, b = _config(tmp_path, "SeqA", tmp_path / "raw_a"), _config(tmp_path, "SeqB",
                                                                   tmp_path / "raw_b")
    absent = _config(tmp_path, "SeqGone", tmp_path / "raw_gone")
    data = tmp_path / "data"
    console = _console()
    code = convert_datasets([str(a), str(b), str(absent)], data, None, None, 2, "process",
                            False, console)
    text = console.export_text()
    assert code == 0, text
    assert text.count("skipped SeqGone: raw data") == 1 and "not found" in text
    store_a, store_b = data / "real" / "SeqA.h5", data / "real" / "SeqB.h5"
    for path, n in ((store_a, 5), (store_b, 7)):
        st = StoreSequence(path)
        assert len(st) == n and st.provenance["conversion"]["key"] == stored_key(path)
        st.close()
    mtimes = {p: p.stat().st_mtime_ns for p in (store_a, store_b)}

    # unchanged inputs and options: nothing converted again
    console = _console()
    assert convert_datasets([str(a), str(b)], data, None, None, 2, "local", False, console) == 0
    text = console.export_text()
    assert text.count("is up to date") == 2
    assert {p: p.stat().st_mtime_ns for p in mtimes} == mtimes

    # a changed option converts that sequence again; a touched input file too
    _config(tmp_path, "SeqA", tmp_path / "raw_a", period=0.2)
    later = os.stat(tmp_path / "raw_b" / "frame_003.npy").st_mtime_ns + 10**9
    os.utime(tmp_path / "raw_b" / "frame_003.npy", ns=(later, later))
    console = _console()
    assert convert_datasets([str(a), str(b)], data, None, None, 1, "local", False, console) == 0
    assert "2 converted, 0 up to date" in console.export_text()
    st = StoreSequence(store_a)
    assert st.sensor.period_s == pytest.approx(0.2)
    st.close()

    # --force converts an up-to-date store again
    console = _console()
    assert convert_datasets([str(a)], data, None, None, 1, "local", True, console) == 0
    assert "1 converted" in console.export_text()


def test_a_failing_conversion_fails_the_batch_but_not_the_others(tmp_path):
    _frames(tmp_path / "ok")
    _frames(tmp_path / "bad")
    np.save(tmp_path / "bad" / "frame_002_dop.npy", np.zeros(3))  # wrong length
    ok, bad = _config(tmp_path, "Ok", tmp_path / "ok"), _config(tmp_path, "Bad", tmp_path / "bad")
    console = _console()
    code = convert_datasets([str(ok), str(bad)], tmp_path / "data", None, None, 2, "local",
                            False, console)
    text = console.export_text()
    assert code == 1 and "failed Bad" in text and "frame_002" in text
    assert (tmp_path / "data" / "real" / "Ok.h5").exists()
    assert not (tmp_path / "data" / "real" / "Bad.h5").exists()
    with pytest.raises(DataError, match="nothing to convert"):
        convert_datasets([str(_config(tmp_path, "Gone", tmp_path / "gone")), str(
            _config(tmp_path, "Gone2", tmp_path / "gone2"))], tmp_path / "data", None, None, 1,
            "local", False, console)


def test_public_experiment_runs_what_exists_and_skips_the_rest(tmp_path):
    exp_dir = tmp_path / "configs" / "experiments"
    exp_dir.mkdir(parents=True)
    shutil.copy(EXPERIMENTS / "public.yaml", exp_dir / "public.yaml")
    real = tmp_path / "data" / "real"
    real.mkdir(parents=True)
    seq = constant_twist_sequence(n_frames=12, n_points=300, max_range_m=40)
    for stem in ("VoD_clip1", "NTU4DRadLM_cp", "NTU4DRadLM_nyl", "HeLiPR_Aeva_Town01"):
        write_store(seq, real / f"{stem}.h5")
    exp = load_experiment(exp_dir / "public.yaml")
    console = _console()
    jobs = jobs_for_experiment(exp, console)
    text = console.export_text()
    skipped = [line for line in text.splitlines() if "skipped" in line]
    assert len(skipped) == 6, text  # Loop1, Snail x2, ColoRadar, two CARLA walls
    assert all(line.startswith("public: skipped ") for line in skipped)
    assert not any(name in text for name in ("VoD", "HeLiPR", "(routes)"))
    runs = {(j.name, j.method, j.seed) for j in jobs}
    assert {n for n, _, _ in runs} == {"VoD_clip1", "NTU4DRadLM_cp", "NTU4DRadLM_nyl",
                                       "HeLiPR_Aeva_Town01"}
    # the paper's pairing per class: ICP on sparse radar, DICP on semi-dense, ours on both;
    # no Doppler method on HeLiPR's ego-compensated velocities
    assert {m for n, m, _ in runs if n == "VoD_clip1"} == {"icp-p2p", "doppler"}
    assert {m for n, m, _ in runs if n == "NTU4DRadLM_cp"} == {"dicp", "doppler"}
    assert {m for n, m, _ in runs if n == "HeLiPR_Aeva_Town01"} == {"icp-p2p"}
    classes = {j.name: j.sensor_class for j in jobs}
    assert classes["VoD_clip1"] == "Sparse 4D Radar"
    assert classes["NTU4DRadLM_nyl"] == "Semi-Dense 4D Radar"
    # nothing at all: one error, not an empty table
    for p in real.iterdir():
        p.unlink()
    with pytest.raises(DataError, match="none of its stores exist"):
        jobs_for_experiment(load_experiment(exp_dir / "public.yaml"), _console())
