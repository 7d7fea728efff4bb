"""bench run's ground-truth checks (bench.studies.run_checks_study): nothing on the correct
inputs and their realistic perturbations (GT jittered 5 mm, resampled to 5 Hz, lagged 20 ms);
each fault a check exists for is caught (duplicate rows warned, a repeated stamp with another
pose, a stamp going backwards and a GT that does not overlap refused, a GT stopping early
warned about its length). Gaps, jumps and a stalled GT have no check: pinned as silent."""

from bench.studies.run_checks_study import study


def test_correct_inputs_raise_nothing_and_each_fault_is_caught():
    rows = study(frames=120)
    passing = [r for r in rows if r["kind"] == "pass"]
    assert len(passing) == 32
    assert all(r["said"] == "silent" for r in passing), [r for r in passing
                                                         if r["said"] != "silent"]
    faults = [r for r in rows if r["kind"] == "fault"]

    def said(case: str) -> set[str]:
        return {r["said"] for r in faults if r["case"] == case}

    assert said("duplicate rows (logged twice)") == {"warned"}
    assert said("repeated stamp, other pose") == {"refused"}
    assert said("stamp going backwards") == {"refused"}
    assert said("GT not overlapping (shifted)") == {"refused"}
    assert said("GT stops early") <= {"warned", "refused"}
    # no check in bench run (the frames are left unscored, or scored against the fault)
    for case in ("gap in the GT", "position jump", "stalled GT (pose repeated)",
                 "GT partly overlapping (shifted)"):
        assert said(case) == {"silent"}, case
