"""A sweep of broken inputs through `bench convert`, `bench inspect` and `bench run`, run as the
user runs them (the `bench` entry point in a subprocess, so `main()`'s handling is exercised).

Each case must end with the expected exit code (0 all fine, 1 a run failed, 2 a user error), a
message naming the file (and the frame, where there is one), no traceback, and nothing under
the final output name (no store, no metrics.json, no temporary file).

Every case runs once, concurrently, in a module fixture (the sweep takes well under a minute);
each case is then checked by its own test.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import constant_twist_sequence
from helpers_bags import Motion, make_truth, write_gt_tum, write_ntu_bag
from loaders.scan import MemorySequence, Scan
from loaders.store import write_store

ROOT = Path(__file__).resolve().parents[1]
# the running interpreter's bench (whichever venv runs the tests: `make test VENV=...`)
BENCH = [sys.executable, "-m", "bench.cli"]
FRAMES = 10


@dataclass
class Case:
    args: list[str]
    code: int
    says: list[str]  # substrings the output must contain (file, frame, what was expected)
    absent: list[Path] = field(default_factory=list)  # must not exist afterwards
    single_error: bool = True  # exactly one "error:" message (user errors)


def tum_rows(stamps, x):
    return "".join(f"{t:.6f} {xx:.6f} 0 0 0 0 0 1\n" for t, xx in zip(stamps, x, strict=True))


def npy_folder(root: Path, name: str, break_frame=None) -> Path:
    """A frame folder of FRAMES frames (0.1 s apart) with a TUM file; ``break_frame(folder)``
    damages it."""
    folder = root / name
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(FRAMES):
        p = rng.uniform(-20, 20, (50, 3))
        np.save(folder / f"frame_{i:03d}.npy", p)
        np.save(folder / f"frame_{i:03d}_dop.npy", rng.normal(0, 1, 50))
    t = 0.1 * np.arange(FRAMES)
    (folder / "gt.txt").write_text(tum_rows(t, 0.8 * t))
    if break_frame is not None:
        break_frame(folder)
    return folder


def stores(root: Path) -> dict[str, Path]:
    seq = constant_twist_sequence(n_frames=30, n_points=300)
    good = write_store(seq, root / "good.h5")
    out = {"good": good}
    out["zero"] = root / "zero.h5"
    out["zero"].write_bytes(b"")
    out["random"] = root / "random.h5"
    out["random"].write_bytes(np.random.default_rng(1).bytes(20000))
    out["truncated"] = root / "truncated.h5"
    out["truncated"].write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    nan = root / "nan.h5"
    shutil.copy(good, nan)
    with h5py.File(nan, "r+") as h5:
        off = h5["frames/offset"][:]
        h5["points/xyz"][off[7]] = np.nan  # frame 7's first point
    out["nan"] = nan
    short_dop = root / "short_doppler.h5"
    shutil.copy(good, short_dop)
    with h5py.File(short_dop, "r+") as h5:
        h5["points/doppler"].resize(h5["points/doppler"].shape[0] - 5, axis=0)
    out["short_doppler"] = short_dop
    scans = [seq.scan(i) for i in range(len(seq))]
    s = scans[4]
    scans[4] = Scan(s.stamp, s.points[:1], s.doppler[:1], {"power": s.fields["power"][:1]})
    out["single"] = write_store(MemorySequence("single", seq.sensor, scans, seq.ground_truth),
                                root / "single.h5")
    scans = [Scan(x.stamp, x.points, None) for x in (seq.scan(i) for i in range(len(seq)))]
    out["no_doppler"] = write_store(MemorySequence("nodop", seq.sensor, scans,
                                                   seq.ground_truth), root / "no_doppler.h5")
    return out


def bags(root: Path) -> dict[str, Path]:
    motion = Motion()
    truth = make_truth(motion, 6, 40)
    good = write_ntu_bag(root / "good.bag", truth)
    gt = root / "gt_odom.txt"
    write_gt_tum(gt, motion, truth.stamps[0] - 0.1, truth.stamps[-1] + 0.1)
    out = {"good": good, "gt": gt}
    out["zero"] = root / "zero.bag"
    out["zero"].write_bytes(b"")
    out["random"] = root / "random.bag"
    out["random"].write_bytes(b"#ROSBAG V2.0\n" + np.random.default_rng(2).bytes(5000))
    out["truncated"] = root / "truncated.bag"
    out["truncated"].write_bytes(good.read_bytes()[: good.stat().st_size * 2 // 3])
    out["empty_frame"] = write_ntu_bag(root / "empty_frame.bag", truth, empty_frame=3)
    return out


def build_cases(tmp: Path) -> dict[str, Case]:
    st = stores(tmp)
    bg = bags(tmp)
    out = tmp / "out"
    out.mkdir()
    cases: dict[str, Case] = {}

    # -- frames, through convert (npy-frames) ------------------------------------------------
    def frame_case(name, damage, says, code=2, extra=()):
        folder = npy_folder(tmp, name, damage)
        dest = out / f"{name}.h5"
        cases[f"convert-{name}"] = Case(
            ["convert", "npy-frames", str(folder), "--period", "0.1", *extra, "--out", str(dest)],
            code, says, [dest] if code else [])

    def empty(folder):
        np.save(folder / "frame_003.npy", np.zeros((0, 3)))
        np.save(folder / "frame_003_dop.npy", np.zeros(0))

    def all_nan(folder):
        np.save(folder / "frame_004.npy", np.full((50, 3), np.nan))

    def single(folder):
        np.save(folder / "frame_005.npy", np.ones((1, 3)))
        np.save(folder / "frame_005_dop.npy", np.zeros(1))

    def dop_length(folder):
        np.save(folder / "frame_006_dop.npy", np.zeros(49))

    def dop_missing(folder):
        (folder / "frame_002_dop.npy").unlink()

    def gt_text(text):
        return lambda folder: (folder / "gt.txt").write_text(text)

    t = 0.1 * np.arange(FRAMES)
    frame_case("empty-frame", empty, ["frame_003.npy", "frame 3", "empty scan"])
    frame_case("nan-frame", all_nan, ["frame_004.npy", "frame 4", "empty scan"])
    frame_case("single-point-frame", single, [], code=0)
    frame_case("doppler-length", dop_length, ["frame_006.npy", "frame 6", "(49,)"])
    frame_case("doppler-missing", dop_missing, ["frame_002_dop.npy", "missing Doppler"])
    frame_case("gt-short", gt_text(tum_rows(t[:6], t[:6])), ["gt.txt", "6 GT rows", "10 frames"])
    frame_case("gt-short-by-time", gt_text(tum_rows(t[:6], t[:6])), [], code=0,
               extra=["--associate", "time"])
    frame_case("gt-garbled", gt_text(tum_rows(t[:3], t[:3]) + "0.3 1 2 three 0 0 0 1\n"),
               ["gt.txt", "line 4", "expected 8 numbers"])
    back = t.copy()
    back[[5, 6]] = back[[6, 5]]
    frame_case("gt-backwards", gt_text(tum_rows(back, t)),
               ["gt.txt", "pose row 6", "goes backwards"], extra=["--associate", "time"])
    # associated by row order (the default) the stamps are not used, but rows out of time
    # order would give the poses to the wrong frames
    frame_case("gt-backwards-by-order", gt_text(tum_rows(back, t)),
               ["gt.txt", "pose row 6", "goes backwards"])
    dup = np.r_[t[:5], t[4], t[5:]]
    frame_case("gt-duplicate-stamp", gt_text(tum_rows(dup, np.arange(len(dup)))),
               ["gt.txt", "pose row 5", "repeats the stamp"], extra=["--associate", "time"])
    frame_case("gt-duplicate-row", gt_text(tum_rows(dup, np.r_[t[:5], t[4], t[5:]])), [],
               code=0, extra=["--associate", "time"])
    frame_case("gt-no-overlap", gt_text(tum_rows(t + 1000, t)),
               ["gt.txt", "does not overlap", "time offset"], extra=["--associate", "time"])

    # -- stores, through inspect and run ----------------------------------------------------
    for name in ("zero", "random", "truncated"):
        path = st[name]
        cases[f"inspect-{name}-store"] = Case(["inspect", str(path)], 2, [path.name])
        run_out = out / f"run-{name}"
        cases[f"run-{name}-store"] = Case(
            ["run", "--method", "doppler", "--data", str(path), "--out", str(run_out)], 2,
            [path.name], [run_out])
    cases["inspect-nan-store"] = Case(["inspect", str(st["nan"])], 2,
                                      ["nan.h5", "frame 7", "non-finite"])
    cases["run-nan-store"] = Case(
        ["run", "--method", "doppler", "--data", str(st["nan"]), "--out", str(out / "rn")], 1,
        ["nan.h5", "frame 7", "non-finite"], [out / "rn" / "metrics.json"], single_error=False)
    for cmd in ("inspect", "run"):
        args = ([cmd, str(st["short_doppler"])] if cmd == "inspect" else
                [cmd, "--method", "doppler", "--data", str(st["short_doppler"]), "--out",
                 str(out / "rsd")])
        cases[f"{cmd}-short-doppler-store"] = Case(args, 2, ["short_doppler.h5",
                                                             "points/doppler"], [out / "rsd"])
    cases["inspect-single-point-store"] = Case(["inspect", str(st["single"])], 0, [])
    # a frame with one point: the run finishes, with a named warning about that frame
    cases["run-single-point-store"] = Case(
        ["run", "--method", "doppler", "--data", str(st["single"]), "--out", str(out / "r1")],
        0, ["warning", "single.h5", "frame 4", "1 point(s) to register"])
    # a Doppler method on a store without Doppler: refused before any job (exit 2)
    cases["run-no-doppler-store"] = Case(
        ["run", "--method", "doppler", "--data", str(st["no_doppler"]), "--out",
         str(out / "rnd")], 2, ["no_doppler.h5", "doppler needs Doppler"], [out / "rnd"])

    # -- bags, through convert ----------------------------------------------------------------
    for name in ("zero", "random", "truncated", "empty_frame"):
        dest = out / f"bag-{name}.h5"
        says = [bg[name].name] + (["frame 3", "empty scan"] if name == "empty_frame" else [])
        cases[f"convert-{name}-bag"] = Case(
            ["convert", "ntu4dradlm", str(bg[name]), "--gt", str(bg["gt"]), "--out", str(dest)],
            2, says, [dest])

    # -- experiments and options --------------------------------------------------------------
    def yaml_case(name, text, says):
        path = tmp / f"{name}.yaml"
        path.write_text(text.format(store=st["good"], out=out / name))
        cases[f"run-yaml-{name}"] = Case(["run", str(path)], 2, [path.name, *says],
                                         [out / name])

    good_seq = "sequences: [{{path: {store}}}]\nout: {out}\n"
    yaml_case("unknown-key", "name: x\n" + good_seq + "methods: [{{name: doppler}}]\nfoo: 1\n",
              ["foo"])
    yaml_case("unknown-method", "name: x\n" + good_seq + "methods: [{{name: nosuch}}]\n",
              ["nosuch"])
    yaml_case("unknown-param", "name: x\n" + good_seq
              + "methods: [{{name: doppler, params: {{tau_spatial: 1}}}}]\n", ["tau_spatial"])
    yaml_case("bad-yaml", "name: x\n" + good_seq + "methods: [{{name: doppler\n", [])
    for name, param, says in (("bad-value", "tau_spatial_m=abc", ["tau_spatial_m"]),
                              ("unknown-param", "nonsense=1", ["nonsense"]),
                              ("no-equals", "tau_spatial_m", ["key=value"])):
        run_out = out / f"p-{name}"
        cases[f"run-p-{name}"] = Case(["run", "--method", "doppler", "--data", str(st["good"]),
                                       "-p", param, "--out", str(run_out)], 2, says,
                                      [run_out / "metrics.json"])

    # -- output destinations --------------------------------------------------------------------
    folder = npy_folder(tmp, "fine")
    (out / "a-folder.h5").mkdir()
    cases["convert-out-is-a-folder"] = Case(
        ["convert", "npy-frames", str(folder), "--period", "0.1", "--out",
         str(out / "a-folder.h5")], 2, ["a-folder.h5", "is a folder"])
    blocker = out / "a-file"
    blocker.write_text("")
    cases["convert-out-unwritable"] = Case(
        ["convert", "npy-frames", str(folder), "--period", "0.1", "--out",
         str(blocker / "x.h5")], 2, ["a-file"])
    cases["run-out-unwritable"] = Case(
        ["run", "--method", "doppler", "--data", str(st["good"]), "--out",
         str(blocker / "run")], 2, ["a-file"])
    return cases


def run_bench(args: list[str]) -> subprocess.CompletedProcess:
    env = {**os.environ, "COLUMNS": "200", "OMP_NUM_THREADS": "1"}
    # in the session's temporary working folder: default outputs (results/...) go there; the
    # inspect plot goes next to its store (in the temporary folder too)
    return subprocess.run([*BENCH, *args], capture_output=True, text=True, cwd=Path.cwd(),
                          env=env, timeout=120)


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("broken")
    cases = build_cases(tmp)
    with ThreadPoolExecutor(3) as pool:
        done = dict(zip(cases, pool.map(lambda c: run_bench(c.args), cases.values()),
                        strict=True))
    return tmp, cases, done


CASE_NAMES = [
    "convert-empty-frame", "convert-nan-frame", "convert-single-point-frame",
    "convert-doppler-length", "convert-doppler-missing", "convert-gt-short",
    "convert-gt-short-by-time", "convert-gt-garbled", "convert-gt-backwards",
    "convert-gt-backwards-by-order",
    "convert-gt-duplicate-stamp", "convert-gt-duplicate-row", "convert-gt-no-overlap",
    "inspect-zero-store", "run-zero-store", "inspect-random-store", "run-random-store",
    "inspect-truncated-store", "run-truncated-store", "inspect-nan-store", "run-nan-store",
    "inspect-short-doppler-store", "run-short-doppler-store", "inspect-single-point-store",
    "run-single-point-store", "run-no-doppler-store",
    "convert-zero-bag", "convert-random-bag", "convert-truncated-bag",
    "convert-empty_frame-bag",
    "run-yaml-unknown-key", "run-yaml-unknown-method", "run-yaml-unknown-param",
    "run-yaml-bad-yaml", "run-p-bad-value", "run-p-unknown-param", "run-p-no-equals",
    "convert-out-is-a-folder", "convert-out-unwritable", "run-out-unwritable",
]


def test_every_case_is_listed(sweep):
    assert sorted(sweep[1]) == sorted(CASE_NAMES)


@pytest.mark.parametrize("name", CASE_NAMES)
def test_broken_input(sweep, name):
    tmp, cases, done = sweep
    case, proc = cases[name], done[name]
    output = proc.stdout + proc.stderr
    flat = " ".join(output.split())  # undo any line wrapping of long paths
    context = f"bench {' '.join(case.args)}\n--- exit {proc.returncode}\n{output}"
    assert "Traceback" not in output and "most recent call last" not in output, context
    assert proc.returncode == case.code, context
    for text in case.says:
        assert text in flat, f"{text!r} missing\n{context}"
    if case.code == 2 and case.single_error:
        assert len(re.findall(r"(?m)^\s*error:", output)) == 1, context
    for path in case.absent:
        assert not path.exists(), f"{path} exists\n{context}"
    leftovers = [p for p in tmp.rglob("*.tmp")]
    assert leftovers == [], leftovers
