"""The unification pairs' covariance (turntable/unification.py, derived in derive/unify.py): each pair's
misfit in the two components across the bisector of its directions, Wahba's sensitivity from the
derived gradients, and lever arms named only where their targeted test on the pairs fails. At MEMS
sizes the misfit's three components gave the chi-square a third, nearly noiseless direction per pair
(chi2 1.8-6.6 times its dof on clean units, every one inflated and told to add lever arms)."""
from pathlib import Path

import numpy as np
import pytest

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.fit.gauss_newton import tangent_basis
from simucal.fit.rotations import log_so3, wahba
from simucal.turntable.simulate import Scenario, mems_unit, simulate
from simucal.turntable.pairs import pair_misfits, wahba_sensitivity

RATES = (12.0, -12.0, 30.0, -30.0)


def _pairs(seed, n=9, nz=5, noise=1e-3):
    """n random pairs about a random rotation, their directions' derivatives in nz inputs (tangent)."""
    rng = np.random.default_rng(seed)
    C = wahba(rng.normal(size=(3, 3)), np.eye(3), np.ones(3))
    u_b = rng.normal(size=(n, 3))
    u_b /= np.linalg.norm(u_b, axis=1, keepdims=True)
    u_d = u_b @ C.T + noise * rng.normal(size=(n, 3))
    u_d /= np.linalg.norm(u_d, axis=1, keepdims=True)
    D_b, D_d = (tangent_basis(u) @ rng.normal(size=(n, 2, nz)) for u in (u_b, u_d))
    return u_b, D_b, u_d, D_d, rng.uniform(0.5, 2.0, n), C


def _moved(u, D, h):
    v = u + h * D
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_wahba_sensitivity_is_the_derivative_of_the_solution():
    u_b, D_b, u_d, D_d, w, _ = _pairs(1)
    C = wahba(u_b, u_d, w)
    J_phi = wahba_sensitivity(u_b, D_b, u_d, D_d, w, C)
    h = 1e-6
    for k in range(D_b.shape[-1]):
        Cp, Cm = (wahba(_moved(u_b, D_b[..., k], s), _moved(u_d, D_d[..., k], s), w) for s in (h, -h))
        fd = (log_so3(C.T @ Cp) - log_so3(C.T @ Cm)) / (2 * h)
        assert np.allclose(J_phi[:, k], fd, rtol=1e-6, atol=1e-9), (k, J_phi[:, k], fd)


def test_a_pairs_misfit_lies_whole_in_two_components_and_moves_as_derived():
    u_b, D_b, u_d, D_d, w, _ = _pairs(2)
    C = wahba(u_b, u_d, w)
    J_phi = wahba_sensitivity(u_b, D_b, u_d, D_d, w, C)
    r, J, _, _ = pair_misfits(u_b, D_b, u_d, D_d, C, J_phi)
    assert r.shape == (len(u_b), 2)
    assert np.allclose(np.linalg.norm(r, axis=1), np.linalg.norm(u_d - u_b @ C.T, axis=1), rtol=1e-12)
    m = u_d + u_b @ C.T
    E = tangent_basis(m / np.linalg.norm(m, axis=1, keepdims=True))  # held fixed: its turn is second order

    def misfit(s, k):
        ub, ud = _moved(u_b, D_b[..., k], s), _moved(u_d, D_d[..., k], s)
        return np.einsum("nia,ni->na", E, ud - ub @ wahba(ub, ud, w).T)
    h = 1e-6
    for k in range(D_b.shape[-1]):
        assert np.allclose(J[..., k], (misfit(h, k) - misfit(-h, k)) / (2 * h), rtol=1e-5, atol=1e-9), k
    S = np.einsum("naz,nbz->nab", J, J)
    assert np.linalg.cond(S).max() < 1e6  # two components that both carry noise, no near-null one


def _unification(sc, seed):
    meta, samples, segments, _ = simulate(sc, seed)
    return calibrate(io.MeasurementSet(Path(f"seed{seed}"), meta, samples, segments)).to_json()["unification"]


def _mems(seed):
    sc = mems_unit(seed)  # biases 50 mg and 0.5 deg/s, scale factors 2e-2, noise 2e-4 g and 30 deg/h a row
    sc.outer_rate_dps = RATES
    return sc


@pytest.mark.parametrize("grade,seeds", [("mems", 8), ("navigation", 4)])
def test_clean_units_pairs_sit_at_their_dof_uninflated_and_name_no_lever_arms(grade, seeds):
    """Clean units on Table 1 with Table 2 (56 pairs at +-12 and +-30 deg/s): the pairs' chi-square at
    its dof over seeds, no inflation, no lever arms named, their targeted test passing."""
    ratios = []
    for seed in range(seeds):
        u = _unification(_mems(seed) if grade == "mems" else Scenario(outer_rate_dps=RATES), seed)
        assert u["method"] == "rate_run_means" and u["pairs"] == 56
        ratios.append(u["chi2"] / u["dof"])
        note = u.get("note", "")
        assert "inflated" not in note and "size_effect" not in note, note
        assert "size_effect" not in u["cross_check"]["note"]
        assert len(u["lever_arms"]["tested"]) == 9 and not u["lever_arms"]["fails"], u["lever_arms"]
    assert 0.8 < np.mean(ratios) < 1.2, np.round(ratios, 2)


def test_lever_arms_are_named_where_their_targeted_test_fails():
    """A 5 mm lever arm of the y accelerometer (acc.size_effect.yx) at +-20 and 40 deg/s: the pairs' targeted
    test fails and the note names the size effects; calibrated with it added, it is no longer tested."""
    sc = Scenario(plan="fibonacci24", outer_rate_dps=(20.0, -20.0, 40.0), acc_effects={"acc.size_effect.yx": 0.005})
    u = _unification(sc, 13)
    assert u["lever_arms"]["fails"] and u["lever_arms"]["p_value"] < 1e-6
    assert "--add acc.size_effect.*" in u["note"] and u["lever_arms"]["text"] in u["note"]
    meta, samples, segments, _ = simulate(sc, 13)
    added = calibrate(io.MeasurementSet(Path("s"), meta, samples, segments), add=("acc.size_effect.yx",))
    lever = added.to_json()["unification"]["lever_arms"]
    assert "acc.size_effect.yx" not in lever["tested"] and not lever["fails"], lever
