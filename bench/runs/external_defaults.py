"""The defaults of ``bench score``'s contract (``bench.runs.external``), importable without
numpy for the command line's option defaults."""

#: a scan and a pose this close are the same instant [s] (evo's default --t_max_diff)
DEFAULT_TOLERANCE_S = 0.01
#: the least share of the scans with ground truth an estimate must cover (``--min-coverage``)
DEFAULT_MIN_COVERAGE = 0.9
