"""bench score's checks study (bench.studies.score_checks), its parts checked one by one: a case
run through the reader and the checks (passed / warned / refused on the vendored sample), the
sample's bases, the verdict of each outcome, the study's loop (with stand-in cases: which bases
get faults, the seed, the rows), the printed table (hand-made rows, the expected markdown
written out) and the exit code."""

import json
from pathlib import Path

import numpy as np
import pytest

from bench.studies import score_checks as sk
from bench.studies.score_cases import Base, Case, correct_cases, fault_cases, pieces, write_tum
from loaders.trajectory import Trajectory


@pytest.fixture(scope="module")
def gt_copy():
    return sk.sample_bases([], None)[0]


def test_the_sample_is_the_vendored_store():
    assert sk.SAMPLE == Path(__file__).resolve().parents[1] / "samples" / "ntu4dradlm-loop1.h5"
    assert sk.SAMPLE.is_file()


def test_sample_bases_are_the_gt_copy_each_run_and_kiss(tmp_path, gt_copy):
    assert (gt_copy.name, gt_copy.kind, gt_copy.piece) == ("sample: GT copy", "real", "whole")
    assert len(gt_copy.scans) == 250 and len(gt_copy.gt) == 250
    np.testing.assert_array_equal(gt_copy.stamps, gt_copy.gt.stamps)
    np.testing.assert_array_equal(gt_copy.poses, gt_copy.gt.poses)
    run = tmp_path / "doppler" / "est_tum.txt"
    run.parent.mkdir()
    write_tum(run, gt_copy.stamps[::2] + 0.01, gt_copy.poses[::2])
    kiss = write_tum(tmp_path / "kiss.tum", gt_copy.stamps[1::3], gt_copy.poses[1::3])
    out = sk.sample_bases([run], kiss)
    assert [b.name for b in out] == ["sample: GT copy", "sample: doppler",
                                     "sample: kiss-icp pipeline on the exported bag"]
    assert all(b.kind == "real" and b.piece == "whole" for b in out)
    for b in out:
        np.testing.assert_array_equal(b.scans, gt_copy.scans)
        np.testing.assert_array_equal(b.gt.stamps, gt_copy.gt.stamps)
    np.testing.assert_allclose(out[1].stamps, gt_copy.stamps[::2] + 0.01, atol=1e-9)
    np.testing.assert_allclose(out[1].poses, gt_copy.poses[::2], atol=1e-7)
    np.testing.assert_allclose(out[2].stamps, gt_copy.stamps[1::3], atol=1e-9)
    np.testing.assert_allclose(out[2].poses, gt_copy.poses[1::3], atol=1e-7)
    assert len(sk.sample_bases([run], None)) == 2


def test_run_case_passes_and_refuses_as_bench_score_would(tmp_path, gt_copy):
    """On the sample's first half: the ground truth as given passes, on the store's clock; a
    KITTI file of inverse poses, read with its stamps file (the case's options reach the
    reader), is refused for its convention."""
    half = pieces(gt_copy)[0]
    asis = correct_cases(half, tmp_path, np.random.default_rng(0))[0]
    outcome, message = sk.run_case(asis)
    assert outcome == "passed" and message.startswith("on the store's clock"), message
    inverse = [c for c in fault_cases(half, tmp_path) if c.variant == "KITTI of inverse poses"]
    outcome, message = sk.run_case(inverse[0])
    assert outcome == "refused" and "inverse poses" in message, message


def test_run_case_joins_several_warnings(tmp_path, gt_copy, monkeypatch):
    class Found:
        warnings = ["first", "second"]
        clock = "clock line"

    seen = {}

    def fake_check(seq, est, spec, T, name, store):
        seen.update(spec=spec, name=name, store=store, T=T, seq=seq)
        return Found()

    monkeypatch.setattr(sk, "check_estimate", fake_check)
    case = correct_cases(gt_copy, tmp_path, np.random.default_rng(0))[2]
    assert sk.run_case(case) == ("warned", "first | second")
    assert seen["spec"].max_gap_s == 0.25 and seen["spec"].name == "study"
    assert seen["spec"].trajectory == case.path
    assert seen["name"] == str(case.path) and seen["store"] == "store"
    np.testing.assert_array_equal(seen["T"], np.eye(4))
    assert seen["seq"].stamps is gt_copy.scans
    Found.warnings = []
    assert sk.run_case(case) == ("passed", "clock line")


def test_run_case_reads_with_the_cases_stamp_unit(tmp_path, gt_copy, monkeypatch):
    """A TUM file of millisecond stamps with the option stamp_unit "ms" is read in seconds."""
    seen = []

    class Found:
        warnings = []
        clock = "ok"

    def fake_check(seq, est, spec, T, name, store):
        seen.append(est)
        return Found()

    monkeypatch.setattr(sk, "check_estimate", fake_check)
    ms = [c for c in fault_cases(gt_copy, tmp_path) if c.variant == "stamps in ms"][0]
    assert sk.run_case(Case(gt_copy, "ms read as ms", ms.path, {"stamp_unit": "ms"})) == (
        "passed", "ok")
    np.testing.assert_allclose(seen[0].trajectory.stamps, gt_copy.stamps, atol=1e-6)


def case(cause=None):
    return Case(Base("b", "real", *(np.zeros(1),) * 3, None), "v", Path("x"), cause=cause)


def test_classify_names_false_alarms_detections_other_causes_and_misses():
    assert sk.classify(case(), "passed", "fine") == "passed"
    assert sk.classify(case(), "warned", "w") == "false alarm"
    assert sk.classify(case(), "refused", "r") == "false alarm"
    assert sk.classify(case("clock"), "passed", "its clock does not fit") == "missed"
    for words in ("its clock does not fit", "does not overlap", "--time-offset"):
        assert sk.classify(case("clock"), "refused", f"x {words} y") == "detected"
        assert sk.classify(case("clock"), "warned", f"x {words} y") == "detected"
    assert sk.classify(case("clock"), "refused", "positions in mm") == "other cause"
    assert sk.classify(case("w x y z"), "refused", "in w x y z order") == "detected"
    assert sk.classify(case("w x y z"), "refused", "its clock does not fit") == "other cause"
    assert sk.classify(case("bridged a gap"), "warned", "it bridged a gap of 3 s") == "detected"


def stub_base(name, kind="real", piece="whole"):
    z = np.zeros(2)
    return Base(name, kind, z, z, z, Trajectory(np.array([0.0, 1.0]), np.eye(4)[None]
                                                .repeat(2, 0)), piece)


def test_study_runs_every_case_faults_on_whole_bases_flat_and_straight_pieces(monkeypatch,
                                                                               tmp_path):
    real = stub_base("sample: GT copy")
    calls = {"draws": [], "runs": None, "correct": [], "faults": []}

    def sample_bases(runs, kiss):
        calls["runs"] = (runs, kiss)
        return [real]

    def synthetic_bases(rng):
        calls["rng"] = rng
        calls["draws"].append(rng.random())
        return [stub_base("synthetic curve", "synthetic", "exact GT")]

    def pieces(b):
        assert b is real
        return [stub_base(b.name, b.kind, p) for p in ("first half", "flat speed", "straight",
                                                       "frames 60-190")]

    def correct(b, folder, rng):
        assert folder == tmp_path and rng is calls["rng"]
        calls["correct"].append((b.name, b.piece))
        return [Case(b, "ok", folder / "ok")]

    def faults(b, folder):
        assert folder == tmp_path
        calls["faults"].append((b.name, b.piece))
        return [Case(b, "bad", folder / "bad", {}, "clock", -0.5)]

    def run(c):
        if c.cause is None:
            return ("passed", "on the store's clock")
        return ("refused", "y" * 500 + " its clock does not fit")

    for name, f in (("sample_bases", sample_bases), ("synthetic_bases", synthetic_bases),
                    ("pieces", pieces), ("correct_cases", correct), ("fault_cases", faults),
                    ("run_case", run)):
        monkeypatch.setattr(sk, name, f)
    rows = sk.study([Path("r")], Path("k"), tmp_path, seed=7)
    assert calls["runs"] == ([Path("r")], Path("k"))
    assert calls["draws"] == [np.random.default_rng(7).random()]
    got = [(r["base"], r["piece"], r["variant"]) for r in rows]
    assert got == [
        ("sample: GT copy", "whole", "ok"), ("sample: GT copy", "whole", "bad"),
        ("synthetic curve", "exact GT", "ok"), ("synthetic curve", "exact GT", "bad"),
        ("sample: GT copy", "first half", "ok"),
        ("sample: GT copy", "flat speed", "ok"), ("sample: GT copy", "flat speed", "bad"),
        ("sample: GT copy", "straight", "ok"), ("sample: GT copy", "straight", "bad"),
        ("sample: GT copy", "frames 60-190", "ok")]
    ok, bad = rows[2], rows[3]
    assert ok == {"base": "synthetic curve", "kind": "synthetic", "piece": "exact GT",
                  "variant": "ok", "cause": None, "size": None, "outcome": "passed",
                  "verdict": "passed", "message": "on the store's clock"}
    assert (bad["cause"], bad["size"], bad["outcome"], bad["verdict"]) == (
        "clock", -0.5, "refused", "detected")
    assert bad["message"] == "y" * 400
    assert calls["correct"] == [(b, p) for b, p, v in got if v == "ok"]
    assert calls["faults"] == [(b, p) for b, p, v in got if v == "bad"]
    sk.study([], None, tmp_path)  # the default seed is 0 (the published tables')
    assert calls["draws"][-1] == np.random.default_rng(0).random()


def row(variant, kind, outcome, verdict, cause=None, size=None):
    return {"variant": variant, "kind": kind, "outcome": outcome, "verdict": verdict,
            "cause": cause, "size": size}


TABLE_ROWS = [
    row("as is", "real", "passed", "passed"), row("as is", "real", "warned", "false alarm"),
    row("as is", "real", "passed", "passed"),
    row("as is", "synthetic", "refused", "false alarm"),
    row("shifted, as given", "real", "refused", "detected", "clock", 0.1),
    row("shifted, as given", "real", "passed", "missed", "clock", -0.1),
    row("shifted, as given", "real", "refused", "detected", "clock", 0.5),
    row("shifted, as given", "real", "refused", "detected", "clock", -0.5),
    row("shifted, as given", "real", "refused", "detected", "clock", 1.0),
    row("shifted, as given", "real", "refused", "other cause", "clock", -1.0),
    row("shifted, --max-gap 0.3", "real", "passed", "missed", "clock", 0.1),
    row("shifted, --max-gap 0.3", "real", "warned", "detected", "clock", -0.1),
    row("shifted, --max-gap 0.3", "real", "refused", "detected", "clock", 0.5),
    row("shifted, --max-gap 0.3", "real", "refused", "detected", "clock", -0.5),
    row("shifted, --max-gap 0.3", "real", "refused", "detected", "clock", 2.0),
    row("positions in mm", "real", "refused", "detected", "positions in"),
    row("positions in mm", "real", "refused", "other cause", "positions in"),
    row("positions in mm", "real", "passed", "missed", "positions in"),
    row("sheared rotation block", "real", "refused", "detected", "no rotation", 0.01),
    row("sheared rotation block", "real", "refused", "detected", "no rotation", 0.2),
]


def test_table_counts_each_variant_and_the_smallest_shift_every_base_detected():
    lines = sk.table(TABLE_ROWS).split("\n")
    assert lines == [
        "| input | store | cases | refused | warned | passed | verdict |",
        "|---|---|---:|---:|---:|---:|---|",
        "| as is | real | 3 | 0 | 1 | 2 | 1 false alarms |",
        "| as is | synthetic | 1 | 1 | 0 | 0 | 1 false alarms |",
        "| fault: positions in mm | real | 3 | 2 | 0 | 1 | 1 detected, 1 other cause, 1 missed |",
        "| fault: sheared rotation block | real | 2 | 2 | 0 | 0 | 2 detected, 0 other cause, "
        "0 missed |",
        "| fault: shifted, --max-gap 0.3 | real | 5 | 3 | 1 | 1 | 4 detected, 0 other cause, "
        "1 missed; every base at every size from 0.5 s; detected per size 0.1 s: 1/2, "
        "0.5 s: 2/2, 2 s: 1/1 |",
        "| fault: shifted, as given | real | 6 | 5 | 0 | 1 | 4 detected, 1 other cause, "
        "1 missed; some base missed at the largest size; detected per size 0.1 s: 1/2, "
        "0.5 s: 2/2, 1 s: 1/2 |",
    ]


def test_table_says_every_size_when_the_smallest_is_detected_everywhere():
    rows = [row("shifted, as given", "synthetic", "refused", "detected", "clock", s)
            for s in (0.05, -0.05, 5.0)]
    assert sk.table(rows).split("\n")[2] == (
        "| fault: shifted, as given | synthetic | 3 | 3 | 0 | 0 | 3 detected, 0 other cause, "
        "0 missed; every base at every size from 0.05 s; detected per size 0.05 s: 2/2, "
        "5 s: 1/1 |")


def test_main_prints_the_table_the_json_and_fails_on_a_false_alarm(monkeypatch, capsys):
    seen = {}

    def study(runs, kiss, folder):
        seen.update(runs=runs, kiss=kiss, folder=folder, existed=folder.is_dir())
        return [dict(r, message="m") for r in TABLE_ROWS[:3]]

    monkeypatch.setattr(sk, "study", study)
    assert sk.main(["--runs", "a/est_tum.txt", "b/est_tum.txt", "--kiss", "k.tum"]) == 1
    out = capsys.readouterr().out
    assert seen["runs"] == [Path("a/est_tum.txt"), Path("b/est_tum.txt")]
    assert seen["kiss"] == Path("k.tum")
    assert seen["existed"] and not seen["folder"].exists()  # a temporary folder, removed
    assert seen["folder"].name.startswith("score-checks-")
    assert out == sk.table([dict(r, message="m") for r in TABLE_ROWS[:3]]) + "\n"
    assert sk.main(["--json"]) == 1
    assert seen["runs"] == [] and seen["kiss"] is None
    out = capsys.readouterr().out
    head, sep, first, rest = out.split("\n", 3)  # a table of one row, then the JSON
    assert first.startswith("| as is | real | 3 |")
    assert json.loads(rest) == [dict(r, message="m") for r in TABLE_ROWS[:3]]
    assert rest.split("\n")[:3] == ["[", " {", '  "variant": "as is",']  # indented by one
    monkeypatch.setattr(sk, "study", lambda runs, kiss, folder: [TABLE_ROWS[0]])
    assert sk.main([]) == 0


def test_main_help_names_the_options(capsys):
    with pytest.raises(SystemExit) as stop:
        sk.main(["--help"])
    assert stop.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "false alarms and detections of bench score's checks" in out
    assert ("--runs [RUNS ...] est_tum.txt files of the harness's own runs on the sample "
            "--kiss KISS kiss-icp pipeline's TUM poses on the sample's exported bag --json print "
            "every case as JSON after the table") in out
