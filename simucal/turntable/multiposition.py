"""The traditional multi-position method (dong2018's 'previous method', Tables 3 and 4): the mean
outputs regressed on the inputs computed from the commanded angles of an ideal table, b = k
assumed: y = M f + b by least squares, no model test beyond the residual."""
from __future__ import annotations

from typing import TypedDict

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.norm_fit import check_not_coplanar
from simucal.generated import table
from simucal.io import blocks, calibration, records, units
from simucal.turntable.observations import commanded_up_k


class AffineFit(TypedDict):
    """y = M f + b fitted by least squares (_affine_fit), in the sensor's units."""
    M: np.ndarray                     # (3, 3)
    bias: np.ndarray                  # (3,)
    residual_rms: float
    std: dict[str, records.Std]       # of M and bias, by the fit's own scatter


def multiposition(ms, acc_obs, acc_segs, gyro_obs, gyro_segs) -> dict[str, AffineFit]:
    """Traditional method: y = M f + b with f from commanded angles, ideal table, b = k.

    Gyro inputs: rate runs (w_T + w_e sin L) along the commanded vertical, and
    the static positions' Earth rate (its heading taken from outer_deg, 0 where blank).
    """
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    w_ie_n = table.earth_rate_n(w_e, lat)
    out: dict[str, AffineFit] = {}
    if acc_obs is not None:
        up, _ = commanded_up_k(acc_segs)
        out["acc"] = _affine_fit(up, acc_obs.N, "acc")
    if gyro_obs is not None:
        up, _ = commanded_up_k(gyro_segs)
        f = up * np.array([s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat) for s in gyro_segs])[:, None]
        N = gyro_obs.N
        statics = [s for s in ms.segments if s.kind == "static"]
        if statics:
            C = table.C_k_n(np.radians([s.outer_deg or 0.0 for s in statics]),
                            np.radians([s.middle_deg for s in statics]), np.radians([s.inner_deg for s in statics]),
                            np.zeros(7))
            gyro = ms.gyro_dph()
            Ns = np.array([gyro[ms.rows(s.segment)].mean(0) for s in statics])
            f = np.vstack([f, np.einsum("nji,j->ni", C, w_ie_n)])
            N = np.vstack([N, Ns])
        out["gyro"] = _affine_fit(f, N, "gyro")
    return out


def _affine_fit(f, N, sensor) -> AffineFit:
    """y = M f + b by least squares, refused where the inputs f do not span three dimensions: inputs in
    one plane (a gyro's rate runs all about axes of one plane, the Earth rate alone out of it) leave M
    along its normal to the noise, a confident wrong answer rather than a rank deficiency."""
    check_not_coplanar(f, sensor, "the multi-position regression: ", "the table frame")
    X = np.column_stack([f, np.ones(len(f))])
    if len(f) < 5 or np.linalg.matrix_rank(X) < 4:
        raise CalibrationError(f"the multi-position {sensor} regression is rank deficient: input directions "
                               "must span three dimensions (and a bias needs a fourth position)")
    coef, *_ = np.linalg.lstsq(X, N, rcond=None)
    r = N - X @ coef
    dof = max(len(f) - 4, 1)
    s2 = np.sum(r ** 2, 0) / dof
    cov = np.linalg.inv(X.T @ X)
    return {"M": coef[:3].T, "bias": coef[3], "residual_rms": float(np.sqrt(np.mean(r ** 2))),
            "std": {"M": np.sqrt(np.outer(s2, np.diag(cov)[:3])).tolist(), "bias": np.sqrt(s2 * cov[3, 3]).tolist()}}


def calibrate_multiposition(ms, acc_model="acc_baseline", gyro_model="gyro_baseline", ids=(), acc_noise_g=None,
                            gyro_noise_dph=None, noise_curves=None) -> calibration.Calibration:
    """The calibration of a turntable set by the multi-position method (static positions, and the
    rate runs for gyros); models and effects are the exact method's, refused here."""
    from simucal.turntable.observations import read_observations
    if ids or acc_model != "acc_baseline" or gyro_model != "gyro_baseline":
        raise CalibrationError("the multi-position method is the linear y = M f + b; --add and models need "
                               "--method exact")
    cal, obs = read_observations(ms, "multiposition", {"acc": {"static"}, "gyro": {"rate"}}, acc_noise_g,
                                 gyro_noise_dph, noise_curves)
    for sensor, r in multiposition(ms, *obs).items():
        setattr(cal, sensor, blocks.affine_block(sensor, r["M"], r["bias"], r["std"], r["residual_rms"],
                                                      "linear y = M f + b on commanded inputs"))
    if ms.has_gyro and cal.gyro is None:
        cal.drop_sensor("gyro", "no usable rate runs in segments.csv: the multi-position gyro regression needs "
                                "rate runs about several axes")
    return cal
