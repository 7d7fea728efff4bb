"""bench score's contract for trajectories made elsewhere (bench.runs.external.score): a clock that
does not fit the scans is refused with the offset or unit that fits (on the vendored real
NTU4DRadLM sample, its ground truth taken as an estimate and shifted by known offsets), the
coverage share is of the scans WITH ground truth, an estimate too short is named as such, the
Boreas submission format scores as its TUM twin, and run names and folders are guarded."""

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from helpers_cli import run_bench as _bench

from bench.runs.external.match import match_to_scans
from bench.runs.external.score import ExternalSpec, score_external
from bench.runs.folders import read_run
from bench.runs.job import Job, run_job
from conftest import constant_twist_sequence
from loaders.errors import DataError
from loaders.posefile import read_tum
from loaders.scan import MemorySequence
from loaders.se3 import tum_from_T
from loaders.store import StoreSequence, write_store
from loaders.trajectory import Trajectory

SAMPLE = Path(__file__).resolve().parents[1] / "samples" / "ntu4dradlm-loop1.h5"
PERIOD_S = 1 / 12  # the sample's scan period
#: a suggested offset is right within this for a copy of the ground truth (measured: 1e-6 s)
EXACT_S = 0.01
#: the motion profiles' fit itself, between the grid steps of PERIOD_S / 8 = 0.0104 s (measured
#: 1e-6 s for a copy of the ground truth; a fit to the nearest grid step is 0.005 s off here)
FIT_S = 0.002


@pytest.fixture(scope="module")
def sample():
    assert SAMPLE.exists(), f"{SAMPLE} missing: the vendored sample is part of the repository"
    seq = StoreSequence(SAMPLE, fields=())
    gt = seq.ground_truth
    seq.close()
    assert len(gt) == 250
    return gt


def write_tum(path: Path, stamps, poses, times=None) -> Path:
    xyz, quat = tum_from_T(np.asarray(poses))
    cols = [np.asarray(stamps)[:, None], xyz, quat] + ([np.asarray(times)[:, None]]
                                                        if times is not None else [])
    np.savetxt(path, np.hstack(cols), fmt="%.17g")
    return path


def suggested(message: str) -> float:
    found = re.findall(r"with --time-offset (-?\d+\.\d+)", message)
    assert found, message
    return float(found[-1])


def test_a_clock_off_by_a_fraction_of_a_period_is_refused_with_the_offset(sample, tmp_path):
    """GT 0.37 s behind the scans (est_stamp + 0.37 = sensor clock): no scan has a pose within
    0.01 s; the refusal names the estimate and the offset that fits; asked to interpolate
    (--max-gap), every scan is covered but the clock check still refuses; the suggested offset
    scores it exactly."""
    path = write_tum(tmp_path / "late.tum", sample.stamps - 0.37, sample.poses)
    with pytest.raises(DataError) as err:
        score_external(SAMPLE, ExternalSpec(path, "late"), tmp_path / "r")
    text = str(err.value)
    assert text.startswith(f"{path} does not overlap the scans of {SAMPLE}: no scan has a pose "
                           "within 0.01 s")
    assert suggested(text) == pytest.approx(0.37, abs=EXACT_S)
    with pytest.raises(DataError, match=r"late.tum: its clock does not fit the scans") as err:
        score_external(SAMPLE, ExternalSpec(path, "late", max_gap_s=0.3), tmp_path / "r")
    offset = suggested(str(err.value))
    assert offset == pytest.approx(0.37, abs=EXACT_S)
    assert not (tmp_path / "r").exists()
    # on another clock, with an offset given that is 0.37 s short: the suggestion is the whole
    other = write_tum(tmp_path / "other.tum", sample.stamps - 1000.37, sample.poses)
    with pytest.raises(DataError, match="no scan has a pose within") as err:
        score_external(SAMPLE, ExternalSpec(other, "late", time_offset_s=1000.0),
                       tmp_path / "r")
    assert suggested(str(err.value)) == pytest.approx(1000.37, abs=EXACT_S)
    out = score_external(SAMPLE, ExternalSpec(path, "late", time_offset_s=offset),
                         tmp_path / "r")
    res = read_run(out.run_dir).result
    assert out.coverage["matched"] == 250 and res.relative(8.0).trans_m_mean < 1e-6


def test_the_profile_fit_is_finer_than_its_grid(sample, tmp_path):
    """The ground truth resampled at 27 Hz from 0.013 s (so no shift is a whole number of grid
    steps) and 0.37 s behind, scored with --max-gap: refused; the fit the message states is
    0.37 s within FIT_S (a fit to the nearest grid step is up to 0.005 s off)."""
    from scipy.spatial.transform import Rotation, Slerp

    q = np.arange(0.013, sample.stamps[-1], 1 / 27)
    poses = np.repeat(np.eye(4)[None], len(q), axis=0)
    poses[:, :3, :3] = Slerp(sample.stamps, Rotation.from_matrix(sample.poses[:, :3, :3]))(
        q).as_matrix()
    poses[:, :3, 3] = np.column_stack([np.interp(q, sample.stamps, sample.poses[:, k, 3])
                                       for k in range(3)])
    path = write_tum(tmp_path / "27hz.tum", q - 0.37, poses)
    with pytest.raises(DataError, match="its clock does not fit") as err:
        score_external(SAMPLE, ExternalSpec(path, "r27", max_gap_s=0.2), tmp_path / "r")
    fit = re.findall(r"only shifted by ([+-]\d+\.\d+) s", str(err.value))
    assert float(fit[0]) == pytest.approx(0.37, abs=FIT_S)


@pytest.mark.parametrize("shift_s, refused", [(0.005, False), (-0.005, False), (0.05, True),
                                             (-0.05, True), (0.1, True), (-0.1, True)])
def test_a_copy_of_the_ground_truth_a_little_off(sample, tmp_path, shift_s, refused):
    """Interpolated (--max-gap): a copy of the ground truth off by less than the tolerance
    (0.01 s) passes; off by 0.05 s or more, either way, is refused: the profiles of a copy fit
    exactly (the bootstrap interval of the shift is the shift itself, measured within 1e-4 s),
    so the data decide; the suggestion is the shift (a negative shift is flagged as a positive
    one is: a mutant that flagged only positive shifts survived before)."""
    path = write_tum(tmp_path / "off.tum", sample.stamps - shift_s, sample.poses)
    spec = ExternalSpec(path, "off", max_gap_s=0.2)
    if refused:
        with pytest.raises(DataError, match="its clock does not fit") as err:
            score_external(SAMPLE, spec, tmp_path / "r")
        assert suggested(str(err.value)) == pytest.approx(shift_s, abs=EXACT_S)
        assert "95 % interval" in str(err.value)
    else:
        # within the tolerance of its scan: every scan matched, on the store's clock
        out = score_external(SAMPLE, spec, tmp_path / "r")
        assert out.coverage["matched"] == 250 and out.clock.startswith("on the store's clock")


@pytest.mark.parametrize("shift_s", [5.0, -5.0])
def test_whole_scan_periods_off_match_every_stamp_yet_are_refused(sample, tmp_path, shift_s):
    """GT shifted by 60 scan periods: stamp matching (evo's rule) pairs 190 of the 250 scans,
    each with the wrong pose; the motion profile sees the clock: refused even when the
    coverage is allowed, with the offset that fits; --trust-clock scores it as it is."""
    path = write_tum(tmp_path / "shifted.tum", sample.stamps + shift_s, sample.poses)
    m = match_to_scans(Trajectory(sample.stamps + shift_s, sample.poses), sample.stamps)
    assert m.report["matched"] == 190  # the stamps alone look fine
    with pytest.raises(DataError, match=r"shifted.tum: its clock does not fit the scans of "
                                        r".*ntu4dradlm-loop1.h5") as err:
        score_external(SAMPLE, ExternalSpec(path, "shifted", min_coverage=0.5), tmp_path / "r")
    assert suggested(str(err.value)) == pytest.approx(-shift_s, abs=EXACT_S)
    trusted = score_external(SAMPLE, ExternalSpec(path, "shifted", min_coverage=0.5,
                                                  trust_clock=True), tmp_path / "r")
    assert trusted.coverage["scored"] == 190 and trusted.clock.startswith("not checked")


@pytest.fixture(scope="module")
def doppler_run(tmp_path_factory):
    """The harness's doppler run on the sample: a real odometry's output."""
    out = tmp_path_factory.mktemp("doppler")
    outcome = run_job(Job(store=SAMPLE, method="doppler", seed=None, out_root=out))
    assert outcome.status == "done", outcome.message
    return read_tum(outcome.run_dir / "est_tum.txt")


def test_a_real_odometry_on_its_clock_passes_and_shifted_is_refused(doppler_run, tmp_path):
    """A real odometry's output is not refused on its own clock (its stamps are the scans'; its
    profile fits best at -0.06 s, an interval of about [-0.27, +0.13] s around it); shifted by 5
    s it is refused, the suggestion within one scan period of -5 s; 0.37 s early with
    interpolation asked, it is refused listing every offset a scan period apart the interval
    cannot tell apart (-0.37 among them); 0.37 s late, the 20 s sample cannot tell (the gain's
    interval reaches below 0): scored as given, saying the clock could not be checked."""
    est = doppler_run
    own = write_tum(tmp_path / "own.tum", est.stamps, est.poses)
    out = score_external(SAMPLE, ExternalSpec(own, "own"), tmp_path / "r")
    assert out.coverage["matched"] == 250 and out.clock.startswith("on the store's clock")
    assert not out.warnings
    shifted = write_tum(tmp_path / "ahead.tum", est.stamps + 5.0, est.poses)
    with pytest.raises(DataError, match="its clock does not fit") as err:
        score_external(SAMPLE, ExternalSpec(shifted, "ahead", min_coverage=0), tmp_path / "r")
    assert suggested(str(err.value)) == pytest.approx(-5.0, abs=PERIOD_S + 1e-6)
    early = write_tum(tmp_path / "early.tum", est.stamps + 0.37, est.poses)
    with pytest.raises(DataError, match="its clock does not fit") as err:
        score_external(SAMPLE, ExternalSpec(early, "early", max_gap_s=0.2), tmp_path / "r")
    offsets = [float(v) for v in re.findall(r"--time-offset (-?\d+\.\d+)", str(err.value))]
    assert len(offsets) >= 3 and "they fit alike" in str(err.value)
    assert min(abs(o + 0.37) for o in offsets) < 1e-3  # the true offset is among them
    late = write_tum(tmp_path / "late.tum", est.stamps - 0.37, est.poses)
    out = score_external(SAMPLE, ExternalSpec(late, "late", max_gap_s=0.2), tmp_path / "r")
    assert out.clock.startswith("the clock could not be checked")
    assert "the data cannot tell that shift from none" in out.clock


@pytest.mark.parametrize("unit, factor", [("ms", 1e3), ("us", 1e6), ("ns", 1e9)])
def test_stamps_in_another_unit_are_refused_naming_it(sample, tmp_path, unit, factor):
    path = write_tum(tmp_path / f"{unit}.tum", sample.stamps * factor, sample.poses)
    with pytest.raises(DataError, match=rf"{unit}.tum: read in seconds, its stamps move it at "
                                        rf".* stamps in another unit, or positions in another "
                                        rf"unit\? .*the path length settles it: stamps in \w+ "
                                        rf".*score it with --stamp-unit {unit}"):
        score_external(SAMPLE, ExternalSpec(path, unit), tmp_path / "r")
    if unit == "ms":
        out = score_external(SAMPLE, ExternalSpec(path, unit, stamp_unit="ms"), tmp_path / "r")
        assert out.coverage["matched"] == 250
        # an estimate of another scale (x 3) in ms is still told: speeds within 10x of the unit
        scaled = sample.poses.copy()
        scaled[:, :3, 3] *= 3.0
        path = write_tum(tmp_path / "scaled.tum", sample.stamps * factor, scaled)
        with pytest.raises(DataError, match="score it with --stamp-unit ms"):
            # a name of its own: the folder "ms" holds the score of another trajectory
            score_external(SAMPLE, ExternalSpec(path, "ms-scaled"), tmp_path / "r")
        # the other way: seconds read as nanoseconds
        path = write_tum(tmp_path / "s.tum", sample.stamps, sample.poses)
        with pytest.raises(DataError, match=r"s.tum: read in nanoseconds, its stamps move it .*"
                                            r"stamps in seconds .*score it with --stamp-unit s "):
            score_external(SAMPLE, ExternalSpec(path, "s", stamp_unit="ns"), tmp_path / "r")


def _partial_gt_store(tmp_path: Path, with_gt: int = 40) -> tuple[Path, Trajectory]:
    """60 scans, ground truth on the first ``with_gt`` only."""
    base = constant_twist_sequence(n_frames=60, n_points=800, max_range_m=70)
    gt = base.ground_truth
    part = Trajectory(gt.stamps[:with_gt], gt.poses[:with_gt])
    store = write_store(MemorySequence("part", base.sensor, list(base), part),
                        tmp_path / "part.h5")
    return store, gt


def test_the_coverage_share_is_of_the_scans_with_ground_truth(tmp_path):
    """36 of the 40 scans with GT is 90 % (the default --min-coverage): scored; over all 60
    scans it would be 60 % and refused. 30 of 40 (75 %) is refused, naming the estimate."""
    store, gt = _partial_gt_store(tmp_path)
    path = write_tum(tmp_path / "first36.tum", gt.stamps[:36], gt.poses[:36])
    out = score_external(store, ExternalSpec(path, "first36"), tmp_path / "r")
    assert out.coverage["scans_with_gt"] == 40 and out.coverage["scored"] == 36
    assert out.coverage["share_scored"] == pytest.approx(0.9)
    short = write_tum(tmp_path / "first30.tum", gt.stamps[:30], gt.poses[:30])
    with pytest.raises(DataError, match=r"first30.tum covers 30 of the 40 scans of .*part.h5 "
                                        r"with ground truth \(75.0 %\), below --min-coverage"):
        score_external(store, ExternalSpec(short, "first30"), tmp_path / "r")


def test_an_estimate_too_short_is_named_not_the_ground_truth(tmp_path):
    store, gt = _partial_gt_store(tmp_path, with_gt=60)
    path = write_tum(tmp_path / "two.tum", gt.stamps[:2], gt.poses[:2])  # 2 of 60 scans: 3 %
    with pytest.raises(DataError) as err:
        score_external(store, ExternalSpec(path, "two"), tmp_path / "r")
    assert str(err.value).startswith(f"{path} covers 2 of the 60 scans")
    with pytest.raises(DataError) as err:
        score_external(store, ExternalSpec(path, "two", min_coverage=0), tmp_path / "r")
    text = str(err.value)
    assert text.startswith(f"{path} is too short to score: it covers 2 of the 60 scans")
    assert "GT path length" not in text


def test_a_large_tolerance_does_not_extend_an_estimate(tmp_path):
    store, gt = _partial_gt_store(tmp_path, with_gt=60)
    path = write_tum(tmp_path / "half.tum", gt.stamps[:30], gt.poses[:30])
    out = score_external(store, ExternalSpec(path, "half", tolerance_s=100.0, min_coverage=0),
                         tmp_path / "r")
    assert out.coverage["scored"] == 30 and out.coverage["share_scored"] == pytest.approx(0.5)


def test_tolerance_zero_keeps_the_matches_and_the_reported_times(tmp_path):
    """Stamps equal to the scans' (bit for bit): with --tolerance 0 every scan is matched and
    keeps the method's reported time (a strict < would lose both)."""
    store, gt = _partial_gt_store(tmp_path, with_gt=60)
    times = np.linspace(1.0, 2.0, 60)
    path = write_tum(tmp_path / "timed.tum", StoreSequence(store, fields=()).stamps, gt.poses,
                     times)
    out = score_external(store, ExternalSpec(path, "timed", tolerance_s=0.0), tmp_path / "r")
    assert out.coverage["matched"] == 60
    rows = (out.run_dir / "frames.csv").read_text().splitlines()[1:]
    np.testing.assert_allclose([float(r.split(",")[2]) for r in rows], times, atol=1e-6)


def test_a_boreas_submission_scores_as_its_tum_twin(sample, tmp_path, capsys, monkeypatch):
    """One trajectory (the sample's GT, perturbed so the figures are not zero) written as TUM
    and as a Boreas submission (int stamps [us], T_k_i = the inverse of each pose, by NumPy's
    general inverse): the same figures, detected by content and with --format boreas."""
    rng = np.random.default_rng(1)
    poses = sample.poses.copy()
    poses[:, :3, 3] += np.cumsum(rng.normal(0, 0.02, (len(poses), 3)), axis=0)
    stamps_us = np.round(sample.stamps * 1e6).astype(np.int64) + 1_600_000_000_000_000
    tum = write_tum(tmp_path / "est.tum", stamps_us * 1e-6 - 1.6e9, poses)
    boreas = tmp_path / "loop1.txt"
    boreas.write_text("".join(
        f"{t} " + " ".join(f"{v:.17g}" for v in np.linalg.inv(T)[:3, :].ravel()) + "\n"
        for t, T in zip(stamps_us, poses, strict=True)))
    offset = "-1600000000"  # the stamps are 1.6e9 s ahead of the sample's
    results = []
    for name, path, extra in (("tum", tum, []), ("boreas", boreas, []),
                              ("boreas-given", boreas, ["--format", "boreas"])):
        args = ["score", str(path), "--store", str(SAMPLE), "--name", name, "--out",
                str(tmp_path / "r")] + extra
        if name != "tum":
            args += [f"--time-offset={offset}"]
        code, out = _bench(args, capsys, monkeypatch)
        assert code == 0, out
        results.append(read_run(tmp_path / "r" / "ntu4dradlm-loop1" / name).result)
    tum_res = results[0]
    assert tum_res.relative(8.0).trans_m_mean > 0.01
    for res in results[1:]:
        assert res.frames_scored == tum_res.frames_scored == 250
        for length in (8.0, 48.0):
            assert res.relative(length).trans_m_mean == pytest.approx(
                tum_res.relative(length).trans_m_mean, rel=1e-6)
            assert res.relative(length).rot_deg_mean == pytest.approx(
                tum_res.relative(length).rot_deg_mean, rel=1e-6, abs=1e-9)
        assert res.ape.trans_rmse_m == pytest.approx(tum_res.ape.trans_rmse_m, rel=1e-6)


@pytest.mark.parametrize("extra, message", [
    (["--time-offset", "1e300"], "--time-offset 1e+300: the stamps of"),
    (["--time-offset", "nan"], "--time-offset nan: expected a finite number of seconds"),
    (["--max-gap", "-1"], "--max-gap -1: expected a finite gap > 0 s"),
    (["--tolerance", "-1"], "--tolerance -1: expected a finite tolerance >= 0 s"),
    (["--min-coverage", "1.5"], "--min-coverage 1.5: expected a share in [0, 1]"),
    (["--stamp-unit", "min"], "--stamp-unit 'min': expected one of s, ms, us, ns"),
    (["--name", "../../outside"], "--name '../../outside': expected one path component"),
    (["--name", "a/b"], "--name 'a/b': expected one path component"),
    (["--name", ".."], "--name '..': expected one path component"),
    (["--name", "icp-p2p_seed"], "--name 'icp-p2p_seed' is the run folder of the harness's "
                                 "icp-p2p run with its seed"),
])
def test_bad_options_are_one_message_and_exit_2(sample, tmp_path, capsys, monkeypatch, extra,
                                                message):
    path = write_tum(tmp_path / "gt.tum", sample.stamps, sample.poses)
    args = ["score", str(path), "--store", str(SAMPLE), "--out", str(tmp_path / "r")]
    if "--name" not in extra:
        args += ["--name", "x"]
    code, out = _bench(args + extra, capsys, monkeypatch)
    assert code == 2 and message in out, out
    assert "Traceback" not in out and len(out.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists() and not (tmp_path / "outside").exists()


def test_an_index_column_is_refused_on_the_command_line(sample, tmp_path, capsys, monkeypatch):
    xyz, quat = tum_from_T(sample.poses)
    path = tmp_path / "indexed.tum"
    np.savetxt(path, np.column_stack([np.arange(250), sample.stamps, xyz, quat]), fmt="%.17g")
    code, out = _bench(["score", str(path), "--store", str(SAMPLE), "--name", "idx", "--out",
                        str(tmp_path / "r")], capsys, monkeypatch)
    assert code == 2 and f"{path}: 9 columns whose first is an integer index" in out, out
    assert "Traceback" not in out


def test_a_harness_run_of_the_same_name_is_not_replaced_unasked(sample, tmp_path, capsys,
                                                                 monkeypatch):
    """A harness run under the name (as a labelled variant's folder would be): refused; with
    --replace-run it is replaced and the command says so. A folder of other files: refused
    always, its files untouched."""
    base = constant_twist_sequence(n_frames=30, n_points=800, max_range_m=70)
    store = write_store(MemorySequence("twist", base.sensor, list(base), base.ground_truth),
                        tmp_path / "twist.h5")
    results = tmp_path / "r"
    harness = run_job(Job(store=store, method="icp-p2p", seed=True, out_root=results)).run_dir
    mine = results / "twist" / "mine"
    shutil.copytree(harness, mine)
    path = write_tum(tmp_path / "est.tum", base.ground_truth.stamps, base.ground_truth.poses)
    args = ["score", str(path), "--store", str(store), "--name", "mine", "--out", str(results)]
    code, out = _bench(args, capsys, monkeypatch)
    assert code == 2 and "holds a harness run (method icp-p2p)" in out and "--replace-run" in out
    assert read_run(mine).result.method == "icp-p2p"
    code, out = _bench(args + ["--replace-run"], capsys, monkeypatch)
    assert code == 0, out
    assert "replaced a harness run (method icp-p2p) by the external run mine" in out
    assert read_run(mine).result.label == "mine (external)"
    assert read_run(harness).result.method == "icp-p2p"  # the harness's own folder untouched
    other = results / "twist" / "notes"
    other.mkdir()
    (other / "todo.txt").write_text("mine")
    code, out = _bench([*args[:5], "notes", *args[6:], "--replace-run"], capsys, monkeypatch)
    assert code == 2 and "holds files that are no run" in out
    assert (other / "todo.txt").read_text() == "mine" and len(list(other.iterdir())) == 1
