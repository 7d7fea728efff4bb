"""Trajectories made elsewhere, scored as runs of their own (``bench score``): ``score`` (the
contract and the run folder), ``match`` (an estimate brought to the store's scan stamps),
``clock`` and ``clock_check`` (is it on the scans' clock?), ``names`` (where a scored run may go).
The contract's defaults are here, importable without numpy for the command line's option
defaults.

May import ``loaders``, ``metrics``, the rest of ``bench.runs``, ``bench.data`` and bench's ground
floor; never ``bench.report`` or above."""

#: a scan and a pose this close are the same instant [s] (evo's default --t_max_diff)
DEFAULT_TOLERANCE_S = 0.01
#: the least share of the scans with ground truth an estimate must cover (``--min-coverage``)
DEFAULT_MIN_COVERAGE = 0.9
