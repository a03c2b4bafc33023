"""Designed rotation sequences. The built-ins fitted to a table time, PSINS' published
19 positions turned about the unit's own axes, the design never worse than the built-in it starts from
and the same call designing the same sequence, what it writes read back by simulate and calibrated, the
unit taken from a calibration file, and what it cannot use refused in one line."""
import json

import numpy as np
import pytest

import simucal
from simucal.errors import InputError
from simucal.fit.rotations import log_so3
from simucal.generated import table
from simucal.turntable.simulate import unit_from_calibration
from simucal.turntable import sequence as seq
from tests.cli_helpers import refused, run


def test_a_sequence_fitted_to_minutes_keeps_its_moves_and_pauses_and_lasts_them():
    for make in seq.SEQUENCES.values():
        steps = make()
        fitted = seq.in_minutes(steps, 20.0)
        assert seq.duration_s(fitted) == pytest.approx(1200.0)
        assert [(s.axis, s.angle_deg, s.rate_dps) for s in fitted] == [(s.axis, s.angle_deg, s.rate_dps) for s in steps]
    pauses = [s.rest_s for s in seq.in_minutes(seq.dong2018(), 20.0) if s.rest_s < seq.MIN_REST_S]
    assert pauses and set(pauses) == {1.0}  # one position's axes turn one after another, as written
    with pytest.raises(InputError, match="psins19: its 18 moves leave rests under 5 s in 4 min"):
        seq.in_minutes(seq.psins19(), 4.0, "psins19")


def test_sysclbt19_turns_about_the_unit_axes_of_psins_published_scheme():
    """PSINS' rows turn about its y, y, y, -y, -y, -y, z, x x x, -x -x -x, z z, -z -z -z; its x, y, z are this
    table's z, x, y (the docstring's relabelling): each move must turn the unit 90 deg about that axis."""
    psins_axis = [1] * 6 + [2] + [0] * 6 + [2] * 5
    psins_sign = [1, 1, 1, -1, -1, -1, 1, 1, 1, 1, -1, -1, -1, 1, 1, -1, -1, -1]
    ours = {0: 2, 1: 0, 2: 1}
    at = np.zeros(3)
    for s, a, sign in zip(seq.sysclbt19(), psins_axis, psins_sign):
        before = table.C_k_n(*np.radians(at), np.zeros(7))
        at[seq.AXES.index(s.axis)] += s.angle_deg
        turned = np.degrees(log_so3(before.T @ table.C_k_n(*np.radians(at), np.zeros(7))))
        assert turned == pytest.approx(90.0 * sign * np.eye(3)[ours[a]], abs=1e-9)


@pytest.fixture(scope="module")
def designed():
    return simucal.design_sequence(5.0, evaluations=40)


def test_the_design_is_no_worse_than_its_start_and_the_same_call_designs_the_same(designed):
    assert designed["worst_ratio"] <= designed["built_in"][designed["start"]] + 1e-12
    assert designed["worst_ratio"] == max(x["ratio"] for x in designed["parameters"])
    steps = designed["sequence"]["steps"]
    assert seq.duration_s([seq.Step(**s) for s in steps]) == pytest.approx(300.0)
    assert all(s["rate_dps"] == 60.0 and s["rest_s"] >= seq.MIN_REST_S for s in steps)
    again = simucal.design_sequence(5.0, evaluations=40)
    assert again["sequence"] == designed["sequence"] and again["worst_ratio"] == designed["worst_ratio"]


def test_the_reference_in_its_own_minutes_sets_the_targets(designed):
    """The targets are the reference's stds: a reference given twice the time sets each target lower."""
    longer = simucal.design_sequence(5.0, reference_minutes=10.0, evaluations=3)
    for a, b in zip(designed["parameters"], longer["parameters"]):
        assert b["target"] < a["target"]
    assert longer["reference"]["name"] == "psins19" and longer["reference_minutes"] == 10.0
    best = simucal.design_sequence(5.0, reference="best", evaluations=3)  # each target the built-ins' smallest
    assert best["reference"]["name"] == "best of psins19, sysclbt19, dong2018"
    assert all(b["target"] <= a["target"] for a, b in zip(designed["parameters"], best["parameters"]))
    assert any(b["target"] < 0.5 * a["target"] for a, b in zip(designed["parameters"], best["parameters"]))


def test_plan_design_writes_a_sequence_that_simulate_reads_and_calibrate_calibrates(tmp_path):
    r = run("plan", "--sequence", "--design", "--minutes", "5", "--evaluations", "3", "-o", tmp_path / "d.csv")
    assert r.exit_code == 0, r.output
    assert "targets: psins19's stds in 5 min" in r.output and "worst ratio" in r.output
    sidecar = json.loads((tmp_path / "d.json").read_text())
    assert [vars(s) for s in seq.read_sequence(tmp_path / "d.csv")] == sidecar["sequence"]["steps"]
    ms = simucal.simulate(sequence=str(tmp_path / "d.csv"), seed=3)
    cal = simucal.calibrate(ms, method="systematic")
    z = [(cal.acc.params[k] - v) / cal.acc.std[k] for k, v in ms.truth["acc"]["params"].items()]
    assert np.max(np.abs(z)) < 4.5 and cal.acc.p_value > 1e-3


def test_the_unit_comes_from_a_systematic_calibration_file(tmp_path):
    ms = simucal.simulate(sequence=str(_short(tmp_path)), seed=1)
    ms.write(tmp_path / "set")
    path = tmp_path / "cal.json"
    simucal.save(path, simucal.calibrate(tmp_path / "set", method="systematic"))
    stated = json.loads(path.read_text())["systematic"]["white_noise_per_sample"]
    assert stated["rate_hz"] == pytest.approx(100.0)
    # white noise: twice the std per sample at four times the rate
    sc, said = unit_from_calibration(path, rate_hz=400.0)
    assert sc.acc_noise_g == pytest.approx(2 * np.sqrt(np.mean(np.square(stated["acc_g"]))))
    assert sc.gyro_params["b_x"] == pytest.approx(simucal.load(path).gyro.params["b_x"]) and str(path) in said


def test_what_a_design_cannot_use_is_refused(tmp_path):
    exact = tmp_path / "exact.json"
    simucal.save(exact, simucal.calibrate(simucal.simulate(seed=0), method="exact"))
    with pytest.raises(InputError, match="states no white noise per sample with its rate.*--acc-noise-g"):
        unit_from_calibration(exact)
    assert unit_from_calibration(exact, 1e-4, 1.0)[0].acc_noise_g == 1e-4
    refused(run("plan", "--minutes", "5", "--score", "table1"), "--minutes", "a sequence's design")
    refused(run("plan", "--sequence", "--design", "--score", "table1"), "--score", "without --design")
    refused(run("plan", "--sequence", "--design", "--minutes", "1"), "leave rests under 5 s")


def _short(tmp_path):
    path = tmp_path / "short.csv"
    seq.write_sequence(path, seq.in_minutes(seq.sysclbt19(rate_dps=60.0), 6.0))
    return path
