"""Across datasets: how each method fares over every sequence of a results folder - the mean
ranks per sensor class (``overview``, ``ranks``) and the pairwise verdicts (``pairwise``).

May import ``bench.report.tables``, ``bench.report.names``, ``bench.runs`` and below.
"""
