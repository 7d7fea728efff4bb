"""The studies room: measurements of the harness itself - the paper's reproduction
(``reproduce``), speed and scale benchmarks, the coverage of the intervals, fidelity and realism
of the synthetic suite, independent re-implementations and the CI regression (``regress``).

May import ``bench.report``, ``bench.runs``, ``bench.data`` and below; never ``bench.commands``,
``cli`` or ``api``.
"""
