"""The studies room: measurements of the harness itself - the paper's reproduction
(``reproduce``), speed and scale benchmarks, the coverage of the intervals, fidelity and realism
of the synthetic suite, independent re-implementations and the CI regression (``regress``),
the false alarms and detections of the checks that refuse or warn (``score_checks`` with its
``score_cases`` for ``bench score``, ``inspect_clock_study`` and ``inspect_checks_study`` for
``bench inspect``, ``run_checks_study`` for ``bench run``'s ground-truth checks,
``calibrate_checks_study`` for ``bench calibrate``'s verdicts).

May import ``bench.report``, ``bench.runs``, ``bench.data`` and below; never ``bench.commands``,
``cli`` or ``api``.
"""
