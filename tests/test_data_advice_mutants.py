"""bench/data/advice.py: advice that names only options the store's loader has, and the
refusals of a store without raw radial Doppler. Loaders are stand-ins (a registry entry whose
class is made here), so the option names are known by construction; one real loader (HeLiPR)
checks the two sources of names (its ``Options`` model and its ``__init__``)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
from pydantic import BaseModel

from bench.data import advice
from bench.data.advice import (
    compensated_doppler,
    doppler_refusal,
    loader_name,
    loader_options,
    option_flag,
)


class _ModelOptions(BaseModel):
    doppler_field: str = "v"
    reconstruct_doppler_from_gt: bool = False


class WithModel:
    Options = _ModelOptions

    def __init__(self, path, topic=None, **kwargs):
        pass


class KeywordsOnly:
    def __init__(self, folder, doppler_field="d"):
        pass


class NoSignature:
    Options = _ModelOptions
    __init__ = 3  # not callable: inspect.signature raises TypeError


def _entry(cls=None, error=None):
    def load_class():
        if error is not None:
            raise error
        return cls
    return SimpleNamespace(load_class=load_class)


@pytest.fixture
def loaders(monkeypatch):
    table = {"model": _entry(WithModel), "keywords": _entry(KeywordsOnly),
             "nosig": _entry(NoSignature), "broken": _entry(error=ImportError("no rosbags"))}
    monkeypatch.setattr(advice, "LOADERS", table)
    return table


def test_the_names_are_the_options_model_s_fields_and_the_init_s_parameters(loaders):
    assert loader_options("model") == {"doppler_field", "reconstruct_doppler_from_gt", "path",
                                       "topic", "kwargs"}
    assert loader_options("keywords") == {"folder", "doppler_field"}
    assert loader_options("nosig") == {"doppler_field", "reconstruct_doppler_from_gt"}


def test_an_unknown_or_unimportable_loader_has_no_names(loaders):
    assert loader_options("nope") is None
    assert loader_options("broken") is None
    assert loader_options(None) is None


def test_no_loader_is_looked_up_as_the_empty_name(loaders):
    loaders[""] = _entry(KeywordsOnly)
    assert loader_options(None) == {"folder", "doppler_field"}


def test_a_real_loader_s_names_come_from_both_places():
    names = loader_options("helipr")
    assert {"reconstruct_doppler_from_gt", "path", "options"} <= names
    assert "self" not in names


def test_the_flag_is_the_option_spelled_with_dashes_when_the_loader_takes_it(loaders):
    assert option_flag({"loader": "model"}, "reconstruct_doppler_from_gt") == \
        "--reconstruct-doppler-from-gt"
    assert option_flag({"loader": "keywords"}, "doppler_field") == "--doppler-field"
    assert option_flag({"loader": "keywords"}, "reconstruct_doppler_from_gt") is None
    assert option_flag({"loader": "broken"}, "doppler_field") is None
    assert option_flag({}, "folder") is None


def test_the_loader_s_name_or_its_loader():
    assert loader_name({"loader": "vod"}) == "vod"
    assert loader_name({"loader": None}) == "its loader"
    assert loader_name({}) == "its loader"


def _scan(doppler):
    return SimpleNamespace(doppler=doppler)


class _Seq(list):
    """A sequence of scans with a sensor (and, optionally, a base it is a frame range of)."""

    def __init__(self, scans, kind="radial", **attrs):
        super().__init__(scans)
        self.sensor = SimpleNamespace(doppler_kind=kind)
        for k, v in attrs.items():
            setattr(self, k, v)


def test_raw_radial_doppler_is_not_refused(loaders):
    assert doppler_refusal("s.h5", "doppler", _Seq([_scan([1.0])])) is None
    assert doppler_refusal("s.h5", "doppler", _Seq([], has_doppler=True)) is None


def test_no_doppler_values_name_the_loader_s_doppler_field_option(loaders):
    seq = _Seq([_scan(None)], provenance={"loader": "keywords"})
    assert doppler_refusal("s.h5", "doppler", seq) == (
        "s.h5: doppler needs Doppler, but the store has no Doppler values; convert it again "
        "naming the Doppler field (bench convert keywords ... --doppler-field NAME)")


def test_no_doppler_from_a_loader_without_such_option_says_convert_from_data_with_doppler(
        loaders):
    for seq in (_Seq([]), _Seq([_scan([1.0])], has_doppler=False, provenance=None)):
        assert doppler_refusal("s.h5", "calibration from Doppler", seq) == (
            "s.h5: calibration from Doppler needs Doppler, but the store has no Doppler "
            "values; convert it from data with Doppler")


def test_a_frame_range_asks_its_base_store(loaders):
    base = _Seq([_scan([1.0])], has_doppler=False, provenance={"loader": "model"})
    part = _Seq([_scan([1.0])], base=base)
    assert doppler_refusal("s.h5", "doppler", part).endswith(
        "(bench convert model ... --doppler-field NAME)")
    base.has_doppler = True
    assert doppler_refusal("s.h5", "doppler", part) is None
    part.sensor.doppler_kind = "ego-compensated"
    assert doppler_refusal("s.h5", "doppler", part) == compensated_doppler("s.h5", "doppler",
                                                                           base.provenance)


def test_ego_compensated_doppler_names_the_opt_in_when_the_loader_has_it(loaders):
    start = ("s.h5: doppler needs the raw radial Doppler velocity, but the store's Doppler is "
             "ego-compensated (sensor doppler_kind 'ego-compensated': static points read about "
             "0 m/s); ")
    seq = _Seq([_scan([0.0])], kind="ego-compensated", provenance={"loader": "model"})
    assert doppler_refusal("s.h5", "doppler", seq) == start + (
        "convert it again with `bench convert model ... --reconstruct-doppler-from-gt` "
        "(results marked GT-assisted)")
    assert compensated_doppler("s.h5", "doppler", {"loader": "keywords"}) == start + (
        "reconstructing the radial velocity from the ground truth's ego motion is an explicit "
        "opt-in of the loader (doppler_kind 'gt-reconstructed')")


def test_gt_reconstructed_doppler_is_radial_enough(loaders):
    seq = _Seq([_scan([0.0])], kind="gt-reconstructed", provenance={"loader": "model"})
    assert doppler_refusal("s.h5", "doppler", seq) is None
