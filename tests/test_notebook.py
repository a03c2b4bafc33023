"""What a notebook user does with only the documented API (README, "Python API"):
calibrate a DataFrame, apply the calibration to another DataFrame in the user's own units (temp_c taken
from the frame where the model follows temperature), validate, read the parameter table."""
import numpy as np
import pytest

import simucal

EFFECT, SIZE_G_PER_C = "acc.bias_temperature.z", 5e-5  # a z bias that follows temperature, g/degC
G = 9.80665


def _frame(seed, ramp_c):
    """A raw recording (pulse/s) of one unit over a temperature ramp, as a DataFrame and its set."""
    import pandas as pd
    ms = simucal.simulate(seed=seed, rate_hz=20.0, temperature_c=ramp_c, effects={EFFECT: SIZE_G_PER_C})
    return pd.DataFrame(ms.to_arrays()), ms


@pytest.fixture(scope="module")
def notebook():
    df, ms = _frame(1, (10.0, 40.0))
    cal = simucal.calibrate(simucal.MeasurementSet.from_dataframe(df, acc_unit="pulse/s", gyro_unit="pulse/s",
                                                                  segments=ms.segments, meta=ms.meta), add=[EFFECT])
    df2, ms2 = _frame(2, (15.0, 35.0))
    return cal, df2, ms2


def test_parameter_table_holds_the_truth(notebook):
    cal, _, _ = notebook
    params = simucal.parameters(cal, "own").set_index(["sensor", "name"])
    row = params.loc[("acc", EFFECT)]
    assert row["unit"] == "g/degC" and "temperature" in row["meaning"]
    common = simucal.parameters(cal).set_index(["sensor", "name"]).loc[("acc", EFFECT)]  # an effect: its id in both
    assert (common["value"], common["std"], common["meaning"]) == (row["value"], row["std"], row["meaning"])
    assert abs(row["value"] - SIZE_G_PER_C) < 5 * row["std"], row
    assert (params["std"] > 0).all() and params["value"].notna().all()


def test_apply_to_a_frame_in_the_user_s_units_with_its_temperature(notebook):
    cal, df2, ms2 = notebook
    scale_acc = np.asarray(ms2.meta["acc_pulses_per_g"])  # the user's frame: nominal m/s^2 and deg/s
    scale_gyro = np.asarray(ms2.meta["gyro_pulses_per_arcsec"]) * 3600.0  # pulse/s per deg/s
    mine = df2.copy()
    mine[["ax", "ay", "az"]] = df2[["ax", "ay", "az"]].to_numpy() / scale_acc * G
    mine[["gx", "gy", "gz"]] = df2[["gx", "gy", "gz"]].to_numpy() / scale_gyro
    out = simucal.apply(cal, mine, acc_unit="m/s^2", gyro_unit="deg/s")
    assert type(out) is type(mine) and list(out.columns) == list(mine.columns) and len(out) == len(mine)
    assert (out["t_s"] == mine["t_s"]).all() and (out["temp_c"] == mine["temp_c"]).all()
    raw = df2[["ax", "ay", "az", "gx", "gy", "gz"]].to_numpy()
    ref = simucal.apply(cal, raw, acc_unit="pulse/s", gyro_unit="pulse/s", temp_c=df2["temp_c"].to_numpy())  # g, deg/h
    np.testing.assert_allclose(out[["ax", "ay", "az"]].to_numpy(), ref[:, :3] * G, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(out[["gx", "gy", "gz"]].to_numpy(), ref[:, 3:] / 3600.0, rtol=1e-9, atol=1e-12)
    warmer = simucal.apply(cal, mine.assign(temp_c=mine["temp_c"] + 10.0), acc_unit="m/s^2", gyro_unit="deg/s")
    shift_g = (warmer["az"] - out["az"]).to_numpy() / G  # the model's bias taken out at each row's temp_c
    found = cal.acc.effects[EFFECT].value
    np.testing.assert_allclose(shift_g, -10.0 * found / cal.acc.M[2, 2], rtol=1e-6)
    with pytest.raises(simucal.errors.CalibrationError, match="temp_c"):
        simucal.apply(cal, mine.drop(columns="temp_c"), acc_unit="m/s^2", gyro_unit="deg/s")


def test_validate_on_the_other_recording(notebook):
    cal, _, ms2 = notebook
    v = simucal.validate(cal, ms2)
    assert v.independent and v.verdict["acc"] in ("at the noise floor", "better"), v.verdict
    acc = v.checks[v.checks.sensor == "acc"]
    assert (acc.calibrated_rms < acc.nominal_rms).all()


def test_a_notebook_sees_short_reprs_its_truth_and_plain_names(tmp_path):
    """Every public object's repr is a line under 1 kB (the numbers are in its fields and tables); a set read
    back from its folder has the truth simulate gave it; dir(simucal) lists the API, not the module's own
    machinery; save refuses a suffix it does not write (it would write JSON under a PX4 name)."""
    ms = simucal.simulate(seed=1)
    ms.write(tmp_path / "s")
    read = simucal.read_set(tmp_path / "s")
    assert read.truth == ms.truth and read.truth["acc"]["params"]
    (tmp_path / "s" / "truth.json").write_text("{not json")
    assert simucal.read_set(tmp_path / "s").truth is None  # never an input: a damaged one is only left out
    cal = simucal.calibrate(ms, add=["acc.quadratic.z"])
    for obj in (ms, cal, cal.acc, cal.gyro, simucal.diagnose(ms), simucal.validate(cal, simucal.simulate(seed=2))):
        assert len(repr(obj)) < 1024 and "\n" not in repr(obj), (type(obj).__name__, repr(obj)[:200])
    assert "acc.quadratic.z" in repr(cal.acc) and cal.acc.verdict in repr(cal.acc)
    assert "TYPE_CHECKING" not in dir(simucal) and {"calibrate", "read_set", "__version__"} <= set(dir(simucal))
    with pytest.raises(simucal.errors.InputError, match=r"x\.params: save writes .* not \.params; PX4's"):
        simucal.save(tmp_path / "x.params", cal)
    assert not (tmp_path / "x.params").exists()
    simucal.save(tmp_path / "cal.json", cal)
    assert simucal.load(tmp_path / "cal.json").acc.effects.keys() == cal.acc.effects.keys()


def test_the_advice_is_data_from_diagnosis_to_the_added_effect():
    """Diagnosis.suggested holds the effect the verdict names with its statistics, and Diagnosis.next the
    API's call: the loop runs on them with no sentence parsed, and the model passes after it."""
    ms = simucal.simulate(seed=1, plan="fibonacci48", effects={"acc.quadratic.z": 2e-4})
    d = simucal.diagnose(ms)
    [s] = d.suggested
    assert (s.sensor, s.id, s.add) == ("acc", "acc.quadratic.z", True) and abs(s.estimate - 2e-4) < 4 * s.std
    assert s.unit and s.p_value < 1e-3 and isinstance(s.estimate, float)
    assert d.next.function == "calibrate" and d.next.options == {"add": ["acc.quadratic.z"]}
    assert d.next.call == d.next_command and d.next.command.startswith("simucal calibrate ")
    cal = getattr(simucal, d.next.function)(ms, **d.next.options)
    assert cal.acc.verdict == "passes" and list(cal.acc.effects) == ["acc.quadratic.z"]
    after = simucal.diagnose(ms, add=[x.id for x in d.suggested if x.add])
    assert after.suggested == [] and after.next.options == {"add": ["acc.quadratic.z"]}  # the model keeps it


def test_a_frame_s_attrs_stay_small_and_its_segments_come_back_as_a_table():
    """to_dataframe's attrs hold the units only (pandas copies attrs along every operation); the segments are
    segments_frame(), which from_dataframe takes back to the same calibration."""
    ms = simucal.simulate(seed=1, plan="fibonacci48")
    df, segments = ms.to_dataframe(), ms.segments_frame()
    assert df.attrs == {"acc_unit": "pulse/s", "gyro_unit": "pulse/s"} and len(segments) == len(ms.segments) == 102
    back = simucal.MeasurementSet.from_dataframe(df, acc_unit=df.attrs["acc_unit"], gyro_unit=df.attrs["gyro_unit"],
                                                 segments=segments, meta=ms.meta)
    assert simucal.calibrate(back).gyro.chi2 == simucal.calibrate(ms).gyro.chi2
    assert simucal.simulate("handheld", seed=1).segments_frame() is None


def test_help_lists_every_parameter_of_every_public_function():
    """help() of each public function names each of its parameters in its Parameters section."""
    import inspect
    missing = {}
    for name in simucal.__all__:
        obj = getattr(simucal, name)
        if inspect.isfunction(obj):
            doc = inspect.getdoc(obj) or ""
            section = doc.split("Parameters")[1].split("Returns")[0] if "Parameters" in doc else ""
            absent = [p for p in inspect.signature(obj).parameters if p not in section]
            if absent or not section:
                missing[name] = absent
    assert not missing, missing
