"""Experiment configuration (YAML under configs/experiments/), validated with pydantic.

    name: paper-synthetic
    suite: synthetic-paper          # a synthetic suite, generated/cached under data_dir
    synthetic:                      # and/or synthetic sequences of its own (generated)
      - {name: campus-lidar-1000, scene: campus, sensor: lidar-dense, frames: 40, seed: 1000}
    sequences:                      # and/or explicit stores
      - path: data/real/Loop1_0.h5
        display_name: Loop1_0
        sensor_class: Semi-Dense 4D Radar
        start: 0                    # optional: run frames start .. start + frames - 1 only
        frames: 500
    methods:
      - name: doppler
      - name: icp-p2p
        params: {max_iterations: 100}
        seeds: [true, false]        # default: both, or [true] for methods without a guess
    lengths_m: [8, 16, 24, 32, 40, 48]     # relative-error segment lengths [m]
    kitti_lengths_m: [100, 200, 300, 400, 500, 600, 700, 800]   # KITTI drift (the default)
    alignment: se3                  # APE: none, origin, se3, sim3, first-N, sim3-first-N
    jobs: 2
    out: results/paper-synthetic

Unknown keys, unknown methods and unknown method parameters are errors. Relative paths
(``data_dir``, ``out``, sequence ``path``s, ``external`` files) are relative to the YAML file.
``external:`` lists trajectories made elsewhere, scored after the runs as runs of their own
(``bench score``: ``{name: my-odom, trajectory: odom.tum, store: data/real/Loop1_0.h5}`` and
its options: format, stamps, topic, frame_times, time_offset_s, tolerance_s, max_gap_s,
pose_frame, extrinsic). A method entry may
carry a ``label`` (variants of one method: each its own folder and table row) and a
``sequences`` list (run it only on those sequences; glob patterns such as ``VoD*`` allowed).

A sequence ``path`` may be a glob (``data/real/NTU4DRadLM_*.h5``): every matching store is one
sequence, named by its file stem, in natural order. With ``optional: true`` a path that matches
nothing is skipped with one line (naming its ``dataset``) instead of being an error: an
experiment over whichever converted stores exist (``configs/experiments/public.yaml``).

Parameter sweeps (``bench.runs.sweep``): a method entry's parameter given as a list of values
where the parameter itself takes one value (``params: {tau_spatial_m: [2.0, 3.0, 4.0]}``), or
any parameter listed under ``sweep:`` (``sweep: {voxel_m: [0.25, 0.5], map_seconds: [0.5, 1]}``),
expands to one labelled variant per point of the grid over those keys, labelled
``"<label or method> key=value ..."``. A parameter whose value is itself a list (e.g.
``angle_noise_deg: [0.4, 2.6]``) is that value in ``params``: sweep it under ``sweep:`` (a list
of its values). An experiment with sweeps may name its ``criterion`` (``Criterion``: the tuning
rule of configs/splits.yaml, folds of sequences and a reference point); ``bench run`` then
prints the sweep's table, each point's criterion with its interval and the decision.
``default_differs`` says why a method's default is not the sweep's choice, where it is not
(configs/tuning/*.yaml; tests/test_tuning.py holds every tuned default to its sweep).
"""

from __future__ import annotations

import glob
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from bench.runs.external import DEFAULT_MIN_COVERAGE, DEFAULT_TOLERANCE_S
from loaders.errors import DataError, did_you_mean, validation_problems
from methods.registry import METHODS, get_method, seed_options
from metrics.ape import Alignment
from metrics.kitti import KITTI_LENGTHS_M
from metrics.relative import DEFAULT_LENGTHS_M, MetricError

if TYPE_CHECKING:
    from bench.runs.sweep import Variant


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class SequenceEntry(_Strict):
    path: Path
    name: str | None = None
    display_name: str | None = None
    sensor_class: str | None = None
    start: int = Field(0, ge=0)              # first frame of the store to run (0-based)
    frames: int | None = Field(None, ge=2)   # frames from ``start`` (default: to the end)
    optional: bool = False                   # absent store(s): skipped with one line
    dataset: str | None = None               # what the store(s) hold (for that line)

    @property
    def is_glob(self) -> bool:
        return any(c in str(self.path) for c in "*?[")

    @property
    def frame_range(self) -> tuple[int, int | None] | None:
        """(start, frames) when only part of the store runs, else None."""
        return None if self.start == 0 and self.frames is None else (self.start, self.frames)


class SyntheticEntry(_Strict):
    """A synthetic sequence of the experiment's own (``loaders.synthetic``: a scene, a sensor,
    a seed and generator options), written to ``data_dir/synthetic-entries/`` when missing
    (bench.data.synth.ensure_entries_with_progress). What the tuning experiments
    (configs/tuning/) run on: the tuning seeds of configs/splits.yaml, which no reported suite
    uses."""

    name: str
    display_name: str | None = None
    sensor_class: str | None = None
    scene: str
    sensor: str
    frames: int = Field(ge=2)
    seed: int
    options: dict = Field(default_factory=dict)

    def suite_entry(self):
        from loaders.sensor_classes import DENSE_LIDAR
        from loaders.synthetic.sensors import SENSORS
        from loaders.synthetic.suite import SuiteEntry

        if self.sensor not in SENSORS:
            raise DataError(f"unknown synthetic sensor {self.sensor!r}; known: "
                            f"{', '.join(SENSORS)}")
        from loaders.synthetic.scenes import SCENES

        if self.scene not in SCENES:
            raise DataError(f"unknown synthetic scene {self.scene!r}; known: {', '.join(SCENES)}")
        kind = SENSORS[self.sensor].kind
        klass = self.sensor_class or (DENSE_LIDAR if kind == "lidar" else "4D Radar")
        return SuiteEntry(self.name, self.display_name or self.name, klass, self.scene,
                          self.sensor, self.frames, self.seed, dict(self.options))


class MethodEntry(_Strict):
    name: str
    label: str | None = None           # a variant's name in folders and tables
    params: dict = Field(default_factory=dict)
    sweep: dict[str, list] | None = None  # a grid: one variant per combination of values
    seeds: list[bool] | None = None
    sequences: list[str] | None = None  # run only on these sequences (names or store stems)

    @model_validator(mode="after")
    def _check(self) -> MethodEntry:
        if self.name not in METHODS:
            raise ValueError(f"unknown method {self.name!r}{did_you_mean(self.name, METHODS)}; "
                             f"registered: {', '.join(METHODS)}")
        Params = getattr(get_method(self.name), "Params", None)
        keys = [] if Params is None else list(Params.model_fields)
        for point in self.variants():
            if Params is None:
                break
            try:
                Params.model_validate(point.params)
            except ValidationError as err:
                where = f" (sweep point {point.label})" if point.point else ""
                raise ValueError(f"{self.name} params{where}: " + "; ".join(
                    validation_problems(err, lambda loc: keys, "parameter"))) from None
        return self

    def variants(self) -> list[Variant]:
        """The runs this entry stands for: itself, or one variant per sweep point."""
        from bench.runs.sweep import expand

        return expand(self)

    def seed_options(self) -> list[bool | None]:
        """Seed options to run (``methods.registry.seed_options``)."""
        return seed_options(self.name, self.seeds)


class Fold(_Strict):
    """One fold of the tuning rule: the sequences a point must improve on significantly
    (``tuning``) and those on which the improvement must not reverse (``validation``)."""

    tuning: list[str] = Field(min_length=1)
    validation: list[str] = Field(min_length=1)


class Criterion(_Strict):
    """How a sweep decides. The tuning rule of configs/splits.yaml (``folds`` given;
    bench/runs/tuning_rule.py): ``C`` = the mean over ``lengths_m`` and over both errors of
    the point's mean relative error divided by the ``reference`` point's (the library's or
    paper's value; keys not given: the method's default), with block-bootstrap intervals at
    ``level`` (``reps`` draws); a point replaces the reference only when significant and at
    least ``min_gain`` better on every fold's tuning sequences, not reversed on its validation
    sequences and not significantly worse on the ``domain`` sequences; a best point on the
    grid's edge asks for a wider grid.

    Legacy (``error`` given instead of ``folds``; no sweep of configs/ uses it since the
    LiDAR sweeps and the independent references moved to the rule, kept for experiments of
    one's own): the lowest mean of ``error`` (rotation [deg],
    translation [m] or ``both``, each over the points' mean) over ``lengths_m``; points within
    ``tie_within`` of the best tie (the first listed wins); the default stays unless beaten by
    more than ``keep_default_within``."""

    lengths_m: list[float] = Field(min_length=1)
    folds: list[Fold] | None = None
    domain: list[str] = Field(default_factory=list)
    reference: dict = Field(default_factory=dict)
    level: float = Field(0.95, gt=0, lt=1)
    reps: int = Field(1000, ge=100)
    min_gain: float = Field(0.0, ge=0, lt=1)  # least improvement of C on a tuning half
    error: Literal["rotation", "translation", "both"] | None = None
    tie_within: float = Field(0.0, ge=0, lt=1)
    keep_default_within: float = Field(0.0, ge=0, lt=1)

    @model_validator(mode="after")
    def _one_rule(self) -> Criterion:
        if (self.folds is None) == (self.error is None):
            raise ValueError("a criterion gives either 'folds' (the tuning rule of "
                             "configs/splits.yaml) or a legacy 'error'")
        if self.folds is not None and (self.tie_within or self.keep_default_within):
            raise ValueError("'tie_within' / 'keep_default_within' belong to the legacy "
                             "'error' criterion, not to the tuning rule")
        return self

    @property
    def cross_validated(self) -> bool:
        return self.folds is not None

    def sequence_names(self) -> list[str]:
        """Every sequence the rule names (folds, then domain)."""
        names = [n for f in self.folds or () for n in f.tuning + f.validation] + self.domain
        return list(dict.fromkeys(names))


class ExternalEntry(_Strict):
    """A trajectory made elsewhere, scored against ``store``'s ground truth after the jobs ran
    (``bench.runs.external.score``; the options of ``bench score``). It is filed under the sequence
    entry of the same store (its name), else the store's own name."""

    name: str
    trajectory: Path
    store: Path
    format: Literal["auto", "tum", "kitti", "boreas", "bag"] = "auto"
    stamps: Path | None = None
    topic: str | None = None
    frame_times: Path | None = None
    time_offset_s: float = Field(0.0, allow_inf_nan=False)
    tolerance_s: float = Field(DEFAULT_TOLERANCE_S, ge=0, allow_inf_nan=False)
    #: None: no interpolation (as ``bench score`` without --max-gap)
    max_gap_s: float | None = Field(None, gt=0, allow_inf_nan=False)
    pose_frame: Literal["sensor", "body"] = "sensor"
    extrinsic: str | None = None
    stamp_unit: Literal["s", "ms", "us", "ns"] | None = None
    min_coverage: float = Field(DEFAULT_MIN_COVERAGE, ge=0, le=1)
    trust_clock: bool = False

    @field_validator("name")
    @classmethod
    def _own_name(cls, v: str) -> str:
        if v in METHODS:
            raise ValueError(f"{v!r} is a method of the harness; an external run needs a name "
                             "of its own")
        return v


class Experiment(_Strict):
    name: str
    suite: str | None = None
    data_dir: Path = Path("data")
    sequences: list[SequenceEntry] = Field(default_factory=list)
    synthetic: list[SyntheticEntry] = Field(default_factory=list)
    methods: list[MethodEntry]
    #: trajectories made elsewhere, scored beside the runs (``bench score``'s options)
    external: list[ExternalEntry] = Field(default_factory=list)
    lengths_m: list[float] = Field(default_factory=lambda: list(DEFAULT_LENGTHS_M))
    #: KITTI drift's segment lengths [m] and the APE alignment (metrics.Alignment: none,
    #: origin, se3, sim3, first-N, sim3-first-N)
    kitti_lengths_m: list[float] = Field(default_factory=lambda: list(KITTI_LENGTHS_M))
    alignment: str = "se3"
    jobs: int = Field(1, ge=1, le=64)  # as --jobs (bench/options.py)
    out: Path | None = None
    criterion: Criterion | None = None  # picks each sweep's best point
    default_differs: str | None = None  # why a method's default is not the sweep's choice
    #: the point the tuning rule chose when the sweep was last replayed (configs/tuning/;
    #: tests/test_tuning.py holds the method's default to it)
    decided: dict | None = None

    @field_validator("lengths_m", "kitti_lengths_m")
    @classmethod
    def _positive(cls, v: list[float], info) -> list[float]:
        if not v or min(v) <= 0:
            raise ValueError(f"{info.field_name} must be a non-empty list of positive "
                             "lengths [m]")
        return v

    @field_validator("alignment")
    @classmethod
    def _alignment(cls, v: str) -> str:
        try:
            return Alignment.parse(v).name
        except MetricError as err:
            raise ValueError(str(err)) from None

    @model_validator(mode="after")
    def _has_data(self) -> Experiment:
        if self.suite is None and not self.sequences and not self.synthetic:
            raise ValueError("an experiment needs a 'suite', a list of 'sequences' or of "
                             "'synthetic' sequences")
        seen = set()
        for m in self.methods:
            for v in m.variants():
                if (m.name, v.label) in seen:
                    raise ValueError(f"method {m.name!r} is listed twice: give each variant a "
                                     "distinct 'label:'")
                seen.add((m.name, v.label))
        if self.criterion is not None:
            missing = set(self.criterion.lengths_m) - set(self.lengths_m)
            if missing:
                raise ValueError(f"criterion lengths {sorted(missing)} are not among lengths_m")
            known = {s.name for s in self.sequences if s.name} | {s.name for s in self.synthetic}
            unknown = [n for n in self.criterion.sequence_names() if n not in known]
            if unknown:
                raise ValueError(f"criterion names sequences {unknown} that the experiment "
                                 f"does not declare (named: {', '.join(sorted(known))})")
        return self

    def resolved(self, base: Path) -> Experiment:
        """This experiment with its relative paths taken relative to ``base`` (the folder of
        the YAML file)."""
        def at(p: Path) -> Path:
            return p if p.is_absolute() else base / p
        return self.model_copy(update={
            "data_dir": at(self.data_dir),
            "out": at(self.out) if self.out is not None else None,
            "sequences": [s.model_copy(update={"path": at(s.path)}) for s in self.sequences],
            "external": [e.model_copy(update={
                key: at(getattr(e, key)) for key in ("trajectory", "store", "stamps",
                                                     "frame_times")
                if getattr(e, key) is not None}) for e in self.external]})

    @property
    def out_dir(self) -> Path:
        return self.out if self.out is not None else Path("results") / self.name


def load_experiment(path: str | Path) -> Experiment:
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())
        return Experiment.model_validate(data).resolved(path.resolve().parent)
    except FileNotFoundError:
        raise DataError(f"{path}: experiment file not found") from None
    except yaml.YAMLError as err:
        raise DataError(f"{path}: not valid YAML: {err}") from None
    except UnicodeDecodeError:
        raise DataError(f"{path}: not a text file; expected an experiment YAML (a store is run "
                        "with `bench run --method M --data STORE.h5`)") from None
    except ValidationError as err:
        problems = validation_problems(err, _known_keys)
        raise DataError(f"{path}: invalid experiment:\n  " + "\n  ".join(problems)) from None


def _known_keys(loc: tuple) -> list[str] | None:
    """The keys of the experiment model at ``loc`` (for "did you mean")."""
    model = {(): Experiment, ("sequences",): SequenceEntry, ("methods",): MethodEntry,
             ("criterion",): Criterion, ("criterion", "folds"): Fold,
             ("synthetic",): SyntheticEntry, ("external",): ExternalEntry}.get(
        tuple(x for x in loc if not isinstance(x, int)))
    return list(model.model_fields) if model else None


def _natural(path: Path) -> list:
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", path.name)]


def _shown(path: Path) -> str:
    """``path`` normalised, relative to the working folder when inside it."""
    norm = os.path.normpath(path)
    rel = os.path.relpath(norm)
    return norm if rel.startswith("..") else rel


def expand_sequences(sequences: list[SequenceEntry], say=None) -> list[SequenceEntry]:
    """Glob paths expanded (one entry per store, named by its stem unless a single match and
    a name is given), optional absent stores dropped with one line through ``say`` (a
    callable taking a string; default: a warning). Non-optional absent stores are kept (the
    planner reports them)."""
    if say is None:
        import warnings

        def say(text: str) -> None:
            warnings.warn(text, stacklevel=3)
    out: list[SequenceEntry] = []
    for s in sequences:
        if s.is_glob:
            matches = sorted((Path(p) for p in glob.glob(str(s.path))), key=_natural)
            if not matches:
                if s.optional:
                    say(f"skipped {s.dataset or s.path}: no store matches {_shown(s.path)}")
                    continue
                out.append(s)  # the planner names it as not found
                continue
            for m in matches:
                named = len(matches) == 1 and s.name
                out.append(s.model_copy(update={
                    "path": m, "name": s.name if named else m.stem,
                    "display_name": s.display_name if named else None}))
        elif s.optional and not Path(s.path).exists():
            say(f"skipped {s.dataset or s.name or s.path}: store {_shown(s.path)} not found")
        else:
            out.append(s)
    return out
