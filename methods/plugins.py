"""Method modules of your own, named in ``DOPPLER_BENCH_METHODS`` (comma separated module
names on ``PYTHONPATH``; each lists its classes in a ``METHODS`` sequence).

``load(spec, builtin)`` imports them and returns name -> class. Anything wrong with a module is
one ``DataError`` naming the variable and the module: a name that is not a module path, a
module that does not import (missing, a syntax error, an exception while importing), one
without a ``METHODS`` sequence of ``Odometry`` classes with a ``name`` that can name a folder
(letters, digits, ``-_.+``), and a class whose name is a built-in method's, also but for case (a
plugin never replaces one: its runs would be labelled with the built-in's display name), or
another plugin's.
"""

from __future__ import annotations

import importlib
import re

from loaders.errors import DataError

PLUGINS_ENV = "DOPPLER_BENCH_METHODS"
#: a method's name: one folder name (its runs' folders are named by it)
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.+-]{0,63}")
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*")


def module_names(spec: str) -> list[str]:
    """The module names of the variable's value (empty entries ignored)."""
    return [m.strip() for m in (spec or "").split(",") if m.strip()]


def load(spec: str, builtin: dict) -> dict:
    """The plugin methods of ``spec`` (the variable's value): name -> class."""
    from methods.base import Odometry

    where = f"{PLUGINS_ENV}={spec!r}"
    found: dict = {}
    for module_name in module_names(spec):
        if not _MODULE.fullmatch(module_name):
            raise DataError(f"{where}: {module_name!r} is not a module name; expected Python "
                            "module names (e.g. my_methods or lab.methods), comma separated")
        try:
            module = importlib.import_module(module_name)
        except (Exception, SystemExit) as err:  # noqa: BLE001  # any failure is the module's
            detail = f"{type(err).__name__}: {err}"
            raise DataError(f"{where}: cannot import method module {module_name!r} ({detail}); "
                            "fix the module or leave it out of the variable") from None
        classes = getattr(module, "METHODS", None)
        if not isinstance(classes, (list, tuple)):
            raise DataError(f"{where}: module {module_name!r} has no METHODS list; expected "
                            "METHODS = [MyMethod, ...] naming its method classes")
        for cls in classes:
            name = getattr(cls, "name", None)
            if not (isinstance(cls, type) and issubclass(cls, Odometry)):
                raise DataError(f"{where}: {module_name}.METHODS holds {cls!r}; expected "
                                "classes derived from methods.base.Registration or Odometry")
            if not isinstance(name, str) or not name.strip():
                raise DataError(f"{where}: {module_name}.{cls.__qualname__} has no name; give "
                                "it a class attribute name = \"my-method\"")
            if not _NAME.fullmatch(name):
                raise DataError(f"{where}: {module_name}.{cls.__qualname__} is named {name!r}; "
                                "expected a name of letters, digits, '-', '_', '.' or '+' that "
                                "starts with a letter or digit (it names run folders)")
            clash = {n.lower(): n for n in builtin}.get(name.lower())
            if clash is not None and clash != name:
                raise DataError(f"{where}: {module_name}.{cls.__qualname__} is named {name!r}, "
                                f"the built-in method {clash!r} but for case; a plugin cannot "
                                "take a built-in method's name: give it a name of its own")
            if name in builtin:
                raise DataError(f"{where}: {module_name}.{cls.__qualname__} is named {name!r}, "
                                f"the name of the built-in method {builtin[name].__qualname__}; "
                                "a plugin cannot replace a built-in method: give it a name of "
                                "its own")
            if name in found and found[name] is not cls:
                raise DataError(f"{where}: two plugin methods are named {name!r} "
                                f"({found[name].__module__}.{found[name].__qualname__} and "
                                f"{module_name}.{cls.__qualname__}); rename one")
            found[name] = cls
    return found
