"""Plugin method modules (methods.plugins.load) at unit level: a plugin never shadows a
built-in method (by its name, also but for case), and anything wrong with a module is one
DataError naming the variable, its value and the module. Fast: no command runs (the CLI cases
are in tests/test_options.py)."""

from __future__ import annotations

import importlib
import itertools
import textwrap

import pytest

from loaders.errors import DataError
from methods.base import Odometry, Registration
from methods.plugins import PLUGINS_ENV, load, module_names

_serial = itertools.count()


class Builtin(Registration):
    name = "doppler"


BUILTIN = {"doppler": Builtin}


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """write(body) -> the name of a new module of that body importable from tmp_path."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(body: str) -> str:
        name = f"plugin_unit_{next(_serial)}"
        (tmp_path / f"{name}.py").write_text(textwrap.dedent(body))
        importlib.invalidate_caches()  # the folder's listing may be cached from an earlier one
        return name

    return write


def _method(name: str = "mine", cls: str = "Mine", base: str = "Registration") -> str:
    return f"""
        from methods.base import Registration, Odometry

        class {cls}({base}):
            name = {name!r}

        METHODS = [{cls}]
        """


def _refused(spec: str, *says: str, builtin: dict = BUILTIN) -> str:
    with pytest.raises(DataError) as err:
        load(spec, builtin)
    text = str(err.value)
    assert text.startswith(f"{PLUGINS_ENV}={spec!r}: "), text
    for part in says:
        assert part in text, (part, text)
    return text


def test_the_variable_is_named_as_the_user_sets_it():
    assert PLUGINS_ENV == "DOPPLER_BENCH_METHODS"


def test_module_names_of_the_value():
    assert module_names(" a, lab.b ,,c, ") == ["a", "lab.b", "c"]
    assert module_names("") == [] and module_names(None) == []
    assert load("", BUILTIN) == {} and load(" , ", BUILTIN) == {}


@pytest.mark.parametrize("name", ["my-methods", "1abc", "a..b", "a.", ".a", "a b", "lab/x"])
def test_a_name_that_is_no_module_path_is_refused(name):
    _refused(name, f"{name!r} is not a module name",
             "expected Python module names (e.g. my_methods or lab.methods), comma separated")


def test_a_good_plugin_loads_by_its_name(plugin):
    first = plugin(_method("mine-1.0+x_y"))
    second = plugin(_method("other", "Other"))
    got = load(f"{first}, {second}", BUILTIN)
    assert sorted(got) == ["mine-1.0+x_y", "other"]
    assert got["mine-1.0+x_y"].__module__ == first and got["other"].__name__ == "Other"
    odometry = plugin(_method("odo", "Odo", "Odometry"))
    assert list(load(odometry, BUILTIN)) == ["odo"]  # an Odometry, not only a Registration


def test_a_dotted_module_name_loads(plugin, tmp_path):
    (tmp_path / "plugin_lab_pkg").mkdir()
    (tmp_path / "plugin_lab_pkg" / "__init__.py").write_text("")
    (tmp_path / "plugin_lab_pkg" / "methods.py").write_text(textwrap.dedent(_method("lab")))
    assert list(load("plugin_lab_pkg.methods", BUILTIN)) == ["lab"]


@pytest.mark.parametrize("body, error", [
    ("def oops(:\n", "SyntaxError"),
    ("raise RuntimeError('boom')\n", "RuntimeError: boom"),
    ("import sys\nsys.exit(3)\n", "SystemExit: 3"),
    ("import no_such_module_for_plugins\n", "ModuleNotFoundError"),
])
def test_a_module_that_does_not_import_is_one_error_naming_it(plugin, body, error):
    name = plugin(body)
    text = _refused(name, f"cannot import method module {name!r} ({error}")
    assert text.endswith("); fix the module or leave it out of the variable"), text


def test_a_missing_module_is_named(plugin):
    _refused("plugin_absent_module", "cannot import method module 'plugin_absent_module' "
             "(ModuleNotFoundError: ")


@pytest.mark.parametrize("methods", ["", "METHODS = None\n", "METHODS = {object}\n",
                                     "METHODS = 'Mine'\n"])
def test_a_module_without_a_methods_list_is_refused(plugin, methods):
    name = plugin(methods)
    _refused(name, f"module {name!r} has no METHODS list",
             "expected METHODS = [MyMethod, ...] naming its method classes")


def test_methods_may_be_a_tuple(plugin):
    name = plugin("""
        from methods.base import Registration

        class Mine(Registration):
            name = "tup"

        METHODS = (Mine,)
        """)
    assert list(load(name, BUILTIN)) == ["tup"]


@pytest.mark.parametrize("entry", ["object()", "object", "len", "'mine'"])
def test_methods_holds_method_classes_only(plugin, entry):
    name = plugin(f"""
        from methods.base import Registration

        class Mine(Registration):
            name = "mine"

        METHODS = [{entry}]
        """)
    _refused(name, f"{name}.METHODS holds ",
             "expected classes derived from methods.base.Registration or Odometry")


@pytest.mark.parametrize("value", ["None", "''", "'   '", "3"])
def test_a_method_class_without_a_name_is_refused(plugin, value):
    name = plugin(f"""
        from methods.base import Registration

        class Mine(Registration):
            name = {value}

        METHODS = [Mine]
        """)
    _refused(name, f"{name}.Mine has no name",
             'give it a class attribute name = "my-method"')


@pytest.mark.parametrize("bad", ["my method", "-mine", ".mine", "a/b", "é", "a" * 65, "x!"])
def test_a_name_that_cannot_name_a_folder_is_refused(plugin, bad):
    name = plugin(_method(bad))
    _refused(name, f"{name}.Mine is named {bad!r}",
             "expected a name of letters, digits, '-', '_', '.' or '+' that starts with a "
             "letter or digit (it names run folders)")


def test_the_longest_name_is_64_characters(plugin):
    assert list(load(plugin(_method("a" * 64)), BUILTIN)) == ["a" * 64]


def test_a_plugin_cannot_shadow_a_built_in_method(plugin):
    name = plugin(_method("doppler"))
    _refused(name, f"{name}.Mine is named 'doppler', the name of the built-in method Builtin",
             "a plugin cannot replace a built-in method: give it a name of its own")


def test_a_plugin_cannot_take_a_built_in_name_but_for_case(plugin):
    name = plugin(_method("Doppler"))
    text = _refused(name, f"{name}.Mine is named 'Doppler', the built-in method 'doppler' but "
                    "for case", "a plugin cannot take a built-in method's name")
    assert "give it a name of its own" in text
    mixed = {"ICP-p2p": Builtin}
    _refused(plugin(_method("icp-P2P")), "the built-in method 'ICP-p2p' but for case",
             builtin=mixed)


def test_two_plugins_of_one_name_are_refused_naming_both(plugin):
    first = plugin(_method("same", "A"))
    second = plugin(_method("same", "B"))
    _refused(f"{first},{second}", f"two plugin methods are named 'same' ({first}.A and "
             f"{second}.B); rename one")


def test_the_same_class_listed_twice_is_one_method(plugin):
    name = plugin("""
        from methods.base import Registration

        class Mine(Registration):
            name = "twice"

        METHODS = [Mine, Mine]
        """)
    got = load(f"{name},{name}", BUILTIN)
    assert list(got) == ["twice"] and got["twice"].__name__ == "Mine"


def test_the_real_built_in_methods_cannot_be_shadowed(plugin):
    from methods import registry

    builtin = registry.BUILTIN
    assert "doppler" in builtin
    name = plugin(_method("doppler"))
    _refused(name, "cannot replace a built-in method", builtin=builtin)
    assert issubclass(builtin["doppler"], Odometry)
