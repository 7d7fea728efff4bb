"""The explicit registry of methods: name -> class, with a one-line description each.

Add a method by writing one module with a ``Registration`` (pairwise, scan to scan) or an
``Odometry`` (keeps its own state) subclass and listing it here. Your own methods can also live
outside this package: name their modules in the environment variable ``DOPPLER_BENCH_METHODS``
(comma separated); each module lists its classes in a ``METHODS`` sequence. Worker processes
inherit the variable, so plugins run under every executor. A plugin never replaces a built-in
method, and a broken module is one error naming it (``methods.plugins``).
"""

from __future__ import annotations

import os
from enum import Enum

from loaders.errors import DataError, did_you_mean
from loaders.scan import SensorInfo
from methods.base import CONSTANT_VELOCITY, Odometry
from methods.dicp import Dicp
from methods.doppler import DopplerCorrespondence
from methods.doppler_ego import DopplerEgo
from methods.doppler_icp import DopplerIcp
from methods.gicp import GeneralizedIcp, PointToPlaneIcp, VoxelizedGicp
from methods.icp import PointToPointIcp
from methods.kiss import KissIcp
from methods.plugins import PLUGINS_ENV, load

METHODS: dict[str, type[Odometry]] = {
    cls.name: cls
    for cls in (
        DopplerCorrespondence,
        PointToPointIcp,
        Dicp,
        PointToPlaneIcp,
        GeneralizedIcp,
        VoxelizedGicp,
        KissIcp,
        DopplerIcp,
        DopplerEgo,
    )
}

#: the built-in methods (a plugin never replaces one)
BUILTIN: dict[str, type[Odometry]] = dict(METHODS)
_loaded: list[str] = []  # the variable's value the plugins were loaded from


def load_plugins(spec: str | None = None) -> None:
    """Register the plugin methods of ``DOPPLER_BENCH_METHODS`` (or ``spec``) beside the
    built-in ones (``methods.plugins``: anything wrong is one DataError naming the variable and
    the module); again only when the value changed."""
    spec = os.environ.get(PLUGINS_ENV, "") if spec is None else spec
    if _loaded == [spec]:
        return
    found = load(spec, BUILTIN)
    METHODS.clear()
    METHODS.update(BUILTIN)
    METHODS.update(found)
    _loaded[:] = [spec]


load_plugins()


def get_method(name: str) -> type[Odometry]:
    try:
        return METHODS[name]
    except KeyError:
        loaded = os.environ.get(PLUGINS_ENV, "").strip()
        plugins = (f"plugin modules loaded from {PLUGINS_ENV}={loaded}" if loaded else
                   f"a method of your own: name its module in {PLUGINS_ENV}=my_module (on "
                   "PYTHONPATH; it lists its classes in METHODS), see docs/extending.md")
        raise DataError(f"unknown method {name!r}{did_you_mean(name, METHODS)}; registered: "
                        f"{', '.join(METHODS)}; {plugins}") from None


def make_method(name: str, params: dict | None = None,
                sensor: SensorInfo | None = None, seed: bool | None = True) -> Odometry:
    """An instance of method ``name`` with ``params`` validated by its pydantic model, its
    defaults for the seed option (``for_seed``: a no-seed run gets defaults valid without a
    motion prior) and, given the ``sensor``, its sensor-dependent parameters resolved
    (``configured_for``)."""
    cls = get_method(name)
    Params = getattr(cls, "Params", None)
    method = cls() if Params is None else cls(Params.model_validate(params or {}))
    method = method.for_seed(seed)
    return method.configured_for(sensor) if sensor is not None else method


def seed_options(name: str, wanted: list[bool] | None = None) -> list[bool | None]:
    """The seed options to run method ``name`` with (the one rule): ``[None]`` for a method
    that takes no motion prior at all (it runs once), else ``wanted`` (default: both, with and
    without seed)."""
    if not get_method(name).uses_initial_guess:
        return [None]
    return list(wanted) if wanted is not None else [True, False]


def seed_option(name: str, seed: bool) -> bool | None:
    """The seed option of a single run asked for with ``seed`` (None when the method takes no
    prior)."""
    return seed_options(name, [seed])[0]


class Seed(Enum):
    """A run's seed option (the one place it is interpreted): ``WITH`` a motion prior (the
    harness's constant velocity, or the method's own), ``WITHOUT`` (every step from the
    identity), ``NONE`` (a method that takes no prior; it runs once). In ``metrics.json`` and
    ``config.yaml`` it is written as true / false / null (``option``)."""

    WITH = "with"
    WITHOUT = "without"
    NONE = "none"

    @classmethod
    def of(cls, option: bool | None | Seed) -> Seed:
        """From the stored option (true / false / null) or a Seed."""
        if isinstance(option, Seed):
            return option
        return cls.NONE if option is None else (cls.WITH if option else cls.WITHOUT)

    @property
    def option(self) -> bool | None:
        return {Seed.WITH: True, Seed.WITHOUT: False, Seed.NONE: None}[self]

    @property
    def suffix(self) -> str:
        """The run folder's suffix: "_seed", "_noseed" or "" (``run_dir_name``)."""
        return {Seed.WITH: "_seed", Seed.WITHOUT: "_noseed", Seed.NONE: ""}[self]

    @property
    def rank(self) -> int:
        """Row order: with seed before without."""
        return {Seed.WITH: 0, Seed.NONE: 0, Seed.WITHOUT: 1}[self]

    def tag(self, method: str) -> str:
        """Which motion prior a run of ``method`` used: "With Seed" (the harness's
        constant-velocity guess), "With Seed, own model" (the method's own prior), "No Seed"
        or "No initial guess"."""
        if self is Seed.NONE:
            return "No initial guess"
        if self is Seed.WITHOUT:
            return "No Seed"
        cls = METHODS.get(method)
        own = cls is not None and cls.motion_prior not in (None, CONSTANT_VELOCITY)
        return "With Seed, own model" if own else "With Seed"

    def style(self, method: str) -> tuple:
        """(line style, marker, box hatch) of its runs in figures: with and without a seed
        differ in all three."""
        return _SEED_STYLE[self.tag(method)]


_SEED_STYLE = {"With Seed": ("-", "o", ""), "With Seed, own model": ("-", "D", ""),
               "No Seed": ("--", "x", "//////"), "No initial guess": ("-", "s", "")}
#: what the seed tags mean (table captions and figure notes)
SEED_NOTE = ("With Seed: each step starts from the previous step's motion (constant velocity); "
             "With Seed, own model: from the method's own motion prediction instead; No Seed: "
             "from the identity, with every internal prior reset; No initial guess: a method "
             "that takes none.")


# ---- presentation (declared with each method class: ``Odometry.presentation``) --------------

#: colours for methods that declare none (plugins): none is a built-in method's colour
_SPARE_COLORS = ("#393b79", "#637939", "#8c6d31", "#843c39", "#7b4173", "#3182bd", "#e6550d",
                 "#31a354", "#756bb1", "#636363", "#9c9ede", "#cedb9c", "#e7ba52", "#e7969c",
                 "#de9ed6", "#6baed6", "#fd8d3c", "#74c476")
_assigned: dict[str, str] = {}


def display_name(method: str) -> str:
    """The method's name in every table and figure (its class's ``presentation``)."""
    cls = METHODS.get(method)
    return (cls.presentation.display_name if cls is not None else None) or method


def order_key(method: str) -> float:
    """Its row position (the paper's baselines first, its own methods last, then methods
    beyond the paper; a method without an order after every one that has one)."""
    cls = METHODS.get(method)
    order = cls.presentation.order if cls is not None else None
    return float("inf") if order is None else float(order)


def color(method: str) -> str:
    """The method's colour, the same in every figure: the one its class declares, else one of
    its own (registered methods without a colour in registry order, then any other name in
    order of first use), distinct from every other method's while spare colours last."""
    cls = METHODS.get(method)
    if cls is not None and cls.presentation.color:
        return cls.presentation.color
    if not _assigned:
        for name, c in METHODS.items():
            if not c.presentation.color:
                _assign(name)
    return _assigned.get(method) or _assign(method)


def _assign(method: str) -> str:
    taken = {c.presentation.color for c in METHODS.values()} | set(_assigned.values())
    spare = [c for c in _SPARE_COLORS if c not in taken]
    _assigned[method] = spare[0] if spare else _SPARE_COLORS[len(_assigned) % len(_SPARE_COLORS)]
    return _assigned[method]
