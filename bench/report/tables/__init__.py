"""Tables: one model (``model``) rendered to markdown, LaTeX and CSV; its shapes - the paper's
Table III (``paper``), Tables IV-V (``ape``), methods against sequences (``pivot``), a parameter
sweep (``sweep``); telling rows apart (``row_keys``); the marks read from the printed intervals
(``significance``) and whether they hold on both halves (``stability``).

May import ``bench.report.names``, ``bench.report.dataframe``, ``bench.runs`` and below.
"""
