"""The notebook API (and the manual's example, docs/results.md) and `bench compare`."""

import json
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bench.api import COLUMNS, load_results, load_runs_frame, run_method
from bench.cli import app
from conftest import constant_twist_sequence
from loaders.store import write_store

EXAMPLE_PAGE = Path(__file__).resolve().parents[1] / "docs" / "results.md"


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=60, n_points=1500, noise_m=0.02, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def test_manual_notebook_example_runs(store, tmp_path, monkeypatch):
    block = re.search(r"<!-- notebook-example -->\s*```python\n(.*?)```",
                      EXAMPLE_PAGE.read_text(), re.S).group(1)
    monkeypatch.chdir(tmp_path)
    namespace = {"STORE": str(store)}
    assert block.count('"samples/ntu4dradlm-loop1.h5"') == 2  # the vendored sample
    exec(compile(block.replace('"samples/ntu4dradlm-loop1.h5"', "STORE"), "docs/results.md",
                 "exec"), namespace)
    df = namespace["df"]
    assert list(df.columns) == COLUMNS
    assert set(df["method"]) == {"doppler", "icp-p2p"} and len(df) == 2 * 6
    assert (df["trans_m_mean"] > 0).all()


def test_run_method_returns_the_metrics_and_load_results_one_row_per_length(store, tmp_path):
    m = run_method("doppler", store, out=tmp_path / "r" / "twist" / "doppler")
    df = load_results(tmp_path / "r")
    assert len(df) == len(m.relative_error)
    row = df[df["length_m"] == 8.0].iloc[0]
    assert row["trans_m_mean"] == m.relative(8).trans_m_mean
    assert row["seed"] is None and row["ape_trans_m"] == m.ape.trans_rmse_m
    assert row["ape_alignment"] == "se3" and row["velocity_window_s"] == 1.0
    assert row["velocity_err_mps"] == m.velocity.norm_mean_mps
    runs = load_runs_frame(tmp_path / "r")
    assert len(runs) == 1 and runs["kitti_segments"].iloc[0] == m.kitti.n
    # every statistic of the result is a column, a new metric's too
    assert runs["velocity.axis_rmse_mps.0"].iloc[0] == m.velocity.axis_rmse_mps[0]
    assert runs["ape.scale"].iloc[0] == 1.0


def _tables(text: str) -> list[tuple[list[str], list[list[str]]]]:
    """The pipe tables of a markdown text as (header, rows); asserts each is a valid table:
    a header separator row and as many cells in every row as in the header."""
    tables, block = [], []
    for line in [*text.splitlines(), ""]:
        if line.startswith("|"):
            block.append(line)
            continue
        if block:
            def cells(row):
                assert row.startswith("| ") and row.endswith(" |"), row
                return [c.strip() for c in re.split(r"(?<!\\)\|", row)[1:-1]]

            header = cells(block[0])
            assert re.fullmatch(r"\|( :?-+:? \|)+", block[1]), block[1]
            assert len(cells(block[1])) == len(header)
            rows = [cells(r) for r in block[2:]]
            assert all(len(r) == len(header) for r in rows), block
            tables.append((header, rows))
            block = []
    return tables


def _fake_run(root: Path, sequence: str, method: str, seed, errors: dict, time_ms: float,
              diverged: bool = False) -> None:
    """A finished run folder as `bench run` leaves it (the files compare reads); ``errors``:
    length -> (rotation [deg], translation [m], segments)."""
    name = method if seed is None else f"{method}_{'seed' if seed else 'noseed'}"
    d = root / sequence / name
    d.mkdir(parents=True)
    rel = {L: {"rot_deg_mean": r if n else None, "trans_m_mean": t if n else None,
               "rot_deg_median": r if n else None, "trans_m_median": t if n else None, "n": n}
           for L, (r, t, n) in errors.items()}
    (d / "metrics.json").write_text(json.dumps({
        "sequence": sequence, "method": method, "seed": seed, "frames": 50,
        "diverged": diverged, "relative_error": rel, "ape": {"trans_rmse_m": 1.0},
        "time_ms": {"mean": time_ms, "median": time_ms}}))


def _fake_results(root: Path, scale: float = 1.0, time_scale: float = 1.0,
                  drop: str | None = None, diverge: str | None = None) -> Path:
    """Three runs (with seed, no seed, no initial guess) with segments at 8 and 16 m only."""
    for method, seed, t in (("icp-p2p", True, 5.0), ("icp-p2p", False, 6.0),
                            ("doppler", None, 0.5)):
        if drop == f"{method}{seed}":
            continue
        _fake_run(root, "seqA", method, seed,
                  {"8": (1.0 * scale, 0.5 * scale, 10), "16": (2.0 * scale, 1.0 * scale, 4),
                   "48": (0, 0, 0)}, t * time_scale, diverged=diverge == f"{method}{seed}")
    return root


def test_compare_shows_the_changed_cell(store, tmp_path):
    run_method("doppler", store, out=tmp_path / "a" / "twist" / "doppler")
    run_method("doppler", store, params={"tau_spatial_m": 0.5},
               out=tmp_path / "b" / "twist" / "doppler")
    # two results folders: the run given -p is another configuration, labelled as such
    res = CliRunner().invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    (header, rows), _, _ = _tables(res.output)
    assert {"only in A", "only in B"} == {x for r in rows for x in ("only in A", "only in B")
                                          if x in r[-1]}
    assert all("tau_spatial_m A 3.0, B 0.5" in r[-1] for r in rows)
    # the two run folders side by side: the changed cell, the parameter named
    res = CliRunner().invoke(app, ["compare", str(tmp_path / "a" / "twist" / "doppler"),
                                   str(tmp_path / "b" / "twist" / "doppler")])
    assert res.exit_code == 0, res.output
    (header, rows), _, (rheader, rrows) = _tables(res.output)
    row = dict(zip(header, next(r for r in rows if r[0] == "twist" and r[2] == "8"),
                   strict=True))
    assert row["Run"].endswith("Doppler Correspondence (Ours) [tau_spatial_m=0.5]")
    assert row["Note"].startswith("parameters differ: tau_spatial_m A 3.0, B 0.5")
    # each figure is followed by its interval "[low, high]"
    a, b = float(row["Trans. A"].split()[0]), float(row["Trans. B"].split()[0])
    delta = float(row["Trans. change"].split()[0])
    assert a != b and delta == pytest.approx(b - a, abs=2e-3)
    # the per-run metrics: APE (its alignment named), KITTI drift (none on 47 m), velocity
    assert rheader[2:6] == ["APE [m]", "KITTI trans. [%]", "KITTI rot. [deg/100 m]",
                            "Velocity err. [m/s]"] and "alignment: se3" in res.output
    ape_a, ape_b = (float(x) for x in rrows[0][2].split(" -> "))
    assert ape_a != ape_b and rrows[0][3] == "- -> -"
    same = CliRunner().invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "a"),
                                    "--fail-on-regression"])
    assert same.exit_code == 0 and "0 regressions" in same.output


def test_compare_is_valid_markdown_with_seed_tags_times_and_no_empty_cells(tmp_path):
    a = _fake_results(tmp_path / "a")
    b = _fake_results(tmp_path / "b", scale=1.05, time_scale=2.0)
    res = CliRunner().invoke(app, ["compare", str(a), str(b)])
    assert res.exit_code == 0, res.output
    assert "nan" not in res.output.lower() and "None" not in res.output
    (header, rows), (theader, trows), _ = _tables(res.output)
    assert header[:3] == ["Sequence", "Run", "Length [m]"]
    # 3 runs x the 2 lengths with segments; 48 m has none on either side: no cell
    assert sorted((r[1], r[2]) for r in rows) == sorted(
        (run, L) for run in ("(With Seed) ICP point-to-point", "(No Seed) ICP point-to-point",
                             "(No initial guess) Doppler Correspondence (Ours)")
        for L in ("8", "16"))
    assert [r[1] for r in rows[::2]] == ["(With Seed) ICP point-to-point",
                                         "(No Seed) ICP point-to-point",
                                         "(No initial guess) Doppler Correspondence (Ours)"]
    assert "6 cells (0 only in A, 0 only in B), 0 regressions" in res.output
    # one time row per run: A, B and the change B - A
    assert theader == ["Sequence", "Run", "Time A", "Time B", "Change", "Note"]
    times = {r[1]: r[2:5] for r in trows}
    assert times == {"(With Seed) ICP point-to-point": ["5.00", "10.00", "+5.00 (+100.0%)"],
                     "(No Seed) ICP point-to-point": ["6.00", "12.00", "+6.00 (+100.0%)"],
                     "(No initial guess) Doppler Correspondence (Ours)":
                         ["0.50", "1.00", "+0.50 (+100.0%)"]}


def test_compare_marks_regressions_and_runs_on_one_side_only(tmp_path):
    a = _fake_results(tmp_path / "a", drop="icp-p2pFalse")
    b = _fake_results(tmp_path / "b", scale=1.2, drop="doppler" + "None",
                      diverge="icp-p2pTrue")
    runner = CliRunner()
    res = runner.invoke(app, ["compare", str(a), str(b)])
    assert res.exit_code == 0, res.output  # without --fail-on-regression
    (header, rows), (_, trows), _ = _tables(res.output)
    notes = {(r[1], r[2]): r[-1] for r in rows}
    assert notes[("(With Seed) ICP point-to-point", "8")] == \
        "! regression (by value: no intervals); ! newly diverged"
    assert notes[("(No Seed) ICP point-to-point", "8")] == "only in B"
    assert notes[("(No initial guess) Doppler Correspondence (Ours)", "16")] == "only in A"
    only_b = next(r for r in rows if r[1] == "(No Seed) ICP point-to-point")
    assert only_b[3] == "-" and only_b[5] == "-"  # nothing in A, no change
    assert {r[1]: r[-1] for r in trows}["(No Seed) ICP point-to-point"] == "only in B"
    assert "6 cells (2 only in A, 2 only in B), 2 regressions" in res.output
    res = runner.invoke(app, ["compare", str(a), str(b), "--fail-on-regression"])
    assert res.exit_code == 1
    res = runner.invoke(app, ["compare", str(a), str(b), "--fail-on-regression",
                              "--threshold", "0.5"])
    assert res.exit_code == 1  # growth within 50 %, but a run newly diverged
    b2 = _fake_results(tmp_path / "b2", scale=1.2)
    res = runner.invoke(app, ["compare", str(a), str(b2), "--fail-on-regression",
                              "--threshold", "0.5"])
    assert res.exit_code == 0 and "0 regressions" in res.output


def _with_intervals(root: Path, half_width: float) -> None:
    """Give every relative-error figure of the fake runs an interval of +- ``half_width``."""
    for m in root.rglob("metrics.json"):
        data = json.loads(m.read_text())
        for rel in data["relative_error"].values():
            for q in ("rot_deg_mean", "trans_m_mean"):
                if rel["n"]:
                    rel[f"{q}_ci"] = [rel[q] - half_width, rel[q] + half_width]
        m.write_text(json.dumps(data))


def test_compare_says_whether_a_change_lies_beyond_the_printed_intervals(tmp_path):
    # B is 20 % worse: 1.0 -> 1.2 deg and 0.5 -> 0.6 m at 8 m
    a, b = _fake_results(tmp_path / "a"), _fake_results(tmp_path / "b", scale=1.2)
    _with_intervals(a, 0.08)
    _with_intervals(b, 0.08)  # 8 m rotation [0.92, 1.08] vs [1.12, 1.28]: apart; 0.6 vs 0.5 not
    res = CliRunner().invoke(app, ["compare", str(a), str(b)])
    (header, rows), _, _ = _tables(res.output)
    notes = {(r[1], r[2]): r[-1] for r in rows}
    assert notes[("(With Seed) ICP point-to-point", "8")] == \
        "! regression; rotation worse beyond the intervals"
    wide_a, wide_b = _fake_results(tmp_path / "wa"), _fake_results(tmp_path / "wb", scale=1.2)
    _with_intervals(wide_a, 0.5)
    _with_intervals(wide_b, 0.5)
    res = CliRunner().invoke(app, ["compare", str(wide_a), str(wide_b)])
    (header, rows), _, _ = _tables(res.output)
    notes = {(r[1], r[2]): r[-1] for r in rows}
    assert notes[("(With Seed) ICP point-to-point", "8")] == (
        "! regression by value only: A's and B's intervals meet, they cannot tell it from noise")
    assert "of them by value only" in res.output
    # and the other way round: an improvement beyond the intervals is named
    res = CliRunner().invoke(app, ["compare", str(b), str(a)])
    (header, rows), _, _ = _tables(res.output)
    notes = {(r[1], r[2]): r[-1] for r in rows}
    assert notes[("(With Seed) ICP point-to-point", "8")] == "rotation better beyond the intervals"


def test_compare_of_an_empty_folder_is_a_clear_error(tmp_path):
    a = _fake_results(tmp_path / "a")
    (tmp_path / "empty").mkdir()
    res = CliRunner().invoke(app, ["compare", str(a), str(tmp_path / "empty")])
    assert isinstance(res.exception, FileNotFoundError) and "no finished runs" in str(
        res.exception)


def test_markdown_table_escapes_pipes_and_pads_columns():
    from bench.report.compare import markdown_table

    lines = markdown_table(["a", "bb"], [["x|y", "1.5"], ["z", "10.25"]], right={1})
    assert lines == ["| a    |    bb |", "| ---- | ----: |", "| x\\|y |   1.5 |",
                     "| z    | 10.25 |"]
    assert len({len(line) for line in lines}) == 1  # aligned in a terminal


def test_table_over_several_experiments_labels_each(store, tmp_path):
    run_method("doppler", store, out=tmp_path / "exp-a" / "twist" / "doppler")
    run_method("doppler", store, params={"tau_spatial_m": 1.0},
               out=tmp_path / "exp-b" / "twist" / "doppler")
    res = CliRunner().invoke(app, ["table", str(tmp_path / "exp-a"), str(tmp_path / "exp-b"),
                                   "-f", "csv", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    rows = [line for line in res.output.splitlines() if line.startswith("twist,")]
    assert any("exp-a: (No initial guess) Doppler Correspondence (Ours)" in r for r in rows)
    assert any("exp-b: (No initial guess) Doppler Correspondence (Ours)" in r for r in rows)


def _given(root: Path, given: dict, params: dict) -> None:
    """Record in every fake run's config.yaml the parameters it was given (``-p``) and its
    resolved parameters, as `bench run` does."""
    import yaml

    for m in root.rglob("metrics.json"):
        config = {"method": {"name": json.loads(m.read_text())["method"], "params": params,
                             "given": given}}
        (m.parent / "config.yaml").write_text(yaml.safe_dump(config))


def test_compare_keeps_the_parameter_label_and_names_what_differs(tmp_path):
    """A run given -p tau_spatial_m=1 (B) is labelled so, as in `bench table`, is not matched
    with (nor called a regression of) the default run (A), and both notes name the parameter;
    two run folders compared directly say which parameters differ, and no regression."""
    a, b = _fake_results(tmp_path / "a"), _fake_results(tmp_path / "b", scale=1.5)
    _given(a, {}, {"tau_spatial_m": 3.0, "downsample": 1})
    _given(b, {"tau_spatial_m": 1.0}, {"tau_spatial_m": 1.0, "downsample": 1})
    res = CliRunner().invoke(app, ["compare", str(a), str(b), "--fail-on-regression"])
    assert res.exit_code == 0, res.output
    (header, rows), _, _ = _tables(res.output)
    labelled = [r for r in rows if r[1].endswith("[tau_spatial_m=1]")]
    assert labelled and all("only in B" in r[-1] for r in labelled)
    assert all("tau_spatial_m A 3.0, B 1.0" in r[-1] for r in rows)
    assert "! regression" not in res.output and "0 regressions" in res.output
    one_a = next(p.parent for p in a.rglob("metrics.json") if p.parent.name == "doppler")
    one_b = next(p.parent for p in b.rglob("metrics.json") if p.parent.name == "doppler")
    res = CliRunner().invoke(app, ["compare", str(one_a), str(one_b), "--fail-on-regression"])
    assert res.exit_code == 0, res.output
    (header, rows), _, _ = _tables(res.output)
    assert all(r[-1].startswith("parameters differ: tau_spatial_m A 3.0, B 1.0") for r in rows)
    assert "[tau_spatial_m=1]" in rows[0][1]
