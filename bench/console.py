"""The one Console the command line prints with: rich on a terminal, plain when piped.

When stdout is not a terminal (a pipe, a file, CI), nothing is wrapped or coloured, so
``bench table -f csv > t.csv`` is a valid CSV and long lines stay whole in logs.
"""

from __future__ import annotations

import sys

from rich.console import Console


def make_console(stderr: bool = False) -> Console:
    """The Console for stdout (results) or, with ``stderr``, for status lines that must not
    mix with data written to stdout (``bench table -f csv > t.csv``)."""
    if (sys.stderr if stderr else sys.stdout).isatty():
        return Console(highlight=False, stderr=stderr)
    return Console(soft_wrap=True, no_color=True, highlight=False, width=200,
                   force_terminal=False, stderr=stderr)
