"""ruan2019 three-position field calibration on simulated sets."""
import numpy as np
import pytest
import sympy as sp
from simucal.derive import field as dfield

from simucal import io
from simucal.errors import CalibrationError
from simucal.field.drift import field_drift
from simucal.field.simulate import FieldScenario, simulate_field, write_field


def test_observability_one_drift_per_position():
    rank, null = dfield.observability()
    assert rank == 7 and len(null) == 1
    v = dict(zip(dfield.STATES, null[0]))
    assert v[sp.Symbol("eps_N", real=True)] == 0  # the north drift is observable
    assert v[sp.Symbol("eps_E", real=True)] != 0 and v[sp.Symbol("phi_U", real=True)] != 0


@pytest.mark.parametrize("seed", range(4))
def test_drifts_within_bound(tmp_path, seed):
    truth = write_field(tmp_path / "f", FieldScenario(heading_error_deg=5.0), seed)
    r = field_drift(tmp_path / "f")
    hist = r["history"]
    err = np.abs(np.array(r["gyro_drift_dph"]) - truth["gyro_drift_dph"])
    assert np.all(err <= np.maximum(0.06, 3 * np.array(r["std_dph"]))), (err, r["std_dph"])
    assert len(hist) == 3 and all(len(h["eps_N_dph"]) == 300 for h in hist)


@pytest.mark.parametrize("attitudes,hidden", [
    (((0, 0, 0), (90, 0, 0), (90, 0, 0.0)), "y (up)"),        # position 3 not rolled
    (((0, 0, 0), (0, 0, 0), (90, 0, 20.0)), "y (up)"),        # positions 1 and 2 alike: hidden [0, -0.94, 0.35]
])
def test_degenerate_geometry_refused(tmp_path, attitudes, hidden):
    write_field(tmp_path / "f", FieldScenario(attitudes_deg=attitudes, attitude_jitter_deg=0.3, duration_s=60), 1)
    with pytest.raises(CalibrationError, match=r"cannot be seen") as e:
        field_drift(tmp_path / "f")
    assert hidden in str(e.value)


def test_missing_heading_reference_refused(tmp_path):
    meta, samples, segments, _ = simulate_field(FieldScenario(duration_s=60), 0)
    segments[1].heading_ref_deg = None
    io.write_set(tmp_path / "f", meta, samples, segments)
    with pytest.raises(CalibrationError, match="segment 2 has no heading_ref_deg"):
        field_drift(tmp_path / "f")


def test_transition_matrix_matches_scipy():
    import scipy.linalg
    from simucal.generated import field as gen

    from simucal.field.drift import expm
    F = gen.error_model(9.80665, 7.292115e-5, np.radians(45.0))
    for dt in (0.01, 1.0, 30.0):
        ref = scipy.linalg.expm(F * dt)
        assert np.abs(expm(F * dt) - ref).max() <= 1e-12 * np.abs(ref).max()


@pytest.mark.slow
def test_field_calibration_is_a_calibration_file_that_apply_corrects_the_drift_with(tmp_path):
    """The field method writes the one calibration format (methods.py registry, chosen by the
    data), apply subtracts the drift, and a method that takes other data is refused naming the one to use."""
    import json

    from click.testing import CliRunner

    from simucal.api.calibrating import calibrate
    from simucal.cli import main
    from simucal.io import calibration
    truth = write_field(tmp_path / "f", FieldScenario(heading_error_deg=2.0), 3)
    r = CliRunner().invoke(main, ["field-drift", str(tmp_path / "f"), "-o", str(tmp_path / "d.json")])
    assert r.exit_code == 0, r.output
    cal = calibration.load(tmp_path / "d.json").to_json()
    assert cal["method"] == "field" and cal["acc"]["nominal"] and "acc" in cal["not_calibrated"]
    assert np.allclose(cal["gyro"]["bias"], cal["field"]["gyro_drift_dph"]) and np.allclose(cal["gyro"]["M"], np.eye(3))
    assert np.all(np.abs(np.array(cal["gyro"]["bias"]) - truth["gyro_drift_dph"])
                  < 4 * np.array(cal["gyro"]["std"]["bias"]))
    # the default method for a field set
    assert calibrate(tmp_path / "f").to_json()["gyro"]["bias"] == cal["gyro"]["bias"]
    r = CliRunner().invoke(main, ["apply", str(tmp_path / "d.json"), str(tmp_path / "f"), "-o", str(tmp_path / "a")])
    assert r.exit_code == 0, r.output
    before, after = io.read_set(tmp_path / "f"), io.read_set(tmp_path / "a")
    earth = before.meta["earth_rate_dph"] if "earth_rate_dph" in before.meta else 15.04107
    excess = [[abs(np.linalg.norm(ms.gyro_dph()[ms.samples["segment"] == s.segment].mean(0)) - earth)
               for s in ms.segments] for ms in (before, after)]
    assert np.max(excess[1]) < 0.1 * np.max(excess[0]), excess  # |w| at rest is the Earth rate once the drift is gone
    assert np.allclose(after.acc_g(), before.acc_g())  # accelerometers at nominal, unchanged
    for method, words in (("exact", f"use simucal calibrate {tmp_path / 'f'} --method field"),
                          ("handheld", "--method field")):
        r = CliRunner().invoke(main,
                               ["calibrate", str(tmp_path / "f"), "--method", method, "-o", str(tmp_path / "x.json")])
        assert r.exit_code == 2 and words in r.stderr and not (tmp_path / "x.json").exists()
    json.loads((tmp_path / "d.json").read_text())["field"]["history"][0]["eps_N_dph"]  # Fig. 4 from the file
