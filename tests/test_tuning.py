"""configs/tuning/*.yaml: every tuned default of configs/methods/*.yaml has a sweep anyone can
replay (`bench run configs/tuning/<x>.yaml`), run on the declared tuning split only
(configs/splits.yaml), that can choose the default; and the cheapest sweeps are replayed here,
end to end, and must choose the default (or the YAML says why not, ``default_differs``).
The other sweeps print their choice beside the default in the same way (README, "Tuning")."""

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
#: replayed by this test, end to end (the cheapest: 3 vgicp runs, 2 doppler-ego runs of 125
#: frames); the others by `bench run configs/tuning/<x>.yaml`
CHEAPEST = ("vgicp-radar-gate", "doppler-ego-neighbours")


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
        split = "synthetic" if exp.synthetic else "real"
        for m in exp.methods:
            for v in m.variants():
                for key in v.point:
                    swept.setdefault((m.name, key), set()).add(split)
    return swept


def test_every_tuned_default_has_a_sweep_on_its_split():
    tuned, swept = _tuned_keys(), _sweeps()
    assert len(tuned) >= 15  # the parser found the tuned values (doppler-ego's, the ICPs')
    for key, splits in tuned.items():
        assert splits <= swept.get(key, set()), f"{key}: tuned on {splits}, no sweep replays it"


@pytest.mark.parametrize("path", TUNING, ids=[p.stem for p in TUNING])
def test_tuning_sweeps_run_on_the_tuning_split_only_and_can_choose_the_default(path):
    exp = load_experiment(path)
    assert exp.name == f"tune-{path.stem}"
    assert exp.criterion is not None, "a tuning sweep states its criterion"
    assert exp.suite is None  # the reported suites are never tuned on
    real = SPLITS["real"]
    store = (ROOT / real["store"]).resolve()
    tuning_stop = real["tuning"]["start"] + real["tuning"]["frames"]
    for s in exp.sequences:
        assert Path(s.path).resolve() == store
        assert s.frames is not None and s.start + s.frames <= tuning_stop
        assert s.start >= real["tuning"]["start"]
    for s in exp.synthetic:
        assert s.seed in SPLITS["synthetic"]["tuning_seeds"]
    assert exp.sequences or exp.synthetic
    sensors = [StoreSequence(store).sensor] if exp.sequences else [
        SensorInfo(kind, 0.1) for kind in {_kind(s.sensor) for s in exp.synthetic}]
    sweeps = [m for m in exp.methods if any(v.point for v in m.variants())]
    assert sweeps, "a tuning experiment sweeps something"
    for m in sweeps:
        variants = m.variants()
        keys = list(variants[0].point)
        for sensor in sensors:
            fixed = {k: v for k, v in variants[0].params.items() if k not in keys}
            seed = (m.seeds or [True])[0]  # a no-seed sweep holds the no-seed default
            params = make_method(m.name, fixed, sensor, seed).params
            default = {k: getattr(params, k) for k in keys}
            assert any(all(format_value(v.point[k]) == format_value(default[k]) for k in keys)
                       for v in variants), f"{path.name}: the default {default} is not swept"


def _kind(sensor: str) -> str:
    from loaders.synthetic.sensors import SENSORS

    return SENSORS[sensor].kind


@pytest.mark.parametrize("name", CHEAPEST)
def test_the_cheapest_sweeps_choose_the_defaults(name, tmp_path):
    path = ROOT / "configs" / "tuning" / f"{name}.yaml"
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    chosen = [ln for ln in result.output.splitlines() if ln.startswith("chosen")]
    assert chosen, result.output
    assert (tmp_path / "sweep.md").exists() and (tmp_path / "sweeps.json").exists()
    differs = load_experiment(path).default_differs
    for line in chosen:
        assert "agrees" in line or (differs and "DIFFERS" in line), line
