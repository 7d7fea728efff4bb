"""The notebook API (and the README's example) and `bench compare`."""

import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

from bench.api import COLUMNS, load_results, run_method
from bench.cli import app
from conftest import constant_twist_sequence
from loaders.store import write_store

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    seq = constant_twist_sequence(n_frames=60, n_points=1500, noise_m=0.02, max_range_m=70)
    return write_store(seq, tmp_path_factory.mktemp("data") / "twist.h5")


def test_readme_notebook_example_runs(store, tmp_path, monkeypatch):
    block = re.search(r"<!-- notebook-example -->\s*```python\n(.*?)```", README.read_text(),
                      re.S).group(1)
    monkeypatch.chdir(tmp_path)
    namespace = {"STORE": str(store)}
    exec(compile(block.replace('"data/synthetic-paper/Loop1_0.h5"', "STORE"), "README", "exec"),
         namespace)
    df = namespace["df"]
    assert list(df.columns) == COLUMNS
    assert set(df["method"]) == {"doppler", "icp-p2p"} and len(df) == 2 * 6
    assert (df["trans_m_mean"] > 0).all()


def test_run_method_returns_the_metrics_and_load_results_one_row_per_length(store, tmp_path):
    m = run_method("doppler", store, out=tmp_path / "r" / "twist" / "doppler")
    df = load_results(tmp_path / "r")
    assert len(df) == len(m["relative_error"])
    row = df[df["length_m"] == 8.0].iloc[0]
    assert row["trans_m_mean"] == m["relative_error"]["8"]["trans_m_mean"]
    assert row["seed"] is None and row["ape_trans_m"] == m["ape"]["trans_rmse_m"]


def test_compare_shows_the_changed_cell(store, tmp_path):
    run_method("doppler", store, out=tmp_path / "a" / "twist" / "doppler")
    run_method("doppler", store, params={"tau_spatial_m": 0.5},
               out=tmp_path / "b" / "twist" / "doppler")
    res = CliRunner().invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "b")])
    assert res.exit_code == 0, res.output
    line = next(x for x in res.output.splitlines() if x.startswith("twist | doppler") and
                "| 8 |" in x)
    a, b, delta = re.search(r"\| ([\d.]+) -> ([\d.]+) \(([-+][\d.]+)\) \|$",
                            line.split(" | ", 5)[5].rsplit(" | ", 1)[0] + " |").groups()
    assert float(a) != float(b) and float(delta) == pytest.approx(float(b) - float(a), abs=2e-3)
    same = CliRunner().invoke(app, ["compare", str(tmp_path / "a"), str(tmp_path / "a"),
                                    "--fail-on-regression"])
    assert same.exit_code == 0 and "0 regressions" in same.output


def test_table_over_several_experiments_labels_each(store, tmp_path):
    run_method("doppler", store, out=tmp_path / "exp-a" / "twist" / "doppler")
    run_method("doppler", store, params={"tau_spatial_m": 1.0},
               out=tmp_path / "exp-b" / "twist" / "doppler")
    res = CliRunner().invoke(app, ["table", str(tmp_path / "exp-a"), str(tmp_path / "exp-b"),
                                   "-f", "csv", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    rows = [line for line in res.output.splitlines() if line.startswith("4D")
            or ",twist," in line]
    assert any("exp-a: (No initial guess) Doppler Correspondence (Ours)" in r for r in rows)
    assert any("exp-b: (No initial guess) Doppler Correspondence (Ours)" in r for r in rows)
