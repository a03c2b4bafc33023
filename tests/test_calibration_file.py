"""The calibration file as one typed object (issue 25): every method returns a Calibration, whose
JSON is read back to the same object; apply and validate take it as loaded."""
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simucal import methods
from simucal.calibrate import calibrate
from simucal.field.simulate import FieldScenario, write_field
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.io import calibration
from simucal.io.calibration import Calibration, EffectValue, SensorBlock


@pytest.fixture(scope="module")
def every_method(paper_set, tmp_path_factory):
    """{method: its calibration} of a set of the data each takes."""
    tmp = tmp_path_factory.mktemp("methods")
    write_handheld(tmp / "h", HandheldScenario(), 0)
    write_field(tmp / "f", FieldScenario(), 0)
    data = {methods.TURNTABLE: paper_set[0], methods.STREAM: tmp / "h", methods.FIELD: tmp / "f"}
    return {m.name: calibrate(data[m.data], m.name) for m in methods.METHODS.values()}


def _as_written(cal: Calibration) -> dict:
    return json.loads(json.dumps(cal.to_json(), default=float))


def test_every_method_returns_the_typed_calibration_and_its_json_reads_back_the_same(every_method, tmp_path):
    assert set(every_method) == set(methods.NAMES)
    for name, cal in every_method.items():
        assert isinstance(cal, Calibration) and cal.format == calibration.FORMAT
        for s, block in cal.blocks():
            assert isinstance(block, SensorBlock) and block.M.shape == (3, 3) and block.bias.shape == (3,)
            assert all(isinstance(e, EffectValue) for e in block.effects.values())
        written = _as_written(cal)
        assert _as_written(Calibration.from_json(written)) == written, name
        calibration.save(tmp_path / f"{name}.json", cal)
        back = calibration.load(tmp_path / f"{name}.json")
        assert _as_written(back) == written, name
        assert set(written["formula"]) == set(cal.sensors) and written["residual_rms"].keys() == dict(cal.blocks()).keys()


def test_what_a_method_reports_beyond_the_fields_travels_as_details(every_method):
    exact = every_method["exact"]
    assert "test" in exact.acc.details and "noise" in exact.acc.details  # the model test
    assert "consistency" in exact.details and exact.unification is not None
    written = exact.to_json()
    assert written["acc"]["test"] == exact.acc.details["test"] and written["consistency"] == exact.details["consistency"]
    field = every_method["field"]
    assert field.acc.nominal and "acc" in field.not_calibrated and field.details["field"]["gyro_drift_dph"]
    assert field.gyro.library_effects() == ()


finite = st.floats(-1e3, 1e3, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(M=st.lists(finite, min_size=9, max_size=9), bias=st.lists(finite, min_size=3, max_size=3),
       value=finite, std=st.floats(0, 1e3), p=st.one_of(st.none(), st.floats(0, 1)),
       term_of=st.one_of(st.none(), st.just("acc_mine")), extra=st.dictionaries(
           st.sampled_from(["note", "advice", "rows"]), st.one_of(st.none(), st.text(max_size=8), finite)))
def test_any_block_round_trips(M, bias, value, std, p, term_of, extra):
    block = SensorBlock("acc_baseline", np.reshape(M, (3, 3)), bias, "g",
                        {"acc.quadratic.z": EffectValue(value, std, "g/g^2", "z quadratic", term_of)},
                        params={"b_x": bias[0]}, std={"b_x": std}, p_value=p, details=dict(extra))
    cal = Calibration("exact", "set", "0" * 64, {"sensors": ["acc"]}, acc=block, warnings=["w"])
    written = _as_written(cal)
    back = Calibration.from_json(written)
    assert _as_written(back) == written
    assert np.array_equal(back.acc.M, np.reshape(M, (3, 3))) and back.acc.p_value == p
    assert back.acc.library_effects() == (() if term_of else ("acc.quadratic.z",))
