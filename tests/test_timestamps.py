"""Real loggers' sessions (issue 38, item 3): as many poses as parameters, and a logger's time stamps."""
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


def test_zero_dof_turntable_gyro_says_no_test(tmp_path):
    """Nine positions and nine rate runs: the gyro's block has 0 dof; calibrate writes it and says so."""
    from simucal.turntable import plans
    plan = tmp_path / "p9.csv"
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(
        f"{a},{b},{c}\n" for a, b, c in plans.PLANS["fibonacci24"]()[:9]))
    write(tmp_path / "t", Scenario(plan=str(plan), unify_positions=False), 1)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "t"), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    assert "gyro: residual rms" in r.output and "dof 0" in r.output and "no test possible" in r.output
