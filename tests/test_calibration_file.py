"""The calibration file as one typed object (issue 25): every method returns a Calibration, whose
JSON is read back to the same object; apply and validate take it as loaded."""
import json
import types
import typing
from pathlib import Path

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
from simucal.io.importers import import_ferraris_sections
from simucal.api import simulate
from simucal.turntable.sequence import psins19


@pytest.fixture(scope="module")
def every_method(paper_set, tmp_path_factory):
    """{method: its calibration} of a set of the data each takes."""
    tmp = tmp_path_factory.mktemp("methods")
    write_handheld(tmp / "h", HandheldScenario(), 0)
    write_field(tmp / "f", FieldScenario(), 0)
    (tmp / "seq.csv").write_text("axis,angle_deg,rate_dps,rest_s\n" + "".join(  # psins19 with 30 s rests
        f"{s.axis},{s.angle_deg},{s.rate_dps},30\n" for s in psins19()))
    simulate(sequence=tmp / "seq.csv").write(tmp / "q")
    data = {methods.TURNTABLE: paper_set[0], methods.STREAM: tmp / "h", methods.FIELD: tmp / "f",
            methods.SEQUENCE: tmp / "q"}
    ferraris = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"  # a protocol's own plan
    import_ferraris_sections(ferraris / "example_ferraris_session.csv", ferraris / "example_ferraris_session_list.json",
                             tmp / "fe", 102.4, 49.6)
    return {m.name: calibrate(data[m.data] if m.any_plan else tmp / "fe", m.name) for m in methods.METHODS.values()}


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
        assert set(written["formula"]) == set(cal.sensors)
        assert all(written[s]["chi2"] is None or isinstance(written[s]["chi2"], float) for s in cal.sensors)


def test_what_a_method_reports_beyond_the_fields_travels_as_details(every_method):
    exact = every_method["exact"]
    assert "test" in exact.acc.details and "noise" in exact.acc.details  # the model test
    assert "consistency" in exact.details and exact.unification is not None
    written = exact.to_json()
    assert written["acc"]["test"] == exact.acc.details["test"] and written["consistency"] == exact.details["consistency"]
    field = every_method["field"]
    assert field.acc.nominal and "acc" in field.not_calibrated and field.details["field"]["gyro_drift_dph"]
    assert field.gyro.library_effects() == ()


def test_every_key_a_method_writes_in_a_block_is_declared(every_method, tmp_path):
    """SensorBlock.details is typed (io.calibration.SensorDetails): every method's blocks, --add auto's
    and a hand-placed session's included, hold only declared keys, each of its declared type's kind."""
    declared = typing.get_type_hints(calibration.SensorDetails)
    kinds = {k: tuple(typing.get_origin(a) or a for a in (typing.get_args(t) if typing.get_origin(t) in
                      (typing.Union, types.UnionType) else (t,))) for k, t in declared.items()}
    cals = dict(every_method)
    cals["exact --add auto"] = calibrate(every_method["exact"].input, add=("auto",))
    for name, cal in cals.items():
        for s, block in cal.blocks():
            unknown = set(block.details) - set(declared)
            assert not unknown, f"{name} {s}: {unknown} not in SensorDetails"
            wrong = {k: type(v).__name__ for k, v in block.details.items() if not isinstance(v, kinds[k])}
            assert not wrong, f"{name} {s}: {wrong} not of the declared types"
    assert {"auto", "auto_stopped", "cross_validation"} <= set(cals["exact --add auto"].acc.details)
    assert {"T", "moves", "gyro_model"} <= set(cals["handheld"].gyro.details)


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


@pytest.mark.parametrize("edit,exit_code,words", [
    (lambda d: d["acc"].pop("bias_unit"), 0, ""),  # not needed to apply: read as the sensor's unit
    (lambda d: d.pop("input_sha256"), 0, ""),
    (lambda d: d.pop("method"), 0, ""),
    (lambda d: (d["layout"].__setitem__("sensors", ["gyro"]), d["acc"].__setitem__("M", "x")), 2, "calibrates no acc"),
    (lambda d: d["acc"].__setitem__("thermal", None), 2, "acc.thermal must be an object"),
    (lambda d: d["acc"].__setitem__("model", None), 2, "is not a model's name"),
    (lambda d: d["acc"].__setitem__("model", "acc_nowhere"), 2, "no model 'acc_nowhere'"),
    (lambda d: d["acc"].__setitem__("param_units", [1, 2]), 2, "acc.param_units must be an object"),
])
def test_a_hand_edited_file_is_read_or_refused_in_one_line(paper_set, tmp_path, edit, exit_code, words):
    """Issue 25's review: the typed object never turns an edited file into an internal error."""
    from click.testing import CliRunner

    from simucal.cli import main
    d = _as_written(calibrate(paper_set[0]))
    edit(d)
    (tmp_path / "c.json").write_text(json.dumps(d))
    r = CliRunner().invoke(main, ["apply", str(tmp_path / "c.json"), str(paper_set[0]), "-o", str(tmp_path / "out")])
    assert r.exit_code == exit_code and words in r.output, r.output


def test_multiposition_without_rate_runs_says_the_gyro_is_not_calibrated(paper_set, tmp_path):
    """A set whose rate runs are gone: the file names the gyro under not_calibrated (before, it named a gyro
    block it did not have), and apply refuses the data's gyro in one line."""
    from simucal import io
    from simucal.fit.apply import apply
    ms = io.read_set(paper_set[0])
    keep = [s for s in ms.segments if s.kind == "static"]
    rows = np.isin(ms.samples["segment"], [s.segment for s in keep])
    io.write_set(tmp_path / "s", ms.meta, {k: v[rows] for k, v in ms.samples.items()}, keep)
    cal = calibrate(tmp_path / "s", "multiposition")
    assert cal.gyro is None and "gyro" in cal.not_calibrated and cal.sensors == ["acc"]
    calibration.save(tmp_path / "c.json", cal)
    with pytest.raises(calibration.CalibrationFileError, match="calibrates no gyro"):
        apply(calibration.load(tmp_path / "c.json"), tmp_path / "s")
