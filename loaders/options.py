"""The typed options of a loader: what ``bench convert LOADER`` offers and a dataset config sets.

Every loader module declares ``class Options(LoaderOptions)`` with one field per option (type,
default, ``Field(description=...)``: the description is the command-line help) and its
``Sequence`` subclass sets ``Options = Options``, ``inputs`` (help text of the positional paths)
and implements ``open(paths, options)``. ``bench convert LOADER`` is built from the model, so a
new loader needs no command of its own; unknown keys are errors (``extra="forbid"``).
"""

from __future__ import annotations

from pathlib import Path
from typing import ClassVar

from pydantic import BaseModel, ConfigDict, Field


class LoaderOptions(BaseModel):
    """Options every loader takes; a loader's own model subclasses it."""

    model_config = ConfigDict(extra="forbid")

    name: str | None = Field(None, description="sequence name stored in the file "
                             "(default: from the input's name)")


class OpensFromOptions:
    """Mixin for a ``Sequence`` built from paths and a typed options model."""

    Options: ClassVar[type[LoaderOptions]] = LoaderOptions
    #: help text of the positional input(s), e.g. "ROS1 bag(s) of one sequence"
    inputs: ClassVar[str] = "input file(s) or folder"
    #: True when the loader takes several inputs (bags of one route), else exactly one
    many_inputs: ClassVar[bool] = False

    @classmethod
    def open(cls, paths: list[Path], options: LoaderOptions):  # -> Sequence
        """The sequence read from ``paths`` with ``options`` (validated by ``Options``)."""
        raise NotImplementedError
