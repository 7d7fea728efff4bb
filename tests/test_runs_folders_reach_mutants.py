"""bench.runs.folders: what the mutation run (``tools/mutate.py``) left alive after
tests/test_folders_mutants.py. Expected names and records are worked out by hand from the
rules the module states."""

from __future__ import annotations

import pytest

from bench.runs.folders import run_dir_name

# ---- folder names ---------------------------------------------------------------------------


@pytest.mark.parametrize("label, expected", [
    ("Tau ZZ", "Tau-ZZ_seed"),  # capitals are file-name safe: kept
    ("X-ray", "X-ray_seed"),  # only the dashes at either end are stripped, never a letter
    ("-X-", "X_seed"),
])
def test_a_labels_capitals_are_kept_and_only_its_dashes_stripped(label, expected):
    assert run_dir_name("icp-p2p", True, label) == expected
