"""What ``bench calibrate --write`` applies and where it may write
(bench.data.calibration.write): angles narrower than the bound only, the rotation they make
(checked against scipy), the sentence saying so, and the target rules (never the input, an
existing file only with --force and only a store bench calibrate wrote)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.data.calibration.estimate import CorrectedSequence
from bench.data.calibration.write import (
    WRITE_MAX_WIDTH_DEG,
    applied_rotation,
    check_write_target,
    describe_selection,
    select_angles,
    written_by_calibrate,
)
from loaders.errors import DataError

ANGLES = {"roll": 0.5, "pitch": -2.0, "yaw": 1.25}
FITTED = dict.fromkeys(ANGLES, True)


def test_an_angle_is_applied_only_when_fitted_and_narrower_than_the_bound():
    """Bound 1 deg: widths 0.75 (applied), exactly 1.0 (not narrower: left, with its width),
    NaN (no interval); an angle not fitted, or missing from ``fitted``, is not observable even
    with a narrow interval; the default bound is WRITE_MAX_WIDTH_DEG = 2 deg."""
    intervals = {"roll": (0.0, 1.0), "pitch": (-2.375, -1.625), "yaw": (np.nan, np.nan)}
    applied, left = select_angles(ANGLES, intervals, FITTED, 1.0)
    assert applied == {"pitch": -2.0}
    assert isinstance(applied["pitch"], float)
    assert left == {"roll": "interval 1.00 deg wide, not narrower than 1",
                    "yaw": "no interval"}
    applied, left = select_angles(ANGLES, intervals, {"roll": True, "pitch": False}, 1.0)
    assert applied == {}
    assert left == {"roll": "interval 1.00 deg wide, not narrower than 1",
                    "pitch": "not observable", "yaw": "not observable"}
    # the default bound: 1.0 and 0.75 wide are both narrower than 2
    assert WRITE_MAX_WIDTH_DEG == 2.0
    assert select_angles(ANGLES, intervals, FITTED) == ({"roll": 0.5, "pitch": -2.0},
                                                        {"yaw": "no interval"})
    just = {"roll": (0.0, 2.0), "pitch": (-3.0, -1.0 - 1e-9), "yaw": (1.0, 1.5)}
    applied, left = select_angles(ANGLES, just, FITTED)
    assert applied == {"pitch": -2.0, "yaw": 1.25}
    assert left == {"roll": "interval 2.00 deg wide, not narrower than 2"}
    # an angle without an interval entry is treated as having none
    applied, left = select_angles(ANGLES, {"pitch": (-2.1, -1.9)}, FITTED, 1.0)
    assert applied == {"pitch": -2.0} and left == {"roll": "no interval", "yaw": "no interval"}


def test_the_applied_rotation_is_rz_ry_rx_of_the_applied_angles():
    """Checked against scipy (intrinsic ZYX = Rz Ry Rx); an angle left alone is 0."""
    R = applied_rotation(ANGLES)
    ref = Rotation.from_euler("ZYX", [1.25, -2.0, 0.5], degrees=True).as_matrix()
    np.testing.assert_allclose(R, ref, atol=1e-12)
    ref = Rotation.from_euler("ZYX", [0.0, -2.0, 0.0], degrees=True).as_matrix()
    np.testing.assert_allclose(applied_rotation({"pitch": -2.0}), ref, atol=1e-12)
    np.testing.assert_allclose(applied_rotation({}), np.eye(3), atol=0)


def test_the_selection_sentence_names_the_level_bound_angles_and_reasons():
    text = describe_selection({"pitch": -2.0, "yaw": 1.25}, {"roll": "no interval"}, 1.5, 0.9)
    assert text == ("--write applies the angles whose 90 % interval is narrower than 1.5 deg "
                    "(--max-width): pitch -2.000, yaw +1.250; left alone (0 in the written "
                    "rotation): roll (no interval)")
    text = describe_selection({}, {"roll": "not observable", "yaw": "no interval"}, 2.0, 0.95)
    assert text.endswith("(--max-width): none; left alone (0 in the written rotation): roll "
                         "(not observable), yaw (no interval)")
    assert describe_selection({"roll": 0.5}, {}, 2.0, 0.95) == (
        "--write applies the angles whose 95 % interval is narrower than 2 deg (--max-width): "
        "roll +0.500")


@pytest.fixture(scope="module")
def stores(tmp_path_factory):
    """A plain store and one bench calibrate wrote (its provenance has a calibration)."""
    from loaders.store import write_store
    from loaders.synthetic import SyntheticSequence

    folder = tmp_path_factory.mktemp("write")
    seq = SyntheticSequence("loop", "radar-sparse", frames=6, seed=1)
    plain = write_store(seq, folder / "plain.h5")
    made = write_store(CorrectedSequence(seq, np.eye(3), (0, 3)), folder / "made.h5")
    return plain, made


def test_which_files_bench_calibrate_wrote(stores, tmp_path):
    import h5py

    from loaders.store import FORMAT_NAME

    plain, made = stores
    assert written_by_calibrate(made) is True
    assert written_by_calibrate(plain) is False
    notes = tmp_path / "notes.txt"
    notes.write_text("mine")
    assert written_by_calibrate(notes) is False
    assert written_by_calibrate(tmp_path / "absent.h5") is False
    # an HDF5 file that claims the format but holds no store
    fake = tmp_path / "fake.h5"
    with h5py.File(fake, "w") as f:
        f.attrs["format"] = FORMAT_NAME
    assert written_by_calibrate(fake) is False


def test_never_the_input_store(stores, tmp_path):
    import os

    plain, _ = stores
    (tmp_path / "sub").mkdir()
    os.link(plain, tmp_path / "hard.h5")  # the same file by another name
    for target in (plain, tmp_path / "sub" / ".." / ".." / plain.parent.name / plain.name,
                   tmp_path / "hard.h5"):
        for force in (False, True):
            with pytest.raises(DataError, match=r"never writes onto its own input \(not even "
                                                r"with --force\): give another path$"):
                check_write_target(plain, target, force)
    # the input does not exist yet: the paths are compared
    with pytest.raises(DataError, match=r"that is the input store .*a\.h5"):
        check_write_target(tmp_path / "a.h5", tmp_path / "sub" / ".." / "a.h5", True)
    check_write_target(tmp_path / "a.h5", tmp_path / "b.h5", False)


def test_an_existing_target_only_with_force_and_only_a_calibrated_store(stores, tmp_path):
    plain, made = stores
    source = tmp_path / "in.h5"
    check_write_target(source, tmp_path / "new.h5", False)  # a new file: fine
    with pytest.raises(DataError, match=r"--write .*: is a folder"):
        check_write_target(source, tmp_path, True)
    with pytest.raises(DataError, match=r"exists; give another path, or --force to replace a "
                                        r"store bench calibrate wrote$"):
        check_write_target(source, made, False)
    check_write_target(source, made, True)
    for other in (plain, tmp_path / "notes.txt"):
        other.touch()
        with pytest.raises(DataError, match=r"exists and is not a store bench calibrate wrote; "
                                            r"--force replaces only those: give another path$"):
            check_write_target(source, other, True)
