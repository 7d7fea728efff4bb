"""The explicit registry of methods: name -> class, with a one-line description each.

Add a method by writing one module with a ``Registration`` (pairwise, scan to scan) or an
``Odometry`` (keeps its own state) subclass and listing it here. Your own methods can also live
outside this package: name their modules in the environment variable ``DOPPLER_BENCH_METHODS``
(comma separated); each module lists its classes in a ``METHODS`` sequence. Worker processes
inherit the variable, so plugins run under every executor.
"""

from __future__ import annotations

import importlib
import os

from loaders.errors import DataError, did_you_mean
from loaders.scan import SensorInfo
from methods.base import Odometry
from methods.dicp import Dicp
from methods.doppler import DopplerCorrespondence
from methods.doppler_ego import DopplerEgo
from methods.doppler_icp import DopplerIcp
from methods.gicp import GeneralizedIcp, PointToPlaneIcp, VoxelizedGicp
from methods.icp import PointToPointIcp
from methods.kiss import KissIcp

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

PLUGINS_ENV = "DOPPLER_BENCH_METHODS"


def _load_plugins() -> None:
    for module_name in filter(None, (m.strip() for m in os.environ.get(PLUGINS_ENV, "")
                                     .split(","))):
        try:
            module = importlib.import_module(module_name)
        except ImportError as err:
            raise DataError(f"{PLUGINS_ENV}: cannot import method module {module_name!r}: "
                            f"{err}") from None
        for cls in getattr(module, "METHODS", ()):
            METHODS[cls.name] = cls


_load_plugins()


def get_method(name: str) -> type[Odometry]:
    try:
        return METHODS[name]
    except KeyError:
        loaded = os.environ.get(PLUGINS_ENV, "").strip()
        plugins = (f"plugin modules loaded from {PLUGINS_ENV}={loaded}" if loaded else
                   f"a method of your own: name its module in {PLUGINS_ENV}=my_module (on "
                   "PYTHONPATH; it lists its classes in METHODS), README 'Adding a method'")
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
