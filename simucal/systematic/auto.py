"""`--add auto` through the filter: the project's one forward selection (fit/selection.py) over the
filter's steps. While the innovations' test fails, the candidates ranked on the innovations
(innovations.py, the one ranking's gate: fit/family.py) are tried strongest first: each is added to the
filter's states and the filter run again, and it is kept where that filter predicts the updates
better. The innovations are one-step-ahead predictions of the updates not yet seen, so each update's
whitened innovation |L_k^-1 nu_k| is its held-out error (the paired test of cross_validation
compares them with and without the effect).
"""
from __future__ import annotations

import numpy as np

from simucal.fit.results import CandidateRecord, ModelTest, Shape
from simucal.fit.selection import forward_selection
from simucal.systematic.calibrate import run_filter
from simucal.io import records
from simucal.systematic.innovations import family_test, ranked, to_separate

MAX_TERMS = 4


def estimate(result, eid) -> tuple[float, float]:
    """The filter's estimate of an effect's parameter and its std."""
    s = result.sensors
    k = (list(s.acc.params) + list(s.gyro.params)).index(eid)
    return float(s.vector()[k]), float(result.cov[k, k] ** 0.5)


class FilterStep:
    """The filter with a model's effects as a Step of fit/selection.forward_selection (module doc);
    its model is the filter's result (calibrate.Result)."""

    def __init__(self, ms, acc_model, gyro_model, ids=()):
        self.ms, self.models, self.effects = ms, (acc_model, gyro_model), tuple(ids)
        self.model = run_filter(ms, acc_model, gyro_model, self.effects)
        self.innovations, self.signatures = family_test(self.model)

    def test(self) -> ModelTest:
        t = self.innovations
        return ModelTest(t["nis"], t["dof"], t["p_value"], t["test"])

    def rank(self) -> tuple[list[CandidateRecord], Shape | None]:
        return [c.to_dict() for c in ranked(self.innovations, self.signatures)], None

    def add(self, eid):
        trial = FilterStep(self.ms, *self.models, self.effects + (eid,))
        if trial.model.diverged:  # a model whose passes diverge or do not converge would be refused whole
            return f"with {eid} the filter diverged ({trial.model.diverged})"
        if not trial.model.converged:
            return (f"with {eid} the filter's passes did not converge (the last of {trial.model.passes} moved an "
                    f"estimate by {trial.model.step_std:.2g} of its std)")
        return trial

    def held_out(self):
        return np.linalg.norm(self.innovations["innovations_whitened"], axis=1).tolist()

    def estimates(self) -> dict[str, tuple[float, float]]:
        s = self.model.sensors
        names = [f"acc {k}" for k in s.acc.base.params] + [f"gyro {k}" for k in s.gyro.base.params]
        na = len(s.p_acc)
        idx = list(range(len(s.acc.base.params))) + [na + j for j in range(len(s.gyro.base.params))]
        p, std = s.vector(), np.sqrt(np.diag(self.model.cov))
        return {k: (float(p[i]), float(std[i])) for k, i in zip(names, idx)}

    def to_separate(self, chosen, twin):
        return "what would tell them apart: " + to_separate(chosen["id"], twin["id"])

    def after(self) -> records.AutoStep:
        value, std = estimate(self.model, self.effects[-1])
        return {"nis_after": self.innovations["nis"], "p_value_after": self.innovations["p_value"],
                "filter_estimate": value, "filter_std": std}


def select(ms, acc_model, gyro_model, ids=(), max_terms=MAX_TERMS):
    """(the filter's result with the effects chosen, the effect ids, the steps, why it stopped)."""
    chosen = forward_selection(FilterStep(ms, acc_model, gyro_model, ids), max_terms)
    s = chosen.model.sensors
    return chosen.model, s.acc.effects + s.gyro.effects, chosen.steps, chosen.stopped
