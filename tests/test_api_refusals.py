"""The Python API holds the commands' standards (found by a new user's review): it never writes over
its inputs, never leaves a sensor raw or a unit mix-up unsaid, refuses what it cannot use in one
line, and gives the same table whatever made a set."""
import numpy as np
import pandas as pd
import pytest

import simucal
from simucal.errors import CalibrationError
from simucal.io.outputs import OutputError


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A raw turntable set (5 Hz) and its calibration; two other recordings of the same unit."""
    root = tmp_path_factory.mktemp("api_refusals")
    for name, seed in (("a", 1), ("b", 2)):
        simucal.simulate(seed=seed, rate_hz=5.0).write(root / name)
    return root, simucal.calibrate(str(root / "a"))


def test_save_never_writes_over_data(made, tmp_path):
    root, cal = made
    meta = (root / "b" / "meta.json").read_bytes()
    with pytest.raises(OutputError, match="would write over a file of the measurement set"):
        simucal.save(root / "b" / "meta.json", cal)
    with pytest.raises(OutputError, match="into the input"):
        simucal.save(root / "a" / "cal.json", cal)  # inside the set it was made from
    with pytest.raises(OutputError, match="into the input"):
        simucal.save(root / "a" / "v.json", simucal.validate(cal, str(root / "a")))
    assert (root / "b" / "meta.json").read_bytes() == meta
    simucal.save(tmp_path / "cal.json", cal)
    assert simucal.load(tmp_path / "cal.json").acc.params == cal.acc.params


def test_a_frame_with_a_sensor_partly_missing_is_refused(made):
    root, cal = made
    df = pd.DataFrame(simucal.read_set(str(root / "b")).to_arrays())
    with pytest.raises(CalibrationError, match="the frame lacks gz"):
        simucal.apply(cal, df.drop(columns=["gz"]))
    typo = df.rename(columns={"ax": "acc_x", "ay": "acc_y", "az": "acc_z"})
    with pytest.raises(CalibrationError, match="the frame lacks ACC_X"):
        simucal.apply(cal, typo, columns={"ax": "ACC_X", "ay": "acc_y", "az": "acc_z"})
    only_acc = simucal.apply(cal, df.drop(columns=["gx", "gy", "gz"]), sensor="acc")  # one sensor, said so
    both = simucal.apply(cal, df)
    assert np.allclose(only_acc[["ax", "ay", "az"]], both[["ax", "ay", "az"]])
    assert np.allclose(np.linalg.norm(both[["ax", "ay", "az"]].to_numpy(), axis=1).mean(), 1.0, atol=1e-3)


def test_units_unknown_or_mixed_up_are_refused(made):
    root, cal = made
    raw = simucal.read_set(str(root / "b"))
    x = np.column_stack([raw.samples[c] for c in ("ax", "ay", "az", "gx", "gy", "gz")])  # pulse/s, as recorded
    with pytest.raises(CalibrationError, match=r"acc_unit='mg': not a unit simucal knows; one of \('g'"):
        simucal.apply(cal, x, acc_unit="mg")
    with pytest.raises(CalibrationError, match="gyro_unit='dps'"):
        simucal.apply(cal, x, gyro_unit="dps")
    with pytest.raises(CalibrationError, match=r"acc_unit='g'\): calibrated: the acc outputs are .* times the known"):
        simucal.apply(cal, x, acc_unit="g")  # pulse/s said to be g


def test_other_objects_are_refused_naming_the_constructor(made):
    root, cal = made
    df = pd.DataFrame(simucal.read_set(str(root / "b")).to_arrays())
    for call in (lambda: simucal.calibrate(df), lambda: simucal.validate(cal, df), lambda: simucal.noise(df),
                 lambda: simucal.diagnose(df)):
        with pytest.raises(TypeError, match=r"is a DataFrame, .*; make one with simucal.MeasurementSet.from_dataframe"):
            call()


def test_one_column_order_and_segments_from_a_frame(made, tmp_path):
    root, _ = made
    sim = simucal.simulate(seed=2, rate_hz=5.0)
    assert list(sim.to_arrays()) == list(simucal.read_set(str(root / "b")).to_arrays())[:len(sim.to_arrays())]
    assert list(sim.to_arrays())[:8] == ["t_s", "segment", "ax", "ay", "az", "gx", "gy", "gz"]
    ms = simucal.read_set(str(root / "b"))
    back = simucal.MeasurementSet.from_dataframe(pd.DataFrame(ms.to_arrays()), acc_unit=ms.meta["acc_unit"],
                                                 gyro_unit=ms.meta["gyro_unit"], meta=ms.meta,
                                                 segments=pd.read_csv(root / "b" / "segments.csv",
                                                                      float_precision="round_trip"))
    assert back.segments == ms.segments  # rate runs' empty outer_deg: None, as the reader has it


@pytest.mark.slow
def test_add_as_text_and_thermal_of_one_ramp():
    sets = [simucal.simulate(seed=t, temperature_c=float(t), rate_hz=2.0, effects={"acc.bias_temperature.x": 1e-5})
            for t in (0, 25, 50)]
    cal = simucal.calibrate(sets)  # in-memory plateaus
    rows = simucal.parameters(cal)
    slope = rows[(rows.sensor == "acc") & (rows.name == "bias_x.T1")].iloc[0]  # the one vocabulary: b_x.T1's entry
    assert slope.unit == "g/degC" and slope.own_name == "b_x.T1" and abs(slope.value - 1e-5) < 4 * slope['std'], slope
    ramp = simucal.simulate(seed=3, temperature_c=(0.0, 50.0), rate_hz=2.0)
    assert simucal.calibrate(ramp, thermal=True).acc.thermal is not None  # thermal=True is not ignored
    assert "acc.quadratic.z" in simucal.calibrate(sets[1], add="acc.quadratic.z").acc.effects  # not its letters
    th = simucal.calibrate(sets)
    x = np.column_stack([sets[1].samples[c] for c in ("ax", "ay", "az", "gx", "gy", "gz")])
    with pytest.warns(UserWarning, match="temp_c looks like kelvin"):  # as `simucal apply` says it
        simucal.apply(th, x, temp_c=np.full(len(x), 298.0))
    with pytest.warns(UserWarning, match="temp_c"):
        simucal.apply(th, x, temp_c=np.full(len(x), 90.0))  # beyond the calibrated 0..50 degC: said


def test_the_whole_api_is_listed():
    assert {"lot", "calibrate", "MeasurementSet"} <= set(dir(simucal))
    assert callable(simucal.lot)


def test_a_frame_s_first_mistakes_are_named_with_the_column_row_and_option():
    """A segment column without segments= (was silently a stream, then blamed on t_s); sensor
    columns under other names (was "neither acc nor gyro given"); a string in a number column (was pandas'
    "could not convert string to float", no column or row)."""
    from simucal.io import MeasurementSetError
    n = 8
    df = pd.DataFrame({"ax": [0.0] * n, "ay": [0.0] * n, "az": [1.0] * n, "t_s": np.arange(n) * 0.01,
                       "segment": [1] * n})
    with pytest.raises(MeasurementSetError, match="'segment' gives each row a segment, but no segments="):
        simucal.MeasurementSet.from_dataframe(df, acc_unit="g", gyro_unit="deg/h")
    named = df.drop(columns="segment").rename(columns={"ax": "acc_x", "ay": "acc_y", "az": "acc_z"})
    with pytest.raises(MeasurementSetError, match=r"no accelerometer or gyro columns among \['acc_x'.*columns=\{'ax'"):
        simucal.MeasurementSet.from_dataframe(named, acc_unit="g", gyro_unit="deg/h")
    typo = df.drop(columns="segment").astype({"az": object})
    typo.loc[5, "az"] = "1.0g"
    with pytest.raises(MeasurementSetError, match=r"column 'az', row 5: '1.0g' is not a number"):
        simucal.MeasurementSet.from_dataframe(typo, acc_unit="g", gyro_unit="deg/h")


# Placeholders for the arguments a call needs beside the one tested: never read, the types are checked first.
BLANK = simucal.Calibration.__new__(simucal.Calibration)
REQUIRED = {"import_recording": ("ulog", ["w.ulg"], "out"), "calibrate": ("set",), "validate": ("cal.json", "set"),
            "diagnose": ("set",), "noise": ("set",), "sequence_observability": ("psins19",),
            "calibrate_each": (["set"], "out"), "calibrate_instances": (["set"],),
            "import_instances": ("ulog", "w.ulg", "out"), "apply": (BLANK, None), "apply_set": (BLANK, "set"),
            "parameters": (BLANK,)}


def _wrong_values(annotation: str) -> list:
    """Values of a wrong type for a parameter so annotated: a str where a list of paths or of numbers is; a str
    and a bool (and where a whole number is, a fraction) where a number is; none where it takes neither."""
    import re
    if annotation.startswith("Sequence[float]"):
        return ["10"]
    if annotation.startswith("Sequence[") and "Path" in annotation:
        return ["w.ulg"]
    if re.search(r"\b(int|float)\b", annotation) and not annotation.startswith(("Sequence", "Data")):
        return ["ten", True] + ([2.5] if "float" not in annotation else [])
    return []


def test_every_public_function_refuses_an_argument_of_a_wrong_type_in_one_line():
    """A wrong type was a bare TypeError deep inside (design_sequence('ten')) or misread (one path as a str, read a
    character at a time: "would write into the input ."); now each is one InputError naming the function, the
    argument, what was given and what is expected."""
    import inspect

    from simucal.errors import InputError
    tested = set()
    for name in simucal.__all__:
        f = getattr(simucal, name)
        if not inspect.isfunction(f):
            continue
        params = inspect.signature(f).parameters
        required = [p for p in params.values() if p.default is p.empty and p.kind is p.POSITIONAL_OR_KEYWORD]
        annotated = {p.name: p.annotation for p in params.values() if p.kind is not p.VAR_KEYWORD}
        if any(p.kind is p.VAR_KEYWORD for p in params.values()):  # calibrate's options
            annotated.update(simucal.CalibrateOptions.__annotations__)
        for arg, annotation in annotated.items():
            for wrong in _wrong_values(str(getattr(annotation, "__forward_arg__", annotation))):  # options': ForwardRef
                given = dict(zip([p.name for p in required], REQUIRED.get(name, ())))
                given[arg] = wrong
                with pytest.raises(InputError) as refusal:
                    f(**given)
                text = str(refusal.value)
                assert "\n" not in text and text.startswith(f"{name}: {arg}={wrong!r} is a {type(wrong).__name__}, ")
                tested.add(name)
    assert {"import_recording", "design_sequence", "calibrate", "diagnose", "validate", "noise", "simulate", "plan",
            "sequence_observability", "montecarlo", "calibrate_each", "audit", "apply"} <= tested
