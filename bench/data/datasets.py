"""The real sequences (``configs/datasets/<Name>.yaml``), read and validated in one place: which
raw files, which loader with which options, which frames, and the store they become under
``DATA_DIR/real/``. Used by ``bench convert dataset`` and by ``bench reproduce`` (which uses the
stores that exist).

    loader: ntu4dradlm
    raw_dir: data/raw/ntu4dradlm/loop2
    raw_files: [loop2_2022-06-03_0.bag, gt_odom.txt]   # what must be there (globs allowed)
    inputs: [loop2_2022-06-03_*.bag]                   # the loader's positional inputs
    options: {gt: gt_odom.txt, topic: /radar_enhanced_pcl}

``inputs`` default to the raw folder itself (folder loaders). ``options`` are validated by the
loader's own ``Options`` model (the same that builds ``bench convert LOADER``); path options
and inputs are relative to ``raw_dir``. Input globs expand in natural order (``_2`` before
``_10``)."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from bench.paths import DATASET_CONFIGS
from loaders.errors import DataError, validation_problems
from loaders.registry import LOADERS, get_loader


class FrameSelection(BaseModel):
    model_config = ConfigDict(extra="forbid")

    start: int = Field(0, ge=0)
    frames: int | None = Field(None, ge=1)
    stride: int = Field(1, ge=1)


def _natural(path: Path) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


def expand(root: Path, entries: list[str]) -> list[Path]:
    """``entries`` relative to ``root``, glob patterns expanded in natural order."""
    paths: list[Path] = []
    for entry in entries:
        entry = entry.rstrip("/") or "."
        if any(c in entry for c in "*?["):
            paths += sorted(root.glob(entry), key=_natural)
        else:
            paths.append(root / entry)
    return paths


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
    """One real sequence. ``options`` are validated by the loader's ``Options`` model."""

    model_config = ConfigDict(extra="forbid")

    name: str
    display_name: str
    sensor_class: str
    #: the dataset it belongs to (groups rows in `bench datasets` and public.yaml)
    dataset: str = ""
    in_main_table: bool = True
    #: one of the paper's sequences (`bench reproduce` uses its store when present)
    paper: bool = True
    loader: str
    raw_dir: Path
    raw_files: list[str]
    inputs: list[str] = Field(default_factory=lambda: ["."])
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

    def raw_root(self, raw_dir: Path | None = None) -> Path:
        return Path(raw_dir or self.raw_dir)

    def loader_options(self, raw_dir: Path | None = None):
        """The options validated by the loader's model, path options made relative to the raw
        folder and ``name`` set to this sequence's name."""
        from bench.data.loader_options import validate_options
        from loaders.options import is_path_field

        Options = get_loader(self.loader).load_class().Options
        values = {"name": self.name, **self.options}
        root = self.raw_root(raw_dir)
        for key, field in Options.model_fields.items():
            if is_path_field(field) and values.get(key) not in (None, ""):
                p = Path(values[key])
                values[key] = p if p.is_absolute() else root / p
        return validate_options(Options, values, where=f"{self.name}: options")

    def input_paths(self, raw_dir: Path | None = None) -> list[Path]:
        return expand(self.raw_root(raw_dir), self.inputs)

    def check_raw(self, raw_dir: Path | None = None) -> Path:
        """The raw folder when it holds every ``raw_files`` entry, else one DataError naming
        what is missing (``loaders.layout.require_paths``)."""
        from loaders.layout import require_paths

        entry = get_loader(self.loader)
        return require_paths(self.raw_root(raw_dir), self.raw_files,
                             self.dataset or entry.dataset or self.loader, entry.layout)

    def open(self, raw_dir: Path | None = None):
        """The raw data opened with its loader and options, frame range applied."""
        from loaders.scan import select_frames

        self.check_raw(raw_dir)
        Loader = get_loader(self.loader).load_class()
        options = self.loader_options(raw_dir)
        paths = self.input_paths(raw_dir)
        if not getattr(Loader, "many_inputs", False) and len(paths) != 1:
            raise DataError(f"{self.name}: loader {self.loader} takes one input, the config's "
                            f"inputs give {len(paths)}: {', '.join(map(str, paths))}")
        seq = Loader.open(paths, options)
        fr = self.frame_range
        return select_frames(seq, fr.start, fr.frames, fr.stride)

    def conversion_key(self, raw_dir: Path | None = None) -> str:
        """A hash of what determines the store: loader (and its code, ``loader_code_hash``),
        validated options, frame range and every input file's path, size and modification time
        (folders: every file inside). A store carrying the same key is up to date."""
        root = self.raw_root(raw_dir)
        files: list[Path] = []
        for p in [*self.input_paths(raw_dir), *expand(root, self.raw_files)]:
            files += sorted(f for f in p.rglob("*") if f.is_file()) if p.is_dir() else [p]
        options = self.loader_options(raw_dir).model_dump(mode="json")
        stats = []
        for f in dict.fromkeys(files):
            st = f.stat()
            stats.append([str(f.resolve()), st.st_size, st.st_mtime_ns])
        blob = json.dumps({"loader": self.loader, "options": options, "files": stats,
                           "frame_range": self.frame_range.model_dump(),
                           "code": loader_code_hash(self.loader)}, sort_keys=True)
        return hashlib.sha256(blob.encode()).hexdigest()


def loader_code_hash(loader: str) -> str:
    """A hash of the code that reads ``loader``'s data: its module and the shared loader core
    (``loaders/*.py`` except the other loaders' own modules), so a fixed loader converts its
    stores again while a change to another dataset's loader leaves them alone."""
    import importlib.util

    own = get_loader(loader).module
    others = {e.module for e in LOADERS.values()} - {own}
    spec = importlib.util.find_spec("loaders.registry")
    folder = Path(spec.origin).parent
    digest = hashlib.sha256()
    for path in sorted(folder.glob("*.py")):
        if f"loaders.{path.stem}" not in others:
            digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def read_dataset_config(name_or_path: str | Path) -> DatasetConfig:
    """A dataset config by sequence name (``Loop1_0``) or path; DataError naming the file."""
    path = Path(name_or_path)
    if not path.suffix:
        path = DATASET_CONFIGS / f"{name_or_path}.yaml"
    if not path.exists():
        from loaders.errors import did_you_mean

        have = sorted(p.stem for p in DATASET_CONFIGS.glob("*.yaml"))
        raise DataError(f"{path}: dataset config not found{did_you_mean(path.stem, have)}; "
                        f"known: {', '.join(have)}")
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


def select_configs(names: list[str]) -> list[DatasetConfig]:
    """Configs by name, path or glob over the names (``'NTU4DRadLM_*'``), in the order given,
    each once; DataError for a name or pattern that matches nothing."""
    import fnmatch

    have = sorted(p.stem for p in DATASET_CONFIGS.glob("*.yaml"))
    chosen: dict[str, DatasetConfig] = {}
    for name in names:
        if any(c in name for c in "*?[") and not Path(name).suffix:
            matched = [n for n in have if fnmatch.fnmatchcase(n, name)]
            if not matched:
                raise DataError(f"no dataset config matches {name!r}; known: {', '.join(have)}")
            for n in matched:
                chosen.setdefault(n, read_dataset_config(n))
        else:
            cfg = read_dataset_config(name)
            chosen.setdefault(cfg.name, cfg)
    return list(chosen.values())
