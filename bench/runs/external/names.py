"""Where a ``bench score`` run may go: its name is one path component, not a harness method's
name nor a harness run folder's (``icp-p2p_seed``), and an existing folder of that name that
holds a run of another kind (a harness run) is replaced only when asked (``replace_run``), a
folder that holds other files and no run never (``bench.runs.external.score``)."""

from __future__ import annotations

from pathlib import Path

from bench.runs.folders import RUN_RECORDS
from loaders.errors import DataError
from methods.registry import METHODS, Seed

#: the ``kind`` of an external run's identity (config.yaml)
EXTERNAL = "external"


def check_name(name: str) -> str:
    """The run's name: one path component (its folder), not a harness method's name nor a
    harness run folder's (``<method>_seed`` / ``<method>_noseed``)."""
    if not name or not name.strip():
        raise DataError("--name: give the external method a name (e.g. --name my-odometry)")
    if any(c in name for c in "/\\\0") or name in (".", "..") or name != name.strip():
        raise DataError(f"--name {name!r}: expected one path component (no '/', '\\', "
                        "surrounding spaces, '.' or '..'): the run's folder under "
                        "RESULTS_DIR/SEQUENCE/")
    if name in METHODS:
        raise DataError(f"--name {name!r} is a method of the harness; an external run needs a "
                        f"name of its own (e.g. {name}-ext), so it never replaces that run")
    for method in METHODS:
        for seed in (Seed.WITH, Seed.WITHOUT):
            if name == method + seed.suffix:
                how = "with" if seed is Seed.WITH else "without"
                raise DataError(f"--name {name!r} is the run folder of the harness's {method} "
                                f"run {how} its seed; an external run needs a name of its own "
                                f"(e.g. {name}-ext), so it never replaces that run")
    return name


def check_run_folder(run_dir: Path, replace_run: bool) -> str:
    """"" when ``run_dir`` is free or holds an external run (``bench score``'s own), else what
    it holds: a run of another kind is refused unless ``replace_run`` (then its records are
    cleared before the external run is written, with a warning saying what it replaced); a
    folder with files but no run is always refused."""
    if not run_dir.is_dir() or not any(run_dir.iterdir()):
        return ""
    config = _config(run_dir)
    is_run = config is not None or any((run_dir / n).exists() for n in RUN_RECORDS)
    if not is_run:
        raise DataError(f"{run_dir} holds files that are no run; bench score writes only into "
                        "a new folder or one of its own runs: choose another --name or --out")
    kind = _mapping(config, "identity").get("kind")
    if kind == EXTERNAL or isinstance((config or {}).get("external"), dict):
        return ""
    method = _mapping(config, "method").get("name", "?")
    what = f"a harness run (method {method})"
    if not replace_run:
        raise DataError(f"{run_dir} holds {what}; bench score does not replace it: choose "
                        "another --name (or --replace-run to replace that run)")
    return what


def _mapping(config: dict | None, key: str) -> dict:
    """``config[key]`` when it is a mapping, else {} (a config.yaml written by hand or by another
    tool may hold anything there)."""
    value = (config or {}).get(key)
    return value if isinstance(value, dict) else {}


def _config(run_dir: Path) -> dict | None:
    import yaml

    path = run_dir / "config.yaml"
    if not path.exists():
        return None
    try:
        config = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError):
        return {}
    return config if isinstance(config, dict) else {}
