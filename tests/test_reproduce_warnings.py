"""`make reproduce-table` says each planning warning once (bench.studies.reproduce.plan_tables):
the tables' experiments are planned each and then as one union, and only the union speaks."""

from __future__ import annotations

import warnings

from rich.console import Console

from bench.runs.experiment import Experiment
from bench.studies.reproduce import plan_tables
from conftest import SAMPLE_STORE


def test_a_short_path_warning_is_said_once_for_two_tables(tmp_path):
    """The vendored sample's 109 m path is too short for KITTI's 200-800 m: two experiments
    on it (as Tables III and IV share sequences) give that warning once, not once per plan."""
    experiments = {
        name: Experiment.model_validate({
            "name": name, "sequences": [{"path": str(SAMPLE_STORE)}],
            "methods": [{"name": "doppler"}], "out": str(tmp_path / "out")})
        for name in ("table3", "table4")}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        per_table, union = plan_tables(experiments, Console(file=open("/dev/null", "w")))
    said = [str(w.message) for w in caught if "path is" in str(w.message)]
    assert said, "the sample's path is shorter than KITTI's 200 m: a warning is expected"
    assert len(said) == len(set(said))
    assert set(per_table) == {"table3", "table4"} and len(union) >= 1
