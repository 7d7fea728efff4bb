"""`bench` run in-process as its console entry point runs it (bench.cli.main: a DataError is
one message and exit 2, no traceback): the exit code and the printed text, whitespace
folded."""

import pytest


def bench_main(monkeypatch, capsys, *args) -> tuple[int, str]:
    from bench.cli import main

    monkeypatch.setattr("sys.argv", ["bench", *map(str, args)])
    with pytest.raises(SystemExit) as exit_:
        main()
    out = capsys.readouterr()
    code = exit_.value.code
    return (0 if code is None else code), " ".join((out.out + out.err).split())
