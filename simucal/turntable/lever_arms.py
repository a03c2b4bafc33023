"""The unification pairs' targeted test of lever arms (turntable/unification.py).

Under a rate w_T an accelerometer r away from the outer axis feels w_T^2 r's part across the axis
(acc.size_effect.*): the rate run's mean specific force leaves the axis by an angle that grows with
w_T^2, while its norm changes only to second order, so the norm fit hardly sees it and the pairs (the
direction of that mean against the gyro's axis) do. The test is the score test (Rao 1948) of the size
effects the accelerometer model lacks on the pairs' misfits: each misfit whitened by its own
covariance, the small rotation phi of C_b^d projected out (it is refitted with them), and the
misfit's part in the span of the size effects' columns, chi-square on that span's rank (F where the
pairs' noise is estimated: Satterthwaite's dof). Only where it fails does the unification name lever
arms as the pairs' misfit.
"""
from __future__ import annotations

import numpy as np

from simucal.fit.augmented import effect_ids, regressor
from simucal.fit.distributions import chi2_sf_estimated
from simucal.fit.results import ALPHA
from simucal.generated import unify as eq
from simucal.generated.effects import EFFECTS
from simucal.io import records

RANK_TOL = 1e-6  # a size effect's whitened column below this share of the largest: not seen by these pairs


def size_effect_ids(model) -> list[str]:
    """The library's size effects (one lever arm component of one accelerometer each) the model lacks."""
    return [e for e in effect_ids("acc") if e.split(".")[1] == "size_effect" and e not in model.effects]


def lever_arm_test(un, pairs) -> records.LeverArms | None:
    """The targeted test of lever arms on the rate runs' pairs (un: a Unifier; pairs: its solve's answer
    for the rate runs' means), or None where nothing is left to test."""
    ids = size_effect_ids(un.am)
    if not ids or pairs["dof"] <= 0:
        return None
    f, Ju, _ = un.acc_mean_inputs()
    aux = un.acc_means[3]
    cols = np.zeros(f.shape + (len(ids),))
    for k, eid in enumerate(ids):
        cols[:, EFFECTS[eid].axis, k] = regressor(eid, f, aux)
    # at fixed outputs a term q phi on axis a moves the calibrated input by -Ju^-1 e_a phi per unit q
    Z = pairs["R_b"] @ eq.direction_jacobian(f) @ -np.linalg.solve(Ju, cols)  # (n, 2, k)
    w, V = np.linalg.eigh(pairs["S_inv"])
    W = np.swapaxes(V * np.sqrt(np.maximum(w, 0.0))[:, None, :], 1, 2)  # W^T W = S^-1, pair by pair

    def white(A):
        return (W @ A).reshape(2 * len(A), -1)
    Q = np.linalg.qr(white(pairs["R_phi"]))[0]
    Zw = white(Z)
    Zw -= Q @ (Q.T @ Zw)
    U, s, _ = np.linalg.svd(Zw, full_matrices=False)
    seen = s > RANK_TOL * s.max() if s.size and s.max() > 0 else np.zeros(s.shape, bool)
    if not seen.any():
        return None
    stat = float(np.sum((U[:, seen].T @ white(pairs["misfit"][..., None])[:, 0]) ** 2))
    dof = int(seen.sum())
    p = float(chi2_sf_estimated(stat, dof, pairs["noise_dof"]))
    return {"tested": ids, "statistic": stat, "dof": dof, "p_value": p, "fails": bool(p < ALPHA),
            "text": f"chi2 {stat:.3g} on {dof} dof, p = {p:.2g}"}


def misplaced_by(acc_fails: bool, lever) -> str:
    """What misplaces the rate runs' directions, in words: a failing accelerometer model first, lever arms
    only where their targeted test on the pairs fails (lever_arm_test)."""
    arms = f"lever arms the accelerometer model lacks ({lever['text']}; --add acc.size_effect.*)" \
        if lever is not None and lever["fails"] else None
    if acc_fails:
        return ("the accelerometer model fails its own test (the acc lines above say what it lacks; add that first)"
                + (f", else {arms}" if arms else ""))
    return arms or ("rate runs that are not whole revolutions, or an effect neither model holds"
                    + (f" (not lever arms: their targeted test passes, {lever['text']})" if lever else ""))
