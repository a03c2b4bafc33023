"""Physical consistency of a turntable calibration: refuse what cannot be physics.

A norm observation cannot see the handedness of a triad (a reversed axis fits
as well as a right one, with mirrored directions), nor whether meta.json's
latitude is right. So, after the fits:

- handedness: the fitted input directions against the commanded table vertical
  (static positions for accelerometers, rate-run axes for gyros), and the two
  triads against each other (unification.py). A reflection explains a residual
  no rotation can: the triad is refused, naming the axis whose reversal brings
  the residual to the noise.
- latitude: at rest the gyros see the Earth rate, whose component along the
  specific force (up) is w_ie sin L, estimated with the gyro bias from the static
  positions alone. Where the gyros resolve it (a std of L below 10 deg), a latitude
  that differs from meta.json's by more than max(5 sigma, 3 deg) is refused,
  stating the measured one; where the positions' noise is unknown, the fit's own
  residuals give it (n - 4 dof) and 5 sigma becomes the t quantile of the same tail.
"""
from __future__ import annotations

import math

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.apply import model_inputs
from simucal.fit.aux_inputs import specific_force
from simucal.fit.distributions import chi2_sf, t_isf
from simucal.fit.rotations import log_so3, wahba
from simucal.fit.aux_inputs import AuxInputs, column_means
from simucal.io import run_or_rows, units
from simucal.io.records import LatitudeCheck, NoiseUsed
from simucal.fit.noise import mean_and_sigma
from simucal.turntable.observations import commanded_up_k, refuse_outliers

FIVE_SIGMA_TAIL = float(chi2_sf(25.0, 1)) / 2  # the normal tail beyond 5 sigma, one side
GROSS_RAD = 0.05  # a direction residual no table (1 deg errors give 0.017 rad) or noise explains


def mirror_test(u_from, u_to):
    """Wahba of u_to ~ C u_from. Returns (axis, residual, residual with that axis of u_to
    reversed): axis is None unless no rotation fits (residual > GROSS_RAD) and reversing one
    axis does (to 0.3 of the residual); of the three axes, the one whose reversal needs the
    smallest rotation, i.e. the one named assuming the axes are near nominal."""
    w = np.ones(len(u_from))
    resid = float(np.sqrt(np.mean(np.sum((u_to - u_from @ wahba(u_from, u_to, w).T) ** 2, axis=1))))
    if resid <= GROSS_RAD or np.linalg.matrix_rank(u_from, tol=1e-3) < 3:
        return None, resid, None
    fits = []
    for k in range(3):
        D = np.diag([-1.0 if j == k else 1.0 for j in range(3)])
        C = wahba(u_from, u_to @ D, w)
        r = float(np.sqrt(np.mean(np.sum((u_to @ D - u_from @ C.T) ** 2, axis=1))))
        if r < 0.3 * resid:
            fits.append((np.linalg.norm(log_so3(C)), k, r))
    if not fits:
        return None, resid, None
    _, k, r = min(fits)
    return k, resid, r


def mirror_error(what, whose, axis, resid, r):
    """The refusal of a reflected triad, naming the axis."""
    ax = "xyz"[axis]
    return CalibrationError(
        f"{what}: no rotation fits (direction residual {resid:.2g} rad), but reversing {whose} {ax} axis does "
        f"({r:.2g} rad): a left-handed triad, that axis wired or declared with its sign reversed (named assuming "
        f"the unit is mounted near nominal; a reflection can be put on any one axis). Fix the sign of that "
        "column in samples.csv (or the wiring) and calibrate again")


def latitude(ms, gm, fg, C_b_d, u_b, static_gyro) -> LatitudeCheck:
    """The latitude the gyros measure at rest, against meta.json's; refuses a mismatch.

    u_b: (n, 3) unit specific force (up) in b at static positions; static_gyro: (N (n, 3)
    deg/h, sigma (n, 3) or None where unknown, AuxInputs) of their gyro outputs. With w_i the calibrated rate in d
    and up_i = C_b^d u_b,i, the Earth rate's vertical component gives, per position,
        up_i . w_i = up_i . db + w_ie sin L,
    solved by weighted least squares for sin L and a bias correction db, so a bias that a
    failing rate-run model got wrong does not bias L (the rate runs give only M here)."""
    w_e = units.earth_rate_dph(ms.meta)
    L_meta = float(ms.meta["latitude_deg"])
    N, sig, aux = static_gyro
    p = fg.vector(gm.params)
    up_d = u_b @ C_b_d.T
    w_d = model_inputs(gm, p, N, aux.with_values(**specific_force(up_d)), ms.path / "samples.csv")
    X = np.column_stack([up_d, np.full(len(up_d), w_e)])
    n = len(X)
    if n < 6 or np.linalg.matrix_rank(X / w_e, tol=1e-3) < 4:
        return {"verdict": f"not checked: {n} static positions, which do not separate the gyro bias from the Earth "
                           "rate's vertical component (it needs at least 6, not all on one cone)"}
    sd = np.sqrt(np.einsum("ni,ni->n", up_d ** 2, sig ** 2)) if sig is not None else np.ones(n)
    coef, *_ = np.linalg.lstsq(X / sd[:, None], np.einsum("ni,ni->n", up_d, w_d) / sd, rcond=None)
    r = (np.einsum("ni,ni->n", up_d, w_d) - X @ coef) / sd
    chi2 = float(r @ r)
    # unknown noise: the residuals' variance component, with n - 4 dof
    cov = np.linalg.inv((X / sd[:, None]).T @ (X / sd[:, None])) * (chi2 / (n - 4) if sig is None else
                                                                  max(1.0, chi2 / (n - 4)))
    s_L, std_s = float(coef[3]), float(np.sqrt(cov[3, 3]))
    noise_dof = n - 4 if sig is None else math.inf
    noise: NoiseUsed = ({"std_dph": float(np.sqrt(chi2 / (n - 4))), "dof": n - 4,
                         "source": "one gyro row per static position and no gyro_noise_dph: estimated from this "
                                   "fit's residuals"} if sig is None else
                        {"std_dph": float(np.median(sig)), "source": "each position's scatter or the stated noise"})
    out: LatitudeCheck = {"meta_deg": L_meta, "positions": n, "sin_L_measured": s_L, "sin_L_std": std_s,
                          "chi2": None if sig is None else chi2, "dof": n - 4, "noise": noise}
    if abs(s_L) > 1 + 5 * std_s:
        raise CalibrationError(
            f"{ms.path}: at rest the gyros measure a vertical rate of {s_L * w_e:.3g} deg/h, more than the "
            f"Earth's rate ({w_e} deg/h): check gyro_unit, earth_rate_dph and the static segments")
    L = float(np.degrees(np.arcsin(np.clip(s_L, -1, 1))))
    std_L = float(np.degrees(std_s / max(np.cos(np.radians(L)), 0.05)))
    out.update({"measured_deg": L, "std_deg": std_L})
    if std_L > 10.0:
        out["verdict"] = (f"not checked: the gyros do not resolve the Earth rate's vertical component (latitude "
                          f"std {std_L:.3g} deg)")
        return out
    if abs(L - L_meta) > max(t_isf(FIVE_SIGMA_TAIL, noise_dof) * std_L, 3.0):
        raise CalibrationError(
            f"{ms.path / 'meta.json'}: latitude_deg is {L_meta:g}, but the gyros measure {L:.2f} +- {std_L:.2g} deg "
            f"(the Earth rate's component along gravity at {n} static positions): fix latitude_deg (north "
            "positive); if it is right, the gyro model lacks an effect of that size at rest (g-sensitivity: "
            "--add gyro.g_sensitivity.*)")
    out["verdict"] = (f"agrees: measured {L:.2f} +- {std_L:.2g} deg, meta.json {L_meta:g} deg"
                      + (f" (gyro noise at rest {noise['std_dph']:.2g} deg/h, from this fit's residuals, "
                         f"{n - 4} dof)" if sig is None else ""))
    return out


def handedness(ms, fa, acc_obs, acc_segs, fg, gyro_segs) -> list[str]:
    """Each triad's fitted directions against the commanded table vertical (consistency.py):
    refuses a reflected triad; where both are reflected, the table's angles follow another
    convention than the spec's, which the exact method does not need (a note)."""
    return handedness_verdict(ms,
                              {"accelerometer": mirrored(fa, acc_segs, False), "gyro": mirrored(fg, gyro_segs, True)})


def mirrored(fit, segs, rate_sign: bool):
    """consistency.mirror_test of one triad's fitted directions against the commanded vertical:
    (axis, residual, r) where the triad is a mirror image, else None. rate_sign: the directions
    are rate runs', signed by their commanded rate."""
    if fit is None or fit.directions is None:
        return None
    rows = [i for i, s in enumerate(segs) if s.middle_deg is not None and s.inner_deg is not None
            and (rate_sign or s.kind == "static")]
    if len(rows) < 3:
        return None
    up_k, _ = commanded_up_k([segs[i] for i in rows])
    u = fit.directions[rows] * (np.sign([segs[i].outer_rate_dps for i in rows])[:, None] if rate_sign else 1.0)
    axis, resid, r = mirror_test(up_k, u)
    return None if axis is None else (axis, resid, r)


def handedness_verdict(ms, found: dict) -> list[str]:
    """found: {triad: mirrored(...)}. One reflected triad is refused; two are a note."""
    found = {k: v for k, v in found.items() if v is not None}
    if len(found) == 1:
        (sensor, (axis, resid, r)), = found.items()
        raise mirror_error(f"{ms.path}: the {sensor} directions against the commanded table vertical",
                           f"the {sensor}'s", axis, resid, r)
    if len(found) == 2:
        return ["handedness: both triads are mirror images of the commanded table geometry, so the table's angles "
                "follow another sign convention than the spec's (segments.csv); the exact method does not use them"]
    return []


def latitude_check(ms, fa, acc_segs, gm, fg, C_b_d, gyro_noise_dph=None) -> LatitudeCheck:
    """consistency.latitude at the static positions that have gyro data; their noise from their
    scatter, else the stated one (gyro_noise_dph, else meta's), else estimated by the latitude
    fit itself."""
    rows, static_gyro = static_gyro_rows(ms, acc_segs, gyro_noise_dph)
    if not rows:
        return {"verdict": "not checked: no static positions"}
    return latitude(ms, gm, fg, C_b_d, fa.directions[rows], static_gyro)


def static_gyro_rows(ms, acc_segs, gyro_noise_dph=None):
    """The accelerometer's static rows (indices into acc_segs) and the gyro there: (N (n, 3) deg/h,
    sigma (n, 3) or None where no row's noise is known, AuxInputs). Formed once per set (calibrate
    asks for the latitude check and again for the gyro's model test)."""
    key = ("static_gyro_rows", tuple(s.segment for s in acc_segs), repr(gyro_noise_dph), ms.t_ref_c)  # aux: dtemp_c
    return ms._once(key, ("gx", "gy", "gz"), lambda: _static_gyro_rows(ms, acc_segs, gyro_noise_dph))


def _static_gyro_rows(ms, acc_segs, gyro_noise_dph):
    rows = [i for i, s in enumerate(acc_segs) if s.kind == "static"]
    if not rows:
        return rows, None
    raw = ms.raw("gyro")
    stated = units.stated_noise(ms.meta, "gyro") if gyro_noise_dph is None else gyro_noise_dph
    N: list[np.ndarray] = []
    sig_list: list[np.ndarray] = []
    groups = []
    # each static segment's gyro rows checked, then their mean and its std, on one thread (segment_observations)
    for i in rows:
        r = ms.rows(acc_segs[i].segment)
        refuse_outliers(ms, raw, r, "gyro", acc_segs[i].segment)
        m, sd = mean_and_sigma(ms.in_units("gyro", run_or_rows(r)), stated)
        N.append(m)
        sig_list.append(sd)
        groups.append(r)
    sig_all = np.array(sig_list)
    sig = None if np.isnan(sig_all).all() else np.where(np.isnan(sig_all), np.nanmax(sig_all), sig_all)
    return rows, (np.array(N), sig, AuxInputs(column_means(ms.samples, groups, t_ref_c=ms.t_ref_c)))
