"""The `bench` entry point itself, as a user runs it (exit codes and the message formatting of
``bench.cli.main``: a DataError is one message and exit 2, no traceback), for tests."""

import pytest

from bench.cli import main


def run_bench(args, capsys, monkeypatch) -> tuple[int, str]:
    """(exit code, stdout + stderr) of ``bench ARGS``."""
    monkeypatch.setattr("sys.argv", ["bench", *map(str, args)])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    code = exit_.value.code
    return (0 if code is None else code), out.out + out.err


def bench_main(monkeypatch, capsys, *args) -> tuple[int, str]:
    """(exit code, printed text with whitespace folded) of ``bench ARGS``."""
    code, text = run_bench(args, capsys, monkeypatch)
    return code, " ".join(text.split())
