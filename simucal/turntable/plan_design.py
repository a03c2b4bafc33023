"""Test-plan design: the Fisher information of a plan, its scores, and D/A-optimal plans.

A plan is a list of commanded table positions (gamma, alpha, beta), optionally with an
outer-axis rate for rate runs. With a nominal table, the input direction of each
position in k is the vertical C_n^k z (at rest: the specific force; under rate: the
rate axis). The information of the model's parameters is the exact problem's
Gauss-Newton matrix at the nominal parameters with every direction profiled out
(norm_fit.normal_equations, Schur complement of the 2x2 direction blocks), weighted by
the stated noise: its inverse is the Cramer-Rao bound of the exact fit.

- score: CRLB of every parameter, correlations, the D-criterion per position
  det(H / n)^(1/m) and the A-criterion trace(H^-1) (both in the parameters' units).
- design: the D- (or A-) optimal n-position plan over a fine candidate grid on the
  sphere (a spherical Fibonacci set), by Fedorov exchange from the best of several
  random starts, each direction then written as table angles (plans.angles_for).
- separate: the positions to add to a plan so that two candidate effects are told apart:
  the expected likelihood-ratio statistic (noncentrality) of fitting the wrong one to data
  that carry the other at its stated size, both ways, raised greedily over the candidate
  grid (and rates, for gyros) until the 1-dof test reaches the target power.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from simucal.errors import CalibrationError
from simucal.io import results
from simucal.fit.augmented import AugmentedModel
from simucal.fit.models import GeneratedModel
from simucal.fit.norm_fit import Observations, check_not_coplanar, normal_equations
from simucal.generated import table
from simucal.generated.effects import SEPARATE
from simucal.turntable import plans


def directions_k(rows) -> np.ndarray:
    """Unit input directions in k of commanded (gamma, alpha, beta) in degrees, nominal table."""
    a = np.radians(np.asarray(rows, float)[:, :3])
    return table.C_k_n(a[:, 0], a[:, 1], a[:, 2], np.zeros(7))[:, 2, :]


def information(model: AugmentedModel, u, rho, sigma, p=None) -> np.ndarray:
    """H (m, m) of the exact problem at p (default: nominal, all zero) for unit directions u (n, 3)."""
    n, m = len(u), len(model.params)
    p = np.zeros(m) if p is None else np.asarray(p, float)
    rho = np.broadcast_to(np.asarray(rho, float), (n,))
    N = model.output(rho[:, None] * u, p)
    obs = Observations(N, rho, np.full((n, 3), float(sigma)))
    return normal_equations(model, obs, p, u, obs.sigma)[1]


def score(model: AugmentedModel, u, rho, sigma, where="") -> results.PlanScore:
    """CRLB, correlation, D- and A-criteria of a plan (module doc); where: the plan's name, which a refusal starts
    with ("plan FILE: ")."""
    n, m = len(u), len(model.params)
    if n < m:
        raise CalibrationError(f"{where}{n} positions for {m} parameters of {model.name}: "
                               f"the norm gives one equation per position, so a plan needs at least {m}")
    H = information(model, u, rho, sigma)
    d = np.sqrt(np.abs(np.diag(H)))
    singular = not (np.all(np.isfinite(H)) and np.all(d > 0))  # a parameter the plan never moves
    if not singular:
        w = np.linalg.eigvalsh(H / np.outer(d, d))
        singular = w[0] < 1e-10 * w[-1]
    if singular:  # directions in one plane are the usual cause: named, with the plane's normal
        check_not_coplanar(u, "accelerometer" if model.sensor == "acc" else "gyro", where, "the table frame k")
        raise CalibrationError(f"{where}the plan leaves a combination of {model.name}'s parameters unobservable (the "
                               "information is singular): add positions with other input directions")
    cov = np.linalg.inv(H)
    sd = np.sqrt(np.diag(cov))
    return {"model": model.name, "positions": n, "sigma": sigma,
            "crlb": dict(zip(model.params, sd.tolist())), "units": dict(zip(model.params, model.param_units)),
            "correlation": (cov / np.outer(sd, sd)).tolist(),
            "D_per_position": float(np.exp(np.linalg.slogdet(H / n)[1] / m)),
            "A": float(np.trace(cov)), "max_abs_correlation": float(np.max(np.abs(cov / np.outer(sd, sd) - np.eye(m))))}


def _crit(H, criterion):
    """log det H (D) or -trace H^-1 (A) of one or many (..., m, m); -inf where singular."""
    sign, logdet = np.linalg.slogdet(H)
    ok = sign > 0
    if criterion == "D":
        return np.where(ok, logdet, -np.inf)
    Hs = np.where(ok[..., None, None], H, np.eye(H.shape[-1]))
    return np.where(ok, -np.trace(np.linalg.inv(Hs), axis1=-2, axis2=-1), -np.inf)


def design(model: AugmentedModel, n: int, rho, sigma, criterion="D", grid=600, starts=6, seed=0):
    """Unit directions (n, 3) and input norms (n,) of an optimal n-position plan (module doc);
    rho: one input norm, or several (rate runs at several rates) to choose from."""
    m = len(model.params)
    if n < m:
        raise CalibrationError(f"--positions {n}: {model.name} has {m} parameters, so a plan needs at least {m}")
    if criterion not in ("D", "A"):
        raise CalibrationError(f"--criterion {criterion!r}: D or A")
    dirs = plans.fibonacci_directions(grid)
    rhos = np.atleast_1d(np.asarray(rho, float))
    cand = np.concatenate([dirs] * len(rhos))
    cand_rho = np.repeat(rhos, grid)
    grid = len(cand)
    # each candidate's own information (rank <= 3): the plan's H is the sum over its positions
    Hs = np.array([information(model, c[None], r, sigma) for c, r in zip(cand, cand_rho)])
    rng = np.random.default_rng(seed)
    best, best_val = None, -np.inf
    for _ in range(starts):
        pick = list(rng.choice(grid, n, replace=False))
        H = Hs[pick].sum(0)
        val = _crit(H, criterion)
        improved = True
        while improved:  # Fedorov exchange: the best single swap, until none improves
            improved = False
            for i in range(n):
                H_wo = H - Hs[pick[i]]
                vals = _crit(H_wo + Hs, criterion)
                vals[pick] = -np.inf
                j = int(np.argmax(vals))
                if vals[j] > val + 1e-9 * abs(val) + 1e-12:
                    pick[i], H, val, improved = j, H_wo + Hs[j], vals[j], True
        if val > best_val:
            best, best_val = list(pick), val
    return _refine(model, cand[best], cand_rho[best], sigma, criterion), cand_rho[best]


def _refine(model, u, rho, sigma, criterion):
    """The grid's plan refined continuously: every direction moved on the sphere (two angles
    each) to maximise the criterion (L-BFGS-B); kept only where it improves."""
    from scipy.optimize import minimize

    def dirs(x):
        th, ph = x[0::2], x[1::2]
        return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)

    def f(x):
        return -float(_crit(information(model, dirs(x), rho, sigma), criterion))
    x0 = np.ravel(np.stack([np.arccos(np.clip(u[:, 2], -1, 1)), np.arctan2(u[:, 1], u[:, 0])], 1))
    res = minimize(f, x0, method="L-BFGS-B", options={"maxiter": 200})
    return dirs(res.x) if res.fun < f(x0) else u


def plan_rows(u, rate_dps=None) -> list[tuple]:
    """Table angles (gamma, alpha, beta) deg for directions u in k, with the outer rate (one, or one
    per row) for rate runs."""
    rows = plans.angles_for(u)
    if rate_dps is None:
        return rows
    return [r + (float(q),) for r, q in zip(rows, np.broadcast_to(rate_dps, (len(rows),)))]


def _reduced_jacobian(model, u, rho, sigma):
    """The exact problem's weighted parameter Jacobian at the nominal parameters with each position's
    direction profiled out: every 3-row block projected off its own two direction columns (those
    columns touch no other block, so this is the Schur complement row by row). (3n, m)."""
    from simucal.fit.norm_fit import jacobian_blocks
    n, m = len(u), len(model.params)
    rho = np.broadcast_to(np.asarray(rho, float), (n,))
    p = np.zeros(m)
    obs = Observations(model.output(rho[:, None] * u, p), rho, np.full((n, 3), float(sigma)))
    _, Jq, Jd, _ = jacobian_blocks(model, obs, p, u, obs.sigma)
    P = np.einsum("nia,nab,njb->nij", Jd, np.linalg.inv(np.einsum("nia,nib->nab", Jd, Jd)), Jd)
    return ((np.eye(3) - P) @ Jq).reshape(3 * n, m)


def _misfit(J, k, q):
    """|| the part of column k (times q) that the other columns cannot fit ||^2."""
    A = np.delete(J, k, axis=1)
    s = J[:, k] * q
    resid = s - A @ np.linalg.lstsq(A, s, rcond=None)[0]
    return float(resid @ resid)


def reveal(model: AugmentedModel, eid, u, rho, sigma, n_add=3, grid=150):
    """For an effect the plan (u, rho) cannot tell from the model: the n_add positions (directions
    in k, greedy over the grid) that make the most of its signature separable, and the share of its
    signature then separable. The model's own rho is kept for the added positions."""
    aug = AugmentedModel(model.base, model.effects + (eid,))
    k = len(aug.params) - 1
    R = np.broadcast_to(np.asarray(rho, float), (len(u),))
    J = _reduced_jacobian(aug, np.asarray(u, float), R, sigma)
    cand = plans.fibonacci_directions(grid)
    blocks = _reduced_jacobian(aug, cand, float(np.median(R)), sigma).reshape(grid, 3, -1)
    added = []
    for _ in range(n_add):
        vals = [_misfit(np.vstack([J, c]), k, 1.0) for c in blocks]
        j = int(np.argmax(vals))
        J = np.vstack([J, blocks[j]])
        added.append(cand[j])
    share = _misfit(J, k, 1.0) / max(float(J[:, k] @ J[:, k]), 1e-300)
    return np.array(added), float(share)


def noncentrality(model, u, rho, sigma, sizes) -> tuple[float, float]:
    """Expected likelihood-ratio statistics for telling the model's last two effects apart: the
    misfit left when the data carry effect 1 (size sizes[0]) and effect 2 is fitted instead
    (everything else free), and the reverse. model: base + (effect 1, effect 2)."""
    J = _reduced_jacobian(model, u, rho, sigma)
    m = len(model.params)
    return _misfit(J, m - 2, sizes[0]), _misfit(J, m - 1, sizes[1])  # the wrong effect and the rest fitted


def power(lam, alpha=0.01):
    """P(the 1-dof likelihood-ratio test rejects) at noncentrality lam."""
    from scipy.stats import chi2, ncx2
    return float(ncx2.sf(chi2.isf(alpha, 1), 1, lam)) if lam > 0 else alpha


def separate(base: GeneratedModel | str, e1: str, e2: str, u: np.ndarray, rho: ArrayLike, sigma: float,
             sizes: Sequence[float], rates_dph: Sequence[float] | np.ndarray = (), target: float = 0.9,
             alpha: float = 0.01, max_extra: int = 48, grid: int = 150) -> results.Separation:
    """Positions to add to a plan (u, rho) so that effects e1 and e2 are told apart with the target
    power both ways; a dict with the current and final noncentralities, the power and the added
    directions (and their rho), or the reason no positions can."""
    model = AugmentedModel(base, (e1, e2))
    m = len(model.params)
    cand = plans.fibonacci_directions(grid)
    rho_c = np.array(rates_dph if model.sensor == "gyro" and len(rates_dph) else [1.0 if model.sensor == "acc" else
                                                                                   float(np.max(rho))])
    cands = [(c, r) for r in rho_c for c in cand]
    blocks = np.concatenate([_reduced_jacobian(model, cand, r, sigma).reshape(grid, 3, m) for r in rho_c])
    R = np.broadcast_to(np.asarray(rho, float), (len(u),))
    J = _reduced_jacobian(model, np.asarray(u, float), R, sigma)

    def lams(J):
        return _misfit(J, m - 2, sizes[0]), _misfit(J, m - 1, sizes[1])
    lam = lams(J)
    start: results.PowerAt = {"noncentrality": list(lam), "power": [power(x, alpha) for x in lam]}
    added: list[tuple[np.ndarray, float]] = []  # (direction in k, rho)
    while min(power(x, alpha) for x in lam) < target and len(added) < max_extra:
        vals = [min(lams(np.vstack([J, blk]))) for blk in blocks]
        j = int(np.argmax(vals))
        if vals[j] <= min(lam) * (1 + 1e-6) + 1e-12:
            break
        J = np.vstack([J, blocks[j]])
        c, r = cands[j]
        added.append((c, float(r)))
        lam = lams(J)
    ok = min(power(x, alpha) for x in lam) >= target
    return {"effects": [e1, e2], "sizes": list(sizes), "alpha": alpha, "target_power": target, "start": start,
            "noncentrality": list(lam), "power": [power(x, alpha) for x in lam], "reached": ok,
            "added": [{"direction_k": c.tolist(), "rho": r} for c, r in added]}


class TableAdvice:
    """The positions to add to a turntable plan, for fit.candidates.rank_candidates (fit/ranking.rank's unseen and
    pair): the fitted directions taken as the table's (a nominal mounting), 60 trial directions."""

    def reveal(self, model, eid, fit, obs, sig) -> str:
        """Positions that make a candidate this plan cannot see separable (reveal), as a clause ('' where
        none do)."""
        adds, share = reveal(model, eid, fit.directions, obs.rho, float(np.median(sig)), grid=60)
        if share <= 1e-3:
            return ""
        return ("for this plan, adding positions at (outer, middle, inner) = "
                + ", ".join(f"({g:.1f}, {a:.1f}, {b:.1f})" for g, a, b in plan_rows(adds))
                + f" deg (nominal mounting) makes {100 * share:.2g} % of its signature separable")

    def separate(self, model, e, twin, fit, obs, sig) -> str:
        """The plan that would tell candidate e from its twin at its estimated size (separate,
        8 added positions at most), as one sentence."""
        size = max(abs(e.estimate), 3 * e.std)
        rates = np.unique(np.round(obs.rho, 6)) if model.sensor == "gyro" else ()
        sep = separate(model.base, e.id, twin, fit.directions, obs.rho, float(np.median(sig)), (size, size),
                       rates, max_extra=8, grid=60)
        if not sep["added"]:
            return f"no added positions separate them: {SEPARATE[twin.split('.')[1]]}"
        rows = plan_rows(np.array([a["direction_k"] for a in sep["added"]]))
        return (f"{len(rows)} positions added to this plan, (outer, middle, inner) = "
                + ", ".join(f"({g:.1f}, {a:.1f}, {b:.1f})" for g, a, b in rows[:6]) + (" ..." if len(rows) > 6 else "")
                + f" deg (nominal mounting), tell them apart with power {min(sep['power']):.2f} at the estimated "
                f"size {size:.2g} (simucal plan --separate {e.id},{twin} shows all)")
