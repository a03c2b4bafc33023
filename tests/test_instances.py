"""Two IMUs of one log warming up (a PX4 ULog and an ArduPilot DataFlash log, by tests/log_writers.py): one
import writes a set per instance, one calibrate command calibrates both, and each autopilot slot holds its own
instance's curves and device id, as close to its truth as the instance calibrated alone."""
import json

import numpy as np
import pytest
from click.testing import CliRunner
from cli_helpers import refused
from log_writers import write_dataflash, write_ulog
from test_autopilot import _read_ardupilot, _read_px4, ardupilot_correction, px4_offsets

import simucal
from simucal.cli import main
from simucal.errors import CalibrationError

G = 9.80665
T_MID = 37.5
# per instance: a cubic bias in (T - T_MID) per axis, m/s^2 and rad/s; each instance its own
ACC = [np.array([[0.02, 4e-4, -2e-5, 1e-6], [-0.01, -3e-4, 1e-5, 2e-6], [0.015, 2e-4, 3e-5, -1.5e-6]]),
       np.array([[-0.03, -2e-4, 1e-5, -1e-6], [0.02, 5e-4, -2e-5, 0.0], [-0.01, -4e-4, 0.0, 1e-6]])]
GYRO = [np.array([[2e-3, 3e-5, -6e-7, 2e-8], [-1e-3, -2e-5, 4e-7, 1.5e-8], [5e-4, 1.5e-5, 3e-7, -2e-8]]),
        np.array([[-4e-3, -1e-5, 5e-7, -1e-8], [3e-3, 4e-5, -2e-7, 0.0], [-2e-3, -3e-5, 0.0, 2e-8]])]
ACC_IDS, GYRO_IDS = (1442826, 1442834), (2490378, 2490386)


def warmup(seed, seconds=600.0, hz=50.0):
    """Each instance's sensor_accel and sensor_gyro topics (PX4's columns) of one board warming 15 -> 57 degC,
    each sensor at its own jittered stamps, white noise only; instance 1 a degree warmer."""
    rng = np.random.default_rng(seed)
    out = []
    for k in (0, 1):
        def topic(truth, white, device_id):
            t = np.arange(0, seconds, 1 / hz) + rng.uniform(0, 0.1 / hz, int(round(seconds * hz)))
            T = 15 + k + 42 * (1 - np.exp(-t / (seconds / 3.0)))
            xyz = ((T - T_MID)[:, None] ** np.arange(4)) @ truth.T + rng.normal(0, white, (len(t), 3))
            return {"t_us": np.round(t * 1e6), "x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "temperature": T,
                    "device_id": device_id}
        gravity = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [-G, 0, 0, 0]])
        out.append((topic(ACC[k] + gravity, 0.02, ACC_IDS[k]), topic(GYRO[k], 2e-3, GYRO_IDS[k])))
    return out


def _run(*args):
    return CliRunner().invoke(main, [*map(str, args)])


def _rms_error(offsets, truth, T, change=False):
    """rms over T of each axis's curve (3, n) less the truth's; change: of each curve's change from its value
    at T_MID (a still board's accelerometer shows no constant: gravity's)."""
    want = np.stack([np.polynomial.polynomial.polyval(T - T_MID, c) for c in truth])
    if change:
        at = np.argmin(np.abs(T - T_MID))
        offsets, want = offsets - offsets[:, at:at + 1], want - want[:, at:at + 1]
    return np.sqrt(np.mean((offsets - want) ** 2, axis=1))


def test_one_command_calibrates_both_px4_instances_into_their_own_slots(tmp_path):
    imus = warmup(0)
    write_ulog(tmp_path / "w.ulg", [a for a, _ in imus], [g for _, g in imus])
    r = _run("import", "ulog", tmp_path / "w.ulg", "--instance", "all", "-o", tmp_path / "imus", "--latitude-deg", 47)
    assert r.exit_code == 0, r.output
    assert "wrote" in r.output and "instance 1 (sensor_accel+sensor_gyro instance 1" in r.output
    sets = [tmp_path / "imus" / f"instance{k}" for k in (0, 1)]
    assert [json.loads((s / "meta.json").read_text())["log"]["acc_device_id"] for s in sets] == list(ACC_IDS)
    r = _run("calibrate", *sets, "--thermal", "-o", tmp_path / "c.json", "--px4", tmp_path / "tc.params",
             "--html", tmp_path / "tc.html")
    assert r.exit_code == 0, r.output
    assert all((tmp_path / f"c_instance{k}.json").exists() and (tmp_path / f"tc_instance{k}.html").exists()
               for k in (0, 1))
    values, _ = _read_px4(tmp_path / "tc.params")
    assert [n for n in values if n.endswith("_ENABLE")] == ["TC_A_ENABLE", "TC_G_ENABLE"]  # once, as PX4's tool
    T = np.linspace(17.0, 55.0, 50)
    for k in (0, 1):
        assert (values[f"TC_A{k}_ID"], values[f"TC_G{k}_ID"]) == (ACC_IDS[k], GYRO_IDS[k])
        # each slot within the one-instance accuracy: its own instance calibrated alone gives the same curves
        alone = simucal.calibrate([sets[k]], thermal=True)
        own = alone.autopilot_files(sets[k], px4=str(tmp_path / f"alone{k}.params"))[0]
        (tmp_path / f"alone{k}.params").write_text(own.text)
        one, _ = _read_px4(tmp_path / f"alone{k}.params")
        for letter, truth, other, err in (("A", ACC[k], ACC[1 - k], 1e-3), ("G", GYRO[k], GYRO[1 - k], 1e-4)):
            got = px4_offsets(values, letter, T, slot=k)
            np.testing.assert_allclose(got, px4_offsets(one, letter, T, slot=k), rtol=1e-6, atol=1e-9)
            change = letter == "A"
            assert np.all(_rms_error(got, truth, T, change) < err), (k, letter, _rms_error(got, truth, T, change))
            assert np.all(_rms_error(got, other, T, change) > 5 * err)  # not the other instance's curves


def test_one_command_calibrates_both_ardupilot_imus_of_an_older_log(tmp_path):
    """Pre-4.0 logs: IMU and IMU2; INS_TCAL1 and INS_TCAL2 from one command."""
    imus = warmup(1)
    rows = [{"t_us": g["t_us"], "temperature": g["temperature"], "acc": np.c_[a["x"], a["y"], a["z"]],
             "gyro": np.c_[g["x"], g["y"], g["z"]]} for a, g in imus]
    ids = {"INS_ACC_ID": ACC_IDS[0], "INS_ACC2_ID": ACC_IDS[1], "INS_GYR_ID": GYRO_IDS[0], "INS_GYR2_ID": GYRO_IDS[1]}
    write_dataflash(tmp_path / "w.bin", rows, params=ids, numbered=True)
    r = _run("import", "dataflash", tmp_path / "w.bin", "--instance", "0,1", "-o", tmp_path / "imus",
             "--latitude-deg", 47)
    assert r.exit_code == 0, r.output
    sets = [tmp_path / "imus" / f"instance{k}" for k in (0, 1)]
    r = _run("calibrate", *sets, "--thermal", "-o", tmp_path / "c.json", "--ardupilot", tmp_path / "tc.param")
    assert r.exit_code == 0, r.output
    values = _read_ardupilot(tmp_path / "tc.param")
    T = np.linspace(17.0, 55.0, 50)
    for k in (0, 1):
        assert values[f"INS_TCAL{k + 1}_ENABLE"] == 1
        for name, truth, err in (("ACC", ACC[k], 3e-3), ("GYR", GYRO[k], 3e-4)):
            got = ardupilot_correction(values, name, T, 35.0, slot=k)
            want = np.stack([np.polynomial.polynomial.polyval(T - T_MID, c) - np.polynomial.polynomial.polyval(
                35.0 - T_MID, c) for c in truth])
            assert np.all(np.sqrt(np.mean((got - want) ** 2, axis=1)) < err), (k, name)


def test_two_imus_are_never_fitted_as_one_units_plateaus(tmp_path):
    imus = warmup(2, seconds=120.0)
    write_ulog(tmp_path / "w.ulg", [a for a, _ in imus], [g for _, g in imus])
    assert _run("import", "ulog", tmp_path / "w.ulg", "--instance", "all", "-o", tmp_path / "imus",
                "--latitude-deg", 47).exit_code == 0
    with pytest.raises(CalibrationError, match=r"instance0 and .*instance1: two IMUs of a log .* calibrate each apart"):
        simucal.calibrate([tmp_path / "imus" / "instance0", tmp_path / "imus" / "instance1"], thermal=True)
    # an instance the log lacks is named with the ones it has; every set of a folder already written is kept
    r = _run("import", "ulog", tmp_path / "w.ulg", "--instance", "0,3", "-o", tmp_path / "more", "--latitude-deg", 47)
    refused(r, "no IMU source of instance 3 (the log's instances with both sensors: 0, 1)")
    assert not (tmp_path / "more" / "instance0").exists()
    r = _run("import", "ulog", tmp_path / "w.ulg", "--instance", "all", "-o", tmp_path / "imus", "--latitude-deg", 47)
    refused(r, "instance0") and "--force" in r.output
