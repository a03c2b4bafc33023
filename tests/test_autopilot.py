"""Part 4: a thermal calibration's bias polynomials exported as PX4's TC_A0_*/TC_G0_* and
ArduPilot's INS_TCAL1_*. Each round trip evaluates the written file as the autopilot does (its code
re-implemented below, in float32 as the autopilot stores and computes it) and holds it against simucal's
own bias correction (fit/thermal.py's polynomials) over the calibrated range, within 1e-6 of the
correction's size; what an autopilot cannot express is refused or warned, naming it."""
import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from simucal.cli import main
from simucal.errors import CalibrationError
from simucal.fit.thermal import evaluate
from simucal.io import autopilot
from simucal.io.calibration import Calibration, SensorBlock
from simucal.turntable.simulate import Scenario, plant, write

G_STD = 9.80665  # PX4's CONSTANTS_ONE_G and ArduPilot's GRAVITY_MSS
RAD_S_PER_DPH = math.radians(1.0) / 3600.0
REL = 1e-6
NAMES = {"acc": ("dK_x", "dK_y", "dK_z", "theta_yx", "theta_zx", "theta_zy", "b_x", "b_y", "b_z"),
         "gyro": ("dK_x", "dK_y", "dK_z", "phi_yx", "phi_zx", "phi_zy", "b_x", "b_y", "b_z")}


def px4_offsets(params: dict, letter: str, temp_c, slot: int = 0) -> np.ndarray:
    """(3, n): the offset PX4 subtracts from the raw reading: TemperatureCompensation::calc_thermal_offsets_3D
    (src/modules/temperature_compensation/TemperatureCompensation.cpp), float32 parameters and arithmetic:
    dT = T - TREF with T held to TMIN or TMAX outside them; offset_i = x0 + x1 dT + x2 dT^2 + x3 dT^3."""
    p = {k: np.float32(v) for k, v in params.items()}
    T = np.asarray(temp_c, np.float32)
    tmin, tmax, tref = (p[f"TC_{letter}{slot}_{k}"] for k in ("TMIN", "TMAX", "TREF"))
    dT = np.where(T > tmax, tmax - tref, np.where(T < tmin, tmin - tref, T - tref)).astype(np.float32)
    dT2 = dT * dT
    dT3 = dT2 * dT
    x = lambda k, i: p[f"TC_{letter}{slot}_X{k}_{i}"]  # noqa: E731
    return np.stack([x(0, i) + x(1, i) * dT + x(2, i) * dT2 + x(3, i) * dT3 for i in range(3)])


def ardupilot_correction(params: dict, name: str, temp_c, cal_temp_c: float, slot: int = 0) -> np.ndarray:
    """(3, n): what ArduPilot subtracts from the reading: TCal::correct_sensor and TCal::polynomial_eval
    (libraries/AP_InertialSensor/AP_InertialSensor_tempcal.cpp), float32: T and the ordinary calibration's
    temperature both constrained to [TMIN, TMAX], v -= P(T - 35), v += P(T_cal - 35), P(x) = (c1 + (c2 +
    c3 x) x) x * 1e-6."""
    f = np.float32
    tcal = f"INS_TCAL{slot + 1}"
    c = [np.array([params[f"{tcal}_{name}{k}_{a}"] for a in "XYZ"], f)[:, None] for k in (1, 2, 3)]
    lo, hi = f(params[f"{tcal}_TMIN"]), f(params[f"{tcal}_TMAX"])

    def P(x):
        x = f(x)
        return (c[0] + (c[1] + c[2] * x) * x) * x * f(1.0e-6)
    T = np.clip(np.asarray(temp_c, f), lo, hi)
    return P(T - f(35.0)) - P(np.clip(f(cal_temp_c), lo, hi) - f(35.0))


def _read_px4(path) -> tuple[dict, dict]:
    values, types = {}, {}
    for line in path.read_text().splitlines():
        if not line.startswith("#"):
            vehicle, component, name, value, kind = line.split("\t")
            assert (vehicle, component) == ("1", "1")
            values[name], types[name] = float(value), int(kind)
    return values, types


def _read_ardupilot(path) -> dict:
    rows = [line.split(",") for line in path.read_text().splitlines() if not line.startswith("#")]
    assert all(len(r) == 2 for r in rows)
    return {n: float(v) for n, v in rows}


def _simucal_bias_si(cal: Calibration, sensor: str, temp_c, g_mps2: float) -> np.ndarray:
    """(3, n): simucal's bias correction at each temperature, from the calibration's own polynomials."""
    block = getattr(cal, sensor)
    fits, dT = block.thermal["parameters"], np.asarray(temp_c) - block.thermal["t_ref_c"]
    per = g_mps2 if sensor == "acc" else RAD_S_PER_DPH
    return np.stack([evaluate(fits[b]["coefficients"], dT) * per for b in ("b_x", "b_y", "b_z")])


def _close(got, want):
    """Within REL of the correction's size over the range, per axis."""
    scale = np.max(np.abs(want), axis=1, keepdims=True)
    assert np.all(np.abs(got - want) <= REL * scale + 1e-30), np.max(np.abs(got - want) / scale)


def _block(sensor, unit, polys: dict, t_ref_c, lo, hi) -> SensorBlock:
    """A thermal block by hand: `polys` {name: coefficients}; every other parameter constant."""
    fits = {n: {"degree": len(polys.get(n, [0.0])) - 1, "coefficients": list(polys.get(n, [0.0])),
                "std": [1e-9] * len(polys.get(n, [0.0]))} for n in NAMES[sensor]}
    return SensorBlock(f"{sensor}_baseline", np.eye(3), np.zeros(3), unit,
                       params={n: f["coefficients"][0] for n, f in fits.items()},
                       std={n: 1e-9 for n in fits}, param_units={n: unit if n.startswith("b_") else "1" for n in fits},
                       thermal={"t_ref_c": t_ref_c, "plateaus_c": [lo, t_ref_c, hi], "parameters": fits})


T_REF, LO, HI = 22.5, -10.0, 60.0
ACC = {"b_x": [8e-4, 2e-6, 5e-8, -3e-10], "b_y": [-1e-3, -4e-6], "b_z": [-3.2e-3, 1e-6, 0.0, 2e-10]}
GYRO = {"b_x": [-0.34, 0.01, -2e-4, 3e-6], "b_y": [0.17], "b_z": [-0.02, 2e-3, 1e-5]}


def _hand_built(acc=ACC, gyro=GYRO) -> Calibration:
    return Calibration("thermal (exact per plateau)", ["cold", "room", "hot"], None,
                       {"acc_unit": "m/s^2", "gyro_unit": "rad/s", "sensors": ["acc", "gyro"]},
                       acc=_block("acc", "g", acc, T_REF, LO, HI), gyro=_block("gyro", "deg/h", gyro, T_REF, LO, HI),
                       t_ref_c=T_REF, temperature_range_c=[LO, HI])


def _write(made):
    for path, text, *_ in made:
        Path(path).write_text(text)


@pytest.mark.parametrize("meta, g_mps2", [({"acc_unit": "m/s^2", "gravity_mps2": 9.81}, 9.81),
                                          ({"acc_unit": "pulse/s", "gravity_mps2": 9.81}, G_STD)])
def test_px4_round_trip_by_hand(tmp_path, meta, g_mps2):
    """Cubic biases about T_ref 22.5 degC: PX4's offsets from the file are simucal's bias, over -10..60 degC;
    the g is the one the data were divided by (meta's for m/s^2, else the drivers' standard g)."""
    cal, path = _hand_built(), tmp_path / "tc.params"
    made = autopilot.texts([(cal, meta)], px4=str(path))
    assert made[-1][3].startswith("set TC_A0_ID")
    _write(made)
    values, types = _read_px4(path)
    expect = {f"TC_{s}{k}" for s in "AG" for k in ["_ENABLE", "0_TREF", "0_TMIN", "0_TMAX"]
              + [f"0_X{j}_{i}" for j in range(4) for i in range(3)]}
    assert set(values) == expect
    assert {n for n, t in types.items() if t == 6} == {"TC_A_ENABLE", "TC_G_ENABLE"} and set(types.values()) == {6, 9}
    assert (values["TC_A0_TREF"], values["TC_A0_TMIN"], values["TC_G0_TMAX"]) == (T_REF, LO, HI)
    T = np.linspace(LO, HI, 701)
    for sensor, letter in (("acc", "A"), ("gyro", "G")):
        raw = _simucal_bias_si(cal, sensor, T, g_mps2)  # the raw reading at zero input (the sensor's bias)
        corrected = raw - px4_offsets(values, letter, T)  # PX4 subtracts the offset
        _close(raw - corrected, raw)
    assert values["TC_A0_X1_0"] == pytest.approx(2e-6 * g_mps2, rel=1e-8)  # the sign: output = M u + b, b added


def test_each_sensors_own_range(tmp_path):
    """A block's own temperature_range_c (its rows': a ramp's gyro may cover part of it) is its TMIN/TMAX in
    PX4's file; ArduPilot's one INS_TCAL1_TMIN/TMAX per IMU is where both sensors were calibrated."""
    cal = _hand_built()
    cal.gyro.thermal["temperature_range_c"] = [5.0, 45.0]
    px4, ardupilot = tmp_path / "tc.params", tmp_path / "tcal.param"
    _write(autopilot.texts([(cal, {"acc_unit": "g"})], px4=str(px4), ardupilot=str(ardupilot)))
    values, _ = _read_px4(px4)
    assert (values["TC_A0_TMIN"], values["TC_A0_TMAX"], values["TC_G0_TMIN"], values["TC_G0_TMAX"]) == (LO, HI, 5, 45)
    values = _read_ardupilot(ardupilot)
    assert (values["INS_TCAL1_TMIN"], values["INS_TCAL1_TMAX"]) == (5, 45)


def test_ardupilot_round_trip_by_hand(tmp_path):
    """INS_TCAL1_*: the polynomial re-expanded about ArduPilot's 35 degC without its constant; what ArduPilot
    subtracts is simucal's b(T) - b(T_cal) for an ordinary calibration at any T_cal in the range."""
    cal, path = _hand_built(), tmp_path / "tcal.param"
    _write(autopilot.texts([(cal, {"acc_unit": "g"})], ardupilot=str(path)))
    values = _read_ardupilot(path)
    assert len(values) == 3 + 2 * 9 and values["INS_TCAL1_ENABLE"] == 1
    assert (values["INS_TCAL1_TMIN"], values["INS_TCAL1_TMAX"]) == (LO, HI)
    T = np.linspace(LO, HI, 701)
    for sensor, name in (("acc", "ACC"), ("gyro", "GYR")):
        for t_cal in (LO, 20.0, 35.0, HI):
            b = _simucal_bias_si(cal, sensor, T, G_STD)
            want = b - _simucal_bias_si(cal, sensor, [t_cal], G_STD)
            _close(ardupilot_correction(values, name, T, t_cal), want)


def test_what_an_autopilot_cannot_express_is_named():
    """Scale-factor and misalignment drift are warned (named, with their change over the range); a bias of
    degree 4 is refused; a calibration at one temperature or a model without b_x..b_z too."""
    cal = _hand_built(acc={**ACC, "dK_z": [0.006, 3e-6], "theta_zy": [1e-4, 0.0, 1e-9]})
    rows, warnings = autopilot.px4_parameters(autopilot.bias_polynomials(cal, G_STD))
    assert [w.split(" (")[0] for w in warnings] == ["PX4 corrects the bias only, not acc dK_z",
                                                    "PX4 corrects the bias only, not acc theta_zy"]
    assert "changes by 0.00021 from -10 to 60 degC" in warnings[0]  # 3e-6 /degC over 70 degC
    with pytest.raises(CalibrationError, match=r"acc b_y: a polynomial of degree 4 .* --thermal-degree 3"):
        autopilot.ardupilot_parameters(autopilot.bias_polynomials(
            _hand_built(acc={**ACC, "b_y": [0, 1e-6, 0, 0, 1e-12]}), G_STD))
    one = _hand_built()
    one.gyro.thermal = None
    with pytest.raises(CalibrationError, match="gyro: no temperature polynomials .* calibrate --thermal"):
        autopilot.bias_polynomials(one, G_STD)
    other = _hand_built()
    other.acc.thermal["parameters"]["bias_z"] = other.acc.thermal["parameters"].pop("b_z")
    with pytest.raises(CalibrationError, match="acc: the model has no bias parameter b_z"):
        autopilot.bias_polynomials(other, G_STD)


def test_about_re_expands_exactly():
    c = np.array([[1.0, -2.0, 0.5, 0.25]])
    x = np.linspace(-30, 40, 9)
    shifted = autopilot.about(c, 12.5)
    assert np.allclose(np.polynomial.polynomial.polyval(x - 12.5, shifted[0]),
                       np.polynomial.polynomial.polyval(x, c[0]), rtol=1e-13, atol=1e-12)


PLANTED = {"acc.bias_temperature.x": 2e-6, "acc.bias_temperature2.x": 5e-8, "acc.scale_temperature.z": 3e-6,
           "gyro.bias_temperature.z": 2e-3}


@pytest.fixture(scope="module")
def plateaus(tmp_path_factory):
    root = tmp_path_factory.mktemp("autopilot")
    sets = []
    for T, seed in ((0.0, 11), (25.0, 12), (50.0, 13)):
        sc = Scenario(plan="fibonacci48", temp_c=(T, T), t_ref_c=25.0, rate_hz=20)
        plant(sc, [f"{k}={v}" for k, v in PLANTED.items()])
        write(root / f"p{T:g}", sc, seed)
        sets.append(root / f"p{T:g}")
    return root, sets


def _run(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    return r.exit_code, r.output


@pytest.mark.slow
def test_calibrate_thermal_writes_both_files_end_to_end(plateaus):
    """Three simulated plateaus through calibrate --thermal --px4 --ardupilot: both files reproduce the
    calibration file's bias polynomials as each autopilot evaluates them; the planted scale-factor drift is
    warned, naming it."""
    root, sets = plateaus
    code, out = _run("calibrate", *sets, "--thermal", "-o", root / "cal.json", "--px4", root / "tc.params",
                     "--ardupilot", root / "tcal.param")
    assert code == 0, out
    assert "WARNING: PX4 corrects the bias only, not acc dK_z" in out and f"wrote {root / 'tc.params'}" in out
    cal = Calibration.from_json(json.loads((root / "cal.json").read_text()))
    lo, hi = cal.temperature_range_c
    T = np.linspace(lo, hi, 501)
    px4, _ = _read_px4(root / "tc.params")
    ardupilot = _read_ardupilot(root / "tcal.param")
    for sensor, letter, name in (("acc", "A", "ACC"), ("gyro", "G", "GYR")):
        b = _simucal_bias_si(cal, sensor, T, G_STD)  # pulse/s data: the standard g
        _close(px4_offsets(px4, letter, T), b)
        _close(ardupilot_correction(ardupilot, name, T, 25.0), b - _simucal_bias_si(cal, sensor, [25.0], G_STD))
    f = cal.acc.thermal["parameters"]["b_x"]  # the planted slope, through the file, within 3 std
    assert abs(px4["TC_A0_X1_0"] / G_STD - 2e-6) < 3 * f["std"][1]
    assert "# WARNING: ArduPilot corrects the bias only, not acc dK_z" in (root / "tcal.param").read_text()


def test_export_refused_in_one_line_and_nothing_written(plateaus, tmp_path, monkeypatch):
    root, sets = plateaus
    code, out = _run("calibrate", sets[1], "--px4", tmp_path / "x.params", "-o", tmp_path / "c.json")
    assert code == 2 and "--thermal" in out and out.count("\n") == 1
    monkeypatch.setattr(autopilot, "MAX_DEGREE", 1)  # an autopilot of lower degree: the planted quadratic refused
    code, out = _run("calibrate", *sets, "--thermal", "-o", tmp_path / "c.json", "--ardupilot", tmp_path / "a.param")
    assert code == 2 and "acc b_x: a polynomial of degree 2" in out and out.count("\n") == 1, out
    assert not (tmp_path / "c.json").exists() and not (tmp_path / "a.param").exists()
