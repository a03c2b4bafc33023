"""A still board warming up (simucal/handheld/warmup.py): each axis's bias over temperature with
honest stds where the bias also wanders in time, a model test that holds its level, the autopilots' files
with the log's device ids, and refusals that say what still data can give."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from cli_helpers import refused

import simucal

from simucal.api.calibrating import calibrate
from simucal.cli import main
from simucal.errors import CalibrationError
from simucal.handheld.warmup import calibrate_warmup
from simucal.handheld.simulate import WARMUP_ACC_G, WARMUP_GYRO_DPH, WARMUP_T_REF_C, simulate_warmup

T_REF = WARMUP_T_REF_C
ACC_G, GYRO_DPH = np.array(WARMUP_ACC_G), np.array(WARMUP_GYRO_DPH)


def warmup(seed, seconds=1500.0, hz=50.0, wander=True):
    """simulate's warm-up (a still board from 15 to 58 degC, a cubic bias per axis); `wander`: the bias's random
    walk in time, as a MEMS unit's."""
    meta, samples, _ = simulate_warmup(seed, seconds, hz, wander)
    return simucal.MeasurementSet(Path(f"warmup_seed{seed}"), meta, samples, None)


@pytest.mark.slow
def test_the_bias_curves_stds_hold_over_seeds_though_the_bias_wanders():
    """30 seeds: every coefficient's error / std has an rms within 0.75-1.3 (the gyro's full bias, the
    accelerometer's change over temperature), the cubic found on every axis, the model test at its level."""
    z = {"acc": [], "gyro": []}
    fails = 0
    for seed in range(30):
        cal = calibrate_warmup(warmup(seed), t_ref_c=T_REF)
        for sensor, truth in (("acc", ACC_G), ("gyro", GYRO_DPH)):
            block = getattr(cal, sensor)
            for i, a in enumerate("xyz"):
                f = block.thermal["parameters"][f"b_{a}"]
                assert f["degree"] == 3
                first = 1 if sensor == "acc" else 0  # the accelerometer's constant is not seen (gravity)
                z[sensor].append((np.array(f["coefficients"]) - truth[i])[first:] / np.array(f["std"])[first:])
                fails += f["p_value"] < 1e-3
    for sensor, values in z.items():
        rms = np.sqrt(np.mean(np.square(values), axis=0))
        assert np.all((rms > 0.75) & (rms < 1.3)), (sensor, rms)
    assert fails <= 2  # of 180 tests at 1e-3


def test_a_missing_cubic_fails_the_model_test_and_without_a_wander_the_stds_are_conservative():
    cal = calibrate_warmup(warmup(1, wander=False), t_ref_c=T_REF)
    for i, a in enumerate("xyz"):
        f = cal.gyro.thermal["parameters"][f"b_{a}"]
        z = (np.array(f["coefficients"]) - GYRO_DPH[i]) / np.array(f["std"])
        assert np.all(np.abs(z) < 3) and f["p_value"] > 1e-3
    ms = warmup(2, wander=False)
    T = ms.samples["temp_c"]
    ms.samples["gx"] = ms.samples["gx"] + 40.0 * np.sin((T - 15) / 6.0)  # no cubic follows this
    assert calibrate_warmup(ms).gyro.thermal["parameters"]["b_x"]["p_value"] < 1e-3


def test_the_px4_file_holds_the_logs_device_ids(tmp_path):
    from log_writers import write_ulog
    from test_logs import still_board
    acc, gyro = still_board(seconds=300.0, acc_hz=50.0, gyro_hz=100.0)
    write_ulog(tmp_path / "w.ulg", acc, gyro)
    assert CliRunner().invoke(main, ["import", "ulog", str(tmp_path / "w.ulg"), "-o", str(tmp_path / "s"),
                                     "--latitude-deg", "47"]).exit_code == 0
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "s"), "--thermal", "-o", str(tmp_path / "c.json"),
                                  "--px4", str(tmp_path / "tc.params"), "--ardupilot", str(tmp_path / "tc.param"),
                                  "--html", str(tmp_path / "tc.html")])
    assert r.exit_code == 0, r.output
    # the page: each sensor's verdict, and a figure (the curve and its 68 % band) per bias that follows temperature
    page = (tmp_path / "tc.html").read_text()
    cal = simucal.load(tmp_path / "c.json")
    curves = [n for _, b in cal.blocks() for n, f in b.thermal["parameters"].items() if f["degree"] > 0]
    assert curves and page.count("<img") == len(curves)
    assert all(f"{s}: PASSES" in page or f"{s}: FAILS" in page for s in ("acc", "gyro"))
    simucal.save(tmp_path / "again.html", cal)
    assert (tmp_path / "again.html").read_text().count("<img") == len(curves)
    text = (tmp_path / "tc.params").read_text()
    assert "TC_A0_ID\t1442826\t6" in text and "TC_G0_ID\t2490378\t6" in text
    assert "INS_TCAL1_ENABLE,1" in (tmp_path / "tc.param").read_text()
    assert "a still warm-up" in r.output and "scale factors and misalignments stay nominal" in r.output


def test_still_data_say_what_they_can_give(tmp_path):
    ms = warmup(3, seconds=120.0)
    T = np.full(len(ms.samples["t_s"]), 25.0)
    flat = simucal.MeasurementSet.from_arrays(ms.raw("acc"), ms.raw("gyro"), acc_unit="g", gyro_unit="deg/h",
                                              t_s=ms.samples["t_s"], temp_c=T, meta={"latitude_deg": 47.0})
    with pytest.raises(CalibrationError, match="spans 0 degC.*simucal noise"):
        calibrate_warmup(flat)
    flat.write(tmp_path / "still")
    with pytest.raises(CalibrationError, match=r"no motion.*calibrate SET --thermal.*simucal noise"):
        calibrate(tmp_path / "still")
    refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "still"), "--thermal", "--thermal-degree", "2",
                                      "-o", str(tmp_path / "c.json")]), "--thermal-degree",
            "takes its degree from the data")
    refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "still"), "--thermal", "--add", "acc.quadratic.z",
                                      "-o", str(tmp_path / "c.json")]), "--add", "no effects")


def test_validated_on_another_warm_up_of_the_unit(tmp_path):
    """calibrate one warm-up, validate on another of the same unit: each axis's change over the warm-up falls
    from the thermal curve's (mg, hundreds of deg/h) to near the block means' noise; on a moving stream the
    check is refused by name."""
    from simucal.api.validating import validation_report as validate
    warmup(0).write(tmp_path / "a")
    warmup(1).write(tmp_path / "b")
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "a"), "--thermal", "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    report = validate(str(tmp_path / "c.json"), str(tmp_path / "b"))
    acc, gyro = report["checks"]["acc"][0], report["checks"]["gyro"][0]
    assert acc["after_rms"] < acc["before_rms"] / 10 and gyro["after_rms"] < 2 * gyro["floor_rms"]
    assert report["verdict"]["gyro"] == "at the noise floor" and report["verdict"]["acc"] in ("better",
                                                                                              "at the noise floor")
    ms = warmup(2)
    acc = ms.raw("acc").copy()
    acc[len(acc) // 2:] = acc[len(acc) // 2:, ::-1]  # turned onto its side half way
    simucal.MeasurementSet.from_arrays(acc, ms.raw("gyro"), acc_unit="g", gyro_unit="deg/h", t_s=ms.samples["t_s"],
                                       temp_c=ms.samples["temp_c"],
                                       meta={"latitude_deg": 47.0}).write(tmp_path / "moving")
    with pytest.raises(CalibrationError, match="validated on another still warm-up"):
        validate(str(tmp_path / "c.json"), str(tmp_path / "moving"))


def test_a_warm_up_reads_its_temperature_as_every_thermal_path_does(tmp_path):
    """Two holds (25 then 45 degC) give a line, said, and no model test where none can be made; temp_c in
    kelvin, or stated as degF in meta.json, is refused as the plateaus' temp_c is."""
    ms = warmup(4, seconds=600.0)
    n = len(ms.samples["t_s"])
    holds = np.where(np.arange(n) < n // 2, 25.0, 45.0) + np.random.default_rng(0).normal(0, 0.05, n)

    def board(T, **meta):
        return simucal.MeasurementSet.from_arrays(ms.raw("acc"), ms.raw("gyro"), acc_unit="g", gyro_unit="deg/h",
                                                  t_s=ms.samples["t_s"], temp_c=T, meta={"latitude_deg": 47.0, **meta})
    cal = calibrate_warmup(board(holds))
    for _, b in cal.blocks():
        for a in "xyz":
            f = b.thermal["parameters"][f"b_{a}"]
            assert f["degree"] <= 1 and "2 temperatures seen" in f["degree_from"]
            assert f["dof"] == 1 - f["degree"] and (f["p_value"] is None) == (f["degree"] == 1)
    with pytest.raises(CalibrationError, match="kelvin"):
        calibrate_warmup(board(np.asarray(ms.samples["temp_c"]) + 273.15))
    with pytest.raises(CalibrationError, match="degF"):
        calibrate_warmup(board(ms.samples["temp_c"], temp_unit="degF"))


def test_a_second_imu_is_exported_into_its_own_slot(tmp_path):
    """PX4's instance 1 writes TC_A1_* / TC_G1_* with its device ids, ArduPilot's IMU2 INS_TCAL2_*: never the
    first IMU's slot."""
    from log_writers import write_dataflash, write_ulog
    from test_logs import still_board
    acc, gyro = still_board(seconds=300.0, acc_hz=50.0, gyro_hz=100.0)
    write_ulog(tmp_path / "w.ulg", acc, gyro, instance=1)
    imu = {"t_us": acc["t_us"], "acc": np.column_stack([acc[k] for k in "xyz"]),
           "gyro": np.column_stack([acc[k] * 0.01 for k in "xyz"]), "temperature": acc["temperature"]}
    write_dataflash(tmp_path / "w.bin", [imu, imu], numbered=True, params={"INS_ACC2_ID": 11, "INS_GYR2_ID": 12})
    for fmt, log, out in (("ulog", "w.ulg", "px4"), ("dataflash", "w.bin", "ap")):
        assert CliRunner().invoke(main, ["import", fmt, str(tmp_path / log), "-o", str(tmp_path / out),
                                         "--latitude-deg", "47", "--instance", "1"]).exit_code == 0
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "px4"), "--thermal", "-o", str(tmp_path / "c.json"),
                                  "--px4", str(tmp_path / "tc.params")])
    assert r.exit_code == 0, r.output
    text = (tmp_path / "tc.params").read_text()
    assert "TC_A1_ID\t1442826\t6" in text and "TC_G1_X3_2" in text and "TC_A0_" not in text and "TC_G0_" not in text
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "ap"), "--thermal", "-o", str(tmp_path / "d.json"),
                                  "--ardupilot", str(tmp_path / "tc.param")])
    assert r.exit_code == 0, r.output
    text = (tmp_path / "tc.param").read_text()
    assert "INS_TCAL2_ENABLE,1" in text and "INS_TCAL1_" not in text and "INS_ACC2_CALTEMP" in text


def test_a_board_turned_during_its_warm_up_and_stream_options_are_named(tmp_path):
    """A board turned 90 deg half-way is refused as a board that moved (not as too few poses); a hand session's
    options on a still warm-up are refused by name, not ignored."""
    ms = warmup(2, seconds=900.0)
    acc = ms.raw("acc").copy()
    half = np.arange(len(acc)) >= len(acc) // 2
    acc[half] = acc[half][:, [0, 2, 1]] * [1, 1, -1]  # turned 90 deg about x
    simucal.MeasurementSet.from_arrays(acc, ms.raw("gyro"), acc_unit="g", gyro_unit="deg/h", t_s=ms.samples["t_s"],
                                       temp_c=ms.samples["temp_c"],
                                       meta={"latitude_deg": 47.0}).write(tmp_path / "turned")
    refused(CliRunner().invoke(main,
                               ["calibrate", str(tmp_path / "turned"), "--thermal", "-o", str(tmp_path / "c.json")]),
            "the board moved during the warm-up", "2 stretches", "up to 90 deg apart")
    warmup(2, seconds=300.0).write(tmp_path / "still")
    for option in (["--window-s", "2"], ["--min-static-s", "3"], ["--timestamps", "nominal"]):
        refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "still"), "--thermal", *option, "-o",
                                          str(tmp_path / "c.json")]), option[0], "a still warm-up")


def test_a_gap_in_a_warm_up_is_named():
    ms = warmup(6, seconds=600.0)
    t = np.asarray(ms.samples["t_s"])
    keep = (t < 200) | (t > 205)  # 5 s of both sensors missing
    gappy = simucal.MeasurementSet.from_arrays(ms.raw("acc")[keep], ms.raw("gyro")[keep], acc_unit="g",
                                               gyro_unit="deg/h", t_s=t[keep], temp_c=ms.samples["temp_c"][keep],
                                               meta={"latitude_deg": 47.0})
    cal = calibrate_warmup(gappy)
    assert any("1 gap in t_s (5.04 s from t = 199.98 s" in w for w in cal.warnings), cal.warnings
    assert not any("gap" in w for w in calibrate_warmup(ms).warnings)
