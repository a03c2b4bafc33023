"""`--add auto` through the filter: the library effects a failing sequence needs, one at a time.

The smallest forward selection (fit/candidates.forward_selection's steps, on the innovations: that
one is written for the norm fit's observations): while the innovations' test fails, the candidates
are ranked on the innovations (innovations.py, the one ranking's Bonferroni gate); the strongest
that passes the gate is added to the filter's states and the filter run again; it is kept only where
the NIS falls by more than the gate's chi-square (the likelihood ratio of the filter with and without
it, 1 dof). The innovations are one-step-ahead predictions of the rows not yet seen, so the fall in
NIS is itself a held-out test (the norm fit's leave-one-position-out has no counterpart to add).
"""
from __future__ import annotations

from simucal.fit.distributions import chi2_sf
from simucal.fit.ranking import rank
from simucal.fit.results import ALPHA
from simucal.systematic.calibrate import run_filter
from simucal.systematic.innovations import InnovationsProblem, innovation_test, signatures

MAX_TERMS = 4


def ranked(result, test):
    """The candidates (fit/results.Candidate) ranked on result's innovations, gated against its test."""
    sig = signatures(result)
    return rank(InnovationsProblem(sig), list(sig.B), test["p_value"] < ALPHA, "candidates on the innovations")


def estimate(result, eid) -> tuple[float, float]:
    """The filter's estimate of an effect's parameter and its std."""
    s = result.sensors
    names = list(s.acc.params) + list(s.gyro.params)
    k = names.index(eid)
    return float(s.vector()[k]), float(result.cov[k, k] ** 0.5)


def select(ms, acc_model, gyro_model, ids=(), max_terms=MAX_TERMS):
    """(the filter's result with the effects chosen, the effect ids, the steps, why it stopped)."""
    ids = tuple(ids)
    r = run_filter(ms, acc_model, gyro_model, ids)
    test, steps = innovation_test(r.epochs), []
    while test["p_value"] < ALPHA:
        if len(steps) == max_terms:
            return r, ids, steps, f"stopped at {max_terms} effects with the model still failing"
        cands = ranked(r, test)
        best = next((c for c in cands if c.significant), None)
        if best is None:
            return r, ids, steps, "no library effect passes the candidate gate on the innovations; the model still fails"
        r1 = run_filter(ms, acc_model, gyro_model, ids + (best.id,))
        t1 = innovation_test(r1.epochs)
        p_drop = float(chi2_sf(max(test["nis"] - t1["nis"], 0.0), 1))
        if p_drop >= ALPHA / sum(c.separable for c in cands):
            return r, ids, steps, (f"{best.id}, the strongest candidate, does not lower the filter's NIS beyond the "
                                   f"gate (from {test['nis']:.1f} to {t1['nis']:.1f}); the model still fails")
        value, std = estimate(r1, best.id)
        steps.append({"id": best.id, "estimate": value, "std": std, "unit": best.unit, "nis_before": test["nis"],
                      "nis_after": t1["nis"], "p_value_after": t1["p_value"], "p_nis_drop": p_drop,
                      **({"twins": list(best.twins)} if best.twins else {})})
        r, ids, test = r1, ids + (best.id,), t1
    return r, ids, steps, "the model passes its test" if steps else "the model passes its test: nothing added"
