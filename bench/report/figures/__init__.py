"""Figures: every paper figure of a results folder (``draw``, ``bench figures``) with the one
style they share (``style``): relative errors and timing (``errors``), forest plots of the
intervals behind the marks (``forest``), per-axis drift (``drift``), ego-velocity error
(``velocity``) and one scan pair's correspondences (``pair``).

May import ``bench.report.tables``, ``bench.report.names``, ``bench.runs`` and below.
"""
