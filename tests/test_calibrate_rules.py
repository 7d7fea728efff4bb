"""The rules and printed lines of ``bench calibrate`` (bench.data.calibration.calibrate) on
hand-made estimates: one angle's line, the block-bootstrap note, the Doppler result's table,
where the Doppler and hand-eye estimates disagree, the default calibration frames and the
ground-truth coverage check. Each expectation follows from the module's definitions, not from
its output; the end-to-end runs are in tests/test_calibrate.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration import calibrate as cm
from bench.data.calibration.bootstrap import BlockChoice
from bench.data.calibration.estimate import CalibrationResult
from bench.data.calibration.hand_eye import HandEyeResult
from bench.data.calibration.verdict import AGREE, APART, CANNOT_TELL
from loaders.errors import DataError

ANGLES = ("roll", "pitch", "yaw")


# ---------------------------------------------------------------- one angle's line


def test_an_angle_line_prints_estimate_interval_sd_and_source():
    line = cm._angle_line("pitch", -2.0, (-2.1, -1.9), 0.05, 0.95, "velocity")
    assert line == "  pitch   -2.000 deg  95 % [-2.100, -1.900]  sd 0.050  (velocity)"
    assert cm._angle_line("yaw", 1.25, (1.0, 1.5), 0.125, 0.9, "road plane") == \
        "  yaw     +1.250 deg  90 % [+1.000, +1.500]  sd 0.125  (road plane)"


def test_an_unseen_angle_prints_no_number_and_why():
    assert cm._angle_line("roll", 3.0, (2.0, 4.0), 0.5, 0.95, "not observable",
                          "no road plane") == "  roll  not observable: no road plane"
    assert cm._angle_line("roll", 3.0, (2.0, 4.0), 0.5, 0.95, "not observable") == \
        "  roll  not observable"


def test_no_interval_says_how_many_resamples_were_fitted():
    line = cm._angle_line("yaw", 0.5, (np.nan, np.nan), np.nan, 0.95, "velocity",
                          resamples=1)
    assert line == "  yaw     +0.500 deg  no interval (1 resamples could be fitted)  (velocity)"


def test_an_interval_narrower_than_the_printed_resolution_is_never_shown_as_zero_width():
    """Narrower than 1e-3 deg: said in words; exactly 1e-3 wide: printed (it shows)."""
    line = cm._angle_line("pitch", -2.0, (-2.0, -1.9995), 0.0001, 0.95, "velocity")
    assert line == ("  pitch   -2.000 deg  95 % interval narrower than 0.001 deg (every resample "
                    "gives the same angle)  sd < 0.001  (velocity)")
    line = cm._angle_line("pitch", 0.0, (0.0, 0.001), 0.0002, 0.95, "velocity")
    assert line.endswith("95 % [+0.000, +0.001]  sd 0.000  (velocity)")


# ---------------------------------------------------------------- the block note


def _blocked(frames, wanted, n, correlation=(10, 30, 20), fitted=ANGLES, resamples=50):
    block = BlockChoice(frames, frames * 0.08, wanted, tuple(correlation))
    return SimpleNamespace(block=block, frames_total=n, resamples=resamples,
                           fitted=list(fitted))


def test_enough_blocks_give_one_line():
    """120 frames in blocks of 40: 3 blocks, 2 degrees of freedom (= MIN_DOF): no warning."""
    assert cm.MIN_DOF == 2.0
    lines = cm._blocks_lines(_blocked(40, 40, 120))
    assert lines == ["  uncertainty: " + BlockChoice(40, 3.2, 40, (10, 30, 20)).describe(
        50, 120, "each refitted with its own outlier cut")]
    assert "50 resamples" in lines[0] and "2.0 degrees of freedom" in lines[0]


def test_few_blocks_name_the_longest_correlated_residuals():
    """120 frames in blocks of 42: 1.86 degrees of freedom (< 2): the note names the pitch
    residuals (correlated over 30 frames, the longest) and the counts."""
    lines = cm._blocks_lines(_blocked(42, 42, 120))
    assert len(lines) == 2
    # what the wide intervals mean, and what they do not
    assert lines[1].endswith("every interval is wide: the fit's error wanders along the range "
                             "(the pieces show how far), it does not mean an angle is "
                             "unobservable; each is printed with its estimate")
    assert lines[1].startswith("  few blocks: the pitch residuals stay correlated over 30 "
                               "frames, so the blocks are 42 of the 120 frames (2.9 blocks, "
                               "1.9 degrees of freedom)")
    # the correlation lengths follow the fitted angles: without roll, yaw's is the longest
    lines = cm._blocks_lines(_blocked(42, 42, 120, correlation=(10, 30),
                                      fitted=("pitch", "yaw")))
    assert "the yaw residuals stay correlated over 30 frames" in lines[1]


def test_a_capped_block_is_noted_even_with_enough_degrees_of_freedom():
    """The rule asked for 90 frames of 400, capped ... (here: capped at 50, 7 dof) gets the
    note; no correlation lengths: half the asked block is named."""
    lines = cm._blocks_lines(_blocked(50, 90, 400, correlation=()))
    assert len(lines) == 2
    assert "the the residuals stay correlated over 45 frames" in lines[1]
    assert "blocks are 50 of the 400 frames (8.0 blocks, 7.0 degrees of freedom)" in lines[1]


# ---------------------------------------------------------------- the Doppler table


def _cal(angles=(0.5, -2.0, 1.0), half=0.1, source=None, road=None, block=None, reasons=None,
         level=0.95, frames_used=97):
    angles = dict(zip(ANGLES, angles, strict=True))
    src = {"roll": "road plane", "pitch": "velocity", "yaw": "velocity", **(source or {})}
    interval = {a: (v - half, v + half) if src[a] != "not observable" else (np.nan, np.nan)
                for a, v in angles.items()}
    R = Rotation.from_euler("xyz", [angles[a] if src[a] != "not observable" else 0.0
                                    for a in ANGLES], degrees=True).as_matrix()
    return CalibrationResult(R, angles, dict.fromkeys(ANGLES, 0.05), src, frames_used,
                             road or {}, interval, level, block, 50, 120, reasons or {})


def test_the_doppler_table():
    road = {"frames": 80.0, "height_m": 1.734, "road_pitch_in_sensor_deg": 2.0,
            "road_roll_in_sensor_deg": -0.5, "up_pitch_in_gt_deg": 0.25,
            "up_roll_in_gt_deg": -0.125}
    cal = _cal(road=road)
    lines = cm.format_result(cal)
    total = np.degrees(Rotation.from_euler("xyz", [0.5, -2.0, 1.0], degrees=True).magnitude())
    assert lines[0] == (f"Doppler ego velocity + road plane: R_gt_sensor from 97 frames "
                        f"(rotation {total:.3f} deg):")
    assert lines[1] == cm._angle_line("roll", 0.5, (0.4, 0.6), 0.05, 0.95, "road plane")
    assert lines[2] == cm._angle_line("pitch", -2.0, (-2.1, -1.9), 0.05, 0.95, "velocity")
    assert lines[3] == cm._angle_line("yaw", 1.0, (0.9, 1.1), 0.05, 0.95, "velocity")
    assert lines[4] == ("road plane (80 frames): sensor 1.73 m above it; road tilt in the "
                        "sensor frame pitch +2.00 / roll -0.50 deg, world up in the GT frame "
                        "pitch +0.25 / roll -0.12 deg")
    assert len(lines) == 5


def test_the_doppler_table_without_road_and_with_an_unseen_angle():
    cal = _cal(source={"roll": "not observable"}, reasons={"roll": "no road plane found"},
               block=BlockChoice(10, 0.8, 10, (5, 5)))
    lines = cm.format_result(cal)
    assert lines[1] == "  roll  not observable: no road plane found"
    assert lines[4].startswith("  uncertainty: circular block bootstrap, block 10 frames")
    assert "50 resamples" in lines[4]
    assert lines[5] == ("  not observable: roll (held at 0 in the fit; --write leaves them "
                        "alone)")
    assert lines[6] == "road plane: not found (too few points below the sensor)"
    # two angles not observable, one without a reason
    cal = _cal(source={"roll": "not observable", "yaw": "not observable"},
               reasons={"yaw": "no turns"})
    lines = cm.format_result(cal)
    assert lines[1] == "  roll  not observable" and lines[3] == "  yaw   not observable: no turns"
    assert lines[4] == ("  not observable: roll, yaw (held at 0 in the fit; --write leaves them "
                        "alone)")
    # a resample count reaches the "no interval" line
    cal = _cal()
    cal.interval_deg["yaw"] = (np.nan, np.nan)
    assert "no interval (50 resamples could be fitted)" in cm.format_result(cal)[3]


# ---------------------------------------------------------------- Doppler vs hand-eye


def _he(angles=(0.5, -2.0, 1.0), half=0.2, observable=None, block=None, level=0.95):
    angles = dict(zip(ANGLES, angles, strict=True))
    obs = {**dict.fromkeys(ANGLES, True), **(observable or {})}
    R = Rotation.from_euler("xyz", list(angles.values()), degrees=True).as_matrix()
    return HandEyeResult(R, angles, dict.fromkeys(ANGLES, 0.1), obs, 42, "kiss-icp",
                         {"roll": "turn axes", "pitch": "turn axes",
                          "yaw": "displacement directions"},
                         {a: (v - half, v + half) for a, v in angles.items()}, level, block,
                         60, 120)


def test_estimates_disagree_beyond_the_combined_half_widths():
    """Half-widths 0.3 (hand-eye) and 0.4 (Doppler) combine to 0.5: pitch 0.6 apart
    disagrees, yaw 0.4 apart does not; roll 5 apart is not compared when Doppler does not see
    it, nor when hand-eye does not."""
    cal = _cal(angles=(0.0, -2.0, 1.0), half=0.4)
    he = _he(angles=(0.0, -1.4, 1.4), half=0.3)
    assert cm.disagreements(he, cal) == ["pitch (+0.60 deg apart, combined +- 0.50)"]
    he = _he(angles=(0.0, -2.6, 0.6), half=0.3)
    assert cm.disagreements(he, cal) == ["pitch (-0.60 deg apart, combined +- 0.50)"]
    he = _he(angles=(5.0, -2.0, 1.0), half=0.3)
    assert cm.disagreements(he, cal) == ["roll (+5.00 deg apart, combined +- 0.50)"]
    unseen = _cal(angles=(0.0, -2.0, 1.0), half=0.4, source={"roll": "not observable"})
    assert cm.disagreements(he, unseen) == []
    he_blind = _he(angles=(5.0, -2.0, 1.0), half=0.3, observable={"roll": False})
    assert cm.disagreements(he_blind, cal) == []
    # exactly the combined half-widths apart (0.375 and 0.5 combine to 0.625): not apart
    exact = _cal(angles=(0.0, -2.0, 1.0), half=0.5)
    assert cm.disagreements(_he(angles=(0.0, -2.0, 1.625), half=0.375), exact) == []
    assert cm.disagreements(_he(angles=(0.0, -2.0, 1.6875), half=0.375), exact) == [
        "yaw (+0.69 deg apart, combined +- 0.62)"]
    # yaw, after the skipped roll, is still compared
    he_blind = _he(angles=(5.0, -2.0, 2.0), half=0.3, observable={"roll": False})
    assert [s.split()[0] for s in cm.disagreements(he_blind, cal)] == ["yaw"]


def test_no_interval_is_not_a_disagreement():
    """Hand-eye without an interval on yaw (too few resamples fitted), 1 deg from Doppler: not
    "DISAGREE beyond their stated uncertainties" (there is none) but cannot tell, as the
    verdicts say (was: "yaw (+1.00 deg apart, combined +- nan)")."""
    cal = _cal(angles=(0.0, -2.0, 1.0), half=0.1)
    he = _he(angles=(0.0, -2.0, 2.0), half=0.1)
    he.interval_deg["yaw"] = (np.nan, np.nan)
    assert cm.disagreements(he, cal) == []
    text = "\n".join(cm.format_hand_eye(he, cal))
    assert "DISAGREE" not in text
    assert "CANNOT TELL whether the two estimates agree on yaw" in text
    assert "yaw 1.00 deg apart, combined half-widths no finite interval deg" in text


def test_hand_eye_verdicts():
    """Per angle both observe: the difference hand-eye - Doppler, the combined half-width, the
    resolution (default 2 deg, the write bound) and no floor; no interval -> infinite width."""
    cal = _cal(angles=(0.0, -2.0, 1.0), half=0.4, source={"roll": "not observable"})
    he = _he(angles=(0.0, -1.4, 1.2), half=0.3)
    he.interval_deg["yaw"] = (np.nan, np.nan)
    got = cm.hand_eye_verdicts(he, cal)
    assert [v.angle for v in got] == ["pitch", "yaw"]
    assert got[0].diff_deg == pytest.approx(0.6) and got[0].combined_deg == pytest.approx(0.5)
    assert got[0].resolution_deg == 2.0 and got[0].floor_deg == 0.0 and got[0].kind == APART
    assert got[1].combined_deg == float("inf") and got[1].kind == CANNOT_TELL
    he = _he(angles=(9.0, -2.1, 1.2), half=1.5, observable={"roll": False})
    got = cm.hand_eye_verdicts(he, _cal(angles=(0.0, -2.0, 1.0), half=1.5), 2.5)
    assert [(v.angle, v.kind) for v in got] == [("pitch", AGREE), ("yaw", AGREE)]
    assert got[0].resolution_deg == 2.5
    assert [v.kind for v in cm.hand_eye_verdicts(
        he, _cal(angles=(0.0, -2.0, 1.0), half=1.5), 2.0)] == [CANNOT_TELL, CANNOT_TELL]


def test_the_hand_eye_table():
    cal = _cal(angles=(0.0, -2.0, 1.0), half=0.4, source={"yaw": "not observable"})
    he = _he(angles=(0.3, -1.9, 1.0), half=0.3, observable={"roll": False},
             block=BlockChoice(20, 1.6, 20, (8,)))
    lines = cm.format_hand_eye(he, cal, 1.5)
    assert lines[0] == ("hand-eye alignment of kiss-icp (no Doppler): R_gt_sensor from 42 "
                        "segments (turn axes first, then displacement directions):")
    assert lines[1] == ("  roll  not observable: neither the turn axes nor the displacement "
                        "directions spread around it")
    assert lines[2] == (cm._angle_line("pitch", -1.9, (-2.2, -1.6), 0.1, 0.95, "turn axes")
                        + "  difference to Doppler +0.100 deg")
    assert lines[3] == cm._angle_line("yaw", 1.0, (0.7, 1.3), 0.1, 0.95,
                                      "displacement directions")
    assert lines[4] == "  uncertainty: " + he.block.describe(
        60, 120, f"both stages refitted on each; blocks of at least {cm.HE_BLOCK_S:g} s asked")
    between = np.degrees((Rotation.from_matrix(he.R_gt_sensor)
                          * Rotation.from_matrix(cal.R_gt_sensor).inv()).magnitude())
    assert lines[5] == f"  the two rotations differ by {between:.3f} deg in all"
    assert lines[6].startswith("  the two estimates agree on pitch")
    assert lines[6].endswith("--max-width 1.5 deg")
    # no interval on the hand-eye side: how many resamples could be fitted
    he.interval_deg["pitch"] = (np.nan, np.nan)
    assert "no interval (60 resamples could be fitted)" in cm.format_hand_eye(he, cal)[2]


def test_the_hand_eye_table_judges_at_the_resolution_asked():
    """Combined half-widths 1.70 deg (1.2 each): at --max-width 1.5 the intervals cannot tell,
    at 2 they agree."""
    cal = _cal(angles=(0.0, -2.0, 1.0), half=1.2)
    he = _he(angles=(0.0, -2.1, 1.1), half=1.2)
    assert "CANNOT TELL whether the two estimates agree on roll, pitch, yaw" in \
        "\n".join(cm.format_hand_eye(he, cal, 1.5))
    assert cm.format_hand_eye(he, cal, 2.0)[-1].startswith(
        "  the two estimates agree on roll, pitch, yaw")


def test_the_hand_eye_table_says_disagree_and_names_the_angles():
    cal = _cal(angles=(0.0, -2.0, 1.0), half=0.1)
    he = _he(angles=(0.0, -1.0, 2.0), half=0.1)
    lines = cm.format_hand_eye(he, cal)
    assert len(lines) == 6  # no block: no uncertainty line
    assert lines[-1].startswith("  DISAGREE beyond their stated uncertainties in pitch (+1.00 "
                                "deg apart, combined +- 0.14), yaw (+1.00 deg apart")
    assert lines[-1].endswith(": at least one estimate is biased (Doppler: the GT's own velocity "
                              "and the road plane; hand-eye: the odometry's drift and the lever "
                              "arm), so neither is exact; check with `bench inspect` before "
                              "applying one")


# ---------------------------------------------------------------- frames and ground truth


def test_calibration_frames():
    """Default: the first half of what follows ``start``; at least 5 frames inside the
    store, start not negative."""
    assert cm.calibration_frames(100, 0, None) == (0, 50)
    assert cm.calibration_frames(100, 10, None) == (10, 55)
    assert cm.calibration_frames(100, 10, 90) == (10, 100)
    assert cm.calibration_frames(100, 0, 5) == (0, 5)
    with pytest.raises(DataError, match=r"start=0, frames=4: expected at least 5 frames "
                                        r"within the store's 100"):
        cm.calibration_frames(100, 0, 4)
    with pytest.raises(DataError, match="start=10, frames=91"):
        cm.calibration_frames(100, 10, 91)
    with pytest.raises(DataError, match="start=-1, frames=10"):
        cm.calibration_frames(100, -1, 10)
    with pytest.raises(DataError, match="frames=4"):
        cm.calibration_frames(9, 0, None)  # half of 9 is 4
    assert cm.calibration_frames(10, 0, None) == (0, 5)


class _GT:
    def __init__(self, stamps, covered):
        self.stamps = np.asarray(stamps, float)
        self.covered = covered

    def coverage_mask(self, stamps):
        return np.asarray(self.covered(np.asarray(stamps)), bool)


def _seq(gt, n=20):
    return SimpleNamespace(ground_truth=gt, stamps=np.arange(n) * 0.1 + 100.0)


def test_ground_truth_check_needs_three_covered_scans_of_the_range():
    """The range 5..14 (stamps 100.5-101.4 s): 3 covered scans pass; 2 name how many of the
    10 are covered, the GT's span and the scans'; none says no scan; no GT at all, or a GT
    without poses, is named."""
    cm._check_ground_truth(_seq(_GT([101.2, 101.4], lambda s: s >= 101.15)), "s.store", 5, 15)
    with pytest.raises(DataError) as err:
        cm._check_ground_truth(_seq(_GT([101.3, 101.35, 101.4], lambda s: s >= 101.25)),
                               "s.store", 5, 15)
    msg = str(err.value)
    assert msg.startswith("s.store: only 2 of the 10 scans of frames 5-14 has ground truth "
                          "(the store's ground truth spans 101.300-101.400 s, the scans "
                          "100.500-101.400 s)")
    assert msg.endswith("calibration needs the GT velocity at 3 or more scans: check the GT's "
                        "clock (`bench inspect` shows its coverage)")
    with pytest.raises(DataError, match=r"s.store: no scan of frames 5-14 has ground truth "
                                        r"\(the store's ground truth spans 0.000-1.000 s"):
        cm._check_ground_truth(_seq(_GT([0.0, 1.0], lambda s: s < 0)), "s.store", 5, 15)
    with pytest.raises(DataError, match=r"\(the store's ground truth has no poses, the scans"):
        cm._check_ground_truth(_seq(_GT([], lambda s: s < 0)), "s.store", 5, 15)
    with pytest.raises(DataError, match="s.store: calibration needs ground truth; this store "
                                        "has none"):
        cm._check_ground_truth(_seq(None), "s.store", 5, 15)


# ---------------------------------------------------------------- calibrate_store's flow


class _Lines:
    def __init__(self) -> None:
        self.lines: list[str] = []

    def print(self, line, highlight=True) -> None:
        assert highlight is False  # store paths and numbers printed as they are
        self.lines.append(str(line))


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """A 12-frame synthetic store (ground truth and Doppler)."""
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence

    seq = SyntheticSequence("loop", "radar-sparse", frames=12, seed=2)
    return write_store(seq, tmp_path_factory.mktemp("calib") / "s.h5")


@pytest.fixture
def flow(monkeypatch):
    """calibrate_store with its estimators replaced by hand-made results (the flow, not the
    fits): records what each was called with."""
    calls = {}
    cal = _cal(angles=(0.5, -2.0, 1.0), half=0.2, source={"roll": "not observable"})
    cal.interval_deg["yaw"] = (0.5, 1.5)  # 1 deg wide
    he = _he(angles=(0.3, -1.9, 1.25), half=0.2, observable={"yaw": False})
    cues = SimpleNamespace()

    def collect(part, min_speed, name):
        calls["collect"] = (int(part.indices[0]), len(part), min_speed, name)
        cues.n_frames = len(part)
        return cues

    def calibrate(got, bootstrap, name):
        assert got is cues
        calls["calibrate"] = (bootstrap, name)
        return cal

    def fit_pieces(got, bounds, bootstrap, name):
        assert got is cues
        calls["pieces"] = (bounds, bootstrap, name)
        return ["the pieces"]

    def format_pieces(pieces, offset, resolution):
        calls["format_pieces"] = (pieces, offset, resolution)
        return ["PIECES"]

    def hand_eye(part, bootstrap):
        calls["hand_eye"] = (int(part.indices[0]), len(part), bootstrap)
        if calls.get("hand_eye_fails"):
            raise DataError("too few turns")
        return he

    monkeypatch.setattr(cm, "collect_cues", collect)
    monkeypatch.setattr(cm, "calibrate_cues", calibrate)
    monkeypatch.setattr(cm, "fit_pieces", fit_pieces)
    monkeypatch.setattr(cm, "format_pieces", format_pieces)
    monkeypatch.setattr(cm, "piece_bounds", lambda n: [("bounds of", n)])
    monkeypatch.setattr(cm, "hand_eye_on", hand_eye)
    return SimpleNamespace(calls=calls, cal=cal, he=he)


def test_calibrate_store_estimates_on_the_asked_frames_and_says_what_write_would_apply(
        store, flow):
    out = _Lines()
    got = cm.calibrate_store(store, console=out, min_speed_mps=1.5, bootstrap=17, start=2,
                             frames=6, max_width_deg=0.5)
    assert got is flow.cal
    name = f"{store} frames 2-7"
    assert flow.calls["collect"] == (2, 6, 1.5, name)
    assert flow.calls["calibrate"] == (17, name)
    assert flow.calls["pieces"] == ([("bounds of", 6)], 17, name)
    assert flow.calls["format_pieces"] == (["the pieces"], 2, 0.5)
    assert flow.calls["hand_eye"] == (2, 6, 17)
    assert out.lines[0] == (f"{store}: estimating on frames 2-7 of 12 (runs on a corrected "
                            "store score only the others)")
    assert out.lines[1:1 + len(cm.format_result(flow.cal))] == cm.format_result(flow.cal)
    assert "PIECES" in out.lines
    table = cm.format_hand_eye(flow.he, flow.cal, 0.5)
    start = out.lines.index(table[0])
    assert out.lines[start:start + len(table)] == table
    assert table[-1].endswith("--max-width 0.5 deg")  # pitch agrees at that resolution
    assert not any(line.startswith("note: every frame") for line in out.lines)
    # the Doppler estimate's angles with intervals narrower than 0.5 deg: pitch only
    assert out.lines[-1] == ("--write would apply the angles whose 95 % interval is narrower "
                             "than 0.5 deg (--max-width): pitch -2.000; left alone (0 in the "
                             "written rotation): roll (not observable), yaw (interval 1.00 deg "
                             "wide, not narrower than 0.5)")
    # 2 + 8 frames of 12: not every frame
    out = _Lines()
    cm.calibrate_store(store, console=out, start=2, frames=8)
    assert not any(line.startswith("note: every frame") for line in out.lines)


def test_calibrate_store_defaults_and_every_frame_used(store, flow):
    """Defaults: the first half, 200 resamples, 2 m/s; all 12 frames asked: a note that none
    is left to score; without a console nothing is printed."""
    cm.calibrate_store(store)
    assert flow.calls["collect"] == (0, 6, 2.0, f"{store} frames 0-5")
    assert flow.calls["calibrate"][0] == 200 and flow.calls["hand_eye"][2] == 200
    assert flow.calls["format_pieces"][2] == 2.0
    out = _Lines()
    cm.calibrate_store(store, console=out, frames=12)
    assert ("note: every frame is used, so runs on a corrected store have none to score"
            in out.lines)


def test_calibrate_store_hand_eye_only_when_asked_or_applied(store, flow):
    """hand_eye=False: no hand-eye fit with --apply doppler, one with --apply hand-eye; a
    hand-eye that cannot be fitted is a printed note for --apply doppler, the error for
    --apply hand-eye."""
    cm.calibrate_store(store, hand_eye=False)
    assert "hand_eye" not in flow.calls
    out = _Lines()
    cm.calibrate_store(store, console=out, hand_eye=False, apply="hand-eye")
    assert "hand_eye" in flow.calls
    # the hand-eye estimate's observable angles narrower than 2 deg: roll and pitch
    assert out.lines[-1].startswith("--write would apply the angles whose 95 % interval is "
                                    "narrower than 2 deg (--max-width): roll +0.300, pitch "
                                    "-1.900; left alone (0 in the written rotation): yaw (not "
                                    "observable)")
    flow.calls["hand_eye_fails"] = True
    out = _Lines()
    cm.calibrate_store(store, console=out)
    assert ("hand-eye alignment (no Doppler): not possible here: too few turns" in out.lines)
    assert not any(line.startswith("hand-eye alignment of") for line in out.lines)
    with pytest.raises(DataError, match="too few turns"):
        cm.calibrate_store(store, apply="hand-eye")


def test_calibrate_store_refuses_an_unknown_estimate(store, flow):
    with pytest.raises(DataError, match=r"--apply 'both': choose from doppler, hand-eye"):
        cm.calibrate_store(store, apply="both")
    assert flow.calls == {}


@pytest.mark.parametrize("width", [0.0, -1.0, float("nan"), float("inf")])
def test_calibrate_store_refuses_a_max_width_that_is_not_a_positive_number(store, flow, width):
    with pytest.raises(DataError, match=rf"--max-width {width}: expected a positive number of "
                                        "degrees"):
        cm.calibrate_store(store, max_width_deg=width)
    assert flow.calls == {}


def test_calibrate_store_refuses_a_store_without_doppler(flow, tmp_path):
    """A store whose scans carry no Doppler: the words bench run refuses it with, naming the
    store and "calibration from Doppler"; nothing is estimated."""
    from loaders.scan import MemorySequence, Scan
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence

    seq = SyntheticSequence("loop", "radar-sparse", frames=8, seed=2)
    plain = MemorySequence("p", seq.sensor, [Scan(s.stamp, s.points) for s in seq],
                           seq.ground_truth, {})
    path = write_store(plain, tmp_path / "plain.h5")
    with pytest.raises(DataError, match=rf"^{path}: calibration from Doppler needs Doppler, "
                                        "but the store has no Doppler values"):
        cm.calibrate_store(path)
    assert flow.calls == {}


def test_calibrate_store_checks_the_ground_truth_of_the_asked_frames(flow, tmp_path):
    """GT 1000 s after the scans: the store and the frames asked are named."""
    from loaders.scan import MemorySequence
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence
    from loaders.trajectory import Trajectory

    seq = SyntheticSequence("loop", "radar-sparse", frames=12, seed=2)
    gt = seq.ground_truth
    late = MemorySequence("l", seq.sensor, list(seq), Trajectory(gt.stamps + 1000.0, gt.poses),
                          {})
    path = write_store(late, tmp_path / "late.h5")
    with pytest.raises(DataError, match=rf"^{path}: no scan of frames 3-8 has ground truth"):
        cm.calibrate_store(path, start=3, frames=6)
    assert flow.calls == {}


def test_calibrate_store_write_below_a_file_is_refused_naming_the_option(store, flow, tmp_path):
    (tmp_path / "f").write_text("a file")
    target = tmp_path / "f" / "out.h5"
    with pytest.raises(DataError, match=rf"^--write {target}: {tmp_path / 'f'} is a file; "
                                        "expected a folder"):
        cm.calibrate_store(store, target)


def test_calibrate_store_writes_the_chosen_estimates_applied_angles(store, flow, tmp_path):
    """--write with --apply hand-eye: the GT turned by the applied angles only (yaw left at
    0), the provenance naming the estimate, both estimates' angles, what was left alone, the
    bound and the frames used."""
    from bench.data.calibration.write import applied_rotation
    from loaders.store import StoreSequence

    out = _Lines()
    target = tmp_path / "fixed.h5"
    cm.calibrate_store(store, target, console=out, start=1, frames=5, apply="hand-eye",
                       max_width_deg=1.5)
    fixed, original = StoreSequence(target), StoreSequence(store)
    try:
        c = fixed.provenance["calibration"]
        assert c["applied_estimate"] == "hand-eye"
        assert c["frames"] == [1, 6]
        assert c["doppler_rpy_deg"] == [0.5, -2.0, 1.0]
        assert c["hand_eye_rpy_deg"] == [0.3, -1.9, 1.25]
        assert c["applied_rpy_deg"] == [0.3, -1.9, 0.0]
        assert c["left_alone"] == {"yaw": "not observable"}
        assert c["max_width_deg"] == 1.5
        R = applied_rotation({"roll": 0.3, "pitch": -1.9})
        np.testing.assert_allclose(c["R_gt_sensor"], R, atol=1e-12)
        T = np.eye(4)
        T[:3, :3] = R
        np.testing.assert_allclose(fixed.ground_truth.poses[3],
                                   original.ground_truth.poses[3] @ T, atol=1e-9)
    finally:
        fixed.close()
        original.close()
    assert out.lines[-2].startswith("--write applies the angles whose 95 % interval")
    assert out.lines[-1] == (f"wrote {target} (ground truth and extrinsic corrected by the "
                             "hand-eye estimate's applied angles, points unchanged; frames 1-5 "
                             "are not scored)")
    # without hand-eye: no hand-eye angles recorded; an existing one replaced with force
    cm.calibrate_store(store, target, hand_eye=False, force=True)
    fixed = StoreSequence(target)
    try:
        assert "hand_eye_rpy_deg" not in fixed.provenance["calibration"]
        assert fixed.provenance["calibration"]["applied_estimate"] == "doppler"
    finally:
        fixed.close()
    with pytest.raises(DataError, match="exists"):
        cm.calibrate_store(store, target, hand_eye=False)
