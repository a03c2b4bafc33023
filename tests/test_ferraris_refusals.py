"""A Ferraris set the method cannot take whole is refused or cut to what it can give, saying why in one
line: a pose commanded off its pair is named with its fix (not left to the exact fit, which cannot take six
poses), and a missing turn drops the gyro alone, naming the axis to turn about. imucal's real session, its
segments.csv or turns edited, and sessions simulated by tests/test_ferraris_tilt.py."""
import json
from pathlib import Path

import numpy as np
import pytest

from simucal import io
from simucal.api import calibrate
from simucal.errors import CalibrationError
from simucal.io.importers import import_ferraris_sections

from cli_helpers import refused, run
from test_ferraris_tilt import ferraris_session

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """imucal's example session as imported: six poses (segments 1-6), turns about x, y, z (7-9)."""
    out = tmp_path_factory.mktemp("ferraris") / "example"
    import_ferraris_sections(DATA / "example_ferraris_session.csv", DATA / "example_ferraris_session_list.json",
                             out, 102.4, 49.6)
    return out


def _edited(session, folder, pose_middle_deg=None, drop_segment=None):
    """A copy of the session with segment 3's middle angle changed, or one segment and its rows dropped."""
    ms = io.read_set(session)
    segs = [s for s in ms.segments if s.segment != drop_segment]
    if pose_middle_deg is not None:
        segs = [io.Segment(s.segment, s.kind, s.outer_deg, pose_middle_deg, s.inner_deg, s.outer_rate_dps)
                if s.segment == 3 else s for s in segs]
    keep = ms.samples["segment"] != drop_segment
    io.write_set(folder, ms.meta, {k: v[keep] for k, v in ms.samples.items()}, segs)
    return folder


OFF_PAIR = ("segments.csv: the six static poses are no longer three opposite pairs", "segment 3 is commanded at "
            "middle_deg 45, inner_deg 0", "command segment 3 at middle_deg 90, inner_deg 0 (the opposite of segment 4)")


@pytest.mark.parametrize("method", [None, "ferraris"])
def test_a_pose_commanded_off_its_pair_is_named_with_its_fix(session, tmp_path, method):
    """Pose y_p commanded at 45 deg instead of 90: its accelerometer still reads it opposite y_a, so the
    command is wrong: named, with the angles that fix it (the exact fit used to stop at 'did not converge ...
    add positions'); nothing written."""
    s = _edited(session, tmp_path / "s", pose_middle_deg=45.0)
    r = run("calibrate", s, "-o", tmp_path / "cal.json", *(["--method", method] if method else []))
    refused(r, *OFF_PAIR, "reads gravity 172 deg from it")
    assert "converge" not in r.stderr and not (tmp_path / "cal.json").exists()
    with pytest.raises(CalibrationError, match="command segment 3 at middle_deg 90, inner_deg 0"):
        calibrate(s, method=method or "auto")


def test_a_pose_placed_off_its_pair_is_told_the_method_that_takes_it(tmp_path):
    """The hand placed y_p at 45 deg and segments.csv says so: the data agree, so the poses are not opposite
    (not a command to fix): placed opposite, or calibrated by the multi-position method."""
    ms, _ = ferraris_session(0, pose_45="y_p", placed_45=True)
    with pytest.raises(CalibrationError) as e:
        calibrate(ms)
    line = str(e.value)
    assert "\n" not in line
    assert "segments 4 and 6 are commanded 135 deg apart (the accelerometer agrees: 137 deg)" in line
    assert line.endswith("place segment 4 opposite segment 6 (middle_deg 90, inner_deg 0), or calibrate by the "
                         "commanded attitudes: --method multiposition")
    assert calibrate(ms, method="multiposition").acc is not None  # the method it names takes it


def test_a_missing_turn_drops_the_gyro_alone_naming_the_axis(session, tmp_path):
    """No turn about z: the accelerometer (the six poses fix it) calibrated and written, the gyro NOT
    CALIBRATED with the turn to add (both used to be refused: 'the 8 gyro input directions lie in one plane')."""
    s = _edited(session, tmp_path / "s", drop_segment=9)
    r = run("calibrate", s, "-o", tmp_path / "cal.json")
    assert r.exit_code == 0, r.output
    why = ("the turns are about x and y only (segments 7, 8): the Ferraris gyro matrix needs a turn about each axis; "
           "add a turn about z")
    assert f"gyro: NOT CALIBRATED: {why}" in r.output and "one plane" not in r.output
    written = json.loads((tmp_path / "cal.json").read_text())
    assert "gyro" not in written and written["not_calibrated"]["gyro"].startswith(why)
    whole = calibrate(session)
    assert np.array_equal(written["acc"]["M"], whole.acc.M.tolist())  # the accelerometer as with every turn
    cal = calibrate(s)
    assert cal.gyro is None and cal.not_calibrated["gyro"].startswith(why) and cal.acc is not None


def test_one_turn_names_both_missing_axes():
    ms, _ = ferraris_session(0, turns="x")
    cal = calibrate(ms)
    assert cal.acc is not None and "add a turn about y and z" in cal.not_calibrated["gyro"]
