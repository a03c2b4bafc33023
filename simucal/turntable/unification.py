"""Tie the gyro parameter frame d to the accelerometer frame b: C_b^d, with its covariance.

dong2018 section 2 (eq. 13-27) reads C_b^d from the commanded table angles at the
Table 2 positions, so every error of the table's angles enters it. Two ways that
need no accurate angles, both Wahba's problem (min sum w_i |u_d,i - C u_b,i|^2,
solved by SVD):

- rate_run_means (the default): over whole revolutions of the outer axis a rate
  run's mean specific force (in b, from the calibrated accelerometers) and its
  mean rate (in d, the gyro fit's input direction) both lie along the outer axis,
  whatever the table's position errors, tilt or non-perpendicularity. Lever arms
  add a centripetal term perpendicular to the axis; the accelerometer model's
  size-effect terms remove it when they are fitted (--add acc.size_effect.*).
- static_pairs (the cross-check): each rate run's axis paired with the gravity
  direction of the static position at the same commanded middle/inner angles; the
  table's position errors at those angles enter directly.

Covariance, first order. The inputs z are the accelerometer fit's parameters and
directions, the rate runs' mean accelerometer outputs and the gyro fit's parameters
and directions, with their covariance (the fits' full covariances, inflated by
chi2/dof when a model fails). With C = C0 (I + [phi x]) and v_i = C0^T u_d,i:
    phi = A^-1 sum_i w_i u_b,i x (dv_i - du_b,i),  A = sum_i w_i (I - u_b,i u_b,i^T),
and the gyro matrix in b, M_b = M_d(p_g) C, follows by the chain rule.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.apply import model_function, solve_inputs
from simucal.fit.distributions import chi2_isf, chi2_sf
from simucal.fit.norm_fit import full_covariance, tangent_basis
from simucal.fit.rotations import log_so3, skew, wahba
from simucal.generated import table
from simucal.generated import unify as eq
from simucal.io import units
from simucal.turntable.consistency import GROSS_RAD, mirror_error, mirror_test

CHI2_3DOF_P1E3 = float(chi2_isf(1e-3, 3))  # the chi-square quantile, 3 dof, p = 1e-3


@dataclass
class Inputs:
    """The stacked input vector z: its covariance and where each part starts."""
    cov: np.ndarray
    acc: int        # first index of [p_a, t_a]
    acc_means: int  # first index of the rate runs' mean accelerometer outputs
    gyro: int       # first index of [p_g, t_g]


def _misfit_scale(fit):
    """chi2/dof when the fit's model fails (as calibration.inflate_if_failing), else 1."""
    from simucal.fit.candidates import ALPHA
    if fit.p_value is not None and fit.p_value < ALPHA and fit.chi2 and fit.dof:
        return max(1.0, fit.chi2 / fit.dof)
    return 1.0


def wahba_sensitivity(u_b, D_b, u_d, D_d, w, C):
    """d phi / dz (3, nz) from du_b/dz (n, 3, nz) and du_d/dz (n, 3, nz) (module doc)."""
    A = np.einsum("n,nij->ij", w, np.eye(3) - np.einsum("ni,nj->nij", u_b, u_b))
    dv = np.einsum("ji,njz->niz", C, D_d) - D_b
    rhs = np.einsum("n,nij,njz->iz", w, skew(u_b), dv)
    return np.linalg.solve(A, rhs)


class Unifier:
    """Both fits and their covariances, for any pairing of directions."""

    def __init__(self, am, fa, obs_a, gm, fg, obs_g, acc_means=None):
        """acc_means: (rows, N (n_r, 3) g, sigma (n_r, 3), AuxInputs) of the rate runs that have
        accelerometer data (rows: their index in the gyro fit), or None where none has."""
        self.am, self.fa, self.obs_a, self.gm, self.fg, self.obs_g = am, fa, obs_a, gm, fg, obs_g
        self.acc_means = acc_means
        cov_a = full_covariance(am, obs_a, fa) * _misfit_scale(fa)
        cov_g = full_covariance(gm, obs_g, fg) * _misfit_scale(fg)
        sig_m = np.zeros((0, 3)) if acc_means is None else acc_means[2]
        self.z = Inputs(_block_diag(cov_a, np.diag(sig_m.ravel() ** 2), cov_g),
                        0, len(cov_a), len(cov_a) + sig_m.size)
        self.nz = len(self.z.cov)

    def _directions(self, fit, model, start, rows):
        """Fitted unit directions of `rows` and their derivative wrt z (via the tangent steps)."""
        m = len(model.params)
        E = tangent_basis(fit.directions[rows])
        D = np.zeros((len(rows), 3, self.nz))
        for k, i in enumerate(rows):
            D[k, :, start + m + 2 * i:start + m + 2 * i + 2] = E[k]
        return fit.directions[rows], D

    def gyro_directions(self, rows):
        return self._directions(self.fg, self.gm, self.z.gyro, rows)

    def acc_directions(self, rows):
        return self._directions(self.fa, self.am, self.z.acc, rows)

    def acc_mean_directions(self):
        """The rate runs' mean specific force, calibrated: unit u_b and du_b/dz. At the solution
        of h(f, p) = N: df = (dh/df)^-1 (dN - dh/dp dp)."""
        _, N, _, aux = self.acc_means
        p = self.fa.vector(self.am.params)
        M, b = self.am.matrix_and_bias(p)
        f = solve_inputs(model_function(self.am, p), M, b, N, aux, "acc", "the rate runs")
        _, Ju, Jp = self.am.jacobians(f, p, aux)
        Jinv = np.linalg.inv(Ju)
        m, n = len(p), len(N)
        df = np.zeros((n, 3, self.nz))
        df[:, :, self.z.acc:self.z.acc + m] = -np.einsum("nij,njk->nik", Jinv, Jp)
        for i in range(n):
            df[i, :, self.z.acc_means + 3 * i:self.z.acc_means + 3 * i + 3] = Jinv[i]
        r = np.linalg.norm(f, axis=1)
        u = f / r[:, None]
        P = (np.eye(3) - np.einsum("ni,nj->nij", u, u)) / r[:, None, None]
        return u, np.einsum("nij,njz->niz", P, df)

    def solve(self, u_b, D_b, u_d, D_d, w) -> dict:
        """C_b^d, d phi/dz, the pairs' residual rms (rad) and chi-square (2 dof per pair, 3 for C)."""
        C = wahba(u_b, u_d, w)
        J_phi = wahba_sensitivity(u_b, D_b, u_d, D_d, w, C)
        resid = u_d - u_b @ C.T
        chi2 = 0.0
        for i in range(len(u_b)):  # each pair's residual covariance, first order
            Ji = D_d[i] - C @ D_b[i] + C @ skew(u_b[i]) @ J_phi
            S = Ji @ self.z.cov @ Ji.T
            chi2 += float(resid[i] @ np.linalg.pinv(S, rcond=1e-10, hermitian=True) @ resid[i])
        return {"pairs": len(u_b), "C": C, "u_b": u_b, "u_d": u_d, "J_phi": J_phi, "chi2": chi2, "dof": 2 * len(u_b) - 3,
                "residual_rms_rad": float(np.sqrt(np.mean(np.sum(resid ** 2, axis=1)))),
                "rank": int(np.linalg.matrix_rank(u_b, tol=1e-3))}

    def gyro_matrix_in_b(self, C, J_phi):
        """M_b = M_d(p_g) C and the covariance of its 9 entries (row-major):
        dM_b = dM_d C + M_d C [dphi x]."""
        p = self.fg.vector(self.gm.params)
        M_d, _ = self.gm.matrix_and_bias(p)
        d_skew = -np.einsum("abk,kz->abz", _LEVI_CIVITA, J_phi)  # d [phi x] / dz
        J = np.einsum("ia,abz->ibz", M_d @ C, d_skew)
        for k in range(len(p)):  # dM_d/dp by central differences (M_d is linear in p for the built-in models)
            e = np.zeros(len(p))
            e[k] = 1e-6
            J[:, :, self.z.gyro + k] += (self.gm.matrix_and_bias(p + e)[0] - self.gm.matrix_and_bias(p - e)[0]) / 2e-6 @ C
        J = J.reshape(9, self.nz)
        return M_d @ C, self.covariance(J)

    def covariance(self, J):
        return J @ self.z.cov @ J.T


_LEVI_CIVITA = np.zeros((3, 3, 3))
_LEVI_CIVITA[0, 1, 2] = _LEVI_CIVITA[1, 2, 0] = _LEVI_CIVITA[2, 0, 1] = 1
_LEVI_CIVITA[0, 2, 1] = _LEVI_CIVITA[2, 1, 0] = _LEVI_CIVITA[1, 0, 2] = -1


def _block_diag(*blocks):
    out = np.zeros((sum(len(b) for b in blocks),) * 2)
    k = 0
    for b in blocks:
        out[k:k + len(b), k:k + len(b)] = b
        k += len(b)
    return out


def pair_weights(sig_b, sig_d):
    """1 / (direction variance of b + of d) per pair, from each side's per-axis std (unitless)."""
    return 1.0 / (np.mean(sig_b ** 2, axis=1) + np.mean(sig_d ** 2, axis=1))


def unify(un: Unifier, acc_segs, gyro_segs, find):
    """C_b^d by the rate runs' means (or, without accelerometer data in the rate runs, by static
    pairs), its std, the gyro M in b with its std, and the other pairing as a cross-check.
    find(segs, **angles) -> index of the static segment at those angles, or None."""
    rate_sign = np.sign([s.outer_rate_dps for s in gyro_segs])
    sig_d = un.obs_g.sigma / un.obs_g.rho[:, None] if un.obs_g.sigma is not None else np.ones((len(gyro_segs), 3))
    out = {}
    if un.acc_means is not None:
        rows = un.acc_means[0]
        u_b, D_b = un.acc_mean_directions()
        u_d, D_d = un.gyro_directions(rows)
        sign = rate_sign[rows]
        u_d, D_d = u_d * sign[:, None], D_d * sign[:, None, None]  # the axis is +up for a positive rate
        w = pair_weights(un.acc_means[2], sig_d[rows])
        out["rate_run_means"] = un.solve(u_b, D_b, u_d, D_d, w)
    pairs = [(i, j) for j, s in enumerate(gyro_segs)
             if (i := find(acc_segs, middle_deg=s.middle_deg, inner_deg=s.inner_deg)) is not None]
    if len(pairs) >= 2:
        ia, ig = np.array(pairs).T
        u_b, D_b = un.acc_directions(ia)
        u_d, D_d = un.gyro_directions(ig)
        u_d, D_d = u_d * rate_sign[ig, None], D_d * rate_sign[ig, None, None]
        sig_b = un.obs_a.sigma[ia] if un.obs_a.sigma is not None else np.ones((len(ia), 3))
        out["static_pairs"] = un.solve(u_b, D_b, u_d, D_d, pair_weights(sig_b, sig_d[ig]))
    usable = {k: v for k, v in out.items() if v["rank"] >= 2}
    if not usable:
        raise CalibrationError("frame unification needs at least two rate runs about distinct axes, with the "
                               "accelerometers recorded during them, or each with a static position at the same "
                               "middle/inner angles")
    method = "rate_run_means" if "rate_run_means" in usable else "static_pairs"
    fallback = None
    if (method == "rate_run_means" and usable[method]["residual_rms_rad"] > GROSS_RAD and "static_pairs" in usable
            and usable["static_pairs"]["residual_rms_rad"] <= GROSS_RAD):
        # the rate runs' means disagree grossly (not whole revolutions? lever arms at a high rate?) while
        # the static pairs agree: use those, and say so
        fallback = (f"the rate runs' means leave a direction residual of "
                    f"{usable[method]['residual_rms_rad']:.2g} rad (rate runs not whole revolutions, or lever arms "
                    "the model lacks?), so the static pairs tie the frames; they carry the table's angle errors")
        method = "static_pairs"
    best = usable[method]
    if best["residual_rms_rad"] > GROSS_RAD:
        axis, resid, r = mirror_test(best["u_b"], best["u_d"])
        if axis is not None:
            raise mirror_error("the gyro directions (frame d) against the accelerometer's (frame b)",
                               "the gyro's (or the accelerometer's)", axis, resid, r)
        raise CalibrationError(
            f"the gyro frame cannot be tied to the accelerometer frame: the {method.replace('_', ' ')} leave a "
            f"direction residual of {resid:.2g} rad, which no table error or noise explains; check that the rate "
            "runs are whole revolutions and that segments.csv matches the data")
    C, J_phi = best["C"], best["J_phi"]
    M_b, cov_M = un.gyro_matrix_in_b(C, J_phi)
    p_pairs = chi2_sf(best["chi2"], best["dof"]) if best["dof"] > 0 else 1.0
    inflate = max(1.0, best["chi2"] / best["dof"]) if p_pairs < 1e-3 else 1.0
    if inflate > 1:  # the pairs disagree beyond their noise: the stds take the misfit in
        cov_M = cov_M * inflate
        misfit = (f"the {best['pairs']} pairs misfit (chi2 {best['chi2']:.4g} on {best['dof']} dof): stds inflated by "
                  f"{np.sqrt(inflate):.3g}" + ("; lever arms the accelerometer model lacks? (--add acc.size_effect.*)"
                                               if method == "rate_run_means" else ""))
        fallback = f"{fallback}; {misfit}" if fallback else misfit
    info = {"method": method, "pairs": best["pairs"], "C_b_d": C.tolist(),
            "std_rad": np.sqrt(inflate * np.diag(un.covariance(J_phi))).tolist(),
            "std_note": "std of the small rotation phi with C_b_d = C (I + [phi x]), about b's x, y, z",
            "direction_residual_rms_rad": best["residual_rms_rad"], "chi2": best["chi2"], "dof": best["dof"],
            **({"note": fallback} if fallback else {})}
    if method == "rate_run_means" and "static_pairs" in usable:
        two = usable["static_pairs"]
        d = log_so3(C.T @ two["C"])
        cov_d = un.covariance(two["J_phi"] - J_phi)
        z2 = float(d @ np.linalg.pinv(cov_d, rcond=1e-12, hermitian=True) @ d)
        agree = z2 < CHI2_3DOF_P1E3
        info["cross_check"] = {
            "method": "static_pairs", "pairs": two["pairs"], "difference_rad": d.tolist(),
            "difference_std_rad": np.sqrt(np.diag(cov_d)).tolist(), "mahalanobis2": z2, "agree": bool(agree),
            "note": ("the two pairings agree within their noise" if agree else
                     f"the static pairs differ by {np.degrees(np.linalg.norm(d)) * 60:.2g} arcmin "
                     f"({np.sqrt(z2):.1f} sigma): the table's angle errors at the paired positions (which the "
                     "rate-run means do not see), or rate runs that are not whole revolutions, or lever arms "
                     "that the accelerometer model lacks (--add acc.size_effect.*)")}
    return C, M_b, np.sqrt(np.diag(cov_M)).reshape(3, 3), info


def unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs, p_acc, p_gyro, meta, find):
    """dong2018 eq. 25-27 (derived, generated/unify.py) at the Table 2 positions (--method linear)."""
    ia = [find(acc_segs, middle_deg=a, outer_deg=g, inner_deg=0.0) for a, g in eq.TABLE2]
    ig = [find(gyro_segs, middle_deg=a, inner_deg=0.0) for a in eq.GYRO_ALPHAS]
    if None in ia or None in ig:
        raise CalibrationError(f"the paper's frame unification needs the Table 2 static positions "
                               f"(alpha, gamma) = {eq.TABLE2} deg with beta = 0, and rate runs at alpha = "
                               f"{eq.GYRO_ALPHAS} deg, beta = 0; use --method exact, which needs none")
    x = eq.acc_table2(acc_obs.N[ia].reshape(12), p_acc)
    w_T = gyro_segs[ig[0]].outer_rate_dps * 3600.0
    lam = eq.gyro_mounting(gyro_obs.N[ig].reshape(6), p_gyro, w_T, units.earth_rate_dph(meta),
                              np.radians(meta["latitude_deg"]))
    C_b_d = table.mounting(lam).T @ table.mounting(x[:3])
    return C_b_d, {"theta4_rad": x[:3].tolist(), "tilt_rad": x[3:].tolist(), "lambda4_rad": lam.tolist()}
