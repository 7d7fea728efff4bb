"""Marks only where significant: bench.report.significance and the tables built on it.

Run folders are written from synthetic drives with exact ground truth (bench.studies.coverage):
two methods whose errors differ only by noise far below the segment-to-segment spread tie; a
method with five times the noise is significantly worse; a method's seed and no-seed rows are one
contender; a figure resting on one independent segment is shown as such and never marked."""

from __future__ import annotations

import numpy as np
import pytest

from bench.report.significance import BEST, OTHER, SECOND, Stat, mark_significant
from bench.report.table import Part, Row, to_csv, to_markdown
from bench.report.tables import build, select
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult
from metrics.units import relative_units


def _write(root, name, method, seed, gt, est, label=None, unconverged=0):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, i == 0 or i > unconverged)
              for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=(8.0, 48.0))
    config = {"method": method, "seed": seed, "label": label,
              "sequence": {"name": "drive", "display_name": "drive",
                           "sensor_class": "Semi-Dense 4D Radar"}}
    metrics = {**ev.metrics, "sequence": "drive", "method": method, "seed": seed,
               "frames": n, "status": "done"}
    write_run(root / "drive" / name, result, ev.gt, config, metrics)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("significance")
    gt = ground_truth(1200)
    est = noisy_estimate(gt, NoiseModel(), seed=1)
    # gicp: the same estimate with a thousandth of the noise on top (a tie in truth)
    tiny = noisy_estimate(gt, NoiseModel(0.0005, 0.0001), seed=2)
    twin = est @ (np.linalg.inv(gt) @ tiny)
    worse = noisy_estimate(gt, NoiseModel(0.25, 0.05), seed=3)
    _write(root, "vgicp-seed", "vgicp", True, gt, est)
    _write(root, "gicp-seed", "gicp", True, gt, twin)
    _write(root, "gicp-noseed", "gicp", False, gt, twin)
    _write(root, "icp-p2p-seed", "icp-p2p", True, gt, worse, unconverged=200)
    return root


def _marks(table, column, part):
    return {r.keys[-1]: r.cells[column].parts[part].rank for r in table.rows
            if r.cells[column].parts}


def test_ties_share_the_best_mark_and_a_real_difference_does_not(results):
    rows, lengths = select(results)
    table = build("relative", rows, lengths)
    rot8 = _marks(table, 0, 0)
    by_method: dict[str, int] = {}
    for k, v in rot8.items():  # a method's better mark (seed and no-seed are one contender)
        name = k.split(") ")[-1].split(" [")[0]
        by_method[name] = min(v, by_method.get(name, OTHER))
    assert by_method["VGICP"] == BEST and by_method["Generalized-ICP"] == BEST
    # five times the noise: significantly worse; the best of the rest is underlined
    assert by_method["ICP point-to-point"] == SECOND
    # the paper's by-value rule bolds one of the tied pair only
    value = _marks(build("relative", rows, lengths, marks="value"), 0, 0)
    assert sorted(value.values()).count(BEST) == 1
    text = to_markdown(table)
    assert "not significantly different" in text
    assert "by value alone" in to_markdown(build("relative", rows, lengths, marks="value"))


def test_seed_and_no_seed_rows_are_one_contender(results):
    rows, lengths = select(results)
    rot8 = _marks(build("relative", rows, lengths), 0, 0)
    gicp = [v for k, v in rot8.items() if "Generalized-ICP" in k]
    assert len(gicp) == 2
    assert sorted(gicp) == [BEST, OTHER]  # only the better of its two rows is marked


def test_intervals_in_cells_and_csv_and_the_fallback_footnote(results):
    rows, lengths = select(results)
    table = build("relative", rows, lengths, ci=True)
    md = to_markdown(table)
    assert "[low, high] = the 95 % confidence interval" in md
    first = table.rows[0].cells[0].parts[0].text
    assert "[" in first and "]" in first
    csv = to_csv(table)
    assert "rot_deg_mean_ci_low" in csv and "independent_segments" in csv
    # 200 of 1199 frames not converged: footnoted and flagged in the row's label
    assert "200 of 1199 frames not converged" in md
    assert "[fell back]" in md


def test_one_independent_segment_is_shown_as_such_and_never_ranked(results):
    rows, _ = select(results)
    table = build("kitti", rows)  # 600 m drive: the KITTI 100-800 m segments overlap
    assert "segments of 100 m" in table.caption
    assert "(the paths are shorter)" in table.caption
    for r in table.rows:
        part = r.cells[0].parts[0]
        if part.stat is not None and part.stat.n_independent is not None \
                and part.stat.n_independent < 2:
            assert part.rank == OTHER and "segment)" in part.text


def _stat(values, anchor, n):
    from metrics.units import Units

    units = Units(anchor, anchor + 20, {"e": values})
    return Stat(float(np.mean(values)), None, 10, lambda: (n, units, "e", False))


def test_mark_significant_on_constructed_errors():
    rng = np.random.default_rng(0)
    n = 800
    anchor = np.arange(n - 20)
    base = np.abs(np.cumsum(rng.normal(size=anchor.size))) * 0.01 + 0.5
    rows = [Row(["a"], (), [], {"method": "a"}), Row(["b"], (), [], {"method": "b"}),
            Row(["c"], (), [], {"method": "c"}), Row(["d"], (), [], {"method": "d"})]
    parts = [Part("a", stat=_stat(base, anchor, n)),
             Part("b", stat=_stat(base + rng.normal(0, 1e-4, base.size), anchor, n)),
             Part("c", stat=_stat(base * 1.5, anchor, n)),
             Part("d", stat=Stat(0.1, None, 1))]  # lowest value, one independent segment
    assert mark_significant(rows, parts) == [BEST, BEST, SECOND, OTHER]


def test_units_of_a_run_folder_equal_the_metrics_json_figure(results):
    rows, _ = select(results)
    rr = rows[0]
    n, units, quantity, _ = rr.units.relative(8.0, "rot_deg")
    assert n == 1200
    assert units.statistic(quantity) == pytest.approx(rr.result.relative(8.0).rot_deg_mean,
                                                      rel=1e-9)
    assert np.array_equal(units.anchor, relative_units(rr.run.gt, rr.run.est, 8.0).anchor)


# --- mutation review: contenders and the fall-backs of ``worse`` ------------------------------

def _base(seed=0, n=800):
    rng = np.random.default_rng(seed)
    anchor = np.arange(n - 20)
    return anchor, np.abs(np.cumsum(rng.normal(size=anchor.size))) * 0.01 + 0.5


def test_a_methods_better_row_represents_it_and_labelled_variants_are_apart():
    n = 800
    anchor, base = _base()
    rows = [Row(["a seed"], (), [], {"method": "a"}), Row(["a no seed"], (), [], {"method": "a"}),
            Row(["b"], (), [], {"method": "b"})]
    parts = [Part("", stat=_stat(base * 2.0, anchor, n)), Part("", stat=_stat(base, anchor, n)),
             Part("", stat=_stat(base * 1.2, anchor, n))]
    assert mark_significant(rows, parts) == [OTHER, BEST, SECOND]
    # two labelled variants of one method are two contenders, each marked on its own
    rows = [Row(["a x"], (), [], {"method": "a", "label": "x"}),
            Row(["a y"], (), [], {"method": "a", "label": "y"})]
    parts = [Part("", stat=_stat(base, anchor, n)), Part("", stat=_stat(base * 1.5, anchor, n))]
    assert mark_significant(rows, parts) == [BEST, SECOND]


def _rows(k):
    return [Row([str(i)], (), [], {"method": str(i)}) for i in range(k)]


def test_without_common_segments_overlapping_intervals_tie_and_plain_values_tie_when_equal():
    # own intervals only: a difference is significant when they do not overlap
    parts = [Part("", stat=Stat(1.0, (0.8, 1.2))), Part("", stat=Stat(1.1, (0.9, 1.3))),
             Part("", stat=Stat(2.0, (1.25, 2.5)))]
    assert mark_significant(_rows(3), parts) == [BEST, BEST, SECOND]
    # no interval at all (a time per frame): by value, equal values share the mark
    parts = [Part("", stat=Stat(5.0)), Part("", stat=Stat(5.0)), Part("", stat=Stat(6.0))]
    assert mark_significant(_rows(3), parts) == [BEST, BEST, SECOND]


def test_runs_over_other_frames_are_not_paired_and_partly_shared_segments_are():
    from metrics.units import Units

    anchor, base = _base()

    def stat(values, anchor, n_frames):
        units = Units(anchor, anchor + 20, {"e": values})
        return Stat(float(np.mean(values)), (0.0, 10.0), 10,
                    lambda: (n_frames, units, "e", False))

    # b 50 % worse on the same segments, but scored on other frames (800 vs 900): only the
    # (overlapping) own intervals may be compared: a tie
    parts = [Part("", stat=stat(base, anchor, 800)),
             Part("", stat=stat(base * 1.5, anchor, 900))]
    assert mark_significant(_rows(2), parts) == [BEST, BEST]
    # b lacks a's first 10 segments: the 770 both have are paired, and b is worse on them
    parts = [Part("", stat=stat(base, anchor, 800)),
             Part("", stat=stat(base[10:] * 1.5, anchor[10:], 800))]
    assert mark_significant(_rows(2), parts) == [BEST, SECOND]


def test_only_the_shared_segments_are_compared_and_each_with_its_own_twin():
    from metrics.units import Units

    # errors rising along the path; b is a on every segment both have but lacks a's first 10
    # (its mean is higher only because of that): paired on the same segments, a tie. Paired
    # with the wrong segments (a's first 770) b would be 10 steps of the rise above a.
    anchor = np.arange(780)
    a = np.linspace(0.5, 1.5, 780)

    def stat(values, anchor):
        units = Units(anchor, anchor + 20, {"e": values})
        return Stat(float(np.mean(values)), (0.0, 10.0), 10, lambda: (800, units, "e", False))

    parts = [Part("", stat=stat(a, anchor)), Part("", stat=stat(a[10:], anchor[10:]))]
    assert parts[1].stat.value > parts[0].stat.value
    assert mark_significant(_rows(2), parts) == [BEST, BEST]
