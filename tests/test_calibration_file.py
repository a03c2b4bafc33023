"""The calibration file as one typed object: every method returns a Calibration, whose
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
from simucal.api.calibrating import calibrate, calibrate_thermal
from simucal.field.simulate import FieldScenario, write_field
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.io import calibration, details, records
from simucal.io import MeasurementSet
from simucal.io.calibration import Calibration, EffectValue, SensorBlock
from simucal.io.importers import import_ferraris_sections
from simucal.api import simulate
from simucal.turntable.sequence import psins19

CUBIC = ("from simucal.derive.frames import f_b\nfrom simucal.derive.models import Term\n"  # a term no library has
         "from simucal.derive.models.baseline import ACC_BASELINE\n"
         "MODELS = [ACC_BASELINE.with_terms('acc_cubic_truth',\n"
         "                               [Term('K3_x', 'x', f_b[0] ** 3, 'g/g^3', 'x cubic')])]\n")


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
    return {m.name: calibrate(data[m.data] if m.any_plan else tmp / "fe", method=m.name)
            for m in methods.METHODS.values()}


@pytest.fixture(scope="module")
def thermal_calibrations():
    """{kind: its thermal calibration}: turntable plateaus (fitted jointly) and a still warm-up log
    (handheld/warmup.py). The plateaus of a hand-placed unit, each fitted alone, write the records mypy
    checks in calibrate._thermal_block (no simulator writes such plateaus)."""
    plateaus = [simulate(seed=i, plan="fibonacci24", temperature_c=T, t_ref_c=25.0) for i, T in enumerate((0, 25, 50))]
    t = np.arange(0, 600.0, 0.1)
    T = 15 + 40 * (1 - np.exp(-t / 200.0))
    rng = np.random.default_rng(0)
    acc = np.array([0, 0, -1.0]) + 1e-4 * (T - 30)[:, None] + rng.normal(0, 2e-3, (len(t), 3))
    gyro = 2.0 * (T - 30)[:, None] + rng.normal(0, 180.0, (len(t), 3))
    still = MeasurementSet.from_arrays(acc, gyro, acc_unit="g", gyro_unit="deg/h", t_s=t, temp_c=T,
                                       meta={"latitude_deg": 47.0})
    return {"thermal joint": calibrate_thermal(plateaus), "thermal warm-up": calibrate_thermal([still])}


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
    assert (written["acc"]["test"] == exact.acc.details["test"]
            and written["consistency"] == exact.details["consistency"])
    field = every_method["field"]
    assert field.acc.nominal and "acc" in field.not_calibrated and field.details["field"]["gyro_drift_dph"]
    assert field.gyro.library_effects() == ()


def _undeclared(value, declared, where: str) -> list[str]:
    """Where the JSON value breaks its declared type (io/records.py): a key a TypedDict does not declare,
    or a value of another kind, at any depth."""
    origin, args = typing.get_origin(declared), typing.get_args(declared)
    if declared is typing.Any or declared is object:
        return [f"{where}: declared Any"]
    if isinstance(declared, typing.ForwardRef) or declared == "JSONValue":
        return []
    if typing.is_typeddict(declared):
        if not isinstance(value, dict):
            return [f"{where}: {type(value).__name__}, not an object"]
        hints = typing.get_type_hints(declared, localns=vars(records))  # JSONValue: its forward reference
        return [f"{where}.{k}: not declared in {declared.__name__}" for k in value if k not in hints] + [
            e for k, v in value.items() if k in hints for e in _undeclared(v, hints[k], f"{where}.{k}")]
    if origin in (typing.Union, types.UnionType):
        found = [_undeclared(value, a, where) for a in args]
        return [] if any(not f for f in found) else min(found, key=len)
    if origin is list:
        if not isinstance(value, list):
            return [f"{where}: {type(value).__name__}, not a list"]
        return [e for i, v in enumerate(value) for e in _undeclared(v, args[0], f"{where}[{i}]")]
    if origin is dict:
        if not isinstance(value, dict):
            return [f"{where}: {type(value).__name__}, not an object"]
        return [e for k, v in value.items() for e in _undeclared(v, args[1], f"{where}.{k}")]
    if declared is type(None):
        return [] if value is None else [f"{where}: {value!r}, not null"]
    kinds = (int, float) if declared is float else (declared,)
    return [] if isinstance(value, kinds) else [f"{where}: {type(value).__name__}, not {declared.__name__}"]


def test_every_record_a_method_writes_is_declared_at_every_depth(every_method, thermal_calibrations):
    """What a method writes beside the fields is typed (io/details.py, io/records.py): every method's file,
    --add auto's, a hand-placed session's and the thermal ones included, holds only the keys its method's classes
    declare (details_types: not another method's), each value of its declared type, down to the leaves; no
    record is Any."""
    cals = dict(every_method, **thermal_calibrations)
    cals["exact --add auto"] = calibrate(every_method["exact"].input, add=("auto",))
    planted = {"acc.quadratic.z": 2e-4}  # --add auto's steps, written where it adds an effect
    cals["exact --add auto, adding"] = calibrate(simulate(seed=1, effects=planted), add=("auto",))
    cals["systematic --add auto, adding"] = calibrate(
        simulate(sequence=Path(every_method["systematic"].input).parent / "seq.csv", seed=7, effects=planted),
        method="systematic", add=("auto",))
    cal_hints = typing.get_type_hints(Calibration)
    for name, cal in cals.items():
        written = _as_written(cal)
        problems = []
        own = details.details_types(cal.method)  # the method's own classes: not every method's keys
        block_hints = {k: h for c in own for k, h in typing.get_type_hints(c).items()}
        for s, block in cal.blocks():
            problems += [f"{s}.{k}: not declared in {', '.join(c.__name__ for c in own)} ({cal.method})"
                         for k in block.details if k not in block_hints]
            problems += [e for k in block.details if k in block_hints
                         for e in _undeclared(written[s][k], block_hints[k], f"{s}.{k}")]
            if block.thermal is not None:
                problems += _undeclared(written[s]["thermal"], records.Thermal, f"{s}.thermal")
        problems += _undeclared({k: written[k] for k in cal.details}, records.CalibrationDetails, "details")
        for k in ("layout", "unification"):
            if written.get(k) is not None:
                problems += _undeclared(written[k], cal_hints[k], k)
        assert not problems, f"{name}: {problems[:8]}"
    assert {"auto", "auto_stopped", "cross_validation"} <= set(cals["exact --add auto"].acc.details)
    assert all(cals[k].acc.details["auto"] for k in ("exact --add auto, adding", "systematic --add auto, adding"))
    assert {"T", "moves", "gyro_model"} <= set(cals["handheld"].gyro.details)


def test_the_record_check_finds_an_undeclared_key_and_a_wrong_kind():
    assert _undeclared({"tested": 3, "strongest": "acc.quadratic.z"}, records.Targeted, "t") == []
    assert _undeclared({"tested": 3, "planted": 1}, records.Targeted, "t") == ["t.planted: not declared in Targeted"]
    assert _undeclared({"tested": "3"}, records.Targeted, "t") == ["t.tested: str, not int"]
    assert _undeclared([{"axis": "x", "count": 2, "first_row": "a"}], list[records.Saturation], "s") \
        == ["s[0].first_row: str, not int"]


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
    """The typed object never turns an edited file into an internal error."""
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
    cal = calibrate(tmp_path / "s", method="multiposition")
    assert cal.gyro is None and "gyro" in cal.not_calibrated and cal.sensors == ["acc"]
    calibration.save(tmp_path / "c.json", cal)
    with pytest.raises(calibration.CalibrationFileError, match="calibrates no gyro"):
        apply(calibration.load(tmp_path / "c.json"), tmp_path / "s")


def test_what_plan_and_montecarlo_return_and_what_sets_state_is_declared(tmp_path):
    """simucal.plan's and simucal.montecarlo's results (io/results.py) and the meta.json of every kind of set
    simucal writes, its importers' included (io/meta.py), hold only declared keys of their declared kinds."""
    import simucal
    from simucal.io import meta, results
    assert _undeclared(simucal.plan("table1", separate=["acc.quadratic.z", "acc.scale_asymmetry.z"],
                                    sizes=[1e-4, 1e-4]), results.PlanScore, "plan") == []
    assert _undeclared(simucal.plan(positions=12, model="gyro_baseline", rates_dps=[10, 20]), results.PlanScore,
                       "design") == []
    assert _undeclared(simucal.plan(positions=12, table="hand"), results.PlanScore, "hand") == []
    assert _undeclared(simucal.montecarlo(trials=20), results.MonteCarlo, "montecarlo") == []
    ferraris = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"
    import_ferraris_sections(ferraris / "example_ferraris_session.csv", ferraris / "example_ferraris_session_list.json",
                             tmp_path / "fe", 102.4, 49.6)
    sets = {"ferraris": simucal.read_set(tmp_path / "fe")} | {
        k: simulate(**kw) for k, kw in {"turntable": {}, "raw": {"plan": "fibonacci24", "rate_hz": 20},
                                         "hand": {"scenario": "handheld"}, "field": {"scenario": "field"},
                                         "thermal": {"plan": "fibonacci24", "temperature_c": 40,
                                                     "t_ref_c": 25}}.items()}
    for name, ms in sets.items():
        assert _undeclared(dict(ms.meta), meta.Meta, name) == []


def test_every_key_a_diagnosis_writes_is_declared(every_method, tmp_path):
    """diagnosis.json is typed (fit/results.DiagnosisReport, SensorDiagnosis, CandidateRecord): a turntable set's
    (with --add and without), a stream's, a sequence's, twins chosen at rest and twins no rows tell apart
    (turntable/model_test.choose_twin), and a term found outside the library (its shape and model file) hold
    only declared keys, each of its declared type."""
    from click.testing import CliRunner
    from simucal.api.diagnosing import diagnosis_report
    from simucal.cli import main
    from simucal.fit.results import DiagnosisReport
    from simucal.turntable.simulate import mems_unit, write
    sets = {"turntable": every_method["exact"].input, "stream": every_method["handheld"].input,
            "sequence": every_method["systematic"].input}
    for name, rates, size in (("twins chosen", (12.0, -12.0, 30.0, -30.0), 254.0),
                              ("twins undecided", (1500.0, -1500.0), 359.0)):  # tests/test_twins_evidence.py's
        sc = mems_unit(0)
        sc.outer_rate_dps, sc.gyro_effects = rates, {"gyro.g_sensitivity.xz": size}
        write(tmp_path / name, sc, 0)
        sets[name] = tmp_path / name
    (tmp_path / "cubic.py").write_text(CUBIC)
    ran = CliRunner().invoke(main, ["simulate", str(tmp_path / "cubic"), "--plan", "fibonacci48", "--effect-file",
                                    str(tmp_path / "cubic.py"), "--set", "K3_x=3e-4"])
    assert ran.exit_code == 0, ran.output
    sets["a term outside the library"] = tmp_path / "cubic"
    reports = {k: diagnosis_report(Path(v)) for k, v in sets.items()}
    reports["turntable --add"] = diagnosis_report(Path(sets["turntable"]), add=("acc.quadratic.z",))
    for name, report in reports.items():
        written = json.loads(json.dumps(report, default=float))
        problems = _undeclared(written, DiagnosisReport, "diagnosis")
        assert not problems, f"{name}: {problems[:8]}"
    assert "added" in reports["turntable --add"]["acc"] and "moves_skipped" in reports["stream"]["gyro"]
    assert "shape" in reports["a term outside the library"]["acc"]
    chosen, undecided = (reports[k]["gyro"]["candidates"][0] for k in ("twins chosen", "twins undecided"))
    assert "at_rest" in chosen and undecided.get("twins_undecided")


def test_every_key_a_validation_writes_is_declared(every_method):
    """validation.json is typed (fit/validation.ValidationReport): a turntable's and a stream's report hold only
    declared keys, each of its declared type (on their own rows: the note says so)."""
    from simucal.api.validating import validation_report
    from simucal.fit.validation import ValidationReport
    for method in ("exact", "handheld"):
        cal = every_method[method]
        written = json.loads(json.dumps(validation_report(cal, Path(cal.input)), default=float))
        assert not (problems := _undeclared(written, ValidationReport, "validation")), f"{method}: {problems[:8]}"
        assert written["note"] and not written["independent"]


def test_each_method_has_its_own_details_class():
    """io/details.details_types: a method's blocks may hold every method's keys and its own, not another
    method's (a hand-placed session's blocks no turntable gyro's M_in_d, an exact one's no moves); a thermal
    calibration adds its plateaus to its method's; an unknown method is refused, not given every key."""
    def keys(method):
        return {k for c in details.details_types(method) for k in typing.get_type_hints(c)}
    hand, exact = keys("handheld (Tedaldi): exact norm fit + gyro moves"), keys("exact")
    assert {"moves", "T", "test"} <= hand and "M_in_d" not in hand and "eta_rad" not in hand
    assert {"M_in_d", "static_rows", "test"} <= exact and "moves" not in exact and "plateaus" not in exact
    assert keys("thermal (exact, every row at its own temperature)") == exact | {"plateaus", "groups"}
    assert keys("multiposition") == keys("warm-up (a still board over temperature)") == keys("field")
    assert set(typing.get_type_hints(details.SensorDetails)) == set().union(*map(keys, details.BY_METHOD), {
        "plateaus", "groups"})
    with pytest.raises(KeyError):
        keys("a method nobody wrote")
