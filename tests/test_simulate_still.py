"""simulate's still scenarios: a unit at rest whose noise terms `noise` finds within their stds over seeds,
a still board warming up that `calibrate --thermal` takes, each with its truth.json, and the options they
cannot use refused."""
import numpy as np
import pytest
from click.testing import CliRunner
from cli_helpers import refused

import simucal
from simucal.cli import main
from simucal.errors import InputError


def test_the_still_streams_white_noise_is_found_within_its_stds_over_seeds():
    """10 seeds of 5 minutes: the angle and velocity random walks' error / std has an rms within 0.5-1.6 on
    every axis pooled, and the truth named in truth.json is the one simulated."""
    z = {"gyro": [], "acc": []}
    for seed in range(10):
        ms = simucal.simulate("still", seed=seed, duration_s=300.0)
        truth = ms.truth["noise"]
        report = simucal.noise(ms).report
        for sensor, true in (("gyro", truth["gyro"]["arw_deg_sqrt_h"]), ("acc", truth["acc"]["vrw_g_sqrt_s"] * 1e6)):
            for axis in "xyz":
                n = report[sensor]["axes"][axis]["sheet"]["N"]  # deg/sqrt(h); ug/sqrt(Hz), = ug*sqrt(s)
                z[sensor].append((n["value"] - true) / n["std"])
    for sensor, values in z.items():
        rms = float(np.sqrt(np.mean(np.square(values))))
        assert 0.5 < rms < 1.6, (sensor, rms)


def test_the_warm_up_is_calibrated_over_temperature_from_the_command_line(tmp_path):
    r = CliRunner().invoke(main, ["simulate", "--scenario", "warmup", "--duration-s", "900", "--seed", "3",
                                  "-o", str(tmp_path / "warm")])
    assert r.exit_code == 0 and "warmup scenario, seed 3" in r.output, r.output
    ms = simucal.read_set(tmp_path / "warm")
    assert ms.truth["t_ref_c"] == 37.5 and "temp_c" in ms.samples
    cal = simucal.calibrate(ms, thermal=True, t_ref_c=ms.truth["t_ref_c"])
    for i, a in enumerate("xyz"):
        f = cal.gyro.thermal["parameters"][f"b_{a}"]
        true = ms.truth["gyro"]["bias_dph"][f"b_{a}"][:len(f["coefficients"])]
        assert abs(f["coefficients"][0] - true[0]) < 5 * f["std"][0], (a, f["coefficients"][0], true[0])


@pytest.mark.parametrize("scenario, options, named", [
    ("still", {"effects": {"acc.quadratic.z": 1e-4}}, "effects (--effect)"),
    ("warmup", {"unit_seed": 2}, "unit_seed (--unit-seed)"),
    ("paper", {"duration_s": 60.0}, "duration_s (--duration-s)"),
    ("still", {"plan": "table1"}, "plan (--plan)"),
])
def test_an_option_the_still_scenarios_cannot_use_is_refused(scenario, options, named):
    with pytest.raises(InputError, match=named.replace("(", r"\(").replace(")", r"\)")):
        simucal.simulate(scenario, **options)


def test_the_command_refuses_seconds_for_a_turntable(tmp_path):
    refused(CliRunner().invoke(main, ["simulate", "--duration-s", "60", "-o", str(tmp_path / "x")]),
            "duration_s (--duration-s) 60")
    assert not (tmp_path / "x").exists()
