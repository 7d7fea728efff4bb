"""A loader's options checked by its typed ``Options`` model, with one error listing every
problem. Shared by ``bench convert LOADER`` (``bench.data.convert``: problems named by their
command-line flags) and the dataset configs (``bench.data.datasets``: by their YAML keys), so
it sits below both and neither imports the other."""

from __future__ import annotations

from loaders.errors import DataError


def validate_options(Options, values: dict, flags: dict[str, str] | None = None,
                     where: str = "options"):
    """``values`` validated by the loader's Options model; one DataError listing every
    problem (by command-line flag when ``flags`` names them)."""
    from pydantic import ValidationError

    from loaders.errors import validation_problems

    try:
        return Options.model_validate(values)
    except ValidationError as err:
        problems = validation_problems(err, lambda loc: list(Options.model_fields), "option")
        for key, flag in (flags or {}).items():
            problems = [flag + p[len(key):] if p.startswith(f"{key}: ") else p
                        for p in problems]
        raise DataError(f"{where}:\n  " + "\n  ".join(problems)) from None
