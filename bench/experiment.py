"""Experiment configuration (YAML under configs/experiments/), validated with pydantic.

    name: paper-synthetic
    suite: synthetic-paper          # a synthetic suite, generated/cached under data_dir
    sequences:                      # and/or explicit stores
      - path: data/real/Loop1_0.h5
        display_name: Loop1_0
        sensor_class: Semi-Dense 4D Radar
    methods:
      - name: doppler
      - name: icp-p2p
        params: {max_iterations: 100}
        seeds: [true, false]        # default: both, or [true] for methods without a guess
    lengths_m: [8, 16, 24, 32, 40, 48]
    jobs: 2
    out: results/paper-synthetic

Unknown keys, unknown methods and unknown method parameters are errors.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from loaders.errors import DataError
from methods.registry import METHODS, get_method
from metrics.relative import DEFAULT_LENGTHS_M


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SequenceEntry(_Strict):
    path: Path
    name: str | None = None
    display_name: str | None = None
    sensor_class: str | None = None


class MethodEntry(_Strict):
    name: str
    params: dict = Field(default_factory=dict)
    seeds: list[bool] | None = None

    @model_validator(mode="after")
    def _check(self) -> MethodEntry:
        if self.name not in METHODS:
            raise ValueError(f"unknown method {self.name!r}; registered: {', '.join(METHODS)}")
        Params = getattr(get_method(self.name), "Params", None)
        if Params is not None:
            Params.model_validate(self.params)
        return self

    def seed_options(self) -> list[bool | None]:
        """Seed options to run; ``[None]`` for a method that does not use an initial guess."""
        if not get_method(self.name).uses_initial_guess:
            return [None]
        return list(self.seeds) if self.seeds is not None else [True, False]


class Experiment(_Strict):
    name: str
    suite: str | None = None
    data_dir: Path = Path("data")
    sequences: list[SequenceEntry] = Field(default_factory=list)
    methods: list[MethodEntry]
    lengths_m: list[float] = Field(default_factory=lambda: list(DEFAULT_LENGTHS_M))
    jobs: int = Field(1, ge=1)
    out: Path | None = None

    @field_validator("lengths_m")
    @classmethod
    def _positive(cls, v: list[float]) -> list[float]:
        if not v or min(v) <= 0:
            raise ValueError("lengths_m must be a non-empty list of positive lengths [m]")
        return v

    @model_validator(mode="after")
    def _has_data(self) -> Experiment:
        if self.suite is None and not self.sequences:
            raise ValueError("an experiment needs a 'suite' or a list of 'sequences'")
        return self

    @property
    def out_dir(self) -> Path:
        return self.out if self.out is not None else Path("results") / self.name


def load_experiment(path: str | Path) -> Experiment:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
        return Experiment.model_validate(data)
    except FileNotFoundError:
        raise DataError(f"{path}: experiment file not found") from None
    except (yaml.YAMLError, ValidationError) as err:
        raise DataError(f"{path}: invalid experiment:\n{err}") from err
