"""configs/methods/*.yaml: one per registered method, valid, and equal to the code's defaults
(the published values documented there are the values a run uses)."""

from pathlib import Path

import pytest
import yaml

from methods.registry import METHODS

CONFIGS = Path(__file__).resolve().parents[1] / "configs" / "methods"
BUILT_IN = sorted(n for n in METHODS if not n.startswith("test-"))


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_method_has_a_config_equal_to_its_defaults(name):
    path = CONFIGS / f"{name}.yaml"
    assert path.exists(), f"{path} missing"
    cfg = yaml.safe_load(path.read_text())
    assert cfg["name"] == name
    Params = METHODS[name].Params
    assert Params.model_validate(cfg["params"]) == Params()
    assert "#" in path.read_text().split("params:")[1]  # each value carries its source


def test_no_config_for_an_unknown_method():
    assert {p.stem for p in CONFIGS.glob("*.yaml")} <= set(METHODS)


#: what a default's comment may name as its source (configs/splits.yaml declares the tuning
#: splits): the paper, the authors' or reference code, a library's default, a physical argument
#: or convention, this project's own choice (switches, threads, backends), or a tuning split
SOURCES = ("paper", "code", "authors", "notebook", "o3d", "kiss-icp", "small_gicp", "physical",
           "conventional", "this project", "ablation", "tuning: real", "tuning: synthetic",
           "estimated from", "decided from", "speed", "a cap")


def _param_lines(text: str) -> list[str]:
    lines = text.split("params:", 1)[1].splitlines()
    return [ln for ln in lines if ln.startswith("  ") and not ln.strip().startswith("#")
            and ":" in ln]


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_default_names_its_source(name):
    text = (CONFIGS / f"{name}.yaml").read_text()
    params = _param_lines(text)
    assert len(params) == len(METHODS[name].Params.model_fields)
    for line in params:
        key, _, comment = line.partition("#")
        assert comment, f"{name}: {key.strip()} has no source"
        assert any(s in comment for s in SOURCES), f"{name}: {line.strip()}"


def test_tuned_defaults_name_a_declared_split():
    """A tuned default names one of the splits of configs/splits.yaml (never reported data)."""
    splits = yaml.safe_load((CONFIGS.parent / "splits.yaml").read_text())
    halves = splits["real"]["halves"]
    assert halves["A"] == {"start": 0, "frames": 125}
    assert halves["B"]["start"] >= halves["A"]["start"] + halves["A"]["frames"]  # disjoint
    assert min(splits["synthetic"]["tuning_seeds"]) >= 1000
    for path in CONFIGS.glob("*.yaml"):
        for line in _param_lines(path.read_text()):
            comment = line.partition("#")[2]
            if "tuning" in comment:
                assert "tuning: real" in comment or "tuning: synthetic" in comment, line


def test_reported_suites_never_use_tuning_seeds():
    from loaders.synthetic.suite import SUITES

    tuning = set(yaml.safe_load((CONFIGS.parent / "splits.yaml").read_text())
                 ["synthetic"]["tuning_seeds"])
    for entries in SUITES.values():
        assert not tuning & {e.seed for e in entries}


@pytest.mark.parametrize("name", BUILT_IN)
def test_every_config_says_it_is_a_mirror_of_the_code(name):
    """The defaults live in the code (a method's Params): each file says so on its first line,
    naming the module and class that hold them, and that editing it changes no run (a reader
    took it for the place to change a default: `bench regress` then found 0 changes)."""
    cls = METHODS[name]
    module = cls.__module__.replace(".", "/") + ".py"
    assert (CONFIGS.parents[1] / module).is_file()
    head = " ".join((CONFIGS / f"{name}.yaml").read_text().splitlines()[:4])
    assert head.startswith(f"# A MIRROR of the defaults in {module} ({cls.__name__}.Params)")
    assert "editing this file changes no run" in head and "bench run -p" in head
