"""The Doppler kind is measured, not trusted: ``doppler_kind_check`` and ``bench inspect`` tell
raw radial from ego-compensated Doppler against the GT motion, whatever the loader declared."""

import numpy as np
from rich.console import Console

from bench.data.inspection import inspect_path
from helpers_bags import Motion, make_truth
from helpers_public import write_helipr
from loaders.doppler_check import doppler_kind_check
from loaders.helipr import INTENSITY_AFTER_NS, HeliprSequence
from loaders.scan import MemorySequence, Scan, SensorInfo
from loaders.store import write_store
from loaders.synthetic import SyntheticSequence


def compensated_copy(seq, declared):
    """The same scans with the sensor's own motion removed (static points read 0), declared
    as ``declared``."""
    gt = seq.ground_truth.interpolate(seq.stamps).poses
    dt = np.gradient(seq.stamps)
    v_world = np.gradient(gt[:, :3, 3], axis=0) / dt[:, None]
    scans = []
    for i, s in enumerate(seq):
        v = gt[i, :3, :3].T @ v_world[i]
        d = s.points / np.linalg.norm(s.points, axis=1, keepdims=True)
        scans.append(Scan(s.stamp, s.points, s.doppler + d @ v))
    sensor = SensorInfo(seq.sensor.kind, seq.sensor.period_s, doppler_kind=declared)
    return MemorySequence("comp", sensor, scans, seq.ground_truth)


def synthetic(frames=20):
    return SyntheticSequence("campus", "radar-sparse", frames=frames, seed=4)


def gt_at_scans(seq):
    return seq.ground_truth.interpolate(seq.stamps).poses


def test_radial_and_compensated_are_told_apart():
    seq = synthetic()
    radial = doppler_kind_check(seq, gt_at_scans(seq))
    assert radial.measured == "radial" and not radial.disagrees
    assert radial.frames_used >= 10 and radial.share_radial > 0.8
    comp = compensated_copy(seq, "ego-compensated")
    measured = doppler_kind_check(comp, gt_at_scans(seq))
    assert measured.measured == "ego-compensated" and not measured.disagrees
    assert measured.share_compensated > 0.8 and measured.share_radial < 0.1
    assert "static points near 0 m/s while the sensor moves" in measured.describe()
    # a loader that declared it radial is contradicted
    lied = doppler_kind_check(compensated_copy(seq, "radial"), gt_at_scans(seq))
    assert lied.disagrees and "DISAGREES with the declared kind (radial)" in lied.describe()
    assert doppler_kind_check(seq, None).measured == "not checked (no ground truth)"


def test_bench_inspect_says_so_on_a_store(tmp_path):
    seq = synthetic()
    comp = write_store(compensated_copy(seq, "radial"), tmp_path / "comp.h5")
    console = Console(record=True, width=200)
    report = inspect_path(comp, None, console)
    text = console.export_text()
    assert report["kind"].measured == "ego-compensated"
    assert "Doppler kind: declared radial" in text and "-> ego-compensated" in text
    assert "DISAGREES" in text
    assert "not checked (the Doppler is ego-compensated)" in text
    good = write_store(seq, tmp_path / "radial.h5")
    console = Console(record=True, width=200)
    inspect_path(good, None, console)
    text = console.export_text()
    assert "-> radial" in text and "DISAGREES" not in text


def test_helipr_velocities_are_measured_compensated_and_the_reconstruction_radial(tmp_path):
    t0 = INTENSITY_AFTER_NS * 1e-9 + 10.0
    motion = Motion(t0=t0)
    t = make_truth(motion, frames=12, points=200, period=0.1)
    gt_t = t0 + 0.02 * np.arange(int((t.stamps[-1] - t0) / 0.02) + 3)
    root = write_helipr(tmp_path / "seq", np.round(t.stamps * 1e9).astype(np.int64), t.points,
                        [np.zeros(len(p), np.float32) for p in t.points],
                        np.round(gt_t * 1e9).astype(np.int64), motion.sensor_pose(gt_t))
    released = HeliprSequence(root)
    kind = doppler_kind_check(released, gt_at_scans(released))
    assert kind.declared == kind.measured == "ego-compensated"
    rebuilt = HeliprSequence(root, reconstruct_doppler_from_gt=True)
    kind = doppler_kind_check(rebuilt, gt_at_scans(rebuilt))
    assert kind.declared == "gt-reconstructed" and kind.measured == "radial"
    assert not kind.disagrees and "GT-assisted" in kind.describe()


def test_runs_on_a_gt_reconstructed_store_are_labelled_gt_assisted(tmp_path):
    import warnings

    from bench.api import load_results, run_method
    from bench.report.figures.style import run_name
    from bench.report.names import GT_ASSISTED_NOTE
    from bench.report.tables.ape import collect_ape
    from bench.report.tables.model import to_markdown
    from bench.report.tables.paper import relative_table, select
    from bench.runs.folders import load_runs

    seq = SyntheticSequence("campus", "radar-sparse", frames=40, seed=4)
    scans = list(seq)
    for kind, name in (("radial", "plain"), ("gt-reconstructed", "rebuilt")):
        sensor = SensorInfo("radar", seq.sensor.period_s, doppler_kind=kind)
        store = write_store(MemorySequence(name, sensor, scans, seq.ground_truth),
                            tmp_path / f"{name}.h5")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run_method("icp-p2p", store, out=tmp_path / "results" / name / "icp-p2p_seed")
    results = tmp_path / "results"
    labels = {r.sequence: r.label for r in select(results)[0]}
    assert labels == {"plain": "(With Seed) ICP point-to-point",
                      "rebuilt": "(With Seed) ICP point-to-point [GT-assisted]"}
    rows, lengths = select(results)
    assert not any(r.is_variant for r in rows)  # the mark is not an ablation label
    assert GT_ASSISTED_NOTE in to_markdown(relative_table(rows, lengths))
    ape = collect_ape(results)
    assert sorted(label for label, _ in ape.rows) == sorted(labels.values())
    assert GT_ASSISTED_NOTE in to_markdown(ape.table)
    names = {r.sequence: run_name(r) for r in load_runs(results)}
    assert names["rebuilt"].endswith("[GT-assisted]") and "GT" not in names["plain"]
    df = load_results(results)
    assert set(zip(df["sequence"], df["doppler_kind"], strict=True)) == {
        ("plain", "radial"), ("rebuilt", "gt-reconstructed")}


def test_radial_doppler_of_either_sign_is_measured_radial():
    """The kind check is separate from the sign check: raw radial Doppler reported with the
    opposite convention (approach positive) is still radial, not compensated or
    inconclusive, and the sign check (not this one) flags the sign."""
    from loaders.doppler_check import doppler_sign_check

    seq = synthetic()
    flipped = MemorySequence("flipped", seq.sensor,
                             [Scan(s.stamp, s.points, -s.doppler) for s in seq],
                             seq.ground_truth)
    kind = doppler_kind_check(flipped, gt_at_scans(seq))
    assert kind.measured == "radial" and kind.share_radial > 0.8, kind
    assert doppler_sign_check(flipped, gt_at_scans(seq)).verdict == "appears FLIPPED"
    same = doppler_kind_check(seq, gt_at_scans(seq))
    assert kind.share_radial == same.share_radial  # the same points fit, either sign
