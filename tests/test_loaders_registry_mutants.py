"""Mutation-testing kills for loaders/registry.py: an entry's availability and class, its
catalogue rows, the lookup by name and its message, and the catalogue's order."""

import pytest

from loaders.errors import DataError
from loaders.registry import LOADERS, LoaderEntry, catalogue, get_loader


def _entry(**kw):
    return LoaderEntry("fake", "a fake loader", kw.pop("module", "loaders.options"),
                       kw.pop("cls", "LoaderOptions"), **kw)


def test_an_entry_with_its_module_loads_its_class():
    entry = _entry()
    assert entry.available is True
    from loaders.options import LoaderOptions

    assert entry.load_class() is LoaderOptions


@pytest.mark.parametrize("module", ["no_such_top_module_xyz", "no_such_top_module_xyz.sub",
                                    "loaders.no_such_loader_xyz"])
def test_an_entry_without_its_module_is_unavailable_and_says_so(module):
    entry = _entry(module=module)
    assert entry.available is False
    with pytest.raises(DataError) as err:
        entry.load_class()
    assert str(err.value) == (f"loader 'fake' is listed but unavailable in this installation: "
                              f"module {module} not found")


def test_an_entrys_defaults():
    entry = LoaderEntry("n", "d", "m", "c")
    assert entry.doppler_kind == "radial"
    assert entry.more_rows == ()
    assert (entry.dataset, entry.sensor, entry.example) == ("", "", "")


def test_rows_are_the_entry_then_one_per_more_rows_entry_with_its_fields_replaced():
    entry = _entry(sensor="A", sensor_class="sparse", licence="L",
                   more_rows=({"sensor": "B"}, {"sensor": "C", "licence": "M"}))
    rows = entry.rows()
    assert len(rows) == 3
    assert rows[0] is entry
    assert [r.sensor for r in rows] == ["A", "B", "C"]
    assert [r.licence for r in rows] == ["L", "L", "M"]
    assert all(r.sensor_class == "sparse" and r.name == "fake" for r in rows)
    assert rows[1].more_rows == () and rows[2].more_rows == ()
    assert _entry().rows() == [_entry()]


def test_get_loader_by_name_and_an_unknown_name_lists_them_all_with_a_hint():
    assert get_loader("vod") is LOADERS["vod"]
    with pytest.raises(DataError) as err:
        get_loader("rosbga")
    names = ", ".join(LOADERS)
    assert str(err.value) == (f"unknown loader 'rosbga' (did you mean 'rosbag'?); expected one "
                              f"of {names}")
    assert err.value.__cause__ is None and err.value.__suppress_context__
    with pytest.raises(DataError) as err:
        get_loader("zzzzzzzz")
    assert str(err.value) == f"unknown loader 'zzzzzzzz'; expected one of {names}"


def test_catalogue_is_every_loaders_rows_in_the_tables_order():
    expected = []
    for entry in LOADERS.values():
        expected.append(entry)
        expected.extend(entry.rows()[1:])
    rows = catalogue()
    assert rows == expected
    assert len(rows) == len(LOADERS) + sum(len(e.more_rows) for e in LOADERS.values())
    assert rows[0] is LOADERS[next(iter(LOADERS))]
