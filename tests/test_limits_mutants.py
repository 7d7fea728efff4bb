"""loaders.limits, what tests/test_limits.py leaves open (make mutate's survivors): the default
limit of 256 MB (10^6 bytes) when the variable is unset or blank, the limit read around
surrounding spaces, ``inf`` lifting the limit even for a size beyond int64, the size of a file
checked and returned from ``stat``, and the numbers in file names (at most 19 digits, below
2^63) with the messages a user reads."""

import pytest

from loaders.errors import DataError
from loaders.limits import (
    ENV_VAR,
    NO_LIMIT,
    check_file_size,
    check_frame_bytes,
    file_number,
    max_frame_bytes,
)

MB = 10**6


@pytest.mark.parametrize("text", [None, "", "   "])
def test_the_default_limit_is_256_megabytes(monkeypatch, text):
    if text is None:
        monkeypatch.delenv(ENV_VAR, raising=False)
    else:
        monkeypatch.setenv(ENV_VAR, text)
    assert max_frame_bytes() == 256 * MB
    check_frame_bytes(256 * MB, "f")  # at the limit: allowed
    with pytest.raises(DataError, match="above the per-frame limit of 256 MB"):
        check_frame_bytes(256 * MB + 1, "f")


def test_the_variable_is_read_around_spaces(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "  3 \n")
    assert max_frame_bytes() == 3 * MB


def test_a_word_is_refused_naming_the_variable(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "lots")
    with pytest.raises(DataError, match=r"^BENCH_MAX_FRAME_MB='lots': expected a number of "
                                        r"megabytes$"):
        max_frame_bytes()
    monkeypatch.setenv(ENV_VAR, "0")
    with pytest.raises(DataError, match=r"positive number of megabytes \(or inf: no limit\)$"):
        max_frame_bytes()


def test_inf_lifts_the_limit_beyond_any_int64_size(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "inf")
    check_frame_bytes(2**64, "f")  # more than NO_LIMIT bytes: still no limit


def test_the_message_names_the_place_the_sizes_and_the_variable(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "2048")
    with pytest.raises(DataError) as err:
        check_frame_bytes(3_000 * MB, "scan.bin, frame 7", "the message")
    text = str(err.value)
    assert text.startswith("scan.bin, frame 7: the message would take 3,000 MB, above the "
                           "per-frame limit of 2,048 MB")
    assert text.endswith("raise the limit with BENCH_MAX_FRAME_MB=<MB>")


def test_a_file_size_is_returned_and_checked_before_reading(tmp_path, monkeypatch):
    monkeypatch.setenv(ENV_VAR, "0.001")  # 1000 bytes
    small = tmp_path / "small.bin"
    small.write_bytes(b"\0" * 1000)
    assert check_file_size(small, "here") == 1000
    big = tmp_path / "big.bin"
    big.write_bytes(b"\0" * 1001)
    with pytest.raises(DataError, match=r"^here: the file \(1,001 bytes\) would take 0 MB"):
        check_file_size(big, "here")


def test_a_missing_file_is_one_data_error_naming_the_place(tmp_path):
    with pytest.raises(DataError, match=r"^there: cannot read the file \(No such file"):
        check_file_size(tmp_path / "absent.bin", "there")


@pytest.mark.parametrize("text, value", [("0", 0), ("0042", 42),
                                         ("9223372036854775807", 2**63 - 1),
                                         ("0000000000000000001", 1)])
def test_file_numbers_up_to_int64_are_read(text, value):
    assert file_number(text, "p") == value


@pytest.mark.parametrize("text, digits", [("9223372036854775808", 19),  # 2^63: one too many
                                          ("00000000000000000001", 20),  # small but 20 digits
                                          ("1" * 30, 30)])
def test_file_numbers_beyond_int64_or_19_digits_are_refused(text, digits):
    with pytest.raises(DataError, match=rf"^dir/{text}\.bin: the number in the file name has "
                                        rf"{digits} digits; expected a frame index or a stamp "
                                        r"of at most 19 digits \(below 2\^63\): a stray file\? "
                                        r"move it out of the folder$"):
        file_number(text, f"dir/{text}.bin")


@pytest.mark.parametrize("text", ["", "12a", "-3", "1.5"])
def test_a_file_name_without_a_number_is_refused(text):
    with pytest.raises(DataError, match=rf"^q\.bin: expected a number in the file name, got "
                                        rf"'{text}'$".replace(".5", r"\.5")):
        file_number(text, "q.bin")


def test_sizes_in_the_message_are_rounded_megabytes(monkeypatch):
    # 2,001.5 MB and 1.5 MB round (half to even) to 2,002 and 2: the sizes are bytes / 10^6
    monkeypatch.setenv(ENV_VAR, "1.5")
    with pytest.raises(DataError, match=r"^f: the frame would take 2,002 MB, above the "
                                        r"per-frame limit of 2 MB"):
        check_frame_bytes(2_001_500_000, "f")


def test_a_limit_beyond_what_int64_holds_is_no_limit(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "1e13")  # 10^19 bytes > 2^63 - 1
    assert max_frame_bytes() == NO_LIMIT
    monkeypatch.setenv(ENV_VAR, "9223372000000")  # 9.223372e18 bytes: just below 2^63 - 1
    assert max_frame_bytes() == 9_223_372_000_000_000_000 < NO_LIMIT
