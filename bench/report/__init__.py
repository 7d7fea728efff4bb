"""The report room: what finished runs look like to a reader - ``tables/`` (the table model, the
paper's shapes, marks and their stability), ``figures/`` (every figure with its style),
``summary/`` (across datasets: ranks and pairwise verdicts), ``html/`` (the one page), and the
single jobs ``compare``, ``dataframe``, ``listing``, ``view``, ``names`` and ``commands``.

May import ``bench.runs``, ``bench.data``, ``metrics``, ``loaders`` and bench's ground floor;
never ``bench.studies`` or above. Inside: ``names`` and ``dataframe`` < ``tables`` < ``figures``
< ``summary`` < ``html`` < the single jobs (``tests/test_import_layers.py``).
"""
