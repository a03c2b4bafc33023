"""MEMS units: gyro biases near 0.5 deg/s, accelerometer biases near 50 mg, scale factors and
misalignments near 2e-2, MEMS noise. Systematic calibration on psins19: the filter starts from the first rest
and scales its priors to the unit (systematic/calibrate.start_from_rest); before, such a unit was refused as
unobserved or calibrated hundreds of thousands of stds off. And the exact method on a turntable plan."""
import numpy as np
import pytest

from simucal import io
from simucal.systematic.method import calibrate_systematic
from simucal.turntable.sequence import simulate_sequence
from simucal.turntable.simulate import mems_unit


@pytest.mark.slow
def test_mems_units_are_calibrated_within_their_stds(tmp_path):
    z = []
    for seed in range(6):
        sc = mems_unit(seed)
        meta, samples, segments, _ = simulate_sequence(sc, "psins19", seed)
        io.write_set(tmp_path / str(seed), meta, samples, segments)
        cal = calibrate_systematic(io.read_set(tmp_path / str(seed)))
        assert cal.acc.p_value > 1e-3 and cal.gyro.p_value > 1e-3
        for sensor, truth in (("acc", sc.acc_params), ("gyro", sc.gyro_params)):
            block = getattr(cal, sensor)
            z += [(block.params[k] - v) / block.std[k] for k, v in truth.items()]
    assert np.sqrt(np.mean(np.square(z))) < 1.3 and np.max(np.abs(z)) < 4.5, np.round(z, 2)


@pytest.mark.slow
def test_mems_units_on_a_table_by_the_exact_method(tmp_path):
    from simucal.api.calibrating import calibrate
    from simucal.turntable.simulate import write
    z = []
    for seed in range(8):
        sc = mems_unit(seed)
        sc.plan, sc.acc_noise_g, sc.gyro_noise_dph = "fibonacci24", 2e-5, 3.0  # averaged rows: each mean's noise
        write(tmp_path / str(seed), sc, seed)
        cal = calibrate(tmp_path / str(seed))
        for sensor, truth in (("acc", sc.acc_params), ("gyro", sc.gyro_params)):
            block = getattr(cal, sensor)
            assert block.p_value > 1e-3
            z += [(block.params[k] - v) / block.std[k] for k, v in truth.items()]
    assert np.sqrt(np.mean(np.square(z))) < 1.3 and np.max(np.abs(z)) < 4.5, np.round(z, 2)


@pytest.mark.slow
def test_mems_units_by_hand_within_their_stds(tmp_path):
    """Hand-placed sessions of MEMS units (the simulator's unit: acc biases to 50 mg and
    scale/misalignment to 1e-2, gyro biases to 2 deg/s and T off I by up to 4e-2, 1 mg and 0.1 deg/s noise,
    16-bit counts): the accelerometer biases and the gyro's T within their stds over seeds."""
    from simucal.api.calibrating import calibrate
    from simucal.handheld.simulate import HandheldScenario, write_handheld
    z_acc, z_T = [], []
    for seed in range(8):
        truth = write_handheld(tmp_path / str(seed), HandheldScenario(), seed)
        cal = calibrate(tmp_path / str(seed))
        z_acc += [(cal.acc.params[f"b_{a}"] - b) / cal.acc.std[f"b_{a}"] for a, b in zip("xyz", truth["acc"]["bias"])]
        T, std_T = np.array(cal.gyro.details["T"]), np.array(cal.gyro.std["T"], dtype=float)
        assert cal.gyro.details["gyro_model"] == "full"
        z_T += ((T - np.array(truth["gyro"]["T"])) / std_T).ravel().tolist()
    for z in (z_acc, z_T):
        assert 0.6 < np.sqrt(np.mean(np.square(z))) < 1.4 and np.max(np.abs(z)) < 4.5, np.round(z, 2)


@pytest.mark.slow
def test_mems_units_over_temperature_plateaus(tmp_path):
    """A MEMS unit (mems_unit: biases 50 mg and 0.5 deg/s, scale factors 2e-2) at three
    wandering plateaus with MEMS-sized temperature coefficients (0.1 mg/degC, 10 deg/h/degC, 1e-4/degC):
    calibrate --thermal passes its test and every coefficient the truth holds is within 3.5 of its stds."""
    from simucal.api.calibrating import calibrate
    from simucal.turntable.simulate import at_temperature, plant, write
    planted = {"acc.bias_temperature.x": 1e-4, "gyro.bias_temperature.z": 10.0, "acc.scale_temperature.y": 1e-4}
    sets = []
    for T, seed in ((-10, 1), (25, 2), (60, 3)):
        sc = mems_unit(0)
        sc.plan, sc.rate_hz, sc.acc_noise_g, sc.gyro_noise_dph = "fibonacci24", None, 2e-5, 3.0
        at_temperature(sc, T, t_ref_c=25.0, wander_c=0.3)
        plant(sc, [f"{k}={v}" for k, v in planted.items()])
        write(tmp_path / f"p{T}", sc, seed)
        sets.append(tmp_path / f"p{T}")
    cal = calibrate(sets, t_ref_c=25.0)
    assert cal.acc.p_value > 1e-3 and cal.gyro.p_value > 1e-3, (cal.acc.p_value, cal.gyro.p_value)
    truth = {("acc", "b_x", 1): 1e-4, ("gyro", "b_z", 1): 10.0, ("acc", "dK_y", 1): 1e-4}
    for (sensor, name, degree), value in truth.items():
        par = getattr(cal, sensor).thermal["parameters"][name]
        assert par["degree"] >= degree, (name, par)
        est, std = par["coefficients"][degree], par["std"][degree]
        assert abs(est - value) < 3.5 * std, (name, est, std, value)


def test_passes_that_do_not_converge_are_refused_not_written():
    """A MEMS unit's passes stopped before they converge (here by max_passes=2; a unit on fast turns can
    need 20): calibrate's refusal names it, never a calibration whose estimates are not the stds' fixed point."""
    from pathlib import Path

    from simucal.systematic.calibrate import STEP_STD, run_filter
    from simucal.systematic.method import refusal
    from simucal.turntable.sequence import psins19
    meta, samples, segments, _ = simulate_sequence(mems_unit(1), psins19(rest_s=30.0), 1)
    ms = io.MeasurementSet(Path("mems"), meta, samples, segments)
    early = run_filter(ms, max_passes=2)
    assert early.step_std > STEP_STD
    refused = refusal(early, ms.path)
    assert "did not converge: the last of 2 still moved an estimate" in refused.why
    assert refusal(run_filter(ms), ms.path) is None
    from simucal.report.console import next_command  # diagnose's next: no plan shows convergence
    diag = {"input": "mems", "acc": {"calibrate_refuses": refused.why,
                                     "next_instead": {"command": refused.next, "note": refused.note}}, "gyro": {}}
    command, notes = next_command(diag)
    assert command.startswith("record the sequence again with slower turns") and "did not converge" in notes[0]
