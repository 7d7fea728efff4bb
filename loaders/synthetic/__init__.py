"""Synthetic 4D sensor data (radar and FMCW LiDAR with exact Doppler and ground truth).

Public API::

    SyntheticSequence(scene, sensor, frames, seed=0, noise=True, *, name=None, meta=None,
                      **options)          # a loaders.scan.Sequence, scans generated on demand
    list_scenes() -> dict[str, str]       # scene name -> one-line description
    list_sensors() -> dict[str, str]      # sensor name -> one-line description
    OPTIONS: dict[str, str]               # generator options -> description
    doppler_of(points_s, v_sensor, point_velocity_s=None) -> (N,) radial velocity
    SUITES, SuiteEntry, suite_entries(name), ensure_suite(name, data_dir, progress=None)
    generator_code_hash(directory=loaders/synthetic) -> str  # identity of the generator
"""

from loaders.synthetic.codehash import generator_code_hash
from loaders.synthetic.generate import (
    OPTIONS,
    SyntheticSequence,
    doppler_of,
    list_scenes,
    list_sensors,
)
from loaders.synthetic.suite import SUITES, SuiteEntry, ensure_suite, suite_entries

__all__ = [
    "OPTIONS",
    "SUITES",
    "SuiteEntry",
    "SyntheticSequence",
    "doppler_of",
    "ensure_suite",
    "generator_code_hash",
    "list_scenes",
    "list_sensors",
    "suite_entries",
]
