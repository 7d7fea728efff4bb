"""Every option and environment variable checked before any work: one rule per option name.

``attach(command)`` walks a command tree (the ``bench`` group, and each ``bench convert
LOADER`` command as it is built) and wraps every parameter's ``process_value`` (the hook that
turns the text typed into the value the command gets), so a bad value ends in one
``DataError`` naming the option before the command body runs:

- raw text: a path with a NUL byte or a name longer than the file system allows, an input path
  given as the empty string (which would silently mean the working folder);
- numbers (``NUMBERS``, by option name; ``COMMAND_NUMBERS`` where one name means another
  quantity in one command): NaN and infinities, values below or above the option's range
  (negative counts, absurdly large sizes), for ``int`` / ``float`` options, the ``FRAME`` of a
  ``--pair STORE FRAME``, and comma-separated lists held in a text option (``NUMBER_LISTS``:
  ``--lengths``, ``--sizes``, ``--poses``);
- input paths (``INPUTS``): they exist (a missing one is named with its option).

``check_environment()`` checks the variables the harness reads (``BENCH_MAX_FRAME_MB``,
``DOPPLER_BENCH_TIMING_LOCK``, ``DOPPLER_BENCH_METHODS``: the plugin modules are imported, a
broken one or one that would shadow a built-in method is one error naming it).

Every numeric option of every command has a rule here (``tests/test_options.py`` checks), so a
new option gets its range when it is added.
"""

from __future__ import annotations

import math
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from loaders.errors import DataError

#: the longest file name (one path component) and path the file systems we run on take [bytes]
NAME_MAX, PATH_MAX = 255, 4096


@dataclass(frozen=True)
class Number:
    """The range of a numeric option: ``low`` .. ``high`` (inclusive; ``above``: ``low``
    excluded), always finite; ``what`` says what the number is."""

    low: float
    high: float
    what: str
    above: bool = False

    def expected(self) -> str:
        if self.above:
            return f"{self.what}, above {_text(self.low)} and at most {_text(self.high)}"
        return f"{self.what}, at least {_text(self.low)} and at most {_text(self.high)}"

    def holds(self, value: float) -> bool:
        # an int is compared as it is (one of 400 digits is no float: math.isfinite overflows)
        return ((isinstance(value, int) or math.isfinite(value))
                and (value > self.low if self.above else value >= self.low)
                and value <= self.high)


def _text(x: float) -> str:
    return f"{int(x):,}" if float(x).is_integer() and abs(x) < 1e15 else f"{x:g}"


_SEED = Number(0, 2**32 - 1, "a random seed")
#: every numeric option, by its parameter name (convert's loader options included)
NUMBERS: dict[str, Number] = {
    "frames": Number(1, 10_000_000, "a number of frames"),
    "start": Number(0, 1_000_000_000, "a frame index"),
    "stride": Number(1, 1_000_000, "a frame step"),
    "pair": Number(0, 1_000_000_000, "a frame index"),
    "segment": Number(0, 1_000_000, "a segment number"),
    "bootstrap": Number(10, 10_000, "a number of bootstrap resamples"),
    "seeds": Number(1, 1_000, "a number of synthetic sequences"),
    "seed": _SEED,
    "first_seed": _SEED,
    "jobs": Number(1, 64, "a number of parallel workers"),
    "repeats": Number(1, 100, "a number of timed frames"),
    "threads": Number(1, 256, "a number of threads"),
    "scale_frames": Number(2, 20_000, "a number of frames"),
    "min_speed": Number(0, 100, "a speed in m/s"),
    "max_width": Number(0, 1e6, "an interval width in degrees", above=True),
    "period": Number(0, 3600, "a scan period in seconds", above=True),
    "period_s": Number(0, 3600, "a scan period in seconds", above=True),
    "job_timeout": Number(0, 1e7, "a time in seconds", above=True),
    "threshold": Number(0, 1e6, "a relative growth (0.1 = 10 %)"),
    "tolerance": Number(0, 1e6, "a relative growth (0.1 = 10 %)"),
    "time_offset": Number(-1e10, 1e10, "a clock offset in seconds"),
    "time_offset_s": Number(-1e10, 1e10, "a clock offset in seconds"),
    "max_gap": Number(0, 1e7, "a time gap in seconds", above=True),
    "max_gap_s": Number(0, 1e7, "a time gap in seconds", above=True),
    "min_coverage": Number(0, 1, "a share of the scans"),
    "doppler_sign": Number(-1, 1, "a sign (1 or -1)"),
    "elevation_sign": Number(-1, 1, "a sign (1 or -1)"),
    "point_time_scale": Number(0, 1e12, "a scale factor", above=True),
    "date": Number(20_000_101, 21_000_101, "a date as YYYYMMDD(.5)"),
    "max_speed_mps": Number(0, 1000, "a speed in m/s", above=True),
}
#: where one name means another quantity in one command: (command, name) -> range
COMMAND_NUMBERS: dict[tuple[str, str], Number] = {
    # frames generated (in memory, then written): a 2.3-hour drive at 12 Hz at most
    ("synth", "frames"): Number(2, 100_000, "a number of frames"),
    ("calibrate-coverage", "frames"): Number(10, 100_000, "a number of frames"),
}
#: options a command checks itself, with its own words (bench score's clock and coverage
#: options: its contract, bench/runs/external/)
OWN_CHECKS = {("score", "time_offset"), ("score", "max_gap"), ("score", "tolerance"),
              ("score", "min_coverage")}
#: text options that hold comma-separated numbers: name -> (range of each, integers, example)
NUMBER_LISTS: dict[str, tuple[Number, bool, str]] = {
    "lengths": (Number(0, 100_000, "segment lengths in metres", above=True), False, "8,48"),
    "kitti_lengths": (Number(0, 100_000, "segment lengths in metres", above=True), False,
                      "100,800"),
    "sizes": (Number(1, 1_000_000, "point counts"), True, "1000,64000"),
    "poses": (Number(100, 200_000, "pose counts (a drive with 48 m segments)"), True,
              "2500,40000"),
}
#: text options of a fixed form: name -> (pattern, what is expected)
TEXTS: dict[str, tuple[str, str]] = {
    "scheduler": (r"(tcp|tls|inproc|ucx|ws|wss)://[^\s/]+(:[0-9]{1,5})?/?",
                  "a dask scheduler address, e.g. tcp://HOST:8786"),
}
#: text options naming one of a registry's entries: name -> its entries (imported when used)


def _scenes() -> list[str]:
    from loaders.synthetic import list_scenes

    return list(list_scenes())


def _sensors() -> list[str]:
    from loaders.synthetic import list_sensors

    return list(list_sensors())


CHOICES = {(command, name): entries for command in ("synth", "calibrate-coverage")
           for name, entries in (("scene", _scenes), ("sensor", _sensors))}
#: parameters that name an input: it must exist
INPUTS = {"store", "data", "trajectory", "stamps", "frame_times", "experiment", "path",
          "results_dirs", "results_dir", "a", "b", "run", "speed_csv", "pair", "inputs", "gt",
          "calib", "raw_dir"}
_WRAPPED = "_bench_checked"


def flag(param) -> str:
    """How the user wrote the parameter: ``--min-speed``, or ``STORE`` for an argument."""
    opts = [o for o in getattr(param, "opts", ()) if o.startswith("-")]
    if opts:
        return max(opts, key=len)
    return param.metavar or (param.name or "value").upper()


def number_rule(command: str, name: str) -> Number | None:
    return COMMAND_NUMBERS.get((command, name)) or NUMBERS.get(name)


def number_list(text: str, option: str, name: str) -> tuple[float, ...]:
    """``"8,16,48"`` -> its numbers, each checked against ``NUMBER_LISTS[name]``."""
    rule, integers, example = NUMBER_LISTS[name]
    kind = "whole numbers" if integers else "numbers"
    try:
        values = tuple((int if integers else float)(x) for x in text.split(","))
    except ValueError:
        values = ()
    if not values or not all(rule.holds(v) for v in values):
        bounds = rule.expected()[len(rule.what) + 2:]
        shown = repr(text) if len(text) <= 60 else f"{text[:40]!r}... ({len(text)} characters)"
        raise DataError(f"{option} {shown}: expected {rule.what} ({kind}, {bounds}), comma "
                        f"separated, e.g. {example}")
    return values


def _raw_texts(value: Any) -> list[str]:
    if isinstance(value, str):
        return [value]
    if isinstance(value, (list, tuple)):
        return [v for item in value for v in _raw_texts(item)]
    return []


def check_path_text(text: str, option: str, is_input: bool) -> None:
    """A path as typed: no NUL byte, names the file system takes, an input not empty."""
    if "\0" in text:
        raise DataError(f"{option} {text!r}: a path cannot hold a NUL byte")
    if is_input and not text.strip():
        raise DataError(f"{option} {text!r}: expected a path, got an empty one")
    raw = os.fsencode(text)
    longest = max((len(part) for part in raw.split(b"/")), default=0)
    if longest > NAME_MAX or len(raw) > PATH_MAX:
        raise DataError(f"{option} {text[:60]!r}...: a path of {len(raw)} bytes with a name of "
                        f"{longest}; expected names of at most {NAME_MAX} bytes and paths of at "
                        f"most {PATH_MAX}")


def check_input(path: Path, option: str) -> None:
    """An input path exists (and can be looked at)."""
    try:
        os.stat(path)
    except FileNotFoundError:
        raise DataError(f"{option} {path}: not found") from None
    except OSError as err:
        raise DataError(f"{option} {path}: cannot be read ({err.strerror or err})") from None


def _check_number(value: Any, rule: Number, option: str) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return
    if not rule.holds(value):
        shown = repr(value)
        if len(shown) > 40:
            shown = f"{shown[:20]}... ({len(shown)} digits)"
        raise DataError(f"{option} {shown}: expected {rule.expected()}")


def _check_value(value: Any, command: str, param, option: str) -> None:
    """The coerced value of one parameter against its rules."""
    if value is None:
        return
    name = param.name
    if isinstance(value, (list, tuple)):
        for item in value:
            _check_value(item, command, param, option)
        return
    if isinstance(value, Path):
        if name in INPUTS:
            check_input(value, option)
        return
    if isinstance(value, str):
        if name in NUMBER_LISTS:
            number_list(value, option, name)
        choices = CHOICES.get((command, name))
        if choices is not None and value not in (known := choices()):
            from loaders.errors import did_you_mean

            raise DataError(f"{option} {value!r}: unknown {name}{did_you_mean(value, known)}; "
                            f"choose from {', '.join(known)}")
        if name in TEXTS and not re.fullmatch(TEXTS[name][0], value):
            raise DataError(f"{option} {value!r}: expected {TEXTS[name][1]}")
        return
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if (command, name) in OWN_CHECKS:
            return
        rule = number_rule(command, name)
        if rule is None:  # a new option without a rule: at least finite
            if not math.isfinite(value):
                raise DataError(f"{option} {value!r}: expected a finite number")
            return
        _check_number(value, rule, option)


def _wrap(param, command: str) -> None:
    if getattr(param, _WRAPPED, False):
        return
    original = param.process_value
    option = flag(param)
    is_path = _is_path_param(param)

    def process_value(ctx, value):
        if is_path:
            for text in _raw_texts(value):
                check_path_text(text, option, param.name in INPUTS)
        converted = original(ctx, value)
        if getattr(param, "is_flag", False) or getattr(param, "is_eager", False):
            return converted
        _check_value(converted, command, param, option)
        return converted

    param.process_value = process_value
    setattr(param, _WRAPPED, True)


def _is_path_param(param) -> bool:
    descriptor = getattr(param, "type_descriptor", None)
    return descriptor is not None and "Path" in str(descriptor.annotation)


def attach(command, name: str | None = None) -> None:
    """Wrap every parameter of ``command`` and of its subcommands (those already built)."""
    name = name or getattr(command, "name", "") or ""
    for sub_name, sub in getattr(command, "commands", {}).items():
        attach(sub, sub_name)
    for param in command.params:
        _wrap(param, name)


def numeric_params(command, path: tuple[str, ...] = ()):
    """(command path, parameter) of every int / float parameter in the tree (tests)."""
    for sub_name, sub in getattr(command, "commands", {}).items():
        yield from numeric_params(sub, (*path, sub_name))
    for param in command.params:
        if is_numeric(param):
            yield path, param


def is_numeric(param) -> bool:
    """An int / float parameter (or a tuple holding one, as ``--pair STORE FRAME``)."""
    import typing

    descriptor = getattr(param, "type_descriptor", None)
    if descriptor is None or getattr(param, "is_flag", False):
        return False
    annotation = descriptor.annotation
    return annotation in (int, float) or any(a in (int, float)
                                             for a in typing.get_args(annotation))


def check_environment() -> None:
    """The environment variables the harness reads, each checked (a ``DataError`` naming it):
    the frame limit, the timing lock, the plugin method modules."""
    from loaders.limits import max_frame_bytes
    from methods.timing import TIMING_LOCK_ENV, check_lock_path

    max_frame_bytes()
    check_lock_path(os.environ.get(TIMING_LOCK_ENV))
    from methods.plugins import PLUGINS_ENV, module_names

    # the registry (every method's module) is imported only when there are plugins to load,
    # or to forget those of an earlier value in this process
    if module_names(os.environ.get(PLUGINS_ENV, "")) or "methods.registry" in sys.modules:
        from methods.registry import load_plugins

        load_plugins()
