"""Whose run a run folder holds: a command writes a run only into a new folder or one holding
its own run (the same method, seed option, parameters, frame range and store path for ``bench
run``; the same trajectory file and store for ``bench score``). ``--force`` re-does that run
only, never another (issue 46, the one write rule; ``bench.guard.run_folder`` checks the
folder's kind)."""

from __future__ import annotations

from pathlib import Path

from bench.guard import EXTERNAL, resolved
from loaders.errors import DataError


def run_identity(config: dict) -> dict:
    """What makes a run folder's run the run it is, from its config.yaml: for a harness run
    the method, its seed option, its resolved parameters, the frame range and the store (its
    resolved path: a store changed in place is the same run, done again); for an external
    one (``bench score``) the trajectory file and the store (resolved paths)."""
    identity = config.get("identity") if isinstance(config.get("identity"), dict) else {}
    method = config.get("method") if isinstance(config.get("method"), dict) else {}
    if "external" in config or identity.get("kind") == EXTERNAL:
        external = config.get("external") if isinstance(config.get("external"), dict) else {}
        sequence = config.get("sequence") if isinstance(config.get("sequence"), dict) else {}
        return {"trajectory": _resolved_text(external.get("trajectory")),
                "topic": external.get("topic"), "store": _resolved_text(sequence.get("store"))}
    sequence = config.get("sequence") if isinstance(config.get("sequence"), dict) else {}
    return {"method": identity.get("method", method.get("name")),
            "seed option": identity.get("seed", config.get("seed")),
            "parameters": identity.get("params", method.get("params")),
            "frame range": identity.get("frame_range"),
            "store": _resolved_text(sequence.get("store"))}


def _resolved_text(path) -> str | None:
    return None if path in (None, "") else str(resolved(Path(str(path))))


def foreign_run(run_dir: Path, wanted: dict, maker: str) -> None:
    """Refuse ``run_dir`` when it holds a run (finished or not) whose ``run_identity`` differs
    from ``wanted`` (the run ``maker`` is about to make): another method, seed option,
    parameters, trajectory file or store; ``--force`` never widens this (it re-does the
    command's own run only). The message names what the folder holds."""
    import yaml

    from loaders.yamlio import read_yaml

    path = Path(run_dir) / "config.yaml"
    if not path.is_file():
        return
    try:
        config = read_yaml(path)
    except (OSError, yaml.YAMLError, DataError):
        return
    if not isinstance(config, dict):
        return
    import json

    def plain(value):
        return json.loads(json.dumps(value, default=list))

    held = run_identity(config)
    differs = [k for k in wanted if k in held and plain(held[k]) != plain(wanted[k])]
    if differs:
        first = next(iter(held))  # the method, or the trajectory file: always named
        if "method" in differs:  # another method's parameters say nothing more
            differs = [k for k in differs if k != "parameters"]
        shown = [first, *(k for k in differs if k != first)]
        holds = ", ".join(f"{k} {_differing(held[k], wanted.get(k))!r}" for k in shown)
        asked = ", ".join(f"{k} {_differing(wanted[k], held[k])!r}" for k in differs)
        why = (" (a folder holds one store's runs: another store of that name is another "
               "sequence)" if "store" in differs else "")
        raise DataError(f"{run_dir}: holds another run ({holds}); {maker} would replace it "
                        f"with {asked}{why}: choose another folder or name (--force re-does "
                        "only the same run, never another)")


def _differing(value, other):
    """``value``, or of a dict (parameters) only the entries that differ from ``other``'s."""
    if isinstance(value, dict) and isinstance(other, dict):
        return {k: v for k, v in value.items() if other.get(k) != v}
    return value
