"""bench inspect's sign, kind and height checks on the vendored sample's pieces
(bench.studies.inspect_checks_study): no flag on the correct pieces; each fault (Doppler
negated, Doppler ego-compensated, points mirrored in z) flagged by its own check on every
piece and by no other."""

from bench.studies.inspect_checks_study import FAULTS, study


def test_each_fault_is_flagged_by_its_check_and_nothing_on_the_correct_pieces():
    rows = study()
    correct = [r for r in rows if r["input"] == "correct"]
    assert len(correct) == 7
    assert not any(r["sign"] or r["kind"] or r["height"] for r in correct), correct
    for name, (_, check) in FAULTS.items():
        rs = [r for r in rows if r["input"] == name]
        assert len(rs) == 7 and all(r[check] for r in rs), (name, rs)
        others = {"sign", "kind", "height"} - {check}
        assert not any(r[k] for r in rs for k in others), (name, rs)
