"""The Ferraris method (simucal/turntable/ferraris.py): six hand-placed poses in opposite pairs, the
default for such a set; checked on sessions simulated here by a forward model of its own (not the
method's equations) and on imucal's two real sessions beside imucal itself."""
from pathlib import Path

import numpy as np
import pytest

from simucal.api.calibrating import calibrate
from simucal.errors import CalibrationError
from simucal.fit.rotations import exp_so3
from simucal.io.importers import import_ferraris_sections, import_imucal_annotated
from simucal.turntable.ferraris import acc_fit

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"
G = 9.81  # imucal's default, and the sessions' nominal factor


def _six_poses(rng, tilt_deg, noise_g):
    """A MEMS unit (scales and misalignments ~1e-2, biases ~50 mg) read at the six poses, each tilted at
    random by tilt_deg (std) about every axis: (M, b, y_plus, y_minus), pair j along body axis j."""
    M = np.eye(3) + rng.normal(0, 1e-2, (3, 3))
    b = rng.normal(0, 0.05, 3)
    y = [np.array([M @ exp_so3(rng.normal(0, np.radians(tilt_deg), 3)) @ (sign * e) + b + rng.normal(0, noise_g, 3)
                   for e in np.eye(3)]) for sign in (1, -1)]
    return M, b, y[0], y[1]


@pytest.mark.slow
@pytest.mark.parametrize("tilt_deg", [0.2, 1.0])
def test_stds_hold_the_hand_placements_tilt_over_seeds(tilt_deg):
    """error / std over 300 seeds: near 1 for M and b, though a tilt moves M's misalignments (the
    placement's tilt is estimated from the pairs' mismatch, 6 components, and carried into the stds)."""
    z_M, z_b = [], []
    for seed in range(300):
        M, b, y_plus, y_minus = _six_poses(np.random.default_rng(seed), tilt_deg, 1e-4)
        sig = np.full((3, 3), 1e-4)
        r = acc_fit(y_plus, y_minus, np.eye(3), sig, sig)
        z_M.append(((r["M"] - M) / np.array(r["std"]["M"])).ravel())
        z_b.append((r["bias"] - b) / np.array(r["std"]["bias"]))
    rms_M, rms_b = np.sqrt(np.mean(np.square(z_M), 0)), np.sqrt(np.mean(np.square(z_b), 0))
    assert np.all((rms_M > 0.75) & (rms_M < 1.3)), rms_M
    assert np.all((rms_b > 0.75) & (rms_b < 1.3)), rms_b


@pytest.mark.slow
def test_against_the_truth_beside_ferraris_own_equations_and_the_multiposition_mean():
    """300 seeds of poses tilted by 1 deg: the bias as near the truth as eq. 20's (both second order in the
    tilt), the scale nearer than eq. 23's (which reads the tilt's shortening of each pair as scale), the
    bias 10x nearer than the multi-position method's mean over all six poses (first order), and |f| = 1 at
    every pose."""
    err = {k: [] for k in ("b", "b20", "b_mean", "k", "k23")}
    for seed in range(300):
        M, b, y_plus, y_minus = _six_poses(np.random.default_rng(seed), 1.0, 1e-4)
        r = acc_fit(y_plus, y_minus, np.eye(3))
        assert r["residual_rms"] < 1e-9
        err["b"].append(r["bias"] - b)
        err["b20"].append(np.diag((y_plus + y_minus) / 2) - b)
        err["b_mean"].append(np.vstack([y_plus, y_minus]).mean(0) - b)
        err["k"].append(np.diag(r["M"] - M))
        err["k23"].append(np.diag((y_plus - y_minus).T / 2 - M))
    rms = {k: np.sqrt(np.mean(np.square(v))) for k, v in err.items()}
    assert rms["b"] < 1.25 * rms["b20"] and rms["b"] < rms["b_mean"] / 10, rms
    assert rms["k"] < rms["k23"] / 1.3, rms


def _imucal(session):
    """imucal's own calibration of a shipped session, as imucal's docs run it: (K R, b_a) in m/s^2 or counts."""
    import pandas as pd
    from imucal import FerrarisCalibration, ferraris_regions_from_df, ferraris_regions_from_section_list
    if session == "example":
        data = pd.read_csv(DATA / "example_ferraris_session.csv", header=0, index_col=0)
        regions = ferraris_regions_from_section_list(data, pd.read_json(DATA / "example_ferraris_session_list.json").T)
        cal = FerrarisCalibration().compute(regions, 102.4, "m/s^2", "deg/s")
    else:
        regions = ferraris_regions_from_df(pd.read_csv(DATA / "annotated_session.csv", header=0, index_col=[0, 1]))
        cal = FerrarisCalibration().compute(regions, 204.8, "a.u.", "a.u.")
    return cal.K_a @ cal.R_a, cal.b_a


@pytest.mark.parametrize("session", ["example", "annotated"])
def test_imucal_sessions_with_no_method_no_worse_than_imucal(tmp_path, session):
    """`simucal calibrate SET` chooses the Ferraris method for a six-pose session and puts |f| at the poses
    no further from g than imucal's calibration of the same session does."""
    from simucal import io
    if session == "example":
        import_ferraris_sections(DATA / "example_ferraris_session.csv", DATA / "example_ferraris_session_list.json",
                                 tmp_path / "s", 102.4, 49.6)
        to_g = 1 / G  # m/s^2 as imported; imucal's K R maps m/s^2 to m/s^2
    else:
        import_imucal_annotated(DATA / "annotated_session.csv", tmp_path / "s", 204.8, 2048.0, 16.4, 49.6,
                                turn_deg=360.0)
        to_g = 1 / 2048  # counts; imucal's K R maps m/s^2 (at its g) to counts
    cal = calibrate(tmp_path / "s")
    assert cal.method == "ferraris"
    ms = io.read_set(tmp_path / "s")
    acc = ms.acc_g()
    poses = np.array([acc[ms.rows(s.segment)].mean(0) for s in ms.segments if s.kind == "static"])  # g
    ours = np.linalg.norm((poses - cal.acc.bias) @ np.linalg.inv(cal.acc.M).T, axis=1) - 1
    KR, b_a = _imucal(session)
    raw = poses / to_g if session == "annotated" else poses * G
    theirs = np.linalg.norm((raw - b_a) @ np.linalg.inv(KR).T, axis=1) / G - 1
    assert np.sqrt(np.mean(ours ** 2)) <= np.sqrt(np.mean(theirs ** 2))
    assert cal.gyro is not None and np.all(np.abs(np.diag(cal.gyro.M) - 1) < 0.05)


def test_a_set_that_is_not_six_opposite_poses_is_refused_by_name(paper_set):
    with pytest.raises(CalibrationError, match="six static poses in three pairs of opposite"):
        calibrate(paper_set[0], method="ferraris")
