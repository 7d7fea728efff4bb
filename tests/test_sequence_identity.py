"""Sequences known by their content (bench.runs.sequence_identity): two stores of different
content under one sequence name are told apart in every table, figure, summary and the report,
never paired as one sequence; loaders name a cut or a day's run distinctly."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from typer.testing import CliRunner

from bench.report.summary.overview import summary_table
from bench.report.tables.paper import build, select
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import load_runs, write_run
from bench.runs.sequence_identity import frames_text, sequence_tags
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from helpers_public import synthetic_frames, write_vod
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult


def _config(sha, frames, store="data1.h5", cut=None, own=None, kind="radial"):
    return {"identity": {"store_sha256": sha, "frame_range": own},
            "sequence": {"name": "data1", "display_name": "data1", "frames": frames,
                         "store": store, "store_frame_range": cut, "doppler_kind": kind,
                         "sensor_class": "Semi-Dense 4D Radar"}}


def test_tags_name_what_tells_contents_apart_and_nothing_when_one_content():
    full = _config("a" * 64, 400)
    cut = _config("b" * 64, 190, cut={"start": 60, "frames": 190, "stride": 1})
    assert sequence_tags(["data1"] * 3, [full, cut, full]) == \
        ["frames 0-399", "frames 60-249", "frames 0-399"]
    # one content under the name (two runs of it): no tag
    assert sequence_tags(["data1", "data1"], [full, full]) == ["", ""]
    # a run's own frame range composes with the store's cut (start 60 + 10 * stride 2)
    strided = _config("c" * 64, 5, cut={"start": 60, "frames": 100, "stride": 2}, own=[10, 5])
    assert frames_text(strided) == "frames 80-88, stride 2"
    # same frames, other Doppler (VoD radial / compensated): the Doppler kind tells
    comp = _config("d" * 64, 400, kind="ego-compensated")
    assert sequence_tags(["data1", "data1"], [full, comp]) == \
        ["radial Doppler", "ego-compensated Doppler"]
    # nothing but the bytes differ (a store rewritten in place): its SHA-256 prefix
    again = _config("e" * 64, 400)
    assert sequence_tags(["data1", "data1"], [full, again]) == \
        [f"store {'a' * 12}", f"store {'e' * 12}"]
    # content not recorded (an older run) keeps its name
    assert sequence_tags(["data1", "data1"], [{"sequence": {}}, full]) == ["", ""]


def _write(root, folder, config, method, seed, gt, est):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 48.0))
    write_run(root / folder, result, ev.gt, {**config, "method": method, "seed": seed},
              {**ev.metrics, "sequence": "data1", "method": method, "seed": seed,
               "frames": n, "status": "done"})


@pytest.fixture(scope="module")
def clashing(tmp_path_factory):
    """Two stores named data1 (the bag in full and cut at frame 60), each run by two methods
    written in two results folders under one root: doppler is the better method on the full
    store, icp-p2p on the cut."""
    root = tmp_path_factory.mktemp("clash")
    gt = ground_truth(700)
    good = noisy_estimate(gt, NoiseModel(), 1)
    bad = noisy_estimate(gt, NoiseModel(0.3, 0.06), 2)
    full = _config("a" * 64, 700)
    cut = _config("b" * 64, 700, store="data1_cut.h5",
                  cut={"start": 60, "frames": 700, "stride": 1})
    _write(root, "full/data1/doppler", full, "doppler", None, gt, good)
    _write(root, "full/data1/icp-p2p_seed", full, "icp-p2p", True, gt, bad)
    _write(root, "cut/data1/doppler", cut, "doppler", None, gt, bad)
    _write(root, "cut/data1/icp-p2p_seed", cut, "icp-p2p", True, gt, good)
    return root


def test_tables_and_summary_keep_two_contents_of_one_name_apart(clashing):
    runs = load_runs(clashing)
    assert sorted({r.display_name for r in runs}) == ["data1 [frames 0-699]",
                                                      "data1 [frames 60-759]"]
    assert sorted({r.sequence for r in runs}) == ["data1 [frames 0-699]",
                                                  "data1 [frames 60-759]"]
    rows, lengths = select(clashing)
    table = build("relative", rows, lengths, ci=True)
    groups = {r.group for r in table.rows}
    assert groups == {("Semi-Dense 4D Radar", "data1 [frames 0-699]"),
                      ("Semi-Dense 4D Radar", "data1 [frames 60-759]")}
    # within each group the better method is marked, each against its own sequence's rival:
    # paired, doppler would be better everywhere or nowhere
    summary = summary_table(rows)
    by = {r.keys[1]: r for r in summary.rows}
    assert by["doppler"].cells[0].values["sequences"] == 2
    assert by["icp-p2p"].cells[0].values["sequences"] == 2
    assert by["doppler"].cells[1].values["mean_mark"] == 1.5
    assert by["icp-p2p"].cells[1].values["mean_mark"] == 1.5


def test_several_results_folders_are_told_apart_across_folders(clashing):
    rows, _ = select([clashing / "full", clashing / "cut"])
    assert sorted({r.sequence for r in rows}) == ["data1 [frames 0-699]",
                                                  "data1 [frames 60-759]"]


def test_the_report_shows_each_content_under_its_own_label(clashing):
    from bench.report.html.page import render_page

    page, _ = render_page(clashing)
    assert "data1 [frames 0-699]" in page and "data1 [frames 60-759]" in page


@pytest.fixture(scope="module")
def vod_stores(tmp_path_factory):
    """One VoD folder converted twice with the default name: radial and compensated."""
    from bench.cli import app

    tmp = tmp_path_factory.mktemp("vodclash")
    stamps, points, doppler, poses = synthetic_frames(frames=30)
    comp = [np.zeros_like(d) for d in doppler]
    root = write_vod(tmp / "vod", points, doppler, poses, compensated=comp)
    runner = CliRunner()
    stores = {}
    for kind in ("v_r", "v_r_compensated"):
        stores[kind] = tmp / f"{kind}.h5"
        res = runner.invoke(app, ["convert", "vod", str(root), "--doppler", kind,
                                  "--out", str(stores[kind])])
        assert res.exit_code == 0, res.output
    return tmp, stores


def test_vod_radial_and_compensated_stores_are_two_sequences_in_a_table(vod_stores):
    from bench.api import run_method
    from loaders.store import StoreSequence

    tmp, stores = vod_stores
    names = {k: StoreSequence(p).name for k, p in stores.items()}
    assert names["v_r"] == names["v_r_compensated"] == "vod_00000-00029"  # the clash
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for kind, store in stores.items():
            run_method("icp-p2p", store, out=tmp / "results" / kind / "icp-p2p_seed")
    found = {r.display_name for r in load_runs(tmp / "results")}
    assert found == {"vod_00000-00029 [radial Doppler]",
                     "vod_00000-00029 [ego-compensated Doppler]"}


def test_convert_names_a_cut_by_its_frames(vod_stores, tmp_path):
    from bench.cli import app
    from loaders.store import StoreSequence

    tmp, _ = vod_stores
    out = tmp_path / "cut.h5"
    res = CliRunner().invoke(app, ["convert", "vod", str(tmp / "vod"), "--out", str(out),
                                   "--start", "5", "--frames", "10"])
    assert res.exit_code == 0, res.output
    assert StoreSequence(out).name == "vod_00000-00029_frames5-14"
    named = tmp_path / "named.h5"
    res = CliRunner().invoke(app, ["convert", "vod", str(tmp / "vod"), "--out", str(named),
                                   "--start", "5", "--stride", "2", "--name", "mine"])
    assert res.exit_code == 0, res.output
    assert StoreSequence(named).name == "mine"  # --name wins


def test_a_run_of_another_store_of_the_same_name_is_refused_naming_both(vod_stores):
    """`bench run` of the compensated store into the folder holding the radial store's run
    (both vod_00000-00029) would silently replace it: refused, naming both stores; and one
    plan of both stores (an experiment) is refused the same way."""
    from bench.api import run_method
    from bench.runs.job import Job
    from bench.runs.plan import plan
    from loaders.errors import DataError

    tmp, stores = vod_stores
    out = tmp / "same" / "vod_00000-00029" / "icp-p2p_seed"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run_method("icp-p2p", stores["v_r"], out=out)
        with pytest.raises(DataError) as err:
            run_method("icp-p2p", stores["v_r_compensated"], out=out)
    text = str(err.value)
    assert str(stores["v_r"]) in text and str(stores["v_r_compensated"]) in text
    assert "another store of that name" in text
    assert (out / "metrics.json").exists()  # the first run is still there
    jobs = [Job(store=s, method="icp-p2p", seed=True, out_root=tmp / "exp")
            for s in stores.values()]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(DataError) as err:
            plan(jobs)
    text = str(err.value)
    assert str(stores["v_r"]) in text and str(stores["v_r_compensated"]) in text


def test_snail_bag_in_full_and_cut_never_one_sequence(tmp_path):
    """The issue's case: one Snail-Radar bag converted in full and with --start / --frames.
    By default the two stores have distinct names (day_run, and the cut's frames); forced
    under one --name, their runs are still two sequences in the tables (their frames)."""
    from bench.api import run_method
    from bench.cli import app
    from helpers_bags import Motion, make_truth, write_gt_tum
    from helpers_snail import radar_array, write_snail_bag
    from loaders.se3 import inv_T
    from loaders.snail_radar import T_BODY_XT32, body_T_oculii
    from loaders.store import StoreSequence

    truth = make_truth(Motion(T_body_sensor=inv_T(T_BODY_XT32) @ body_T_oculii()), frames=30,
                       points=60, period=0.1)
    rng = np.random.default_rng(0)
    day = tmp_path / "20240123"
    day.mkdir()
    bag = write_snail_bag(day / "data1.bag", {"/radar_enhanced_pcl2": [
        (t, radar_array("eagle", p, d, rng))
        for t, p, d in zip(truth.stamps, truth.points, truth.doppler, strict=True)]})
    gt = tmp_path / "gt.txt"
    write_gt_tum(gt, truth.motion, truth.stamps[0] - 0.5, truth.stamps[-1] + 0.5, step=0.05)
    runner = CliRunner()

    def convert(out, *extra):
        res = runner.invoke(app, ["convert", "snail-radar", str(bag), "--gt", str(gt),
                                  "--out", str(out), *extra])
        assert res.exit_code == 0, res.output
        return StoreSequence(out).name

    assert convert(tmp_path / "full.h5") == "20240123_data1"
    assert convert(tmp_path / "cut.h5", "--start", "3", "--frames", "15") == \
        "20240123_data1_frames3-17"
    convert(tmp_path / "full_named.h5", "--name", "data1")
    convert(tmp_path / "cut_named.h5", "--start", "3", "--frames", "15", "--name", "data1")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for which in ("full_named", "cut_named"):
            run_method("icp-p2p", tmp_path / f"{which}.h5",
                       out=tmp_path / "results" / which / "data1" / "icp-p2p_seed")
    names = sorted(r.display_name for r in load_runs(tmp_path / "results"))
    assert names == ["data1 [frames 0-29]", "data1 [frames 3-17]"]


def test_helipr_and_vod_names_stay_distinct_across_a_release(tmp_path):
    """HeLiPR: the sequence folder names the sequence (from its root or its LiDAR/Aeva
    folder), so two sequences' stores never share a name; VoD: the frame range does."""
    from helpers_public import write_helipr
    from loaders.helipr import HeliprSequence
    from loaders.vod import VodSequence

    stamps, points, doppler, poses = synthetic_frames("tunnel", "lidar-aeva", frames=4, seed=2)
    ns = np.round((stamps + 1.7e9) * 1e9).astype(np.int64)
    names = set()
    for seq in ("Roundabout01", "Town02"):
        root = write_helipr(tmp_path / seq, ns, points, doppler, ns, poses)
        names.add(HeliprSequence(root).name)
        assert HeliprSequence(root / "LiDAR" / "Aeva").name == seq
    assert names == {"Roundabout01", "Town02"}
    _, vpoints, vdoppler, vposes = synthetic_frames(frames=6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        early = VodSequence(write_vod(tmp_path / "vod_a", vpoints, vdoppler, vposes, first=0))
        late = VodSequence(write_vod(tmp_path / "vod_b", vpoints, vdoppler, vposes, first=40))
    assert (early.name, late.name) == ("vod_00000-00005", "vod_00040-00045")
