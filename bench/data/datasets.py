"""The paper's real sequences (``configs/datasets/<Name>.yaml``), read and validated in one
place: which raw files, which loader with which options, which frames, and the store they become
under ``DATA_DIR/real/``. Used by ``bench convert dataset`` and by ``bench reproduce`` (which
uses the stores that exist)."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from bench.paths import DATASET_CONFIGS
from loaders.errors import DataError, validation_problems
from loaders.registry import LOADERS, get_loader
from loaders.scan import Sequence, select_frames


class FrameSelection(BaseModel):
    model_config = ConfigDict(extra="forbid")

    start: int = Field(0, ge=0)
    frames: int | None = Field(None, ge=1)
    stride: int = Field(1, ge=1)


class Expected(BaseModel):
    """What a store of this sequence should look like (checked by ``bench reproduce``, which
    warns when a store is far off): the sensor kind, the nominal scan period [s] and, where a
    public figure gives it, the ground truth's path length [m]; ``source`` says where from."""

    model_config = ConfigDict(extra="forbid")

    sensor_kind: Literal["radar", "lidar"] | None = None
    period_s: float | None = Field(None, gt=0)
    path_m: float | None = Field(None, gt=0)
    source: str = ""


class DatasetConfig(BaseModel):
    """One paper sequence. ``options`` are the loader's keyword arguments."""

    model_config = ConfigDict(extra="forbid")

    name: str
    display_name: str
    sensor_class: str
    in_main_table: bool = True
    loader: str
    raw_dir: Path
    raw_files: list[str]
    options: dict = Field(default_factory=dict)
    frame_range: FrameSelection = Field(default_factory=FrameSelection)
    store: str
    convert: str = ""  # the equivalent `bench convert` command line (documentation)
    expected: Expected = Field(default_factory=Expected)

    @field_validator("loader")
    @classmethod
    def _known_loader(cls, v: str) -> str:
        if v not in LOADERS:
            raise ValueError(f"unknown loader {v!r}; expected one of {', '.join(LOADERS)}")
        return v

    def open(self, raw_dir: Path | None = None) -> Sequence:
        """The raw data opened with its loader and options, frame range applied."""
        raw = Path(raw_dir or self.raw_dir)
        files = [f.rstrip("/") for f in self.raw_files]
        Loader = get_loader(self.loader).load_class()
        opts = dict(self.options)
        if self.loader == "ntu4dradlm":
            gts = [raw / f for f in files if not f.endswith(".bag")]
            seq = Loader([raw / f for f in files if f.endswith(".bag")],
                         gt=gts[0] if gts else None, name=self.name, **opts)
        elif self.loader == "campus":
            seq = Loader([raw / f for f in files if f.endswith(".bag")], name=self.name, **opts)
        else:
            seq = Loader(raw, name=self.name, **opts)
        fr = self.frame_range
        return select_frames(seq, fr.start, fr.frames, fr.stride)


def read_dataset_config(name_or_path: str | Path) -> DatasetConfig:
    """A dataset config by sequence name (``Loop1_0``) or path; DataError naming the file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = DATASET_CONFIGS / f"{name_or_path}.yaml"
    if not path.exists():
        have = sorted(p.stem for p in DATASET_CONFIGS.glob("*.yaml"))
        raise DataError(f"{path}: dataset config not found; known: {', '.join(have)}")
    try:
        return DatasetConfig.model_validate(yaml.safe_load(path.read_text()) or {})
    except yaml.YAMLError as err:
        raise DataError(f"{path}: not valid YAML: {err}") from None
    except ValidationError as err:
        keys = {(): list(DatasetConfig.model_fields),
                ("frame_range",): list(FrameSelection.model_fields),
                ("expected",): list(Expected.model_fields)}
        problems = validation_problems(err, lambda loc: keys.get(tuple(loc)))
        raise DataError(f"{path}: invalid dataset config:\n  " + "\n  ".join(problems)) from None


def dataset_configs() -> list[DatasetConfig]:
    """Every config under configs/datasets/, in file name order."""
    return [read_dataset_config(p) for p in sorted(DATASET_CONFIGS.glob("*.yaml"))]
