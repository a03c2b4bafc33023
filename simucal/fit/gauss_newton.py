"""The exact norm fit's numerical core (norm_fit.fit_exact), for one set or a batch of sets.

The unknowns are the parameters p and each row's input direction u_i on the unit sphere. Per row:
the weighted residual r_i = (N_i - h(rho_i u_i, p)) / sigma_i and its Jacobian blocks with respect
to p and to a 2-D tangent step of u_i (row_blocks). The directions are eliminated by the Schur
complement of their 2x2 blocks (schur), so each Gauss-Newton step solves an m x m system; fit_batch
runs the Levenberg-Marquardt loop for S sets at once, numpy vectorised over the sets (the
compiled whole fit, derive/templates/exact_fit.c, does the same steps in C).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.fit.aux_inputs import AuxInputs


def directions(model, N, p, aux):
    """The start directions: u = (M^-1 (N - b)) normalised, for one set or a batch (leading axes). A start
    only (the fit then solves for the directions of the whole model): an output turned back into an
    input for use inverts the whole model (fit.directions, apply.model_inputs)."""
    M, b = model.matrix_and_bias(p, aux)
    u = np.linalg.solve(M, (N - b)[..., None])[..., 0]
    return u / np.linalg.norm(u, axis=-1, keepdims=True)


def tangent_basis(u):
    """Orthonormal E (..., 3, 2) with columns perpendicular to unit u (..., 3)."""
    a = np.where(np.abs(u[..., :1]) < 0.9, np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    e1 = np.cross(u, a)
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(u, e1)
    return np.stack([e1, e2], axis=-1)


def row_blocks(model, N, rho, sig, p, u, aux):
    """norm_fit.jacobian_blocks for one set (N (n, 3), p (m,)) or a batch (N (S, n, 3), p (S, m))."""
    rho3 = rho[..., None]
    Nm, Ju, Jp = model.jacobians(rho3 * u, p, aux)
    E = tangent_basis(u)
    r = (N - Nm) / sig
    Jd = -(Ju @ (rho3[..., None] * E)) / sig[..., None]
    Jq = -Jp / sig[..., None]
    return r, Jq, Jd, E


def _inv2(A):
    """Inverses of 2x2 matrices (..., 2, 2) in closed form (LAPACK's per-matrix call costs more
    than the arithmetic); a singular one raises as np.linalg.inv would."""
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    if np.any(det == 0):
        raise np.linalg.LinAlgError("Singular matrix")
    out = np.empty_like(A)
    out[..., 0, 0], out[..., 1, 1] = A[..., 1, 1] / det, A[..., 0, 0] / det
    out[..., 0, 1], out[..., 1, 0] = -A[..., 0, 1] / det, -A[..., 1, 0] / det
    return out


def schur(r, Jq, Jd, E):
    """norm_fit.normal_equations from the blocks, for one set or a batch (leading axes): the sums over
    the rows as matrix products."""
    JdT = Jd.swapaxes(-1, -2)
    B, gd = JdT @ Jq, (JdT @ r[..., None])[..., 0]
    Ainv = _inv2(JdT @ Jd)
    AB, Ag = Ainv @ B, (Ainv @ gd[..., None])[..., 0]
    lead, n, m = Jq.shape[:-3], Jq.shape[-3], Jq.shape[-1]
    Jq2, B2 = Jq.reshape(*lead, 3 * n, m), B.reshape(*lead, 2 * n, m)
    H = Jq2.swapaxes(-1, -2) @ Jq2 - B2.swapaxes(-1, -2) @ AB.reshape(*lead, 2 * n, m)
    g = ((Jq2.swapaxes(-1, -2) @ r.reshape(*lead, 3 * n, 1))[..., 0]
         - (B2.swapaxes(-1, -2) @ Ag.reshape(*lead, 2 * n, 1))[..., 0])
    return r, H, g, Ainv, B, gd, E


def _damped_steps(Hs, gs, dH, lam):
    """-(Hs + lam I)^-1 gs / dH per set (the scaled Levenberg-Marquardt system); NaN rows where singular."""
    m = Hs.shape[-1]
    A = Hs + lam[:, None, None] * np.eye(m)
    try:
        return -np.linalg.solve(A, gs[..., None])[..., 0] / dH
    except np.linalg.LinAlgError:  # find the singular sets one by one
        out = np.full(gs.shape, np.nan)
        for j in range(len(A)):
            try:
                out[j] = -np.linalg.solve(A[j], gs[j]) / dH[j]
            except np.linalg.LinAlgError:
                pass
        return out


def _negligible(dp, g, diag, cost):
    """A step below 1e-6 of every parameter's standard deviation, or a Gauss-Newton decrement at
    round-off level (derive/templates/exact_fit.c tests the same)."""
    decrement = -np.einsum("sa,sa->s", g, dp)
    step = np.max(np.abs(dp) * np.sqrt(np.maximum(diag, 0)), axis=1)
    return (step < 1e-6) | (decrement <= 1e-12 * np.maximum(cost, 1.0))


@dataclass
class _Prior:
    """Parameters held by a prior {name: (value, std)}: pseudo-observations (p_k - value) / std."""
    held: list
    value: np.ndarray
    weight: np.ndarray

    @classmethod
    def of(cls, model, prior):
        prior = prior or {}
        return cls([model.params.index(k) for k in prior], np.array([v for v, _ in prior.values()]),
                   np.array([1.0 / sd ** 2 for _, sd in prior.values()]))

    def cost(self, p):
        return np.sum(self.weight * (p[:, self.held] - self.value) ** 2, axis=1) if self.held else 0.0

    def add(self, H, g, p):
        """H and g of the pseudo-observations added in place (p: the sets' parameters)."""
        if self.held:
            H[:, self.held, self.held] += self.weight
            g[:, self.held] += self.weight * (p[:, self.held] - self.value)


def _view(sub: np.ndarray, n: int) -> slice | np.ndarray:
    """The indices sub of n sets, or a slice where they are all of them (a view: no copies)."""
    return slice(None) if len(sub) == n else sub


def fit_batch(model, N, rho, sig, p0, aux=None, max_iter=200, tol=1e-12, prior=None):
    """The Levenberg-Marquardt loop of fit_exact for S sets (module doc): N, sig (S, n, 3), rho (S, n), p0 (S, m);
    aux per row, shared by the sets (arrays (n,)) or each set's (arrays (S, n)); prior {parameter: (value, std)}.
    Returns p (S, m), u (S, n, 3), cost without the prior (S,), the last H (S, m, m), the iterations (S,) and a status
    (S,): 0 converged, 1 not, 2 singular, 3 a parameter without any input (as derive/templates/exact_fit.c)."""
    S, n, _ = N.shape
    m = len(model.params)
    pr = _Prior.of(model, prior)
    rho3 = rho[..., None]
    p = np.array(p0, float)
    u = directions(model, N, p[:, None, :], aux)
    cost = _costs(model, N, rho3, sig, aux, p, u, pr)
    lam = np.zeros(S)
    status = np.ones(S, int)  # 1 until converged
    active = np.ones(S, bool)
    iters = np.zeros(S, int)
    H_last = np.zeros((S, m, m))
    for it in range(1, max_iter + 1):
        idx = np.nonzero(active)[0]
        if not len(idx):
            break
        iters[idx] = it
        I = _view(idx, S)
        r, H, g, Ainv, Bm, gd, E = schur(*row_blocks(model, N[I], rho[I], sig[I], p[I], u[I], _sets(aux, I)))
        pr.add(H, g, p[idx])
        H_last[idx] = H
        diag = np.einsum("sii->si", H)
        if it == 1:
            dead = np.any(diag <= 1e-300, axis=1)
            status[idx[dead]], active[idx[dead]] = 3, False
        dH = np.sqrt(np.maximum(diag, 1e-300))  # Jacobi scaling: terms of very different size stay conditioned
        Hs, gs = H / (dH[:, :, None] * dH[:, None, :]), g / dH
        gn = _damped_steps(Hs, gs, dH, np.zeros(len(idx)))
        singular = active[idx] & np.isnan(gn[:, 0])
        status[idx[singular]], active[idx[singular]] = 2, False
        # a negligible Gauss-Newton step is the last: taken without the cost test, which a step that
        # small can fail on round-off alone (as derive/templates/exact_fit.c)
        last = active[idx] & _negligible(gn, g, diag, cost[idx])
        need = active[idx].copy()  # Levenberg-Marquardt: damp each set until its cost does not rise
        dp = np.where(need[:, None], gn, 0.0)
        p_new, u_new, new_cost = p[I].copy(), u[I].copy(), cost[idx].copy()
        while need.any():
            k = np.nonzero(need)[0]
            damped = k[(lam[idx[k]] > 0) & ~last[k]]
            if len(damped):
                dp[damped] = _damped_steps(Hs[damped], gs[damped], dH[damped], lam[idx[damped]])
                bad = damped[np.isnan(dp[damped, 0])]
                status[idx[bad]], active[idx[bad]], need[bad] = 2, False, False
                k = np.nonzero(need)[0]
                if not len(k):
                    break
            K, IK = _view(k, len(idx)), _view(idx[k], S)
            dd = -(Ainv[K] @ (gd[K] + (Bm[K] @ dp[K][:, None, :, None])[..., 0])[..., None])[..., 0]
            pk = p[IK] + dp[K]
            v = u[IK] + (E[K] @ dd[..., None])[..., 0]
            uk = v / np.linalg.norm(v, axis=2, keepdims=True)
            ck = _costs(model, N[IK], rho3[IK], sig[IK], _sets(aux, IK), pk, uk, pr)
            ok = last[k] | (ck <= cost[idx[k]] * (1 + 1e-12)) | (lam[idx[k]] > 1e8)
            acc, rej = k[ok], k[~ok]
            p_new[acc], u_new[acc], new_cost[acc] = pk[ok], uk[ok], ck[ok]
            lam[idx[acc]] = np.where(lam[idx[acc]] > 1e-6, lam[idx[acc]] / 10, 0.0)
            lam[idx[rej]] = np.maximum(1e-3, 10 * lam[idx[rej]])
            need[acc] = False
        go = active[idx]
        done = (last | (np.abs(cost[idx] - new_cost) <= tol * np.maximum(cost[idx], 1e-30))  # converged: the cost
                | _negligible(dp, g, diag, cost[idx]))  # stalls, or the step taken is negligible (as above)
        p[idx[go]], u[idx[go]], cost[idx[go]] = p_new[go], u_new[go], new_cost[go]
        fin = go & done
        status[idx[fin]], active[idx[fin]] = 0, False
    return p, u, cost - pr.cost(p), H_last, iters, status


def _sets(aux, idx):
    """aux of the sets idx: each set's inputs (S, n) taken along the sets; per-row ones (n,) are shared."""
    if aux is None or isinstance(idx, slice):
        return aux
    return AuxInputs({k: (np.asarray(v)[idx] if np.ndim(v) >= 2 else v) for k, v in aux.values.items()})


def _costs(model, N, rho3, sig, aux, p, u, pr: _Prior):
    """Each set's weighted sum of squares, with the prior's pseudo-observations."""
    return np.sum(((N - model.output(rho3 * u, p, aux)) / sig) ** 2, axis=(1, 2)) + pr.cost(p)
