"""A gyro whose die lags the board's thermistor: the temperature-rate effect (<sensor>.temperature_rate.<axis>, a
bias in dT/dt) and a still warm-up's model test that can fail (handheld/warmup.py), on warm-ups written by a
forward model of this file's own: the board's temperature T (what the log records) warming through two time
constants under a chamber's slow cycle, the sensor's T_s with dT_s/dt = (T - T_s) / tau from T_s = T at the
start, each bias a quadratic in T_s, white noise and a random walk."""
import json

import numpy as np
import pytest
from click.testing import CliRunner
from cli_helpers import refused
from scipy.signal import lfilter, lfiltic

import simucal
from simucal.cli import main
from simucal.errors import CalibrationError
from simucal.fit.results import ALPHA
from simucal.fit.thermal import temperature_rate
from simucal.handheld.warmup import calibrate_warmup

T_REF = 35.0
HZ = 10.0
ACC_G = np.array([[2e-3, 4e-5, -2e-6], [-1e-3, -3e-5, 1e-6], [1.5e-3, 2e-5, 3e-6]])
GYRO_DPH = np.array([[200.0, 15.0, 0.05], [-150.0, -12.0, 0.04], [90.0, 10.0, -0.03]])  # per degC^k
LAG_S = 30.0


def board_c(t, heat_s=(900.0, 600.0), cycle_s=1800.0, cycle_c=4.0):
    """The thermistor's temperature: 15 to 55 degC through two time constants (its rate starts at 0), plus a
    chamber's cycle, so that the rate at a temperature is not a polynomial in it (else no data tell a lag)."""
    a, b = heat_s
    return (15 + 40 * (1 - (a * np.exp(-t / a) - b * np.exp(-t / b)) / (a - b))
            + cycle_c * (1 - np.cos(2 * np.pi * t / cycle_s)))


def lagged(t, T, tau):
    """T_s with dT_s/dt = (T - T_s) / tau, exact for T linear between samples (an even step), from T_s = T."""
    dt = t[1] - t[0]
    a = np.exp(-dt / tau)
    b = tau / dt * (1 - a)
    num, den = [1 - b, b - a], [1, -a]
    return lfilter(num, den, T, zi=lfiltic(num, den, [T[0]], [T[0]]))[0]


def warmup(seed, lag_s=(0.0, 0.0, 0.0), walk=0.05, seconds=3600.0, **board):
    """A still board (z down): per axis a quadratic bias in its sensor's temperature (lag_s[i] behind the
    thermistor; the accelerometers' not), white noise (3.6 deg/h over a block of 36 samples) and a random walk
    of `walk` (deg/h)/sqrt(s); temp_c the thermistor's, with 0.02 degC of noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1 / HZ)
    T = board_c(t, **board)
    T_s = np.column_stack([lagged(t, T, s) if s else T for s in lag_s])
    gyro = np.column_stack([((T_s[:, i] - T_REF)[:, None] ** np.arange(3)) @ GYRO_DPH[i] for i in range(3)])
    steps = lambda q: np.cumsum(rng.normal(0, q / np.sqrt(HZ), (len(t), 3)), axis=0)  # noqa: E731
    gyro += rng.normal(0, 38.0, gyro.shape) + steps(walk)
    acc = np.array([0, 0, -1.0]) + ((T - T_REF)[:, None] ** np.arange(3)) @ ACC_G.T + rng.normal(0, 6e-4, gyro.shape) \
        + steps(1e-5)
    return simucal.MeasurementSet.from_arrays(acc, gyro, acc_unit="g", gyro_unit="deg/h", t_s=t,
                                              temp_c=T + rng.normal(0, 0.02, len(t)), meta={"latitude_deg": 47.0})


def test_the_temperature_rate_is_a_windowed_slope():
    """The slope of a line over the window about each time: exact on a quadratic, the same by the window's sums
    as by the cumulative sums, one-sided at the ends, the neighbours' central difference where rows are sparse,
    any order of the rows."""
    t = np.arange(0, 200, 0.1)
    T = 20 + 0.05 * t + 1e-3 * t ** 2
    at = np.array([30.0, 100.0, 150.05])
    few = temperature_rate(t, T, at)  # 3 times: the windows' own sums
    every = temperature_rate(t, T)  # every row: cumulative sums
    assert np.allclose(few, 0.05 + 2e-3 * at, atol=1e-10)
    assert np.allclose(every[np.searchsorted(t, at[:2])], 0.05 + 2e-3 * at[:2], atol=2e-4)  # the grid's round-off
    assert np.isclose(every[0], 0.05 + 2e-3 * 2.5, atol=1e-3)  # the first 5 s only
    rows_t, rows_T = np.array([0.0, 60, 120, 180]), np.array([20.0, 21, 23, 26])
    assert np.allclose(temperature_rate(rows_t, rows_T), [1 / 60, 3 / 120, 5 / 120, 3 / 60])
    shuffled = np.random.default_rng(0).permutation(len(t))
    assert np.allclose(temperature_rate(t[shuffled], T[shuffled], at), few)


def _residual_ratio(block):
    r = [block.thermal["parameters"][f"b_{a}"]["residual_rms"] for a in "xyz"]
    return r[0] / np.mean(r[1:])


@pytest.mark.slow
def test_a_die_lagging_its_thermistor_fails_the_model_and_its_rate_brings_the_axis_to_the_floor():
    """30 s of lag on gyro x: the model fails there by the temperature rate's targeted test, which the warning
    names with the lag it implies; --add auto adds that effect alone (-tau b'(T_ref) = -450 (deg/h)/(degC/s)),
    and the axis's residual falls to the other axes' while the bias at T_ref comes back."""
    plain, added = [], []
    for seed in range(3):
        cal = calibrate_warmup(warmup(seed, (LAG_S, 0, 0)), t_ref_c=T_REF)
        x = cal.gyro.thermal["parameters"]["b_x"]
        assert (cal.gyro.p_value < ALPHA and x["p_value"] < ALPHA
                and x["targeted"]["strongest"] == "gyro.temperature_rate.x")
        assert "verdict" in x["targeted"] and cal.gyro.details["advice"] == "gyro.temperature_rate.x"
        assert all(cal.gyro.thermal["parameters"][f"b_{a}"]["p_value"] >= ALPHA for a in "yz")
        assert cal.acc.p_value >= ALPHA
        said = [w for w in cal.warnings if "gyro.temperature_rate.x" in w]
        lag = float(said[0].split("by about ")[1].split(" s")[0])
        assert len(said) == 1 and 20 < lag < 45 and "--add gyro.temperature_rate.x" in said[0]
        auto = calibrate_warmup(warmup(seed, (LAG_S, 0, 0)), t_ref_c=T_REF, add=("auto",))
        assert list(auto.gyro.effects) == ["gyro.temperature_rate.x"] and not auto.acc.effects
        assert [s["id"] for s in auto.gyro.details["auto"]] == ["gyro.temperature_rate.x"]
        assert auto.gyro.p_value >= ALPHA and not any("temperature_rate" in w for w in auto.warnings)
        rate = auto.gyro.effects["gyro.temperature_rate.x"]
        assert abs(rate.value + LAG_S * GYRO_DPH[0, 1]) < 4 * rate.std
        b_x = auto.gyro.thermal["parameters"]["b_x"]
        assert abs(b_x["coefficients"][0] - GYRO_DPH[0, 0]) < min(3 * b_x["std"][0],
                                                                   abs(x["coefficients"][0] - GYRO_DPH[0, 0]))
        plain.append(_residual_ratio(cal.gyro))
        added.append(_residual_ratio(auto.gyro))
    assert np.median(plain) > 1.5 and np.median(added) < 1.25, (plain, added)


@pytest.mark.slow
def test_clean_warm_ups_hold_the_family_at_its_level():
    """12 warm-ups without a lag, at the unit's walk and at 30 times it: no sensor fails; the temperature rate's
    targeted chi2 has chi2(1)'s mean; the walk check's z is a standard normal (the likelihood ratio over the walk
    read the walk low and gave a chi2 mean of 2.1; a walk's block means differenced as points, a z mean of 2
    at the larger walk)."""
    chi2, z = [], []
    for seed in range(12):
        cal = calibrate_warmup(warmup(seed, walk=0.05 if seed % 2 else 1.5), t_ref_c=T_REF)
        for _, block in cal.blocks():
            assert block.p_value >= ALPHA
            for a in "xyz":
                f = block.thermal["parameters"][f"b_{a}"]
                chi2.append(f["targeted"]["statistic"])
                z.append(f["walk_check"]["z"])
    assert 0.55 < np.mean(chi2) < 1.5 and abs(np.mean(z)) < 0.45 and 0.7 < np.std(z) < 1.35, (np.mean(chi2), z)


@pytest.mark.slow
def test_the_rate_through_the_command_line_and_on_another_warm_up(tmp_path):
    """calibrate --thermal --add gyro.temperature_rate.x on a lagged warm-up: the effect on the console and in
    the file; validated on another warm-up of the unit, heated faster (the lag is another bias there), the gyro
    comes nearer its floor than the polynomial alone; effects still data cannot see are refused by name."""
    warmup(0, (LAG_S, 0, 0)).write(tmp_path / "a")
    warmup(5, (LAG_S, 0, 0), heat_s=(600.0, 300.0), cycle_s=900.0, cycle_c=3.0).write(tmp_path / "b")
    runner, after = CliRunner(), {}
    for name, add in (("plain", []), ("rate", ["--add", "gyro.temperature_rate.x"])):
        r = runner.invoke(main, ["calibrate", str(tmp_path / "a"), "--thermal", *add, "-o",
                                 str(tmp_path / f"{name}.json"), "--px4", str(tmp_path / f"{name}.params"),
                                 "--ardupilot", str(tmp_path / f"{name}.param")])
        assert r.exit_code == 0, r.output
        for autopilot, suffix in (("PX4", "params"), ("ArduPilot", "param")):  # no rate parameter: said in the file
            said = f"gyro.temperature_rate.x was fitted beside the bias polynomial, but {autopilot} has no parameter"
            assert (said in (tmp_path / f"{name}.{suffix}").read_text()) == bool(add)
        assert ("gyro: gyro.temperature_rate.x = " in r.output) == bool(add)
        assert ("THE MODEL FAILS" in r.output) != bool(add)
        v = runner.invoke(main, ["validate", str(tmp_path / f"{name}.json"), str(tmp_path / "b"), "-o",
                                 str(tmp_path / f"{name}_v.json")])
        assert v.exit_code == 0, v.output
        check = simucal.load(tmp_path / f"{name}.json")  # the file loads, its effect with it
        assert list(check.gyro.effects) == (["gyro.temperature_rate.x"] if add else [])
        after[name] = json.loads((tmp_path / f"{name}_v.json").read_text())["checks"]["gyro"][0]
    assert after["rate"]["after_rms"] < min(0.8 * after["plain"]["after_rms"], 1.3 * after["rate"]["floor_rms"]), after
    refused(runner.invoke(main, ["calibrate", str(tmp_path / "a"), "--thermal", "--add", "gyro.quadratic.x", "-o",
                                 str(tmp_path / "c.json")]), "--add gyro.quadratic.x", "temperature_rate")
    with pytest.raises(CalibrationError, match="no effects but its bias's temperature rate"):
        calibrate_warmup(warmup(1, seconds=600.0), add=("acc.scale_asymmetry.z",))
