"""What a designed sequence promises (`plan --sequence --design`: each parameter's std from one pass of the
linearised filter over it, simulated on the unit) is what the calibration achieves on it: the filter's reported
std and the errors' scatter over seeds, for a tactical and a MEMS unit. The design's pass is linearised about
the unit's truth, where the calibration's passes converge; about the nominal, a MEMS unit's calibrations on its
8-minute design reported 0.79-1.08 of the promise (gyro eta_z, acc dK_z), and a unit with 1e-2 scale errors
3.1 times gyro dK_z's on psins19's moves at 60 deg/s (systematic/observability.py). The promise is the filter's
covariance, so it holds only where that covariance carries every error the data hold: the noise a 1 s rest block
walks into the tilt and the velocity (filter.transitions) and the table's angle errors about its gimbal axes at a
return (zero_position.attitude_cov) are checked here against their definitions."""
from types import SimpleNamespace
from pathlib import Path

import numpy as np
import pytest

from simucal import io
from simucal.api.planning import reference_stds, sequence_stds
from simucal.fit.distributions import chi2_sf
from simucal.fit.rotations import log_so3
from simucal.generated import table
from simucal.systematic.filter import compose, transitions
from simucal.systematic.method import calibrate_systematic
from simucal.systematic.observability import against_truth
from simucal.systematic.zero_position import attitude_cov
from simucal.turntable import sequence_design
from simucal.turntable.sequence import simulate_sequence
from simucal.turntable.simulate import mems_unit, tactical_unit

MINUTES = 5.0        # the reference, psins19 as written (10 deg/s), needs 4.4 min with 5 s rests
EVALUATIONS = 19     # the built-ins and one round of changes: a design, not the best one
SEEDS = range(1, 6)  # seed 0 is the design's own simulation


def _designed(sc):
    """(the designed steps, each parameter's promised std, the rows naming them)."""
    sc.rate_hz = 100.0
    _, _, rows = reference_stds(sc, "psins19", MINUTES)
    target = np.array([r["std"] for r in rows])
    found = sequence_design.design(lambda steps: np.array([r["std"] for r in sequence_stds(sc, steps)]), MINUTES,
                                   target, 60.0, EVALUATIONS)
    return found.best.steps, found.best.std, rows


def _calibrated(sc, steps, rows, seed):
    """(each parameter's reported std, its error against the truth, each sensor's NEES and dof) of the steps
    simulated at seed and calibrated."""
    meta, samples, segments, truth = simulate_sequence(sc, list(steps), seed)
    cal = calibrate_systematic(io.MeasurementSet(Path(f"designed_{seed}"), meta, samples, segments))
    return against_truth(cal, truth, rows)


@pytest.mark.parametrize("unit", [tactical_unit, mems_unit], ids=["tactical", "mems"])
def test_the_design_promises_what_the_calibration_achieves(unit):
    sc = unit(0)
    steps, promised, rows = _designed(sc)
    runs = [_calibrated(sc, steps, rows, seed) for seed in SEEDS]
    std, err = np.array([r[0] for r in runs]), np.array([r[1] for r in runs])
    ratio = std / promised
    # one computation: the filter's stds on other draws within 2 % (the MEMS design's promise about the nominal:
    # 0.87-1.07 of them, gyro eta_z and dK_x)
    assert np.all((ratio > 0.97) & (ratio < 1.03)), [(r["parameter"], q) for r, q in zip(rows, ratio.T)]
    scatter = float(np.sqrt(np.mean(np.square(err / promised))))  # all parameters and seeds together
    z = float(np.sqrt(np.mean(np.square(err / std))))
    assert 0.8 < scatter < 1.25 and z <= 1.3, (scatter, z)
    assert np.abs(err / std).max() < 4.5
    for sensor in ("acc", "gyro"):  # the errors against the whole block covariance, correlations included
        nees, dof = sum(r[2][sensor][0] for r in runs), sum(r[2][sensor][1] for r in runs)
        assert 1e-3 < chi2_sf(nees, dof) < 1 - 1e-3, (sensor, nees, dof)


def test_a_rest_block_s_noise_is_the_sum_of_its_samples():
    """One 1 s step's Q against the same second as 100 steps of 10 ms composed (filter.compose, where the
    tilt each step's gyro noise leaves drives the velocity of the steps after it): a MEMS unit's noise (30 deg/h,
    2e-4 g per sample at 100 Hz), a tilted attitude. The step's first term alone, G q G^T dt, misses 15 % of the
    horizontal velocity's variance (the accelerometer noise's 18 %)."""
    g0, w_ie = 9.80665, table.earth_rate_n(15.04 * np.pi / 180 / 3600, np.radians(45.0))
    q = np.r_[[(30.0 * np.pi / 180 / 3600) ** 2 * 0.01] * 3, [(2e-4 * g0) ** 2 * 0.01] * 3]
    C, f_b = table.C_k_n(0.3, 0.2, 0.1, np.zeros(7)), None
    f_b = C.T @ [0.0, 0.0, 1.0]

    def steps(n, dt):
        zero = np.zeros((n, 3, 1))
        return transitions(np.repeat(C[None], n, 0), np.repeat(f_b[None], n, 0), zero, zero, np.full(n, dt), q,
                           w_ie, g0)
    A, B, Q = steps(100, 0.01)
    fine = compose(A, B, Q, np.array([99]))[2][0]
    coarse = steps(1, 1.0)[2][0]
    assert np.allclose(coarse, fine, rtol=0.01, atol=1e-3 * np.abs(fine).max()), (np.diag(coarse) / np.diag(fine))


@pytest.mark.parametrize("angles", [(0.0, 90.0, 0.0), (30.0, -90.0, 45.0), (120.0, 180.0, 90.0), (10.0, 30.0, 60.0)])
def test_a_return_s_covariance_is_its_table_angles_errors(angles):
    """The attitude's scatter at a position when each table angle errs by a uniform draw of std sigma (the
    simulator's position errors) against zero_position.attitude_cov: at the middle axis's +-90 deg the inner axis
    lies along the outer one, the vertical takes both their errors (2 sigma^2) and one direction none, which
    sigma^2 I (the updates' R before) missed."""
    sigma, rng = 1e-4, np.random.default_rng(0)
    d = rng.uniform(-1, 1, (20000, 3)) * sigma * np.sqrt(3)
    C = table.C_k_n(*np.radians(angles), np.zeros(7))
    e = np.array([log_so3(table.C_k_n(*np.radians(angles), np.r_[np.zeros(4), x]) @ C.T) for x in d])
    R = attitude_cov(SimpleNamespace(outer_deg=angles[0], middle_deg=angles[1], inner_deg=angles[2]), sigma)
    assert np.allclose(e.T @ e / len(e), R, atol=0.03 * sigma ** 2), (e.T @ e / len(e) / sigma ** 2, R / sigma ** 2)
