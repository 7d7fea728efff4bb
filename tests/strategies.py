"""Hypothesis strategies shared by the property tests (tests/test_props_*.py), their settings
profiles and the in-process runner they call ``bench`` with.

Profiles (``HYPOTHESIS_PROFILE``): ``fast`` (the default, inside `make test`: few examples,
derandomized so CI is stable, no example database written) and ``long`` (`make fuzz`: many
random examples). ``examples(n)`` scales a test's own count: ``n`` in ``fast``, 25 x ``n`` in
``long``.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import os
import sys
import tempfile
import traceback
import tracemalloc
from dataclasses import dataclass
from pathlib import Path

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

# Hypothesis keeps caches (and the patches of failing examples) in a folder of its own: never
# in the checkout (`make test` writes nothing there)
set_hypothesis_home_dir(os.path.join(tempfile.gettempdir(), f"doppler-bench-hypothesis-"
                                                            f"{os.getuid()}"))
_HEALTH = [HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
           HealthCheck.data_too_large, HealthCheck.filter_too_much]
settings.register_profile("fast", max_examples=4, deadline=None, derandomize=True,
                          database=None, suppress_health_check=_HEALTH, print_blob=True)
settings.register_profile("long", max_examples=100, deadline=None, database=None,
                          suppress_health_check=_HEALTH, print_blob=True)
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "fast")
settings.load_profile(PROFILE)
LONG_FACTOR = 25


def examples(n: int) -> settings:
    """A test's own example count: ``n`` in the fast profile, ``LONG_FACTOR`` x more in long."""
    return settings(max_examples=n * (LONG_FACTOR if PROFILE == "long" else 1))


# ---- running bench in-process ----------------------------------------------------------------

#: the most a command on the tiny test inputs may allocate (tracemalloc peak) [bytes]
MEMORY_LIMIT = 300_000_000


@dataclass
class Outcome:
    code: int | str  # the exit code, or "traceback" when an exception escaped main()
    text: str  # stdout + stderr
    peak_bytes: int

    @property
    def errors(self) -> list[str]:
        return [line for line in self.text.splitlines() if line.startswith("error:")]


@contextlib.contextmanager
def environment(env: dict[str, str | None] | None):
    """``os.environ`` with ``env`` set (None: removed), restored afterwards."""
    saved = {k: os.environ.get(k) for k in env or {}}
    try:
        for k, v in (env or {}).items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def bench(args, env: dict[str, str | None] | None = None) -> Outcome:
    """``bench ARGS`` run in this process through ``bench.cli.main`` (the entry point a user
    runs): its exit code, printed text and peak traced memory."""
    from bench.cli import main

    out = io.StringIO()
    argv = sys.argv
    sys.argv = ["bench", *map(str, args)]
    tracemalloc.start()
    try:
        with environment(env), contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            try:
                main()
                code: int | str = 0
            except SystemExit as exit_:
                code = 0 if exit_.code is None else exit_.code
            except BaseException:  # noqa: BLE001  # the property: never a traceback
                out.write(traceback.format_exc())
                code = "traceback"
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        sys.argv = argv
    return Outcome(code, out.getvalue(), peak)


def tree_digest(*roots: Path, skip: tuple[Path, ...] = ()) -> dict[str, str]:
    """Path -> content hash of every file and folder under ``roots`` (``skip``: left out)."""
    skip = tuple(Path(s).resolve() for s in skip)
    found = {}
    for root in roots:
        for dirpath, dirnames, filenames in os.walk(root):
            here = Path(dirpath).resolve()
            if any(here == s or here.is_relative_to(s) for s in skip):
                dirnames[:] = []
                continue
            found[str(here)] = "dir"
            for name in filenames:
                path = here / name
                if any(path == s for s in skip):
                    continue
                try:
                    found[str(path)] = hashlib.sha256(path.read_bytes()).hexdigest()
                except OSError as err:
                    found[str(path)] = f"unreadable {err.errno}"
    return found


def assert_clean(outcome: Outcome, names: tuple[str, ...] = (), ok: tuple[int, ...] = (0,)):
    """The property every command keeps: an exit code of ``ok`` or exit 2 with exactly one
    ``error:`` line (naming one of ``names`` when given), never a traceback, memory bounded."""
    assert outcome.code != "traceback" and "Traceback" not in outcome.text, outcome.text
    assert outcome.peak_bytes < MEMORY_LIMIT, (outcome.peak_bytes, outcome.text[-2000:])
    if outcome.code == 2:
        assert len(outcome.errors) == 1, outcome.text
        if names:
            assert any(n in outcome.errors[0] for n in names), (names, outcome.text)
    else:
        assert outcome.code in ok, (outcome.code, outcome.text)


# ---- numbers, names, paths -------------------------------------------------------------------

#: values no numeric option takes: not numbers, or not finite, or beyond any range (|x| >= 1e13)
bad_numbers = st.one_of(
    st.sampled_from(["nan", "NaN", "-nan", "inf", "-inf", "+inf", "Infinity", "1e999", "-1e999",
                     "1e13", "-1e13", "99999999999999999999", "-99999999999999999999"]),
    st.floats(min_value=1e13, allow_nan=False, allow_infinity=True).map(repr),
    st.floats(max_value=-1e13, allow_nan=False, allow_infinity=True).map(repr),
    st.integers(min_value=10**13, max_value=10**40).map(str),
    st.integers(min_value=300, max_value=5000).map(lambda n: "1" + "0" * n),  # beyond any float
    st.integers(max_value=-(10**13), min_value=-(10**40)).map(str),
)
#: anything typed where a number goes
any_numbers = st.one_of(
    bad_numbers,
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(min_value=-(10**6), max_value=10**7).map(str),
    st.floats(min_value=-1e4, max_value=1e4).map(lambda x: f"{x:.3g}"),
    st.text(alphabet="0123456789.,-+eExX _abn", max_size=12),
)
#: comma-separated number lists (--lengths, --sizes, --poses)
number_lists = st.one_of(
    st.lists(any_numbers.filter(lambda s: "," not in s), min_size=0, max_size=4).map(",".join),
    st.sampled_from(["", ",", "8,,48", "8;48", "8 48", "1e999", "nan,8"]),
)
#: names a user might give a run or a method
names = st.one_of(st.text(max_size=20), st.sampled_from(["", ".", "..", "a/b", "a\\b", " ",
                                                         "x" * 300, "-", "--name"]))


def path_texts(existing: list[Path]) -> st.SearchStrategy[str]:
    """Paths typed on the command line: ``existing`` ones (files and folders of the wrong kind,
    junk), missing ones, empty, with a NUL byte, with over-long names."""
    return st.one_of(
        st.sampled_from([str(p) for p in existing]),
        st.sampled_from(["", " ", "\0", "a\0b", "x" * 256, "/" + "y" * 300 + "/z",
                         "/nonexistent/folder/file.h5", "missing.h5", "/dev/null"]),
        # names that do not exist, relative to the working folder; never "..", "/" or a path
        # that climbs out of the test's folders (a command would read and write there)
        st.text(alphabet="abc_- ", min_size=1, max_size=15).map(lambda t: f"missing-{t}"),
    )


# ---- environment variables --------------------------------------------------------------------

frame_limits = st.one_of(st.sampled_from(["", "256", "inf", "0", "-5", "nan", "abc", "1e400",
                                          " 12 ", "1_000"]), any_numbers)


def lock_paths(tmp: Path) -> st.SearchStrategy[str]:
    """Values of DOPPLER_BENCH_TIMING_LOCK: good ones (a new or existing file in a folder of
    ours), a missing folder, a folder, empty, a NUL byte."""
    return st.sampled_from([str(tmp / "timing.lock"), str(tmp / "missing" / "timing.lock"),
                            str(tmp), "", " ", "rel/missing/x.lock",
                            str(tmp / ("n" * 300))])


# ---- files of every reader --------------------------------------------------------------------

def _row_numbers(width: int) -> st.SearchStrategy[list[str]]:
    finite = st.floats(min_value=-1e3, max_value=1e3, allow_nan=False).map(lambda x: f"{x:.6g}")
    odd = st.sampled_from(["nan", "inf", "-inf", "1e308", "x", "", "0x1p3", "1,5"])
    return st.lists(st.one_of(finite, finite, finite, odd), min_size=width, max_size=width)


@st.composite
def pose_rows(draw, width: int, n_max: int = 40, stamps: bool = True):
    """Rows of a pose file: mostly well-formed (monotonic stamps, unit quaternions), with a
    chance of odd values, wrong widths, a header, blank lines and comments."""
    import numpy as np

    n = draw(st.integers(0, n_max))
    t0 = draw(st.sampled_from([0.0, 1654232000.0, 1e6]))
    dt = draw(st.sampled_from([0.1, 0.05, 0.0, -0.1, 1e-9]))
    rows = []
    for i in range(n):
        kind = draw(st.sampled_from(["good"] * 6 + ["odd", "short", "long"]))
        if kind == "good":
            q = np.array(draw(st.lists(st.floats(-1, 1), min_size=4, max_size=4)))
            q = q / np.linalg.norm(q) if np.linalg.norm(q) > 1e-3 else np.array([0, 0, 0, 1.0])
            values = [t0 + i * dt] if stamps else []
            values += [i * 0.8, 0.1 * i, 0.0]
            values += list(q) if width in (8, 9) else []
            text = [f"{v:.9f}" for v in values]
            if width in (12, 13):  # a 3x4 [R|t] row-major (rotation about z)
                c, s = np.cos(0.01 * i), np.sin(0.01 * i)
                m = [c, -s, 0, i * 0.8, s, c, 0, 0.1 * i, 0, 0, 1, 0]
                text = ([f"{int(t0 * 1e6 + i * dt * 1e6)}"] if width == 13 else []) + \
                    [f"{v:.9f}" for v in m]
            rows.append(" ".join(text))
        elif kind == "odd":
            rows.append(" ".join(draw(_row_numbers(width))))
        else:
            rows.append(" ".join(draw(_row_numbers(width + (-2 if kind == "short" else 3)))))
    if draw(st.booleans()):
        rows.insert(0, draw(st.sampled_from(["# timestamp tx ty tz qx qy qz qw", "#", "t x y",
                                             ""])))
    return "\n".join(rows) + draw(st.sampled_from(["\n", "", "\n\n", "\r\n"]))


def tum_files():
    return pose_rows(8)


def kitti_files():
    return pose_rows(12, stamps=False)


def boreas_files():
    return pose_rows(13)


@st.composite
def stamp_files(draw, n_max: int = 40):
    n = draw(st.integers(0, n_max))
    t0 = draw(st.sampled_from([0.0, 1654232000.0]))
    dt = draw(st.sampled_from([0.1, 0.0, -0.1]))
    rows = [f"{t0 + i * dt:.9f}" for i in range(n)]
    if rows and draw(st.booleans()):
        rows[draw(st.integers(0, len(rows) - 1))] = draw(st.sampled_from(["nan", "x", "", "1 2"]))
    return "\n".join(rows) + "\n"


junk_bytes = st.one_of(st.binary(max_size=200),
                       st.sampled_from([b"", b"\x89HDF\r\n\x1a\n" + b"\0" * 40,
                                        b"#ROSBAG V2.0\n" + b"\0" * 40, b"\xff" * 64]))

#: ways to damage a store (bench.options tests and the store properties)
STORE_DAMAGE = ("drop-attr", "odd-attr", "drop-dataset", "truncate", "nan-stamps",
                "nan-points", "unsorted-stamps", "odd-gt", "empty-frame")
store_damage = st.tuples(st.sampled_from(STORE_DAMAGE),
                         st.sampled_from(["format", "format_version", "fields", "name",
                                          "sensor_kind", "period_s", "n_frames", "provenance",
                                          "doppler_kind", "sensor_model"]),
                         st.sampled_from(["frames/stamp", "frames/offset", "points/xyz",
                                          "points/doppler", "ground_truth/poses",
                                          "ground_truth/stamps", "extrinsic/T_body_sensor"]),
                         st.sampled_from([-1, 0, 3.5, "x", "nan", "[1, 2]", "{}", b"\xff",
                                          float("nan"), 10**12]))


def damage_store(path: Path, damage: tuple) -> None:
    """Apply one ``store_damage`` to the store at ``path`` (in place)."""
    import h5py
    import numpy as np

    kind, attr, dataset, value = damage
    if kind == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[: len(data) // 2])
        return
    with h5py.File(path, "r+") as f:
        if kind == "drop-attr" and attr in f.attrs:
            del f.attrs[attr]
        elif kind == "odd-attr":
            f.attrs[attr] = np.void(value) if isinstance(value, bytes) else value
        elif kind == "drop-dataset" and dataset in f:
            del f[dataset]
        elif kind == "nan-stamps":
            f["frames/stamp"][1] = np.nan
        elif kind == "nan-points":
            xyz = f["points/xyz"]
            xyz[: min(5, len(xyz))] = np.nan
        elif kind == "unsorted-stamps":
            s = f["frames/stamp"][:]
            f["frames/stamp"][:] = s[::-1]
        elif kind == "odd-gt" and "ground_truth/poses" in f:
            poses = f["ground_truth/poses"]
            poses[0] = np.zeros((4, 4)) if value != "nan" else np.full((4, 4), np.nan)
        elif kind == "empty-frame":
            off = f["frames/offset"][:]
            off[2] = off[1]
            f["frames/offset"][:] = off


@st.composite
def npy_frame_folders(draw, n_max: int = 6):
    """A NumPy frame folder's files (``frame_001.npy`` points, ``frame_001_dop.npy`` Doppler):
    name -> array, mostly well-formed, with a chance of odd shapes, dtypes, NaN, empty frames,
    a missing or mismatched Doppler file and stray names."""
    import numpy as np

    files = {}
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    for i in range(1, draw(st.integers(0, n_max)) + 1):
        n = draw(st.sampled_from([50, 50, 50, 0, 1, 3]))
        points = rng.uniform(-30, 30, (n, 3))
        doppler = rng.uniform(-5, 5, n)
        odd = draw(st.sampled_from(["none"] * 5 + ["nan", "shape", "dtype", "no-dop",
                                                   "short-dop", "2d-dop", "inf", "object"]))
        if odd == "nan" and n:
            points[0] = np.nan
        elif odd == "inf" and n:
            doppler[-1] = np.inf
        elif odd == "shape":
            points = points.reshape(-1)
        elif odd == "dtype":
            points = points.astype(np.float16)
        elif odd == "short-dop":
            doppler = doppler[:-1]
        elif odd == "2d-dop":
            doppler = doppler[:, None]
        elif odd == "object":
            points = np.array([["a", "b", "c"]] * max(n, 1), dtype=object)
        files[f"frame_{i:03d}.npy"] = points
        if odd != "no-dop":
            files[f"frame_{i:03d}_dop.npy"] = doppler
    if draw(st.booleans()):
        files[draw(st.sampled_from(["frame_x.npy", "frame_0001.npy", "notes.npy",
                                    "frame_999999999999999999999999.npy"]))] = np.zeros((3, 3))
    return files
