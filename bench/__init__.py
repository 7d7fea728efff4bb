"""The benchmark harness. Importing it pins the numerical libraries' thread counts first
(``bench.threads``), before NumPy & co. load, on every path: the CLI, the API, the workers."""

from bench.threads import pin_threads

pin_threads()
