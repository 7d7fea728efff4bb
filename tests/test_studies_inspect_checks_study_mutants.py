"""bench inspect's data-checks study (bench.studies.inspect_checks_study), its parts checked one
by one: the faults applied to a scan (Doppler negated, replaced by ego-compensated noise, points
mirrored in z), the altered sequence, which flags a report raises (hand-made reports in the
check's own wording), the study's loop on the sample's pieces (the inspection stood in for), the
table (hand-made rows) and the exit code."""

from types import SimpleNamespace

import numpy as np
import pytest

from bench.studies import inspect_checks_study as ics
from loaders.scan import FrameRange, MemorySequence, Scan, SensorInfo
from loaders.store import StoreSequence
from loaders.trajectory import Trajectory


def scan(stamp=1.5, n=4):
    pts = np.arange(3.0 * n).reshape(n, 3) - 4.0
    return Scan(stamp, pts, np.linspace(-2.0, 3.0, n), {"power": np.ones(n)}, "f, frame 0")


def test_negated_flips_only_the_doppler():
    s = scan()
    out = ics.negated(s)
    np.testing.assert_array_equal(out.doppler, -s.doppler)
    np.testing.assert_array_equal(out.points, s.points)
    assert out.stamp == s.stamp and out.source == s.source


def test_mirrored_flips_only_z_and_leaves_the_scan_alone():
    s = scan()
    before = s.points.copy()
    out = ics.mirrored(s)
    np.testing.assert_array_equal(out.points[:, :2], before[:, :2])
    np.testing.assert_array_equal(out.points[:, 2], -before[:, 2])
    np.testing.assert_array_equal(s.points, before)
    np.testing.assert_array_equal(out.doppler, s.doppler)


def test_compensated_is_zero_mean_5_cm_per_s_noise_fixed_per_stamp():
    s = scan(12.345, 20000)
    out = ics.compensated(s)
    assert abs(np.mean(out.doppler)) < 0.002
    np.testing.assert_allclose(np.std(out.doppler), 0.05, rtol=0.03)
    np.testing.assert_array_equal(out.points, s.points)
    np.testing.assert_array_equal(ics.compensated(s).doppler, out.doppler)  # reproducible
    # scans 1 ms apart draw different noise
    other = ics.compensated(scan(12.346, 20000)).doppler
    assert not np.allclose(other, out.doppler)


def test_faults_name_the_check_that_must_flag_them():
    assert ics.FAULTS == {"Doppler negated": (ics.negated, "sign"),
                          "Doppler ego-compensated": (ics.compensated, "kind"),
                          "points mirrored in z": (ics.mirrored, "height")}


def memory_sequence():
    sensor = SensorInfo("radar", 0.1)
    gt = Trajectory(np.array([1.5, 1.6]), np.repeat(np.eye(4)[None], 2, 0))
    return MemorySequence("mem", sensor, [scan(1.5), scan(1.6)], gt, {"loader": "x"})


def test_altered_is_the_same_sequence_through_the_fault():
    base = memory_sequence()
    seen = []

    def change(s):
        seen.append(s.stamp)
        return ics.negated(s)

    alt = ics.Altered(base, change)
    assert len(alt) == 2 and alt.name == "mem" and alt.sensor is base.sensor
    assert alt.ground_truth is base.ground_truth and alt.provenance is base.provenance
    np.testing.assert_array_equal(alt.stamps, [1.5, 1.6])
    out = alt.scan(1)
    assert seen == [1.6]
    np.testing.assert_array_equal(out.doppler, -base.scan(1).doppler)


HEIGHT_OK = ("densest layer at z = -0.52 m (the height most of 30 frames across the sequence "
             "agree on, 97 % of them with their own layer below; points within 10 m): road "
             "below the sensor (sign looks right)")
HEIGHT_BAD = ("densest layer at z = +0.52 m (the height most of 30 frames across the sequence "
              "agree on, 3 % of them with their own layer below; points within 10 m): densest "
              "layer above the sensor (the elevation looks mirrored); store takes no "
              "elevation-sign option (its points' z is as the sensor recorded it): check it")


def report(sign="confirmed", kind=None, height=HEIGHT_OK, gt=()):
    rows = [("frames", "250"), ("height check", height)] if height is not None else []
    return {"sign": SimpleNamespace(verdict=sign), "kind": kind, "rows": rows,
            "gt_findings": list(gt)}


def kind(measured="radial", disagrees=False):
    return SimpleNamespace(measured=measured, disagrees=disagrees)


def test_flags_reads_each_check_in_its_own_words():
    assert ics.flags(report()) == {"sign": False, "kind": False, "height": False, "gt": False}
    assert ics.flags(report(sign="FLIPPED (the Doppler looks negated)"))["sign"]
    assert not ics.flags(report(sign="not enough moving frames"))["sign"]
    assert not ics.flags(report(kind=kind()))["kind"]
    assert ics.flags(report(kind=kind("ego-compensated")))["kind"]
    assert ics.flags(report(kind=kind("radial", True)))["kind"]
    assert ics.flags(report(kind=kind("ego-compensated", True)))["kind"]
    assert ics.flags(report(height=HEIGHT_BAD))["height"]
    assert not ics.flags(report(height=None))["height"]  # no height row: no flag
    assert not ics.flags(report(height="no points above"))["height"]  # no verdict after ":"
    # "above" counts only in the verdict, not before it
    assert not ics.flags(report(height="above: road below the sensor"))["height"]
    assert ics.flags(report(gt=["GT jumps 3 m at 12.0 s"])) == {
        "sign": False, "kind": False, "height": False, "gt": True}


def test_study_inspects_every_piece_correct_and_with_each_fault(monkeypatch):
    seen, closed = [], []

    class Sample(StoreSequence):
        def close(self):
            closed.append(self)
            super().close()

    def inspect(seq):
        seen.append(seq)
        fault = getattr(seq, "change", None)
        name = {ics.negated: "sign", ics.compensated: "kind", ics.mirrored: "height"}.get(fault)
        return report(sign="FLIPPED" if name == "sign" else "confirmed",
                      kind=kind("ego-compensated") if name == "kind" else None,
                      height=HEIGHT_BAD if name == "height" else HEIGHT_OK,
                      gt=["x"] if len(seen) % 5 == 0 else [])

    monkeypatch.setattr(ics, "inspect_sequence", inspect)
    monkeypatch.setattr(ics, "StoreSequence", Sample)
    rows = ics.study()
    assert len(closed) == 1
    pieces = [("whole", 0, 250), ("first half", 0, 125), ("second half", 125, 250),
              ("frames 0-100", 0, 100), ("frames 50-150", 50, 150),
              ("frames 100-200", 100, 200), ("frames 150-250", 150, 250)]
    inputs = ["correct", "Doppler negated", "Doppler ego-compensated", "points mirrored in z"]
    assert [(r["input"], r["piece"]) for r in rows] == [(i, p[0]) for p in pieces
                                                         for i in inputs]
    for k, (r, seq) in enumerate(zip(rows, seen, strict=True)):
        _, a, b = pieces[k // 4]
        cut = seq if r["input"] == "correct" else seq.base
        assert isinstance(cut, FrameRange)
        np.testing.assert_array_equal(cut.indices, np.arange(a, b))
        if r["input"] != "correct":
            assert isinstance(seq, ics.Altered) and seq.change is ics.FAULTS[r["input"]][0]
        check = ics.FAULTS.get(r["input"], (None, None))[1]
        assert {c for c in ("sign", "kind", "height") if r[c]} == ({check} if check else set())
        assert r["gt"] == ((k + 1) % 5 == 0)


def table_rows():
    def row(name, sign=False, kind=False, height=False, gt=False):
        return {"input": name, "piece": "p", "sign": sign, "kind": kind, "height": height,
                "gt": gt}

    return [row("correct"), row("correct", gt=True), row("correct", kind=True),
            row("Doppler negated", sign=True), row("Doppler negated", sign=True, gt=True),
            row("Doppler ego-compensated", kind=True, height=True),
            row("points mirrored in z", height=True), row("points mirrored in z"),
            row("points mirrored in z", height=True, sign=True)]


def test_table_counts_each_flag_per_input():
    assert ics.table(table_rows()).split("\n") == [
        "| input | pieces | sign flagged | kind flagged | height flagged | GT findings |",
        "|---|---:|---:|---:|---:|---:|",
        "| correct | 3 | 0 | 1 | 0 | 1 |",
        "| Doppler negated | 2 | 2 | 0 | 0 | 1 |",
        "| Doppler ego-compensated | 1 | 0 | 1 | 1 | 0 |",
        "| points mirrored in z | 3 | 1 | 0 | 2 | 0 |"]


@pytest.mark.parametrize("flag, code", [(None, 0), ("gt", 0), ("sign", 1), ("kind", 1),
                                        ("height", 1)])
def test_main_fails_on_a_flag_on_a_correct_piece_but_not_on_a_gt_finding(monkeypatch, capsys,
                                                                        flag, code):
    rows = [r for r in table_rows() if r["input"] != "correct"]
    rows.append({"input": "correct", "piece": "p", "sign": False, "kind": False,
                 "height": False, "gt": False} | ({flag: True} if flag else {}))
    monkeypatch.setattr(ics, "study", lambda: rows)
    assert ics.main([]) == code
    assert capsys.readouterr().out == ics.table(rows) + "\n"


def test_main_help_and_the_sample(capsys):
    with pytest.raises(SystemExit):
        ics.main(["--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert ("false alarms and detections of bench inspect's sign, kind, height and GT checks "
            "on the sample") in out
    assert ics.SAMPLE.is_file() and ics.SAMPLE.name == "ntu4dradlm-loop1.h5"
