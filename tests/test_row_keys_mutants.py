"""Rows keyed by everything that determines a run (bench/report/tables/row_keys.py): each item
of a configuration read from where it is recorded, the differences between clashing runs
named, and two runs under one label told apart by what differs or by their folders."""

from __future__ import annotations

from pathlib import Path

from bench.report.tables.row_keys import config_items, differences, distinct_labels


def test_an_empty_configuration_has_its_defaults_and_not_recorded():
    assert config_items({}) == {
        "alignment": "se3", "lengths_m": "none", "kitti_lengths_m": "none",
        "frame_range": "none", "store": "not recorded", "store_sha256": "not recorded",
        "code": "not recorded"}


def test_the_identity_is_read_first():
    config = {
        "identity": {"params": {"voxel": 0.5, "iters": 3, "flag": None, "knn": [5, 10]},
                     "scoring": {"alignment": "sim3", "kitti_lengths_m": [100.0, 200.0]},
                     "lengths_m": [8.0, 16.5], "frame_range": (10, 20),
                     "store_sha256": "0123456789abcdef", "code_sha256": "fedcba9876543210xx",
                     "host": {"cpu": "Xeon", "threads": 4}},
        "method": {"params": {"other": 1}},
        "alignment": "none", "lengths_m": [1.0], "kitti_lengths_m": [1.0],
        "sequence": {"frame_range": [0, 1], "store": "/data/stores/loop.npz"}}
    assert config_items(config) == {
        "voxel": "0.5", "iters": "3", "flag": "none", "knn": "5,10",
        "alignment": "sim3", "lengths_m": "8,16.5", "kitti_lengths_m": "100,200",
        "frame_range": "10,20", "store": "loop.npz", "store_sha256": "0123456789ab",
        "code": "fedcba987654", "host.cpu": "Xeon", "host.threads": "4"}


def test_without_an_identity_the_plain_configuration_is_read():
    config = {"method": {"params": {"max_iterations": 30, "tol": 1e-6}},
              "alignment": "origin", "lengths_m": [8, 24], "kitti_lengths_m": [100],
              "sequence": {"frame_range": [5, 9], "store": "a/b/c.h5"}}
    assert config_items(config) == {
        "max_iterations": "30", "tol": "1e-06", "alignment": "origin", "lengths_m": "8,24",
        "kitti_lengths_m": "100", "frame_range": "5,9", "store": "c.h5",
        "store_sha256": "not recorded", "code": "not recorded"}


def test_parts_recorded_as_none_read_as_absent():
    config = {"identity": None, "method": None, "sequence": None, "alignment": "sim3"}
    assert config_items(config)["alignment"] == "sim3"
    assert config_items({"identity": {"params": None, "scoring": None, "host": None},
                         "method": {"params": {"k": 2.0}}})["k"] == "2"


def test_differences_name_only_what_differs_in_the_order_first_seen_missing_as_not_recorded():
    a = {"method": {"params": {"k": 1}}, "alignment": "se3", "lengths_m": [8]}
    b = {"method": {"params": {"k": 2}}, "alignment": "sim3", "lengths_m": [8]}
    c = {"method": {"params": {"k": 1, "extra": True}}, "alignment": "se3", "lengths_m": [8]}
    assert differences([a, b, c]) == [
        "k=1, alignment=se3, extra=not recorded", "k=2, alignment=sim3, extra=not recorded",
        "k=1, alignment=se3, extra=True"]
    assert differences([a, dict(a)]) == ["", ""]
    assert differences([a]) == [""]


def test_two_stores_told_apart_by_name_leave_their_hashes_out():
    a = {"sequence": {"store": "x/a.npz"}, "identity": {"store_sha256": "1" * 64}}
    b = {"sequence": {"store": "x/b.npz"}, "identity": {"store_sha256": "2" * 64}}
    assert differences([a, b]) == ["store=a.npz", "store=b.npz"]
    same_name = {"sequence": {"store": "y/a.npz"}, "identity": {"store_sha256": "2" * 64}}
    assert differences([a, same_name]) == ["store_sha256=111111111111",
                                           "store_sha256=222222222222"]


def _labels(items):
    return distinct_labels(items, lambda i: i["label"], lambda i: i["seq"],
                           lambda i: i["config"], lambda i: Path("/r") / i["seq"] / i["dir"])


def test_a_unique_label_is_kept_and_a_clash_is_told_apart_by_its_configuration():
    items = [{"label": "ICP", "seq": "s1", "config": {"alignment": "se3"}, "dir": "icp"},
             {"label": "ICP", "seq": "s1", "config": {"alignment": "sim3"}, "dir": "icp_2"},
             {"label": "ICP", "seq": "s2", "config": {"alignment": "sim3"}, "dir": "icp"},
             {"label": "GICP", "seq": "s1", "config": {}, "dir": "gicp"}]
    assert _labels(items) == ["ICP [alignment=se3]", "ICP [alignment=sim3]", "ICP", "GICP"]


def test_a_clash_with_the_same_configuration_is_told_apart_by_its_run_folder():
    items = [{"label": "ICP", "seq": "s", "config": {"code": 1}, "dir": "a"},
             {"label": "ICP", "seq": "s", "config": {"code": 1}, "dir": "b"}]
    assert _labels(items) == ["ICP [run folder a]", "ICP [run folder b]"]
    items = [{"label": "M", "seq": "s", "config": {"alignment": "se3"}, "dir": "a"},
             {"label": "M", "seq": "s", "config": {"alignment": "se3"}, "dir": "b"},
             {"label": "M", "seq": "s", "config": {"alignment": "sim3"}, "dir": "c"}]
    assert _labels(items) == ["M [alignment=se3, run folder a]",
                              "M [alignment=se3, run folder b]", "M [alignment=sim3]"]
    assert _labels([]) == []


def test_a_unique_label_before_a_clash_does_not_stop_the_clash_being_told_apart():
    items = [{"label": "GICP", "seq": "s1", "config": {}, "dir": "gicp"},
             {"label": "ICP", "seq": "s1", "config": {"alignment": "se3"}, "dir": "icp"},
             {"label": "ICP", "seq": "s1", "config": {"alignment": "sim3"}, "dir": "icp_2"}]
    assert _labels(items) == ["GICP", "ICP [alignment=se3]", "ICP [alignment=sim3]"]
