"""An experiment's pairs (issue 34): a store whose Doppler a method cannot use refuses only
that pair (the others run; the refused one is a failed row naming the option that would make
it run; exit 1), and a run made by hand under another sequence name is reused under the
experiment's name, saying so, so its row joins its sequence."""

import dataclasses
import json

import pytest
import yaml

from bench.cli import main
from bench.runs.folders import read_run
from conftest import constant_twist_sequence
from loaders.store import write_store


def _bench(args, capsys, monkeypatch):
    monkeypatch.setattr("sys.argv", ["bench", *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    captured = capsys.readouterr()
    return exit_.value.code, captured.out, captured.err


def _store(path, name, doppler_kind="radial"):
    seq = constant_twist_sequence(n_frames=25, n_points=1000, noise_m=0.02, max_range_m=60)
    seq.name = name
    seq.sensor = dataclasses.replace(seq.sensor, doppler_kind=doppler_kind)
    return write_store(seq, path)


def _experiment(tmp_path, sequences, methods):
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"name": "pairs", "sequences": sequences,
                                    "methods": methods, "out": "res", "jobs": 1}))
    return path


def test_a_store_a_method_cannot_use_refuses_only_that_pair(tmp_path, capsys, monkeypatch):
    _store(tmp_path / "good.h5", "good")
    _store(tmp_path / "comp.h5", "comp", doppler_kind="ego-compensated")
    exp = _experiment(tmp_path, [{"path": "good.h5"}, {"path": "comp.h5"}],
                      [{"name": "doppler"}])
    code, out, err = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 1, out + err
    assert "refused comp / doppler" in out and "ego-compensated" in out
    assert "`sequences:`" in out and "1 run(s) refused" in out
    assert read_run(tmp_path / "res" / "good" / "doppler").result.finished
    refused = read_run(tmp_path / "res" / "comp" / "doppler", failed=True).result
    assert refused.status == "refused" and "ego-compensated" in refused.error
    table = (tmp_path / "res" / "table.md").read_text()
    assert "| failed [1] |" in table and "refused: " in table  # a row saying why


def test_every_pair_refused_is_one_clear_error(tmp_path, capsys, monkeypatch):
    _store(tmp_path / "comp.h5", "comp", doppler_kind="ego-compensated")
    exp = _experiment(tmp_path, [{"path": "comp.h5"}], [{"name": "doppler"}])
    code, out, err = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 2 and "every run of the experiment was refused" in err
    assert "Traceback" not in out + err


def test_a_run_made_by_hand_is_reused_under_the_experiments_name(tmp_path, capsys,
                                                                 monkeypatch):
    _store(tmp_path / "s.h5", "store-name")
    by_hand = tmp_path / "res" / "Named" / "doppler"
    code, out, err = _bench(["run", "--method", "doppler", "--data", str(tmp_path / "s.h5"),
                             "--out", str(by_hand), "--executor", "local"], capsys, monkeypatch)
    assert code == 0 and read_run(by_hand).display_name == "store-name"
    made = json.loads((by_hand / "metrics.json").read_text())
    exp = _experiment(tmp_path, [{"path": "s.h5", "name": "Named",
                                  "display_name": "Named loop"}],
                      [{"name": "doppler"}, {"name": "icp-p2p", "seeds": [True]}])
    code, out, err = _bench(["run", str(exp), "--executor", "local"], capsys, monkeypatch)
    assert code == 0, out + err
    assert f"reused {by_hand} (made as sequence 'store-name'" in err
    assert "under the name 'Named loop'" in err and "skipped Named / doppler" in out
    run = read_run(by_hand)
    assert (run.sequence, run.display_name) == ("Named", "Named loop")
    assert run.result.ape.trans_rmse_m == made["ape"]["trans_rmse_m"]  # the same result
    table = (tmp_path / "res" / "table.md").read_text()
    assert "store-name" not in table and table.count("Named loop") == 1  # one sequence
