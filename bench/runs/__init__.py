"""The runs room: what determines a run (``identity``), what describes it (``provenance``),
planning, jobs, executors, scoring (``evaluate``), run folders (``folders``), sweeps and the
tuning rule. Trajectories made elsewhere are scored in ``external/``.

May import ``loaders``, ``methods``, ``metrics``, ``bench.data`` and bench's ground floor; never
``bench.report`` or above.
"""
