"""The `bench` entry point itself, as a user runs it (exit codes and the message formatting of
``bench.cli.main``), for tests."""

import pytest

from bench.cli import main


def run_bench(args, capsys, monkeypatch) -> tuple[int, str]:
    """(exit code, stdout + stderr) of ``bench ARGS``."""
    monkeypatch.setattr("sys.argv", ["bench", *args])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    return exit_.value.code, out.out + out.err
