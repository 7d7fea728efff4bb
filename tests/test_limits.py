"""loaders.limits: the per-frame limit read from BENCH_MAX_FRAME_MB in MB (10^6 bytes), with
frames between the MB and the MiB reading of the limit (where the two rules differ), and the
variable's edge values (inf lifts the limit; zero, negative, NaN and words are refused)."""

import pytest

from loaders.errors import DataError
from loaders.limits import ENV_VAR, NO_LIMIT, check_frame_bytes, max_frame_bytes


def test_the_limit_is_in_megabytes_not_mebibytes(monkeypatch):
    monkeypatch.setenv(ENV_VAR, "1")
    assert max_frame_bytes() == 1_000_000
    check_frame_bytes(1_000_000, "f")  # at the limit: allowed
    # 1.02 MB is above 1 MB but below 1 MiB (1,048,576 bytes): a MiB reading would allow it
    with pytest.raises(DataError, match=r"f: the frame would take 1 MB, above the per-frame "
                                        r"limit of 1 MB"):
        check_frame_bytes(1_020_000, "f")
    monkeypatch.setenv(ENV_VAR, "2.5")
    assert max_frame_bytes() == 2_500_000
    with pytest.raises(DataError):
        check_frame_bytes(2_500_001, "f")


def test_inf_lifts_the_limit(monkeypatch):
    for text in ("inf", "Infinity", "1e400"):
        monkeypatch.setenv(ENV_VAR, text)
        assert max_frame_bytes() == NO_LIMIT
        check_frame_bytes(10**15, "f")  # a petabyte: no limit, no OverflowError


@pytest.mark.parametrize("text", ["0", "-5", "nan", "-inf", "lots"])
def test_a_limit_that_is_no_positive_number_is_refused(monkeypatch, text):
    monkeypatch.setenv(ENV_VAR, text)
    with pytest.raises(DataError, match=rf"{ENV_VAR}='{text}': expected a"):
        max_frame_bytes()
