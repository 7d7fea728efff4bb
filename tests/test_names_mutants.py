"""bench.report.names from its docstrings: the caption notes, a run's row label, the parameter
suffix and the sequence order (written for a mutation run of the module)."""

from bench.report import names


def test_the_synthetic_note_only_when_a_synthetic_sequence_is_shown():
    note = names.synthetic_note(["Loop1_0", "Campus1 (synthetic)"])
    assert note.startswith("SYNTHETIC DATA: sequences marked (synthetic) are made by this "
                           "repository's generator")
    assert note.endswith("they are not the paper's data. ")
    assert names.synthetic_note(["Loop1_0", "Campus1"]) == ""
    assert names.synthetic_note([]) == ""


def test_gt_assisted_marks_and_note():
    assert names.is_gt_assisted("gt-reconstructed")
    assert not names.is_gt_assisted("measured") and not names.is_gt_assisted(None)
    assert names.gt_assisted_note(["(With Seed) DICP", "(No Seed) icp [GT-assisted]"]) \
        .startswith("GT-ASSISTED: rows marked [GT-assisted] ran on Doppler reconstructed")
    assert names.gt_assisted_note(["(With Seed) DICP", "GT-assisted"]) == ""  # no brackets


def test_hosts_note_when_cpus_differ():
    assert names.hosts_note(["cpu A", "cpu A"]) == ""
    assert names.hosts_note([]) == ""
    assert names.hosts_note([None, ""]) == ""  # both count as not recorded
    assert names.hosts_note(["cpu B", None, "cpu A", "cpu B"]) == (
        "MIXED HOSTS: these times come from runs on different CPUs (cpu A; cpu B; not "
        "recorded); times from different CPUs are not comparable. ")


def test_run_labels():
    assert names.run_label("dicp", True) == "(With Seed) DICP"
    assert names.run_label("icp", False) == "(No Seed) icp"
    assert names.run_label("icp", None, "v2") == "(No initial guess) v2"
    assert names.run_label("dicp", True, doppler_kind="gt-reconstructed") == \
        "(With Seed) DICP [GT-assisted]"
    assert names.run_label("dicp", True, doppler_kind="measured") == "(With Seed) DICP"
    assert names.run_label("x", True, "kiss (external)") == "kiss (external)"
    assert names.run_label("x", True, "kiss (external)", "gt-reconstructed") == \
        "kiss (external) [GT-assisted]"
    assert names.seed_tag("icp", False) == "No Seed"
    # KISS-ICP predicts with its own motion model (methods/kiss.py's motion_prior)
    assert names.seed_tag("kiss-icp", True) == "With Seed, own model"
    assert names.run_label("kiss-icp", True, "k") == "(With Seed, own model) k"


def test_the_overrides_note():
    given = {"method": {"given": {"tol": 0.5, "max_iterations": 3, "voxel": [0.25, 1.0],
                                  "mode": "p2p", "w": (1, 2.5e-7)}}}
    assert names.overrides_note(given) == \
        " [max_iterations=3, mode=p2p, tol=0.5, voxel=0.25,1, w=1,2.5e-07]"
    assert names.overrides_note({**given, "label": "v1"}) == ""
    assert names.overrides_note({"method": {"given": {}}}) == ""
    assert names.overrides_note({"method": {"name": "icp"}}) == ""
    assert names.overrides_note({"method": "icp"}) == ""
    assert names.overrides_note({"method": {"given": ["tol"]}}) == ""
    assert names.overrides_note({}) == ""


def test_sequence_order():
    shown = ["run10", "Tunnel_Vehicles", "Run2", "Loop1_0 (GT calibrated)", "Campus1",
             "Straight Wall", "Loop1_01", "abc", "Campus2"]
    assert sorted(shown, key=names.sequence_key) == [
        "Campus1", "Campus2", "Loop1_0 (GT calibrated)", "Straight Wall", "Tunnel_Vehicles",
        "abc", "Loop1_01", "Run2", "run10"]
    assert names.sequence_key("CurvedWall") == (8, ("curvedwall",))
    assert names.sequence_key("Curved Wall") == (8, ("curved wall",))
    assert names.sequence_key("x") == (11, ("x",))
    assert names.sequence_key("a2b10") == (11, ("a", 2, "b", 10, ""))
