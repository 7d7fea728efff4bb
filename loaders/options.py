"""The typed options of a loader: what ``bench convert LOADER`` offers and a dataset config sets.

Every loader module declares ``class Options(LoaderOptions)`` with one field per option (type,
default, ``Field(description=...)``: the description is the command-line help) and its
``Sequence`` subclass sets ``Options = Options``, ``inputs`` (help text of the positional paths)
and implements ``open(paths, options)``. ``bench convert LOADER`` is built from the model, so a
new loader needs no command of its own; unknown keys are errors (``extra="forbid"``).

Command-line names (``cli_flag``): the field name with ``_`` -> ``-`` and a trailing ``_s``
(seconds) dropped, so ``period_s`` is ``--period`` and ``time_offset_s`` ``--time-offset``; a
field may set its own with ``Field(..., json_schema_extra={"cli": "extrinsic"})`` (for a bool
that defaults to true, ``"on/off"`` names both flags, e.g. ``"remove-gt-origin/keep-utm"``), or
``{"cli": False}`` to be a dataset-config-only key. A bool that defaults to false is a plain flag
(``--no-gt``); one that defaults to true is ``--x/--no-x``. Fields typed ``Path`` (or
``Path | None``) are file options: a dataset config gives them relative to its ``raw_dir``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field
from pydantic.fields import FieldInfo

from loaders.errors import DataError


class LoaderOptions(BaseModel):
    """Options every loader takes; a loader's own model subclasses it."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    name: str | None = Field(None, description="sequence name stored in the file "
                             "(default: from the input's name)")


class GroundTruthTimeOptions(LoaderOptions):
    """The ground-truth association options shared by loaders whose GT has its own clock and
    rate (``loaders.gt.associate``)."""

    time_offset_s: float = Field(0.0, description="GT clock offset [s]: gt_stamp + offset = "
                                 "sensor clock")
    max_gap_s: float | None = Field(None, description="largest GT gap interpolated across [s] "
                                    "(default: the loader's)")
    uncovered: Literal["keep", "trim", "error", "drop"] = Field(
        "keep", description="scans without GT: keep (run, unscored), trim (cut the ends) or "
        "error ('drop' is read as keep)")

    def association(self, default_max_gap_s: float) -> dict[str, Any]:
        """The keyword arguments of ``loaders.gt.associate`` these options set."""
        return {"offset_s": self.time_offset_s, "uncovered": self.uncovered,
                "max_gap_s": default_max_gap_s if self.max_gap_s is None else self.max_gap_s}


class OpensFromOptions:
    """Mixin for a ``Sequence`` built from paths and a typed options model."""

    Options: ClassVar[type[LoaderOptions]] = LoaderOptions
    #: help text of the positional input(s), e.g. "ROS1 bag(s) of one sequence"
    inputs: ClassVar[str] = "input file(s) or folder"
    #: True when the loader takes several inputs (bags of one route), else exactly one
    many_inputs: ClassVar[bool] = False

    @classmethod
    def open(cls, paths: list[Path], options: LoaderOptions):  # -> Sequence
        """The sequence read from ``paths`` with ``options`` (validated by ``Options``). The
        default serves a loader of one input whose constructor takes ``(path, options)``:
        exactly one path; a loader of several inputs, or another constructor, overrides it."""
        if cls.many_inputs:
            raise NotImplementedError(f"{cls.__name__}.open: a loader of several inputs opens "
                                      "them itself")
        if len(paths) != 1:
            raise DataError(f"{cls.__name__}: expected one input ({cls.inputs}), got "
                            f"{len(paths)} paths")
        return cls(paths[0], cls.Options.model_validate(options.model_dump()))


def cli_flag(name: str, field: FieldInfo) -> str | None:
    """The option's command-line name without dashes (``time-offset``), or None when the field
    is a dataset-config-only key."""
    extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
    if "cli" in extra:
        return extra["cli"] or None
    return name.removesuffix("_s").replace("_", "-") if name.endswith("_s") and len(name) > 2 \
        else name.replace("_", "-")


def is_path_field(field: FieldInfo) -> bool:
    """A field that holds a file or folder path (``Path`` or ``Path | None``)."""
    ann = field.annotation
    return ann is Path or Path in getattr(ann, "__args__", ())
