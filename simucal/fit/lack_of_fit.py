"""Is the model wrong? Answers that need no stated noise, and the shape of what is missing.

- fit_with_noise: the exact norm fit (norm_fit.fit_exact) with the noise taken
  from whatever the data give: each segment's own scatter or the stated noise
  where there is one, and for the rows with neither one variance component
  sigma_u^2 estimated from the fit (REML-like: their residual sum of squares
  over their share of the degrees of freedom, 1 - h_ii summed over their rows,
  h the hat matrix of the weighted Jacobian). One row without scatter never
  switches the test off.
- lack_of_fit: an F test of the model against the model plus a generic
  flexible basis (monomials of the input of degree 2 and 3 on each output
  axis, time, temperature, each axis's input times temperature (a scale factor
  drifting with temperature), and for gyros the specific force, alone and times temperature). It needs no
  noise level: F = (|P_G r|^2 / q) / ((|r|^2 - |P_G r|^2) / (dof - q)), with
  P_G the projection on the basis columns made orthogonal to the model's
  Jacobian (the per-position direction unknowns included), linearised at the
  solution.
- describe_shape: the single generic term that explains most of the misfit, its
  numbers and its words ("on the x axis, about 3e-4 * f_x^3 g: odd in f_x, third
  degree"); report/model_files.py writes it as a model file that `--add FILE` accepts.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from typing import Callable, TypedDict

import numpy as np

from simucal.fit.augmented import regressor
from simucal.fit.aux_inputs import DEFAULT_ZERO, FORCE, SENSOR_AUX, T_REF, AuxInputs
from simucal.fit.distributions import chi2_sf, f_sf
from simucal.fit.norm_fit import Fit, Observations, dense_jacobian, fit_exact
from simucal.fit.results import Shape
from simucal.fit.twins import twins
from simucal.io import records, units

DPS = units.DPH_PER_DPS  # gyro rates enter generic terms in deg/s (as in derive/models/effects.py)


@dataclass
class GenericTerm:
    axis: int          # output axis
    exponents: tuple   # powers of the three input components (empty for aux terms)
    aux: str | None    # an auxiliary input's name (t_s, dtemp_c, w2, f_x.., a user's column), else None
    sensor: str
    # exponents and aux both set: the input (in its own unit, g or deg/h) times the auxiliary input,
    # a scale factor that drifts with it (u_x dtemp_c: the x scale factor linear in temperature)
    times: str | None = None  # an aux term times this input too (f_x dtemp_c: a g-sensitivity drifting)

    @property
    def is_scale(self) -> bool:
        return bool(self.aux) and bool(self.exponents)

    @property
    def degree(self) -> int:
        return sum(self.exponents)

    def symbol(self, i):
        return ("f_x", "f_y", "f_z")[i] if self.sensor == "acc" else ("w_x", "w_y", "w_z")[i]

    def text(self) -> str:
        """The regressor as a reader writes it: f_x^3, w_z^2 (deg/s), t_s, w_z dtemp_c."""
        if self.is_scale:
            return f"{self.symbol(self.exponents.index(1))} {self.aux}"
        if self.aux:
            return self.aux + (f" {self.times}" if self.times else "")
        return " ".join(self.symbol(i) + (f"^{e}" if e > 1 else "") for i, e in enumerate(self.exponents) if e)

    def sympy(self) -> str:
        """The regressor as SymPy source for a model file (derive.frames symbols)."""
        if self.is_scale:
            i = self.exponents.index(1)
            aux = self.aux if self.aux in DEFAULT_ZERO else f"column_input({self.aux!r})"
            return f"{'f_b' if self.sensor == 'acc' else 'omega_d'}[{i}] * {aux}"
        if self.times:
            return f"{replace(self, times=None).sympy()} * {self.times}"
        if self.aux in FORCE:
            return f"f_b[{FORCE.index(self.aux)}]"
        if self.aux:
            return self.aux if self.aux in DEFAULT_ZERO else f"column_input({self.aux!r})"
        v = "f_b[{}]" if self.sensor == "acc" else "(omega_d[{}] / %g)" % DPS
        return " * ".join(v.format(i) + (f"**{e}" if e > 1 else "") for i, e in enumerate(self.exponents) if e)

    def unit(self) -> str:
        out = "g" if self.sensor == "acc" else "deg/h"
        if self.is_scale:
            return "1/degC" if self.aux == "dtemp_c" else f"1 per unit of {self.aux}"
        if self.times:
            return f"{replace(self, times=None).unit()}/degC"
        if self.aux:
            return {"t_s": f"{out}/s", "dtemp_c": f"{out}/degC", "w2": "m"}.get(
                self.aux, f"({out})/g" if self.aux in FORCE else f"{out} per unit of {self.aux}")
        return f"{out}/g^{self.degree}" if self.sensor == "acc" else f"({out})/(deg/s)^{self.degree}"

    def name(self) -> str:
        a = "xyz"[self.axis]
        if self.is_scale:
            assert self.aux is not None  # a scale term's aux (is_scale)
            return f"k_{a}_{self.aux.replace('_', '')}"
        if self.aux:
            return f"c_{a}_{self.aux.replace('_', '')}" + (f"_{self.times.replace('_', '')}" if self.times else "")
        return f"c_{a}_" + "".join("xyz"[i] * e for i, e in enumerate(self.exponents))

    def parity(self) -> str:
        if self.is_scale:
            return "a scale factor " + ("linear in temperature (from T_ref)" if self.aux == "dtemp_c" else
                                        f"linear in {self.aux}")
        if self.times:
            return f"{replace(self, times=None).parity()}, changing linearly with temperature (from T_ref)"
        if self.aux:
            return {"t_s": "linear in time", "dtemp_c": "linear in temperature (from T_ref)",
                    "w2": "with the centripetal scale"}.get(
                self.aux, "proportional to the specific force" if self.aux in FORCE else f"linear in {self.aux}")
        parts = [f"{'odd' if e % 2 else 'even'} in {self.symbol(i)}" for i, e in enumerate(self.exponents) if e]
        return ", ".join(parts) + f", {('second', 'third')[self.degree - 2]} degree"

    def values(self, u, obs: Observations) -> np.ndarray:
        if self.is_scale:
            return u[:, self.exponents.index(1)] * obs.aux.column(self.aux, len(u))
        if self.aux:
            return obs.aux.column(self.aux, len(u)) * (obs.aux.column(self.times, len(u)) if self.times else 1.0)
        x = u if self.sensor == "acc" else u / DPS
        return np.prod([x[:, i] ** e for i, e in enumerate(self.exponents)], axis=0)


def catalog_id(term: GenericTerm) -> str | None:
    """The candidate effect (generated/effects.py) with this very regressor, if there is one:
    compared on random inputs, so the catalog's own forms need no second description here."""
    from simucal.generated.effects import EFFECTS
    if term.aux and term.aux not in SENSOR_AUX[term.sensor]:
        return None  # a user's column: no library effect reads it
    rng = np.random.default_rng(0)
    u = rng.normal(size=(6, 3)) * (1.0 if term.sensor == "acc" else DPS)
    aux = AuxInputs({name: rng.normal(size=6) for name in SENSOR_AUX[term.sensor]})
    obs = Observations(u, np.ones(6), None, aux)
    mine = term.values(u, obs)
    for eid, effect in EFFECTS.items():
        if effect.sensor == term.sensor and effect.axis == term.axis:
            if np.allclose(regressor(eid, u, aux), mine, rtol=1e-9, atol=1e-12):
                return eid
    return None


def generic_terms(sensor: str, obs: Observations) -> list[GenericTerm]:
    """Pure powers first, so that a tie (monomials are dependent on a sphere) names the simplest."""
    mono = [e for d in (2, 3) for e in itertools.product(range(d + 1), repeat=3) if sum(e) == d]
    mono.sort(key=lambda e: (sum(e), -max(e)))
    # temp_c only through dtemp_c (the same column from T_ref); then a user's columns
    names = [x for x in SENSOR_AUX[sensor] if x != "temp_c"] + sorted(set(obs.aux.values) - DEFAULT_ZERO - {T_REF})
    aux = [x for x in names if np.ptp(obs.aux.column(x, len(obs.N))) > 0]  # inputs that vary over the positions
    unit = [tuple(int(i == a) for i in range(3)) for a in range(3)]
    return [GenericTerm(a, e, None, sensor) for e in mono for a in range(3)] + \
        [GenericTerm(a, (), x, sensor) for x in aux for a in range(3)] + \
        [GenericTerm(a, unit[a], "dtemp_c", sensor) for a in range(3) if "dtemp_c" in aux] + \
        [GenericTerm(a, (), x, sensor, "dtemp_c") for x in aux if x in FORCE for a in range(3) if "dtemp_c" in aux]


def fit_with_noise(model, obs: Observations, p0=None) -> tuple[Fit, Observations, records.NoiseUsed]:
    """The exact fit with sigma from the data, the statement, or a variance component.
    Returns (fit, the observations with the sigma used (None: one unknown std), noise info)."""
    sig = None if obs.sigma is None else np.asarray(obs.sigma, float)
    known = np.zeros(len(obs.N), bool) if sig is None else np.all(np.isfinite(sig), axis=1)
    if known.all():
        return fit_exact(model, obs, p0), obs, {"source": obs.sigma_source}
    if not known.any():
        obs = replace(obs, sigma=None)
        fit = fit_exact(model, obs, p0)
        s = float(np.sqrt(np.sum(fit.residuals ** 2) / fit.dof)) if fit.dof > 0 else None
        return fit, obs, {"source": "none in the data and none stated: one std for all rows, estimated from the fit "
                               "(so no chi-square test; the lack-of-fit F test decides)",
                     "estimated_std": s, "dof": int(fit.dof), "rows_estimated": int(len(obs.N))}
    assert sig is not None  # some row's noise is known
    s_u = float(np.median(sig[known]))
    for _ in range(8):
        full = np.where(known[:, None], sig, s_u)
        fit = fit_exact(model, replace(obs, sigma=full), p0)
        p0 = fit.vector(model.params)
        J, _ = dense_jacobian(model, replace(obs, sigma=full), fit)
        h = np.einsum("ij,ji->i", J, np.linalg.pinv(J)).reshape(-1, 3)  # hat-matrix diagonal, per component
        share = float(np.sum(1 - h[~known]))
        new = float(np.sqrt(np.sum(fit.residuals[~known] ** 2) / max(share, 1e-9)))
        done = abs(new - s_u) <= 1e-3 * s_u
        s_u = max(new, 1e-300)
        if done:
            break
    fit.dof -= 1  # one variance estimated
    fit.p_value = float(chi2_sf(fit.chi2, fit.dof)) if fit.dof > 0 else None
    return fit, replace(obs, sigma=np.where(known[:, None], sig, s_u)), {
        "source": f"{int(known.sum())} rows from their scatter or the stated noise; {int((~known).sum())} "
                  "rows (one averaged row, no stated noise) from a variance component estimated from the fit",
        "estimated_std": s_u, "dof": share, "rows_estimated": int((~known).sum())}


def with_estimated_sigma(obs: Observations, noise: records.NoiseUsed) -> Observations:
    """The observations with every row's std: where fit_with_noise estimated one std for all
    rows (sigma None, so that the test stays the F test), that std."""
    if obs.sigma is not None or noise.get("estimated_std") is None:
        return obs
    return replace(obs, sigma=np.full(obs.N.shape, noise["estimated_std"]))


def noise_dof(noise: dict) -> float:
    """The degrees of freedom of the noise a fit used: inf where every row's was known (scatter
    or stated), else its variance component's."""
    return float(noise["dof"]) if noise.get("rows_estimated") else math.inf


def _perp_basis(model, obs, fit, terms):
    """Weighted residual r, and the generic columns made orthogonal to the model's Jacobian."""
    J, sig = dense_jacobian(model, obs, fit)
    r = (fit.residuals / sig).ravel()
    Q, _ = np.linalg.qr(J)
    u = fit.directions * obs.rho[:, None]
    cols = []
    for t in terms:
        c = np.zeros((len(u), 3))
        c[:, t.axis] = t.values(u, obs)
        cols.append((c / sig).ravel())
    G = np.array(cols).T
    return r, G, G - Q @ (Q.T @ G), sig


def _left_singular(A):
    """(U, S) of A's thin SVD; where LAPACK's divide and conquer does not converge (it can fail on
    nearly repeated columns, finite as they are), from the eigenvectors of A^T A."""
    try:
        U, S, _ = np.linalg.svd(A, full_matrices=False)
        return U, S
    except np.linalg.LinAlgError:
        w, V = np.linalg.eigh(A.T @ A)
        order = np.argsort(w)[::-1]
        S = np.sqrt(np.maximum(w[order], 0.0))
        return A @ V[:, order] / np.maximum(S, 1e-300), S


def lack_of_fit(model, obs: Observations, fit: Fit) -> records.LackOfFit:
    """F test of the model against model + generic basis (see module doc)."""
    terms = generic_terms(model.sensor, obs)
    r, G, Gp, _ = _perp_basis(model, obs, fit, terms)
    norms = np.linalg.norm(G, axis=0)
    keep = np.linalg.norm(Gp, axis=0) > 1e-6 * np.maximum(norms, 1e-300)
    dof = fit.dof
    if not keep.any() or dof < 4:
        return {"test": "lack-of-fit F test", "p_value": None, "q": 0, "dof": dof,
                "note": "too few degrees of freedom for a lack-of-fit test (need 4 or more)"}
    U, S = _left_singular(Gp[:, keep] / np.linalg.norm(Gp[:, keep], axis=0))
    q = int(min(np.sum(S > 1e-6 * S[0]), dof - max(3, dof // 3)))
    ss1 = float(np.sum((U[:, :q].T @ r) ** 2))
    ss = float(r @ r)
    F = (ss1 / q) / max((ss - ss1) / (dof - q), 1e-300)
    return {"test": "lack-of-fit F test against a generic basis (monomials of the input of degree 2-3 per axis, "
                    "time, temperature, input x temperature" + (", specific force" if model.sensor == "gyro" else "")
                    + ")",
            "F": float(F), "q": q, "dof": int(dof - q), "p_value": float(f_sf(F, q, dof - q))}


def _basis_at(model, obs, fit):
    """The generic terms, the whitened residual, their columns (plain and off the model's span) and
    what each alone explains: (terms, r, G, Gp, sig, n2, ok, proj, lr)."""
    terms = generic_terms(model.sensor, obs)
    r, G, Gp, sig = _perp_basis(model, obs, fit, terms)
    n2 = np.sum(Gp ** 2, axis=0)
    ok = n2 > 1e-12 * np.maximum(np.sum(G ** 2, axis=0), 1e-300)
    proj = np.where(ok, Gp.T @ r, 0.0)
    lr = np.where(ok, proj ** 2 / np.where(ok, n2, 1.0), 0.0)
    return terms, r, G, Gp, sig, n2, ok, proj, lr


def describe_shape(model, obs: Observations, fit: Fit) -> Shape | None:
    """The one generic term that explains most of the misfit, with its estimate."""
    terms, r, _, Gp, sig, n2, ok, _, lr = b = _basis_at(model, obs, fit)
    if not ok.any():
        return None
    best = 0
    for k in range(1, len(terms)):  # the first of near ties (simplest form) stays
        if lr[k] > 1.01 * lr[best]:
            best = k
    s2 = 1.0 if fit.chi2 is not None else float(r @ r) / max(fit.dof, 1)  # unknown noise: the residuals' variance
    cols = {k: Gp[:, k] / np.sqrt(n2[k]) for k in range(len(terms)) if ok[k]}
    return _shape_of(best, twins(best, cols, r, s2), b, model, obs, fit)


def _shape_of(best, alike, b, model, obs, fit) -> Shape:
    """The shape block of generic term `best` (an index into _basis_at's terms); alike: its twins' indices."""
    terms, r, _, Gp, sig, n2, _, proj, lr = b
    t = terms[best]
    coef = float(proj[best] / n2[best])
    after = (fit.residuals / sig).ravel() - coef * Gp[:, best]
    rms_after = float(np.sqrt(np.mean((after.reshape(-1, 3) * sig) ** 2)))
    unit = "g" if model.sensor == "acc" else "deg/h"
    return {"axis": "xyz"[t.axis], "regressor": t.text(), "catalog_id": catalog_id(t), "degree": t.degree,
            "parity": t.parity(), "estimate": coef, "unit": t.unit(), "parameter": t.name(), "sympy": t.sympy(),
            "share_of_misfit": float(lr[best] / max(r @ r, 1e-300)), "residual_rms_after": rms_after,
            "indistinguishable_here": [f"{terms[k].text()} on {'xyz'[terms[k].axis]}" for k in alike][:6],
            "points": {"regressor": t.values(fit.directions * obs.rho[:, None], obs).tolist(),
                       "residual": fit.residuals[:, t.axis].tolist(),
                       # the part of the term the model cannot absorb: what the residual should show
                       "term_visible": (coef * Gp[:, best].reshape(-1, 3) * sig)[:, t.axis].tolist()},
            "text": (f"on the {'xyz'[t.axis]} axis, about {coef:.2g} * {t.text()} {unit}"
                     + (" (rates in deg/s)" if model.sensor == "gyro" and not t.aux else "")
                     + f": {t.parity()}; it explains {100 * lr[best] / max(r @ r, 1e-300):.0f} % of the misfit")}


class TwinFit(TypedDict):
    """A generic term fitted with the model (twin_fits), for rows the fit did not use to judge."""
    shape: Shape                      # its shape block, the others its twins
    column: Callable[[np.ndarray, AuxInputs], np.ndarray]  # (u, aux) -> (n, 3) per unit coefficient
    params: np.ndarray                # [the model's..., the term's]
    cov: np.ndarray                   # their covariance


def twin_fits(model, obs: Observations, fit: Fit, shape: Shape) -> list[TwinFit]:
    """The found term and each of its twins (shape['indistinguishable_here']) fitted with the model,
    linearised at the model's fit (one Gauss-Newton step, exact for a linear term): each's shape
    block (the others its twins), its values as a function column(u, aux) -> (n, 3) per unit
    coefficient, and the parameters [the model's..., the term's] with their covariance, so that
    rows the rate runs did not fit (the gyro's static rows) can judge between them."""
    terms, r, G, Gp, sig, n2, ok, proj, lr = b = _basis_at(model, obs, fit)
    label = {f"{t.text()} on {'xyz'[t.axis]}": k for k, t in enumerate(terms) if ok[k]}
    idx = [label[x]
           for x in [f"{shape['regressor']} on {shape['axis']}"] + shape["indistinguishable_here"] if x in label]
    J, _ = dense_jacobian(model, obs, fit)
    m = len(model.params)
    Jp = np.linalg.pinv(J)
    cov_J = (Jp @ Jp.T)[:m, :m]  # (J^T J)^+
    scale = np.median(np.diag(fit.cov) / np.maximum(np.diag(cov_J), 1e-300))  # as fit.cov (full_covariance)
    p = fit.vector(model.params)
    out: list[TwinFit] = []
    for k in idx:
        t, c, h = terms[k], float(proj[k] / n2[k]), (Jp @ G[:, k])[:m]
        # min |r + J dp - c G|, J^T r = 0 at the fit: dp = c J^+ G; [J, -G]'s covariance by its Schur
        # complement, var c = 1 / |G off J's span|^2
        cov = np.block([[cov_J + np.outer(h, h) / n2[k], h[:, None] / n2[k]], [h[None, :] / n2[k], 1 / n2[k]]]) * scale
        dp = c * h

        def column(u, aux, t=t):
            col = np.zeros((len(u), 3))
            col[:, t.axis] = t.values(u, Observations(u, np.ones(len(u)), None, aux))
            return col
        out.append({"shape": _shape_of(k, [j for j in idx if j != k], b, model, obs, fit), "column": column,
                    "params": np.r_[p + dp, c], "cov": cov})
    return out
