"""The timing both speed studies share: ``time_frames`` times a method, or a library's own
per-frame pipeline driven as a ``Registration`` (``PipelineRun``), exactly as a run times it
(``bench.runs.timed.timed_run``), and ``method_params`` sets a method's thread count.
``bench.studies.speed`` (our methods) and ``bench.studies.speed_reference`` (the libraries'
pipelines beside them) both build on it, so neither imports the other."""

from __future__ import annotations

import numpy as np

from bench.runs.timed import timed_run
from loaders.scan import Scan
from methods.base import MethodParams, Odometry, Registration
from methods.registry import METHODS


def _stats(total_ms: list[float], register_ms: list[float]) -> dict:
    t, r = np.asarray(total_ms), np.asarray(register_ms)
    return {"median_ms": float(np.median(t)), "mean_ms": float(t.mean()),
            "p5_ms": float(np.percentile(t, 5)), "p95_ms": float(np.percentile(t, 95)),
            "register_median_ms": float(np.nanmedian(r)) if np.isfinite(r).any() else np.nan,
            "repeats": len(t)}


class _Prepared:
    """A library pipeline's prepared scan (any object) with its input point count."""

    def __init__(self, data, points: int) -> None:
        self.data, self.points = data, points

    def __len__(self) -> int:
        return self.points


class PipelineRun(Registration):
    """A library's own per-frame pipeline (``preprocess`` / ``register`` / ``threads``,
    ``bench.studies.speed_reference``) driven exactly as a ``Registration`` run, so it is
    timed with the same protocol as the methods."""

    name = "pipeline"
    description = "a library's own per-frame pipeline"

    def __init__(self, pipeline) -> None:
        self.pipeline = pipeline
        self.params = MethodParams()

    @property
    def threads(self) -> int:
        return self.pipeline.threads

    def preprocess(self, scan: Scan) -> _Prepared:
        return _Prepared(self.pipeline.preprocess(scan), len(scan))

    def register(self, source: _Prepared, target: _Prepared, init: np.ndarray):
        return self.pipeline.register(source.data, target.data, init)


def time_frames(method, sequence) -> dict:
    """Frame times of ``method`` (an ``Odometry``, or a library pipeline) as a run times them:
    ``timed_run`` (threads limited, the common warm-up, one seeded run over the sequence's
    distinct frames); figures over every registered frame, by the method's clock."""
    odometry = method if isinstance(method, Odometry) else PipelineRun(method)
    result, timing = timed_run(odometry, sequence, seed=True)
    frames = result.frames[1:]
    return {**_stats([f.time_ms for f in frames], [f.register_ms for f in frames]),
            "correspondences": int(np.median([f.correspondences for f in frames])),
            "iterations": int(np.median([f.iterations for f in frames])),
            "clock": timing["clock"], "cpu_ratio": timing["cpu_process_to_thread"]}


def method_params(name: str, threads: int) -> dict:
    """The parameters that set ``threads`` threads for ``name`` (none when it has no thread
    count: it computes on one)."""
    fields = getattr(METHODS[name], "Params", None)
    has = fields is not None and "num_threads" in getattr(fields, "model_fields", {})
    return {"num_threads": threads} if has else {}
