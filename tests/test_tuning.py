"""configs/tuning/*.yaml: every tuned default of configs/methods/*.yaml has a sweep anyone can
replay (`bench run configs/tuning/<x>.yaml`), run on the declared tuning data only
(configs/splits.yaml), that can choose the default. Every sweep decides by the tuning rule of
configs/splits.yaml (C against the library's or paper's reference value; bench/runs/
tuning_rule.py): a radar sweep by cross-validation over both halves of the real sample with
the synthetic radar as a second domain, a LiDAR sweep (synthetic only) by folds over the
four tuning seeds with the tunnel scene as a second domain; each records its decision
(``decided:``), and the method's default must be it.
The cheapest sweep is replayed here, end to end, and must reach that decision again."""

from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from bench.cli import app
from bench.runs.experiment import load_experiment
from bench.runs.sweep import format_value
from loaders.scan import SensorInfo
from loaders.store import StoreSequence
from methods.registry import make_method

ROOT = Path(__file__).resolve().parents[1]
TUNING = sorted((ROOT / "configs" / "tuning").glob("*.yaml"))
SPLITS = yaml.safe_load((ROOT / "configs" / "splits.yaml").read_text())
#: replayed by this test, end to end (kiss-icp is the cheapest method: 20 runs); the others by
#: `bench run configs/tuning/<x>.yaml`
CHEAPEST = ("kiss-icp-radar-voxel",)


def _tuned_keys() -> dict[tuple[str, str], set[str]]:
    """(method, parameter) -> the splits its comment in configs/methods names as its tuning
    source ("real", "synthetic")."""
    tuned = {}
    for path in (ROOT / "configs" / "methods").glob("*.yaml"):
        name = yaml.safe_load(path.read_text())["name"]
        for line in path.read_text().split("params:", 1)[1].splitlines():
            key, _, comment = line.partition("#")
            if not line.startswith("  ") or ":" not in key:
                continue
            if "(vgicp only)" in comment and name != "vgicp":
                continue  # a parameter the method ignores
            splits = {s for s in ("real", "synthetic") if f"tuning: {s}" in comment}
            if splits:
                tuned[(name, key.split(":")[0].strip())] = splits
    return tuned


def _sweeps() -> dict[tuple[str, str], set[str]]:
    """(method, parameter) -> the splits a tuning YAML sweeps it on."""
    swept = {}
    for path in TUNING:
        exp = load_experiment(path)
        splits = {"real"} if exp.sequences else set()
        splits |= {"synthetic"} if exp.synthetic else set()
        for m in exp.methods:
            for v in m.variants():
                for key in v.point:
                    swept.setdefault((m.name, key), set()).update(splits)
    return swept


def test_every_tuned_default_has_a_sweep_on_its_split():
    tuned, swept = _tuned_keys(), _sweeps()
    assert len(tuned) >= 15  # the parser found the tuned values (doppler-ego's, the ICPs')
    for key, splits in tuned.items():
        assert splits <= swept.get(key, set()), f"{key}: tuned on {splits}, no sweep replays it"


def _half(seq) -> str:
    """The half of the real sample (configs/splits.yaml) a sequence entry runs."""
    for name, half in SPLITS["real"]["halves"].items():
        if (seq.start, seq.frames) == (half["start"], half["frames"]):
            return name
    raise AssertionError(f"{seq.name}: frames {seq.start}+{seq.frames} are not a declared half")


def _defaults(exp, m, keys) -> list[dict]:
    """The method's resolved default for ``keys`` on each kind of sensor the sweep runs on."""
    store = ROOT / SPLITS["real"]["store"]
    sensors = ([StoreSequence(store).sensor] if exp.sequences else []) + [
        SensorInfo(kind, 0.1) for kind in {_kind(s.sensor) for s in exp.synthetic}]
    fixed = {k: v for k, v in m.variants()[0].params.items() if k not in keys}
    seed = (m.seeds or [True])[0]  # a no-seed sweep holds the no-seed default
    out = []
    for sensor in sensors:
        params = make_method(m.name, fixed, sensor, seed).params
        out.append({k: getattr(params, k) for k in keys})
    return out


@pytest.mark.parametrize("path", TUNING, ids=[p.stem for p in TUNING])
def test_tuning_sweeps_run_on_the_declared_data_by_the_rule_and_can_choose_the_default(path):
    exp = load_experiment(path)
    assert exp.name == f"tune-{path.stem}"
    assert exp.criterion is not None, "a tuning sweep states its criterion"
    assert exp.suite is None  # the reported suites are never tuned on
    store = (ROOT / SPLITS["real"]["store"]).resolve()
    halves = {}
    for s in exp.sequences:
        assert Path(s.path).resolve() == store
        halves[s.name] = _half(s)
    for s in exp.synthetic:
        assert s.seed in SPLITS["synthetic"]["tuning_seeds"]
    assert exp.sequences or exp.synthetic
    c = exp.criterion
    if exp.sequences:  # a radar default on the real sample: the rule of configs/splits.yaml
        rule = SPLITS["rule"]
        assert c.cross_validated, f"{path.name}: a radar sweep decides by the tuning rule"
        assert c.lengths_m == rule["lengths_m"] and c.level == rule["level"]
        assert c.reps == rule["reps"] and c.min_gain == rule["min_gain"]
        assert [{"tuning": [halves[n] for n in f.tuning],
                 "validation": [halves[n] for n in f.validation]}
                for f in c.folds] == rule["folds"]
        domain = SPLITS["synthetic"]["radar_domain"]
        by_name = {s.name: s for s in exp.synthetic}
        assert sorted(by_name[n].seed for n in c.domain) == domain["seeds"]
        for n in c.domain:
            s = by_name[n]
            assert (s.scene, s.sensor, s.frames) == (domain["scene"], domain["sensor"],
                                                     domain["frames"])
            assert "gt" not in s.options  # the clean suite: exact ground truth
    else:  # a LiDAR default on synthetic LiDAR only: the same rule, folds over tuning seeds
        assert all(_kind(s.sensor) == "lidar" for s in exp.synthetic), path.name
        _assert_lidar_rule(path, exp)
    assert c.cross_validated, f"{path.name}: every sweep decides by the tuning rule"
    sweeps = [m for m in exp.methods if any(v.point for v in m.variants())]
    assert len(sweeps) == 1, "a tuning experiment sweeps one method entry"
    (m,) = sweeps
    variants = m.variants()
    keys = list(variants[0].point)
    swept = [{k: format_value(v.point[k]) for k in keys} for v in variants]
    for default in _defaults(exp, m, keys):
        assert {k: format_value(default[k]) for k in keys} in swept, \
            f"{path.name}: the default {default} is not swept"
        if c.cross_validated:
            reference = {k: format_value(c.reference.get(k, default[k])) for k in keys}
            assert reference in swept, f"{path.name}: the reference {reference} is not swept"
            assert exp.decided is not None, f"{path.name}: no recorded decision"
            assert {k: format_value(default[k]) for k in keys} == {
                k: format_value(v) for k, v in exp.decided.items()}, \
                f"{path.name}: the default {default} is not the rule's decision {exp.decided}"
            # along every axis where the decision leaves the reference, it is inside the grid
            for k, v in exp.decided.items():
                if format_value(v) != reference[k]:
                    axis = sorted({p[k] for p in (x.point for x in variants)})
                    assert axis[0] < v < axis[-1], f"{path.name}: {k}={v} on the grid's edge"


def _assert_lidar_rule(path: Path, exp) -> None:
    """A LiDAR sweep states the rule of configs/splits.yaml with its LiDAR folds: the same
    lengths, level, draws and least gain; both folds over the declared scene's four tuning
    seeds (two tune, the other two validate, both ways); the declared second domain."""
    c, rule, lidar = exp.criterion, SPLITS["rule"], SPLITS["synthetic"]["lidar"]
    assert c.cross_validated, f"{path.name}: a LiDAR sweep decides by the tuning rule"
    assert c.lengths_m == rule["lengths_m"] and c.level == rule["level"]
    assert c.reps == rule["reps"] and c.min_gain == rule["min_gain"]
    by_name = {s.name: s for s in exp.synthetic}
    seeds = [{"tuning": [by_name[n].seed for n in f.tuning],
              "validation": [by_name[n].seed for n in f.validation]} for f in c.folds]
    assert seeds == SPLITS["lidar_rule"]["folds"], path.name
    for f in c.folds:
        assert not set(f.tuning) & set(f.validation)
        for n in f.tuning + f.validation:
            s = by_name[n]
            assert (s.scene, s.sensor, s.frames) == (lidar["scene"], lidar["sensor"],
                                                     lidar["frames"]), n
    assert sorted(by_name[n].seed for n in c.domain) == lidar["domain_seeds"]
    assert {by_name[n].scene for n in c.domain} == {lidar["domain_scene"]}
    # one LiDAR density per sweep: every sequence generated with the same options
    assert len({tuple(sorted(s.options.items())) for s in exp.synthetic}) == 1


def _kind(sensor: str) -> str:
    from loaders.synthetic.sensors import SENSORS

    return SENSORS[sensor].kind


@pytest.mark.parametrize("name", CHEAPEST)
def test_the_cheapest_sweep_replays_its_decision(name, tmp_path):
    """The sweep's runs in this process (``--executor local``): the decision reads errors,
    which are the same whichever executor runs them (tests/test_executors.py), and a forked
    worker per run pays again for what this process has loaded (kiss-icp, numba's kernels,
    the library lookup): 20 runs cost about 34 s of CPU in workers, 25 s here."""
    import yaml

    original = ROOT / "configs" / "tuning" / f"{name}.yaml"
    spec = yaml.safe_load(original.read_text())
    # the same sweep with its synthetic stores made under tmp_path, not the checkout's data/
    spec["data_dir"] = str(tmp_path / "data")
    for seq in spec.get("sequences", []):
        seq["path"] = str((original.parent / seq["path"]).resolve())
    path = tmp_path / original.name
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"),
                                      "--executor", "local"])
    assert result.exit_code == 0, result.output
    chosen = [ln for ln in result.output.splitlines() if ln.startswith("chosen")]
    assert chosen, result.output
    assert (tmp_path / "out" / "sweep.md").exists() and (tmp_path / "out" / "sweeps.json").exists()
    assert any((tmp_path / "data").rglob("*.h5"))  # its synthetic stores, made there
    decided = " ".join(f"{k}={format_value(v)}"
                       for k, v in load_experiment(original).decided.items())
    for line in chosen:
        assert "agrees" in line and decided in line, line
