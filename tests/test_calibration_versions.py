"""Calibration files of every earlier format, as earlier revisions of main wrote them (tests/data/
calibration_versions/REV: the file and the set it was calibrated from), load and apply as today's
calibration of the same set does; format 1's layout comes from its set, refused in one line without it."""
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import simucal
from simucal.io.calibration_checks import CalibrationFileError

DATA = Path(__file__).parent / "data" / "calibration_versions"
REVISIONS = {"fb97a28": "simucal.calibration/1", "c5dfbac": "simucal.calibration/2",  # the first of format 2
             "5a6e85c": "simucal.calibration/2", "b1bf6b5": "simucal.calibration/2"}  # typed object; later keys


def test_every_format_version_is_held_here():
    """A file of each format a revision ever wrote (the readers' steps and today's)."""
    from simucal.io.calibration import FORMAT
    from simucal.io.calibration_versions import STEPS
    assert set(REVISIONS.values()) == set(STEPS) | {FORMAT}
    for rev, fmt in REVISIONS.items():
        assert json.loads((DATA / rev / "calibration.json").read_text())["format"] == fmt


@pytest.mark.parametrize("rev", REVISIONS)
def test_an_earlier_revisions_file_applies_as_todays_calibration(rev):
    """Against today's calibration of the same set (which uses more rows, and unifies the frames on the rate runs'
    means where earlier revisions took the static pairs): each parameter within 3 of today's stds, the gyro frame's
    rotation within 3 stds of the two pairings' difference (today's cross-check), the applied outputs within what
    those allow, and the validation at the noise floor."""
    cal = simucal.load(DATA / rev / "calibration.json")
    today = simucal.calibrate(DATA / rev / "set")
    for sensor in ("acc", "gyro"):
        old, new = getattr(cal, sensor), getattr(today, sensor)
        assert old.params.keys() == new.params.keys(), sensor
        for name in new.params:
            assert abs(old.params[name] - new.params[name]) < 3 * new.std[name], (sensor, name)
    phi_x = np.array(today.gyro.C_b_model).T @ np.array(cal.gyro.C_b_model) - np.eye(3)  # C_old = C_new (I + [phi x])
    phi_rad = np.array([phi_x[2, 1], phi_x[0, 2], phi_x[1, 0]])
    std_rad = np.array(today.unification["cross_check"]["difference_std_rad"])  # static pairs' less rate runs'

    assert np.all(np.abs(phi_rad) < 3 * std_rad), (phi_rad, std_rad)
    ms = simucal.read_set(DATA / rev / "set")
    old, new = simucal.apply_set(cal, ms), simucal.apply_set(today, ms)
    for column in ("ax", "ay", "az"):
        assert np.allclose(old.samples[column], new.samples[column], rtol=0, atol=1e-4), column
    rate_dph = np.linalg.norm([new.samples[c] for c in ("gx", "gy", "gz")], axis=0)
    for column in ("gx", "gy", "gz"):  # a frame's rotation phi moves an output by up to |phi| |w|
        assert np.all(np.abs(old.samples[column] - new.samples[column]) < 0.05 + 3 * std_rad.max() * rate_dph), column
    assert set(simucal.validate(cal, ms).verdict.values()) == {"at the noise floor"}


def test_a_format_1_file_saved_again_is_todays_format_and_needs_its_set_no_more(tmp_path):
    shutil.copy(DATA / "fb97a28" / "calibration.json", tmp_path / "old.json")
    with pytest.raises(CalibrationFileError, match="holds no layout.*neither beside the file nor in the working"):
        simucal.load(tmp_path / "old.json")
    assert (tmp_path / "old.json").read_bytes() == (DATA / "fb97a28" / "calibration.json").read_bytes()
    shutil.copytree(DATA / "c5dfbac" / "set", tmp_path / "set")  # the same unit, another simulator's bytes
    with pytest.raises(CalibrationFileError, match="is not the set it was calibrated from"):
        simucal.load(tmp_path / "old.json")
    shutil.rmtree(tmp_path / "set")
    shutil.copytree(DATA / "fb97a28" / "set", tmp_path / "set")
    simucal.save(tmp_path / "new.json", simucal.load(tmp_path / "old.json"))
    shutil.rmtree(tmp_path / "set")
    new = simucal.load(tmp_path / "new.json")
    assert json.loads((tmp_path / "new.json").read_text())["format"] == "simucal.calibration/2"
    assert new.layout["acc_unit"] == "pulse/s" and new.gyro.C_b_model is not None


def test_a_newer_or_unknown_format_is_refused_naming_the_ones_read(tmp_path):
    d = json.loads((DATA / "b1bf6b5" / "calibration.json").read_text())
    (tmp_path / "new.json").write_text(json.dumps({**d, "format": "simucal.calibration/3"}))
    with pytest.raises(CalibrationFileError, match=r"format 'simucal.calibration/3', expected "
                                                   r"'simucal.calibration/2' or an earlier one "
                                                   r"\(simucal.calibration/1\)"):
        simucal.load(tmp_path / "new.json")
