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
chi2/dof when a model fails). With C = C0 (I + [phi x]), each pair's misfit (in the plane
across the bisector of u_d and C u_b, where it lies whole: 2 components), phi's sensitivity
(Wahba's gradients) and the normalisation f/|f| are derived (derive/unify.py); the gyro
matrix in b, M_b = M_d(p_g) C, follows by the chain rule. Lever arms are named only where
their targeted test on the pairs fails (lever_arms.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.apply import model_inputs
from simucal.fit.distributions import chi2_sf_estimated
from simucal.fit.gauss_newton import tangent_basis
from simucal.fit.norm_fit import full_covariance
from simucal.fit.results import ALPHA
from simucal.fit.rotations import log_so3, skew, wahba
from simucal.generated import table
from simucal.generated import unify as eq
from simucal.io import units
from simucal.turntable.consistency import GROSS_RAD, mirror_error, mirror_test
from simucal.turntable.lever_arms import lever_arm_test, misplaced_by
from simucal.turntable.pairs import PairSolution, pair_misfits, wahba_sensitivity

ARCMIN_RAD = math.radians(1 / 60)  # a start for an estimated table accuracy


@dataclass
class Part:
    """One block of the inputs z: its covariance for a variance factor of 1, the factor, and the
    factor's degrees of freedom (inf where the noise is known; a variance component's else)."""
    index: slice
    unit_cov: np.ndarray
    var: float = 1.0
    dof: float = math.inf
    estimated: bool = False  # var from the pairs' scatter (Unifier.solve), not from the fits or a statement


def _misfit_scale(fit):
    """chi2/dof when the fit's model fails (as blocks.inflate_if_failing), else 1."""
    if fit.test.fails and fit.chi2 and fit.dof:
        return max(1.0, fit.chi2 / fit.dof)
    return 1.0


def _full_covariance(model, obs, fit):
    """norm_fit.full_covariance, kept on the fit for these model and observations: every tie of the frames
    with one fit (a twin judged, the gyro block) shares it."""
    kept = fit.__dict__.get("_full_covariance")
    if kept is None or kept[0] is not model or kept[1] is not obs:
        kept = fit.__dict__["_full_covariance"] = (model, obs, full_covariance(model, obs, fit))
    return kept[2]


def _sandwich(D, U):
    """D U D^T for D (..., r, q), U (q, q). Per row of a batch D (n, r, q) whose rows each touch few
    columns (a direction depends on its fit's parameters and its own tangent step, not on the other
    rows'), over those columns alone: n k^2 instead of n q^2 (k ~ 11, q ~ 200 on a rich plan)."""
    if D.ndim != 3:
        return D @ U @ np.swapaxes(D, -1, -2)
    used = np.any(D != 0, axis=1)  # (n, q)
    k = int(used.sum(axis=1).max()) if D.size else 0
    if k > D.shape[-1] // 4:
        return D @ U @ D.swapaxes(1, 2)
    cols = np.argsort(~used, axis=1, kind="stable")[:, :max(k, 1)]  # the used columns first; padding has D = 0
    Dg = np.take_along_axis(D, cols[:, None, :], axis=2)
    return Dg @ U[cols[:, :, None], cols[:, None, :]] @ Dg.swapaxes(1, 2)


class Unifier:
    """Both fits and their covariances, for any pairing of directions."""

    def __init__(self, am, fa, obs_a, gm, fg, obs_g, acc_means=None, dof_acc=math.inf, dof_gyro=math.inf) -> None:
        """acc_means: (rows, N (n_r, 3) g, sigma (n_r, 3), AuxInputs) of the rate runs that have
        accelerometer data (rows: their index in the gyro fit), or None where none has; sigma NaN
        where neither their scatter nor a statement gives it: their variance component is then
        estimated from the rate-run pairs (unify). dof_acc, dof_gyro: the degrees of freedom of
        each fit's noise (lack_of_fit.noise_dof)."""
        self.am, self.fa, self.obs_a, self.gm, self.fg, self.obs_g = am, fa, obs_a, gm, fg, obs_g
        self.acc_means = acc_means
        self.parts: dict[str, Part] = {}
        self.add_part("acc", _full_covariance(am, obs_a, fa) * _misfit_scale(fa), dof=dof_acc)
        if acc_means is not None:
            sig_m = acc_means[2]
            if np.isnan(sig_m).any():  # one component for all of them (a set averages its rate runs alike)
                self.add_part("acc_means", np.eye(sig_m.size), float(np.median(obs_a.sigma ** 2)), None)
            else:
                self.add_part("acc_means", np.diag(sig_m.ravel() ** 2))
        self.add_part("gyro", _full_covariance(gm, obs_g, fg) * _misfit_scale(fg), dof=dof_gyro)

    def add_part(self, name, unit_cov, var=1.0, dof=math.inf):
        """Append a block to z; dof None: its variance factor is to be estimated (solve), var its start."""
        k = self.nz
        self.parts[name] = Part(slice(k, k + len(unit_cov)), unit_cov, var, math.inf if dof is None else dof,
                                dof is None)

    @property
    def nz(self):
        return max((p.index.stop for p in self.parts.values()), default=0)

    def _directions(self, fit, model, start, rows):
        """Fitted unit directions of `rows` and their derivative wrt z (via the tangent steps)."""
        m = len(model.params)
        E = tangent_basis(fit.directions[rows])
        D = np.zeros((len(rows), 3, self.nz))
        for k, i in enumerate(rows):
            D[k, :, start + m + 2 * i:start + m + 2 * i + 2] = E[k]
        return fit.directions[rows], D

    def gyro_directions(self, rows):
        return self._directions(self.fg, self.gm, self.parts["gyro"].index.start, rows)

    def acc_directions(self, rows):
        return self._directions(self.fa, self.am, self.parts["acc"].index.start, rows)

    def acc_mean_inputs(self):
        """The rate runs' mean specific force, calibrated (f (n, 3), g), and the model's Jacobians there."""
        _, N, _, aux = self.acc_means
        p = self.fa.vector(self.am.params)
        f = model_inputs(self.am, p, N, aux, "the rate runs")
        _, Ju, Jp = self.am.jacobians(f, p, aux)
        return f, Ju, Jp

    def acc_mean_directions(self):
        """The rate runs' mean specific force, calibrated: unit u_b and du_b/dz. At the solution
        of h(f, p) = N: df = (dh/df)^-1 (dN - dh/dp dp)."""
        f, Ju, Jp = self.acc_mean_inputs()
        Jinv = np.linalg.inv(Ju)
        m, n = Jp.shape[-1], len(f)
        acc, means = self.parts["acc"].index.start, self.parts["acc_means"].index.start
        df = np.zeros((n, 3, self.nz))
        df[:, :, acc:acc + m] = -np.einsum("nij,njk->nik", Jinv, Jp)
        for i in range(n):
            df[i, :, means + 3 * i:means + 3 * i + 3] = Jinv[i]
        return f / np.linalg.norm(f, axis=1, keepdims=True), eq.direction_jacobian(f) @ df

    def _variance(self, D):
        """tr(D cov D^T) per row of D (n, 3, nz), part by part (cov is block-diagonal over them)."""
        return sum(np.trace(S, axis1=-2, axis2=-1) for S in self._by_part(D).values())

    def _by_part(self, J, unit=()):
        """{part: J_k cov_k J_k^T} for J (..., r, nz): what each part contributes to J cov J^T
        (for the parts named in unit, at a variance factor of 1)."""
        return {name: (1.0 if name in unit else p.var) * _sandwich(J[..., p.index], p.unit_cov)
                for name, p in self.parts.items()}

    def _dof(self, S_inv, by_part, rank):
        """Satterthwaite's degrees of freedom of J cov J^T as estimated (each part's share
        tr(S^-1 S_k) / rank over that part's dof): inf where every noise is known."""
        share = {k: float(np.einsum("...ab,...ba->...", S_inv, S).sum()) / rank for k, S in by_part.items()}
        s = sum(a * a / self.parts[k].dof for k, a in share.items())
        return 1.0 / s if s > 0 else math.inf

    def _pairs_chi2(self, resid, by_part):
        """sum_i r_i^T S_i^+ r_i, S_i the pair residual's covariance, and the S_i^+."""
        S = sum(by_part.values())
        S_inv = np.linalg.pinv(S, rcond=1e-10, hermitian=True)
        return float(np.sum(resid * (S_inv @ resid[..., None])[..., 0])), S_inv

    def _estimate_var(self, name, resid, J, dof):
        """The variance factor of part `name` that brings the pairs' chi-square to its dof
        (REML-like: the residuals' scatter beyond what the other parts explain); 0 where those
        explain it all. Bisection on its logarithm (chi2 falls as it grows)."""
        unit = self._by_part(J, unit=(name,))

        def chi2(v):
            return self._pairs_chi2(resid, {k: v * S if k == name else S for k, S in unit.items()})[0]

        hi = self.parts[name].var or 1e-12
        if chi2(0.0) <= dof:
            return 0.0
        while chi2(hi) > dof:
            hi *= 4
        lo = hi / 4
        while chi2(lo) < dof and lo > 1e-300:
            lo /= 4
        for _ in range(200):  # to 1e-9 of the factor (31 halvings of a factor of 4), far below its own std
            if hi <= lo * (1 + 1e-9):
                break
            mid = math.sqrt(lo) * math.sqrt(hi)  # not sqrt(lo * hi): the product underflows to 0 below 1e-324
            lo, hi = (mid, hi) if chi2(mid) > dof else (lo, mid)
        return math.sqrt(lo) * math.sqrt(hi)

    def solve(self, u_b, D_b, u_d, D_d, estimate=None) -> PairSolution:
        """C_b^d, d phi/dz, the pairs' residual rms (rad) and chi-square (2 dof per pair, 3 for C),
        each pair weighted by the inverse of its directions' variance (both sides, from z).
        estimate: the part whose variance factor the pairs' scatter gives (_estimate_var), with
        its share of their degrees of freedom."""
        dof = 2 * len(u_b) - 3
        for _ in range(2 if estimate else 1):  # the weights follow the estimated part
            w = 2.0 / (self._variance(D_b) + self._variance(D_d))
            C = wahba(u_b, u_d, w)
            J_phi = wahba_sensitivity(u_b, D_b, u_d, D_d, w, C)
            resid, J, R_b, R_phi = pair_misfits(u_b, D_b, u_d, D_d, C, J_phi)
            if estimate and dof > 0:
                self.parts[estimate].var = self._estimate_var(estimate, resid, J, dof)
            by_part = self._by_part(J)
        chi2, S_inv = self._pairs_chi2(resid, by_part)
        if estimate:  # its share of the pairs' 2n residual directions
            share = float(np.einsum("nab,nba->", S_inv, by_part[estimate])) / (2 * len(u_b))
            self.parts[estimate].dof = max(dof * share, 1.0)
        return {"pairs": len(u_b), "C": C, "u_b": u_b, "u_d": u_d, "J_phi": J_phi, "chi2": chi2, "dof": dof,
                "misfit": resid, "S_inv": S_inv, "R_b": R_b, "R_phi": R_phi,
                "noise_dof": self._dof(S_inv, by_part, 2 * len(u_b)),
                "residual_rms_rad": float(np.sqrt(np.mean(np.sum(resid ** 2, axis=1)))),
                "rank": int(np.linalg.matrix_rank(u_b, tol=1e-3))}

    def gyro_matrix_in_b(self, C, J_phi):
        """M_b = M_d(p_g) C and the covariance of its 9 entries (row-major):
        dM_b = dM_d C + M_d C [dphi x]."""
        p = self.fg.vector(self.gm.params)
        M_d, _ = self.gm.matrix_and_bias(p)
        d_skew = np.moveaxis(skew(J_phi.T), 0, -1)  # d [phi x] / dz: [.x] is linear
        J = np.einsum("ia,abz->ibz", M_d @ C, d_skew)
        gyro = self.parts["gyro"].index.start
        for k in range(len(p)):  # dM_d/dp by central differences (M_d is linear in p for the built-in models)
            e = np.zeros(len(p))
            e[k] = 1e-6
            J[:, :, gyro + k] += (self.gm.matrix_and_bias(p + e)[0] - self.gm.matrix_and_bias(p - e)[0]) / 2e-6 @ C
        J = J.reshape(9, self.nz)
        return M_d @ C, self.covariance(J)

    def covariance(self, J):
        """J cov J^T, the parts' contributions summed (cov is block-diagonal over them)."""
        return sum(self._by_part(J).values())

    def quadratic_form(self, d, J):
        """d^T (J cov J^T)^+ d for a difference d with d d/dz = J, its covariance and the
        p-value: chi-square, or F where the covariance is estimated (Satterthwaite's dof)."""
        cov_d = self.covariance(J)
        S_inv = np.linalg.pinv(cov_d, rcond=1e-12, hermitian=True)
        z2 = float(d @ S_inv @ d)
        return z2, cov_d, chi2_sf_estimated(z2, len(d), self._dof(S_inv, self._by_part(J), len(d)))


def vertical_k(middle_rad, inner_rad):
    """The table vertical (outer axis) in k at commanded middle/inner angles (n, 3), and its
    derivative with respect to those two angles (n, 3, 2): how a position error moves it."""
    def up(da, db):
        return table.C_k_n(0.0, middle_rad + da, inner_rad + db, np.zeros(7))[:, 2, :]
    h = 1e-6
    return up(0, 0), np.stack([(up(h, 0) - up(-h, 0)) / (2 * h), (up(0, h) - up(0, -h)) / (2 * h)], axis=-1)


def _pairings(un: Unifier, acc_segs, gyro_segs, find, table_std_rad) -> dict:
    """{pairing: un.solve's answer} for the rate runs' means and the static pairs, where the data have them."""
    rate_sign = np.sign([s.outer_rate_dps for s in gyro_segs])
    pairs = [(i, j) for j, s in enumerate(gyro_segs)
             if (i := find(acc_segs, "static", middle_deg=s.middle_deg, inner_deg=s.inner_deg)) is not None]
    if len(pairs) >= 2:  # each pair: the static position's and the rate run's own errors, so twice the variance
        un.add_part("table", 2 * np.eye(2 * len(pairs)), *((table_std_rad ** 2, math.inf) if table_std_rad is not None
                                                            else (ARCMIN_RAD ** 2, None)))
    out = {}
    if un.acc_means is not None:
        rows = un.acc_means[0]
        u_b, D_b = un.acc_mean_directions()
        u_d, D_d = un.gyro_directions(rows)
        sign = rate_sign[rows]
        u_d, D_d = u_d * sign[:, None], D_d * sign[:, None, None]  # the axis is +up for a positive rate
        out["rate_run_means"] = un.solve(u_b, D_b, u_d, D_d, "acc_means" if un.parts["acc_means"].estimated else None)
    if len(pairs) >= 2:
        ia, ig = np.array(pairs).T
        u_b, D_b = un.acc_directions(ia)
        up_k, dup_k = vertical_k(np.radians([acc_segs[i].middle_deg for i in ia]),
                                 np.radians([acc_segs[i].inner_deg for i in ia]))
        C_k_b = wahba(up_k, u_b, np.ones(len(ia)))
        t = un.parts["table"].index.start
        for n in range(len(ia)):  # du_b / d(the pair's middle and inner angle errors), tangent to u_b
            D_b[n, :, t + 2 * n:t + 2 * n + 2] = (np.eye(3) - np.outer(u_b[n], u_b[n])) @ C_k_b @ dup_k[n]
        u_d, D_d = un.gyro_directions(ig)
        u_d, D_d = u_d * rate_sign[ig, None], D_d * rate_sign[ig, None, None]
        out["static_pairs"] = un.solve(u_b, D_b, u_d, D_d, "table" if un.parts["table"].estimated else None)
    return out


def _choose(usable: dict):
    """(the pairing that ties the frames, a note or None): the rate runs' means, unless they disagree
    grossly where the static pairs agree; refused where the one chosen disagrees grossly (a mirrored
    triad is named)."""
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
    return method, fallback


def unify(un: Unifier, acc_segs, gyro_segs, find, table_std_rad=None):
    """C_b^d by the rate runs' means (or, without accelerometer data in the rate runs, by static
    pairs), its std, the gyro M in b with its std, and the other pairing as a cross-check.
    find(segs, kind, **angles) -> index of the first segment of that kind at those angles, or None.
    table_std_rad: the std of each commanded middle/inner angle's position error, which the static
    pairs carry (meta's table_accuracy_arcsec); None: estimated from the static pairs' scatter."""
    usable = {k: v for k, v in _pairings(un, acc_segs, gyro_segs, find, table_std_rad).items() if v["rank"] >= 2}
    method, fallback = _choose(usable)
    best = usable[method]
    C, J_phi = best["C"], best["J_phi"]
    M_b, cov_M = un.gyro_matrix_in_b(C, J_phi)
    lever = lever_arm_test(un, usable["rate_run_means"]) if "rate_run_means" in usable else None
    why = misplaced_by(un.fa.test.fails, lever)
    p_pairs = chi2_sf_estimated(best["chi2"], best["dof"], best["noise_dof"]) if best["dof"] > 0 else 1.0
    inflate = max(1.0, best["chi2"] / best["dof"]) if p_pairs < ALPHA else 1.0
    if inflate > 1:  # the pairs disagree beyond their noise: the stds take the misfit in
        cov_M = cov_M * inflate
        misfit = (f"the {best['pairs']} pairs misfit (chi2 {best['chi2']:.4g} on {best['dof']} dof): stds inflated by "
                  f"{np.sqrt(inflate):.3g}" + (f"; {why}?" if method == "rate_run_means" else ""))
        fallback = f"{fallback}; {misfit}" if fallback else misfit
    noise = _estimated_noise(un)
    means = noise.get("acc_rate_run_means")
    if means and means["p_value_vs_static"] < ALPHA:
        scatter = (f"the rate runs' accelerometer means scatter {means['std_g'] / means['static_std_g']:.3g} times "
                   f"as much as the static positions (F test p = {means['p_value_vs_static']:.2g}): {why}, or "
                   "vibration under rotation")
        fallback = f"{fallback}; {scatter}" if fallback else scatter
    if lever is not None and lever["fails"] and not inflate > 1:  # the targeted test sees what the omnibus did not
        arms = f"the pairs' targeted test of lever arms fails ({lever['text']}): --add acc.size_effect.*"
        fallback = f"{fallback}; {arms}" if fallback else arms
    info = {"method": method, "pairs": best["pairs"], "C_b_d": C.tolist(),
            "std_rad": np.sqrt(inflate * np.diag(un.covariance(J_phi))).tolist(),
            "std_note": "std of the small rotation phi with C_b_d = C (I + [phi x]), about b's x, y, z",
            "direction_residual_rms_rad": best["residual_rms_rad"], "chi2": best["chi2"], "dof": best["dof"],
            "noise": noise, **({"lever_arms": lever} if lever else {}), **({"note": fallback} if fallback else {})}
    if method == "rate_run_means" and "static_pairs" in usable:
        info["cross_check"] = _cross_check(un, C, J_phi, usable["static_pairs"], noise["table_angles"]["text"],
                                           bool(lever and lever["fails"]))
    return C, M_b, np.sqrt(np.diag(cov_M)).reshape(3, 3), info


def _cross_check(un: Unifier, C, J_phi, two, table_text, lever_fails=False) -> dict:
    """The static pairs' C_b^d against the rate runs' means': their difference and its Mahalanobis test
    (lever_fails: the pairs' targeted test of lever arms failed, so the note names them)."""
    d = log_so3(C.T @ two["C"])
    z2, cov_d, p = un.quadratic_form(d, two["J_phi"] - J_phi)
    agree = p >= ALPHA
    return {
        "method": "static_pairs", "pairs": two["pairs"], "difference_rad": d.tolist(),
        "difference_std_rad": np.sqrt(np.diag(cov_d)).tolist(), "mahalanobis2": z2, "p_value": p,
        "agree": bool(agree),
        "note": (f"the two pairings agree within their noise and the table's angle errors ({table_text})"
                 if agree else
                 f"the static pairs differ by {np.degrees(np.linalg.norm(d)) * 60:.2g} arcmin (p = {p:.2g}) beyond "
                 f"their noise and the table's angle errors ({table_text}): rate runs that are not whole "
                 "revolutions, " + ("or lever arms that the accelerometer model lacks (--add acc.size_effect.*), "
                                    if lever_fails else "") + "or a table less accurate than stated")}


def _estimated_noise(un: Unifier) -> dict:
    """What the unification estimated itself, and where from: the rate runs' accelerometer means
    (from the rate-run pairs' scatter, tested against the static positions' noise by an F test)
    and the table's angle errors (stated, or from the static pairs' scatter)."""
    out = {}
    means = un.parts.get("acc_means")
    if means is not None and means.estimated:
        static = float(np.median(un.obs_a.sigma ** 2))
        std = math.sqrt(means.var)
        out["acc_rate_run_means"] = {
            "std_g": std, "dof": means.dof, "static_std_g": math.sqrt(static), "static_dof": un.parts["acc"].dof,
            "p_value_vs_static": chi2_sf_estimated(means.var / static * means.dof, means.dof, un.parts["acc"].dof),
            "source": "one averaged row per rate run and no acc_noise_g: a variance component estimated from the "
                      "rate-run pairs' scatter",
            "text": f"{std:.2g} g per rate run's mean, from the rate-run pairs' scatter ({means.dof:.3g} dof)"}
    table_part = un.parts.get("table")
    if table_part is not None:
        std = math.sqrt(table_part.var)
        stated = not table_part.estimated
        out["table_angles"] = {
            "std_rad": std, "dof": None if stated else table_part.dof,
            "source": "stated (meta.json table_accuracy_arcsec)" if stated else
                      "estimated from the static pairs' scatter (no table_accuracy_arcsec in meta.json)",
            "text": f"{std / units.ARCSEC_RAD:.3g} arcsec per angle, " + (
                "stated" if stated else f"from the static pairs' scatter, {table_part.dof:.3g} dof")}
    return out


def unify_paper(acc_obs, acc_segs, gyro_obs, gyro_segs, p_acc, p_gyro, meta, find):
    """dong2018 eq. 25-27 (derived, generated/unify.py) at the Table 2 positions (--method linear)."""
    ia = [find(acc_segs, "static", middle_deg=a, outer_deg=g, inner_deg=0.0) for a, g in eq.TABLE2]
    ig = [find(gyro_segs, "rate", middle_deg=a, inner_deg=0.0) for a in eq.GYRO_ALPHAS]
    if None in ia or None in ig:
        raise CalibrationError(f"the paper's frame unification needs the Table 2 static positions "
                               f"(alpha, gamma) = {eq.TABLE2} deg with beta = 0, and rate runs at alpha = "
                               f"{eq.GYRO_ALPHAS} deg, beta = 0; use --method exact, which needs none")
    x = eq.acc_table2(acc_obs.N[ia].reshape(12), p_acc)
    w_T = gyro_segs[ig[0]].outer_rate_dps * units.DPH_PER_DPS
    lam = eq.gyro_mounting(gyro_obs.N[ig].reshape(6), p_gyro, w_T, units.earth_rate_dph(meta),
                              np.radians(meta["latitude_deg"]))
    C_b_d = table.mounting(lam).T @ table.mounting(x[:3])
    return C_b_d, {"theta4_rad": x[:3].tolist(), "tilt_rad": x[3:].tolist(), "lambda4_rad": lam.tolist()}
