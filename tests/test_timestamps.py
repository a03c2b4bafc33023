"""Real loggers' sessions: as many poses as parameters, and a logger's time stamps."""
import json

import numpy as np
from click.testing import CliRunner

from simucal.cli import main
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.turntable.simulate import Scenario, write


def test_as_many_poses_as_parameters_calibrates_and_says_no_test(tmp_path):
    """Nine poses (the rest and eight) for the accelerometer's nine parameters: 0 dof. The fit passes
    through every pose (the ellipsoid start from nine rows), the console says no test is possible, and
    the biases (8 g of raw offset) come within 4 std of truth."""
    truth = write_handheld(tmp_path / "s", HandheldScenario(poses=8), 1)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "s"), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    assert "acc: residual rms" in r.output and "dof 0: no test possible" in r.output
    acc = json.loads((tmp_path / "c.json").read_text())["acc"]
    assert acc["dof"] == 0 and acc["p_value"] is None
    z = [(acc["params"][f"b_{a}"] - b) / acc["std"][f"b_{a}"] for a, b in zip("xyz", truth["acc"]["bias"])]
    assert np.max(np.abs(z)) < 4, z


def test_nine_rate_runs_leave_the_gyro_tested_at_rest(tmp_path):
    """Nine positions and nine rate runs: the rate runs hold as many rows as the gyro's parameters (0 dof,
    where the console's formatter died on p = None); its static rows still test it."""
    from simucal.turntable import plans
    plan = tmp_path / "p9.csv"
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(
        f"{a},{b},{c}\n" for a, b, c in plans.PLANS["fibonacci24"]()[:9]))
    write(tmp_path / "t", Scenario(plan=str(plan), unify_positions=False), 1)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "t"), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    gyro = json.loads((tmp_path / "c.json").read_text())["gyro"]
    assert "gyro: residual rms" in r.output and "over 9 rate runs and 9 static positions" in r.output
    assert gyro["dof"] == 18 and gyro["p_value"] is not None and gyro["static_rows"]["dof"] == 18


def _logger_stamps(n, step_s=0.01, late_s=0.00024, wrap_s=0.005):
    """A logger's arrival times of a sensor clocked every step_s: a latency that grows by late_s per
    sample and is paid back (a catch-up step) when it reaches wrap_s: median step 10.24 ms, mean 10.00."""
    i = np.arange(n)
    return i * step_s + (i * late_s) % wrap_s


def _logged_session(tmp_path, stamps):
    from simucal import io
    write_handheld(tmp_path / "true", HandheldScenario(poses=20, move_s=0.6, peak_rate_dps=190.0, gyro_noise_dps=0.005,
                                                       acc_noise_g=2e-4), 3)
    ms = io.read_set(tmp_path / "true")
    io.write_set(tmp_path / "logged", ms.meta, {**ms.samples, "t_s": stamps(len(ms.samples["t_s"]))})
    return tmp_path / "logged"


def _gyro_chi2(tmp_path, folder, *options):
    out = tmp_path / f"c{len(options)}.json"
    r = CliRunner().invoke(main, ["calibrate", str(folder), "-o", str(out), *options])
    assert r.exit_code == 0, r.output
    cal = json.loads(out.read_text())
    return cal["gyro"]["chi2"] / cal["gyro"]["dof"], cal, r.output


def test_a_loggers_arrival_times_are_named_and_integrated_on_the_sensors_clock(tmp_path):
    """Quick moves (0.6 s, 190 deg/s) stamped by a logger: as recorded the moves misfit (chi2/dof ~4.5);
    auto finds the stamps irregular, within half a step of an even clock, and integrates on it: the
    misfit falls 3x or more, to a passing test; the console and the file name the statistics."""
    folder = _logged_session(tmp_path, _logger_stamps)
    recorded, _, _ = _gyro_chi2(tmp_path, folder, "--timestamps", "recorded")
    auto, cal, text = _gyro_chi2(tmp_path, folder)
    st = cal["timestamps"]
    assert st["irregular"] and st["regular_clock"] and st["used"] == "nominal"
    assert abs(st["median_step_ms"] - 10.24) < 0.01 and abs(st["mean_step_ms"] - 10.0) < 0.01
    assert st["catch_up_steps"] > 0 and abs(st["catch_up_median_ms"] - 5.24) < 0.1
    assert "time stamps: irregular: median step 10.24 ms, mean 10 ms" in text and "catch-up steps" in text
    assert recorded > 3 * auto and cal["gyro"]["p_value"] > 0.01, (recorded, auto)


def test_stamps_that_lose_samples_are_kept(tmp_path):
    """Regular stamps are left alone; stamps with 20 samples lost stray 10 steps from an even clock:
    auto keeps them as recorded and says why; nominal on a turntable set is refused in one line."""
    from simucal.io.timestamps import statistics
    t = np.arange(5000) * 0.01
    assert not statistics(t)["irregular"]
    lost = np.delete(_logger_stamps(5000), np.arange(2000, 2020))
    st = statistics(lost)
    assert st["irregular"] and not st["regular_clock"] and st["off_even_clock_steps"] > 5
    folder = _logged_session(tmp_path, lambda n: np.r_[_logger_stamps(n // 2), 0.2 + _logger_stamps(n - n // 2)
                                                        + (n // 2) * 0.01])
    _, cal, text = _gyro_chi2(tmp_path, folder)
    assert cal["timestamps"]["used"] == "recorded" and "so they are kept" in text
    write(tmp_path / "table", Scenario(), 1)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "table"), "-o", str(tmp_path / "t.json"),
                                  "--timestamps", "nominal"])
    assert r.exit_code != 0 and "--timestamps nominal" in r.output + (r.stderr or "")


def test_a_gap_is_named_never_spread(tmp_path):
    """A stream with an hour missing in the middle. --timestamps nominal would spread the hour over
    every step: refused, naming where and how long; auto keeps the stamps, and the console and the file name
    the gap (it was 'regular: step 10 ms' with no line, and the file's irregular false)."""
    from cli_helpers import refused
    from simucal import io
    write_handheld(tmp_path / "true", HandheldScenario(), 3)
    ms = io.read_set(tmp_path / "true")
    t = ms.samples["t_s"].copy()
    half = len(t) // 2
    t[half:] += 3600.0
    io.write_set(tmp_path / "gap", ms.meta, {**ms.samples, "t_s": t})
    refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "gap"), "-o", str(tmp_path / "n.json"),
                                      "--timestamps", "nominal"]),
            "--timestamps nominal would spread", "1 gap in t_s (3600 s from t =", "samples missing")
    assert not (tmp_path / "n.json").exists()
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "gap"), "-o", str(tmp_path / "a.json")])
    assert r.exit_code == 0, r.output
    assert "1 gap in t_s (3600 s from t =" in r.output and "no move is integrated across one" in r.output
    st = json.loads((tmp_path / "a.json").read_text())["timestamps"]
    assert st["used"] == "recorded" and len(st["gaps"]) == 1 and st["gaps"][0]["after_row"] == half - 1


def test_a_sequence_with_samples_missing_in_a_move_is_refused_naming_the_segment(tmp_path):
    """Ten samples missing inside a move of a rotation sequence (was THE MODEL FAILS, chi2 6e9,
    and diagnose sent the user after a missing effect)."""
    from cli_helpers import refused
    from simucal import api, io
    api.simulate(scenario="sequence").write(tmp_path / "seq")
    ms = io.read_set(tmp_path / "seq")
    move = next(s.segment for s in ms.segments if s.kind == "move")
    rows = ms.rows(move)
    keep = np.ones(len(ms.samples["t_s"]), bool)
    keep[rows[len(rows) // 2:len(rows) // 2 + 10]] = False
    io.write_set(tmp_path / "cut", ms.meta, {k: v[keep] for k, v in ms.samples.items()}, ms.segments)
    refused(CliRunner().invoke(main, ["calibrate", str(tmp_path / "cut"), "--method", "systematic", "-o",
                                      str(tmp_path / "c.json")]),
            "1 gap in t_s", "10 samples missing", f"the first in segment {move}", "cannot bridge missing samples")


def test_a_gap_inside_a_turntable_segment_is_named(tmp_path):
    """A raw turntable set with 40 samples missing inside one static segment: calibrated (a mean takes its rows
    as they are), and the console, the file and diagnose's notes name the gap and its segment."""
    from simucal import io
    write(tmp_path / "t", Scenario(rate_hz=20.0), 1)
    ms = io.read_set(tmp_path / "t")
    seg = next(s.segment for s in ms.segments if s.kind == "static")
    rows = ms.rows(seg)
    keep = np.ones(len(ms.samples["t_s"]), bool)
    keep[rows[10:50]] = False
    io.write_set(tmp_path / "gap", ms.meta, {k: v[keep] for k, v in ms.samples.items()}, ms.segments)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "gap"), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    assert "1 gap in t_s" in r.output and "40 samples missing" in r.output and f"inside segment {seg}" in r.output
    assert json.loads((tmp_path / "c.json").read_text())["timestamps"]["gaps"][0]["segment"] == seg
    r = CliRunner().invoke(main, ["diagnose", str(tmp_path / "gap"), "-o", str(tmp_path / "d.json")])
    assert (r.exit_code == 0
            and "40 samples missing" in json.dumps(json.loads((tmp_path / "d.json").read_text())["notes"]))


def test_validate_reads_a_loggers_stamps_as_the_calibration_did(tmp_path):
    """A session calibrated on the sensor's clock, validated on another session of the same
    unit whose stamps a logger wrote. validate reads them as the calibration did (the line says so), both arms
    take this session's own rest bias, and the gyro's direction check has a floor: with the logger's stamps it
    equals the check on the true stamps within that floor, and the calibrated gyro is at it."""
    import simucal
    from simucal import io
    unit = HandheldScenario(poses=20, move_s=0.6, peak_rate_dps=190.0, gyro_noise_dps=0.005, acc_noise_g=2e-4)
    cal = simucal.calibrate(_logged_session(tmp_path / "a", _logger_stamps))
    assert cal.details["timestamps"]["used"] == "nominal"
    from simucal.handheld.simulate import simulate_handheld
    meta, samples, _ = simulate_handheld(unit, 8, unit_seed=3)  # the unit of _logged_session, another session
    io.write_set(tmp_path / "b_true", meta, samples)
    ms = io.read_set(tmp_path / "b_true")
    io.write_set(tmp_path / "b_logged", ms.meta, {**ms.samples, "t_s": _logger_stamps(len(ms.samples["t_s"]))})
    checks = {}
    for name in ("b_true", "b_logged"):
        v = simucal.validate(cal, tmp_path / name)
        checks[name] = v.report["checks"]["gyro"][0]
    true, logged = checks["b_true"], checks["b_logged"]
    assert v.report["timestamps"]["used"] == "nominal"
    assert true["floor_rms"] and abs(logged["after_rms"] - true["after_rms"]) < true["floor_rms"], (true, logged)
    assert logged["verdict"] == "at the noise floor", logged
    simucal.save(tmp_path / "c.json", cal)
    r = CliRunner().invoke(main, ["validate", str(tmp_path / "c.json"), str(tmp_path / "b_logged"), "-o",
                                  str(tmp_path / "v.json")])
    assert r.exit_code == 0, r.output
    assert "time stamps: irregular: median step 10.24 ms" in r.output and "a regular clock took them" in r.output
