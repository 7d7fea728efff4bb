"""Do a table's marks hold on both halves of a sequence (bench.report.tables.stability)?

Synthetic drives with exact ground truth (bench.studies.coverage): a method five times noisier
than another everywhere keeps its verdict on both halves; a method that is good on the first
half and bad on the second does not, and its cells are flagged. The halves are cross-checked
against runs written from the half trajectories themselves and scored by the whole pipeline
(bench.runs.evaluate), so ``half`` scores exactly what a run of that half would."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from bench.cli import app
from bench.report.tables.model import to_markdown
from bench.report.tables.paper import build, relative_table, select
from bench.report.tables.significance import BEST, OTHER
from bench.report.tables.stability import CHANGED, half, stability, with_stability
from bench.runs.evaluate import evaluate_run
from bench.runs.folders import write_run
from bench.studies.coverage import NoiseModel, ground_truth, noisy_estimate
from loaders.errors import DataError
from loaders.trajectory import Trajectory
from methods.base import FrameRecord, OdometryResult

LENGTHS = (8.0, 48.0)


def _write(root, sequence, name, method, gt, est):
    n = len(gt)
    stamps = np.arange(n) / 10.0
    frames = [FrameRecord(i, stamps[i], 1.0, 100, 50, 3, True) for i in range(n)]
    result = OdometryResult(stamps, est, frames)
    ev = evaluate_run(Trajectory(stamps, gt), result, lengths_m=LENGTHS)
    config = {"method": method, "seed": True, "label": None,
              "sequence": {"name": sequence, "display_name": sequence,
                           "sensor_class": "Semi-Dense 4D Radar"}}
    metrics = {**ev.metrics, "sequence": sequence, "method": method, "seed": True,
               "frames": n, "status": "done"}
    write_run(root / sequence / name, result, ev.gt, config, metrics)


def _switching(gt, seed):
    """An estimate with a hundredth of the noise on the first half and four times it on the
    second (its step errors chained along the whole drive)."""
    n = len(gt)
    quiet = noisy_estimate(gt, NoiseModel(0.0005, 0.0001), seed=seed)
    loud = noisy_estimate(gt, NoiseModel(0.2, 0.04), seed=seed + 1)
    steps_gt = np.linalg.inv(gt[:-1]) @ gt[1:]
    steps = np.where((np.arange(1, n) < n // 2)[:, None, None],
                     np.linalg.inv(quiet[:-1]) @ quiet[1:], np.linalg.inv(loud[:-1]) @ loud[1:])
    est = [gt[0]]
    for s in steps:
        est.append(est[-1] @ s)
    assert steps_gt.shape == steps.shape
    return np.array(est)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("stability")
    gt = ground_truth(1600)
    _write(root, "drive", "vgicp_seed", "vgicp", gt, noisy_estimate(gt, NoiseModel(), seed=1))
    _write(root, "drive", "icp-p2p_seed", "icp-p2p", gt,
           noisy_estimate(gt, NoiseModel(0.25, 0.05), seed=3))
    _write(root, "drive", "gicp_seed", "gicp", gt, _switching(gt, 5))
    # a second sequence where the two methods differ alike on both halves
    steady = {"vgicp": noisy_estimate(gt, NoiseModel(), seed=11),
              "icp-p2p": noisy_estimate(gt, NoiseModel(0.25, 0.05), seed=12)}
    for method, est in steady.items():
        _write(root, "steady", f"{method}_seed", method, gt, est)
    # the same runs' halves as runs of their own, scored by the whole pipeline
    for which, part in (("A", slice(0, 800)), ("B", slice(800, 1600))):
        for name, method, est in (("vgicp_seed", "vgicp", noisy_estimate(gt, NoiseModel(), 1)),
                                  ("icp-p2p_seed", "icp-p2p",
                                   noisy_estimate(gt, NoiseModel(0.25, 0.05), seed=3)),
                                  ("gicp_seed", "gicp", _switching(gt, 5))):
            _write(root / "halves" / which, "drive", name, method, gt[part], est[part])
        for method, est in steady.items():
            _write(root / "halves" / which, "steady", f"{method}_seed", method, gt[part],
                   est[part])
    return root


def _main(results):
    return select([results / "drive", results / "steady"])


def test_a_half_scores_what_a_run_of_that_half_scores(results):
    rows, lengths = _main(results)
    for which, tag in ((0, "A"), (1, "B")):
        own = {(r.sequence, r.method): r for r in select(results / "halves" / tag)[0]}
        for rr in rows:
            h = half(rr, which, lengths).result
            ref = own[(rr.sequence, rr.method)].result
            for L in lengths:
                a, b = h.relative(L), ref.relative(L)
                assert a.n == b.n and a.rot_deg_mean == pytest.approx(b.rot_deg_mean, rel=1e-9)
                assert a.trans_m_mean_ci == pytest.approx(b.trans_m_mean_ci, rel=1e-9)
                assert a.spread.n_independent == b.spread.n_independent
            # the whole run is untouched
            assert rr.result.relative(8.0).n > h.relative(8.0).n


def test_a_verdict_that_flips_between_halves_is_flagged_and_counted(results):
    rows, lengths = _main(results)
    table = relative_table(rows, lengths)
    found = stability(rows, lengths, table)
    # an independent count: the tables of the half runs scored as runs of their own
    ranks: dict[tuple, list] = {}
    blind_cells: dict[tuple, list] = {}  # per run: (col, part) a half's table cannot tell
    for tag in "AB":
        hrows = select(results / "halves" / tag)[0]
        htable = relative_table(hrows, lengths)
        for rr, row in zip(hrows, htable.rows, strict=True):
            ranks.setdefault((rr.sequence, rr.method), []).append(row)
            for col in range(len(lengths)):
                for p, part in enumerate(row.cells[col].parts):
                    peers = [r.cells[col].parts[p] for r, x in zip(htable.rows, hrows,
                                                                   strict=True)
                             if x.sequence == rr.sequence and r.cells[col].parts[p].stat
                             is not None and r.cells[col].parts[p].stat.rankable]
                    if not part.stat.rankable or all(q.rank == BEST for q in peers):
                        blind_cells.setdefault((rr.sequence, rr.method), set()).add((col, p))
    held: dict[str, list[int]] = {}
    expect_changed = set()
    for i, (rr, row) in enumerate(zip(rows, table.rows, strict=True)):
        for col in range(len(lengths)):
            for p, part in enumerate(row.cells[col].parts):
                same = all(r.cells[col].parts[p].rank == part.rank
                           for r in ranks[(rr.sequence, rr.method)])
                blind = (col, p) in blind_cells.get((rr.sequence, rr.method), set())
                if part.rank != OTHER:
                    count = held.setdefault(rr.sequence, [0, 0, 0])
                    count[0] += same and not blind
                    count[1] += 1
                    count[2] += blind
                if not same and not blind:
                    expect_changed.add((i, col, p))
    assert found.held == {k: tuple(v) for k, v in held.items()}
    assert found.changed == expect_changed
    where = {(rr.sequence, rr.method): i for i, rr in enumerate(rows)}
    # gicp (quiet, then loud) leads the first half at 8 m and loses the second: flagged
    assert (where[("drive", "gicp")], 0, 0) in found.changed
    # on the steady drive every mark holds or its half cannot tell (bold vgicp, underlined
    # icp-p2p, both lengths): none differs
    k, n, u = found.held["steady"]
    assert n == 8 and k + u == 8 and k >= 4
    assert found.held["drive"][0] < found.held["drive"][1]


def test_the_table_and_the_report_say_it(results, tmp_path):
    rows, lengths = _main(results)
    table = build("relative", rows, lengths, ci=True)
    with_stability(rows, lengths, table)
    md = to_markdown(table)
    assert "per sequence, of its marks: drive:" in md and "cannot tell (of" in md
    flagged = [p for r in table.rows for c in r.cells for p in c.parts if CHANGED in p.text]
    assert flagged and all(p.text.endswith(f" {CHANGED}") for p in flagged)
    # the same marks as without the check (it only adds flags)
    plain = build("relative", rows, lengths, ci=True)
    assert [[p.rank for c in r.cells for p in c.parts] for r in table.rows] == \
        [[p.rank for c in r.cells for p in c.parts] for r in plain.rows]
    res = CliRunner().invoke(app, ["table", str(results / "drive"), "--stability", "--ci",
                                   "--out", str(tmp_path / "t")])
    assert res.exit_code == 0, res.output
    assert "of its marks: drive:" in res.output and CHANGED in res.output
    res = CliRunner().invoke(app, ["table", str(results / "drive"), "--stability",
                                   "--metric", "kitti"])
    assert isinstance(res.exception, DataError) and "relative-error table" in str(res.exception)
    assert any(r.cells[0].parts[0].rank == BEST for r in plain.rows)


def test_a_half_that_cannot_tell_is_counted_so_not_as_holding_or_differing(tmp_path):
    """A 150 m drive: its 48 m figures rest on 3 independent segments and are marked, each
    75 m half's on one, which no rule may mark. Those marks are "cannot tell", never "hold"
    nor flagged as differing; the 8 m marks, which each half can tell, hold."""
    gt = ground_truth(300)
    _write(tmp_path, "short", "vgicp_seed", "vgicp", gt, noisy_estimate(gt, NoiseModel(), 21))
    _write(tmp_path, "short", "icp-p2p_seed", "icp-p2p", gt,
           noisy_estimate(gt, NoiseModel(0.25, 0.05), seed=22))
    rows, lengths = select(tmp_path)
    table = relative_table(rows, lengths)
    marked48 = sum(r.cells[1].parts[p].rank != OTHER for r in table.rows for p in (0, 1))
    assert marked48 >= 2
    found = stability(rows, lengths, table)
    k, n, u = found.held["short"]
    assert u == marked48 and k == n - u
    assert not any(col == 1 for _, col, _ in found.changed)
    assert f"short: {k} hold, 0 differ, {u} cannot tell (of {n})" in found.text()
