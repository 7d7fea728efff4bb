"""The paper's APE tables (IV, V): shape, ranking, Div., failed rows, seed tags, display names,
the alignment in the caption."""

import json

import yaml

from bench.report.tables.ape import collect_ape, write_ape_tables
from bench.report.tables.model import to_csv, to_latex, to_markdown


def _run(root, seq, display, method, seed, ape_m, diverged=False, label=None):
    d = root / seq / f"{label or method}_{seed}"
    d.mkdir(parents=True)
    cfg = {"sequence": {"name": seq, "display_name": display}}
    if label:
        cfg["label"] = label
    (d / "config.yaml").write_text(yaml.safe_dump(cfg))
    (d / "metrics.json").write_text(json.dumps({
        "sequence": seq, "method": method, "seed": seed, "diverged": diverged,
        "relative_error": {}, "ape": {"trans_rmse_m": ape_m, "rot_rmse_deg": 1.0}}))


def test_ranks_divergence_and_order(tmp_path):
    _run(tmp_path, "T1", "Tunnel (Empty)", "icp-p2p", True, 500.0, diverged=True)
    _run(tmp_path, "T1", "Tunnel (Empty)", "dicp", True, 65.27)
    _run(tmp_path, "T1", "Tunnel (Empty)", "doppler", None, 20.16)
    _run(tmp_path, "T1", "Tunnel (Empty)", "doppler-icp", True, 14.5)
    _run(tmp_path, "T2", "Tunnel (Vehicles)", "dicp", True, 37.12)
    _run(tmp_path, "T2", "Tunnel (Vehicles)", "doppler", None, 47.54)
    _run(tmp_path, "T2", "Tunnel (Vehicles)", "doppler-icp", True, 24.06)
    table = collect_ape(tmp_path, ["T1", "T2"])
    assert table.sequences == ["Tunnel (Empty)", "Tunnel (Vehicles)"]
    # the paper's row order: baselines first, its own methods last
    assert [label for label, _ in table.rows] == [
        "(With Seed) ICP point-to-point", "(With Seed) DICP",
        "(No initial guess) Doppler Correspondence (Ours)", "(With Seed) Doppler 4D-ICP (Ours)"]
    md = to_markdown(table.table)
    assert "| (With Seed) ICP point-to-point | Div. | - |" in md
    assert "| (With Seed) Doppler 4D-ICP (Ours) | **14.50** | **24.06** |" in md
    assert "| (No initial guess) Doppler Correspondence (Ours) | <u>20.16</u> | 47.54 |" in md
    assert "| (With Seed) DICP | 65.27 | <u>37.12</u> |" in md
    assert "SE(3) alignment (Umeyama, all poses)" in md and "evo_ape -a" in md
    tex = to_latex(table.table)
    assert r"\textbf{14.50}" in tex and r"\underline{20.16}" in tex and "Div." in tex
    assert r"\caption{" in tex and r"\toprule" in tex and r"\hline" not in tex
    rows = to_csv(table.table).splitlines()
    assert rows[0] == "sequence,sensor_class,method,seed,label,status,row,column,quantity," \
        "value,note"
    assert ",,icp-p2p,with,,Div.,(With Seed) ICP point-to-point,Tunnel (Empty)," \
        "ape_trans_rmse_m,500.0," in rows


def test_both_seed_options_and_labels_get_their_own_rows(tmp_path):
    _run(tmp_path, "L", "Loop1_0", "icp-p2p", True, 3.0)
    _run(tmp_path, "L", "Loop1_0", "icp-p2p", False, 2.0)
    _run(tmp_path, "L", "Loop1_0", "icp-p2p", True, 1.0, label="icp-p2p tau 1 m")
    labels = [label for label, _ in collect_ape(tmp_path).rows]
    assert labels == ["(With Seed) ICP point-to-point", "(No Seed) ICP point-to-point",
                      "(With Seed) icp-p2p tau 1 m"]


def test_write_ape_tables_writes_every_format(tmp_path):
    _run(tmp_path / "r", "L", "Loop1_0", "dicp", True, 2.5)
    texts = write_ape_tables(tmp_path / "r", tmp_path / "out", stem="table4")
    assert set(texts) == {"md", "tex", "csv"}
    for fmt in texts:
        assert (tmp_path / "out" / f"table4.{fmt}").read_text() == texts[fmt]


def test_a_failed_run_stays_as_a_failed_row_with_its_reason(tmp_path):
    _run(tmp_path, "T1", "Tunnel (Empty)", "doppler-icp", True, 14.5)
    d = tmp_path / "T1" / "dicp_seed"
    d.mkdir(parents=True)
    (d / "config.yaml").write_text(yaml.safe_dump({
        "sequence": {"name": "T1", "display_name": "Tunnel (Empty)"},
        "method": {"name": "dicp"}, "seed": True}))
    (d / "failed.json").write_text(json.dumps({"status": "failed",
                                               "error": "DataError: no Doppler in t1.h5"}))
    table = collect_ape(tmp_path).table
    md = to_markdown(table)
    assert "| (With Seed) DICP | failed [1] |" in md
    assert "[1] (With Seed) DICP on Tunnel (Empty): failed: DataError: no Doppler in t1.h5" in md
    assert r"failed\textsuperscript{1}" in to_latex(table)


def test_a_sim3_experiment_says_so_in_the_caption(tmp_path):
    _run(tmp_path, "L", "Loop1_0", "dicp", True, 2.5)
    m = json.loads((tmp_path / "L" / "dicp_True" / "metrics.json").read_text())
    m["ape"].update(requested="sim3", alignment="sim3")
    m["schema"] = 2
    m["relative_error"] = []
    (tmp_path / "L" / "dicp_True" / "metrics.json").write_text(json.dumps(m))
    assert "Sim(3) alignment (Umeyama, all poses), as evo_ape -as" in to_markdown(
        collect_ape(tmp_path).table)
