"""Mutation-testing kills for loaders/options.py: the options model's rules (unknown keys and
non-finite numbers refused), the ground-truth association keywords, the default ``open`` of a
one-input loader, and the command-line name and path-field rules."""

from pathlib import Path

import pytest
from pydantic import Field, ValidationError

from loaders.errors import DataError
from loaders.options import (
    GroundTruthTimeOptions,
    LoaderOptions,
    OpensFromOptions,
    cli_flag,
    is_path_field,
)


class PeriodOptions(LoaderOptions):
    period_s: float = Field(0.1, description="scan period [s]")


def test_unknown_keys_and_non_finite_numbers_are_refused():
    with pytest.raises(ValidationError, match="period_x"):
        PeriodOptions.model_validate({"period_x": 1.0})
    for bad in (float("inf"), float("-inf"), float("nan")):
        with pytest.raises(ValidationError):
            PeriodOptions(period_s=bad)
    with pytest.raises(ValidationError):
        GroundTruthTimeOptions(time_offset_s=float("nan"))
    assert PeriodOptions(period_s=0.25).period_s == 0.25
    assert LoaderOptions().name is None


def test_association_passes_offset_and_uncovered_and_the_loaders_gap_unless_set():
    default = GroundTruthTimeOptions()
    assert default.association(0.5) == {"offset_s": 0.0, "uncovered": "keep", "max_gap_s": 0.5}
    set_ = GroundTruthTimeOptions(time_offset_s=-0.02, max_gap_s=0.3, uncovered="trim")
    assert set_.association(0.5) == {"offset_s": -0.02, "uncovered": "trim", "max_gap_s": 0.3}
    # a gap of zero is a setting, not "unset"
    assert GroundTruthTimeOptions(max_gap_s=0.0).association(0.5)["max_gap_s"] == 0.0
    with pytest.raises(ValidationError):
        GroundTruthTimeOptions(uncovered="skip")


class _OneInput(OpensFromOptions):
    Options = PeriodOptions
    inputs = "one folder of frames"

    def __init__(self, path, options):
        self.path, self.options = path, options


class _ManyInputs(_OneInput):
    many_inputs = True


def test_open_of_one_input_builds_the_sequence_with_options_validated_by_its_model():
    seq = _OneInput.open([Path("run1")], PeriodOptions(name="r", period_s=0.2))
    assert seq.path == Path("run1")
    assert type(seq.options) is PeriodOptions
    assert (seq.options.name, seq.options.period_s) == ("r", 0.2)
    # options of the base model are re-validated by the loader's own model (its defaults)
    seq = _OneInput.open([Path("run2")], LoaderOptions(name="x"))
    assert type(seq.options) is PeriodOptions and seq.options.period_s == 0.1
    assert seq.options.name == "x"


@pytest.mark.parametrize("paths", [[], [Path("a"), Path("b")]])
def test_open_refuses_other_than_one_path_naming_the_loader_the_inputs_and_the_count(paths):
    with pytest.raises(DataError) as err:
        _OneInput.open(paths, PeriodOptions())
    assert str(err.value) == (f"_OneInput: expected one input (one folder of frames), got "
                              f"{len(paths)} paths")


def test_a_loader_of_several_inputs_must_open_them_itself():
    with pytest.raises(NotImplementedError) as err:
        _ManyInputs.open([Path("a")], PeriodOptions())
    assert str(err.value) == "_ManyInputs.open: a loader of several inputs opens them itself"


def test_the_mixins_defaults():
    assert OpensFromOptions.Options is LoaderOptions
    assert OpensFromOptions.many_inputs is False
    assert OpensFromOptions.inputs == "input file(s) or folder"


def _field(**extra):
    return Field(0.0, json_schema_extra=extra) if extra else Field(0.0)


@pytest.mark.parametrize("name, flag", [
    ("period_s", "period"),
    ("time_offset_s", "time-offset"),
    ("a_s", "a"),               # shortest name that loses its seconds suffix
    ("_s", "-s"),               # the suffix alone is kept
    ("max_gap", "max-gap"),
    ("gt", "gt"),
    ("status", "status"),       # ends in "s" but not "_s"
])
def test_cli_flag_drops_the_seconds_suffix_and_dashes_underscores(name, flag):
    assert cli_flag(name, _field()) == flag


def test_cli_flag_of_the_field_itself_wins_and_false_means_config_only():
    assert cli_flag("extrinsic_file", _field(cli="extrinsic")) == "extrinsic"
    assert cli_flag("period_s", _field(cli="on/off")) == "on/off"
    assert cli_flag("period_s", _field(cli=False)) is None
    assert cli_flag("period_s", _field(other="x")) == "period"
    # a callable json_schema_extra is not a mapping: the name rule applies
    assert cli_flag("period_s", Field(0.0, json_schema_extra=lambda s: None)) == "period"


def test_is_path_field_for_path_and_optional_path_only():
    class M(LoaderOptions):
        p: Path = Path("x")
        q: Path | None = None
        s: str = "x"
        t: str | None = None
        n: int = 0

    fields = M.model_fields
    assert is_path_field(fields["p"]) and is_path_field(fields["q"])
    assert not any(is_path_field(fields[k]) for k in ("s", "t", "n", "name"))
