"""The one page (``bench report``): the self-contained HTML page of a results folder
(``page``), the harness's markdown turned into HTML (``markdown``) and what the page reads of
run folders (``runs``).

May import ``bench.report.summary``, ``tables``, ``figures``, ``names``, ``bench.runs`` and below.
"""
