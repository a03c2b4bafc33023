"""`--add auto` over every row of a thermal calibration.

calibrate --thermal --add auto chooses its effects on the plateau nearest T_ref (api/calibrating.py: that
plateau gives the frames, the checks and the model's shape), a third of the rows of three plateaus.
There an effect and its twin can read alike (on fibonacci24 plateaus acc.quadratic.z and
acc.scale_asymmetry.z: auto took the wrong one in 1 seed of 5), and an effect at 10 of the joint
fit's stds is under 6 of one plateau's, where it may not pass the gate at all (auto then added
nothing in 3 seeds of 40). The joint fit, every row at its own temperature, decides both:
- each twin the nearest plateau could not tell from its choice is fitted in its place, and the
  model whose joint chi-square is lower keeps its place;
- while the joint model test (one family: the joint chi-square and the targeted tests of the
  library effects that do not follow temperature, fit/family.py) fails by a targeted test, its
  strongest effect is added and the joint model fitted again (up to MAX_TERMS), kept where it
  lowers the joint chi-square by the twins' level (twins.CANNOT_TELL).
"""
from __future__ import annotations


import numpy as np

from simucal.errors import CalibrationError
from simucal.fit import family
from simucal.fit.augmented import AugmentedModel, effect_ids, follows_temperature
from simucal.fit.candidates import targeted
from simucal.fit.thermal_select import select
from simucal.fit.twins import CANNOT_TELL
from simucal.generated.effects import EFFECTS
from simucal.io.details import FamilyTest

MAX_TERMS = 6  # as selection.forward_selection's


def joint_test(base: AugmentedModel, model, obs, fit) -> FamilyTest:
    """The joint model's test: its chi-square and the targeted tests of the library effects not in base
    that do not follow temperature, one family (fit/family.py)."""
    test: FamilyTest = {"p_value": fit.p_value, "test": "chi-square of every row at its own temperature"}
    ids = [e for e in effect_ids(base.sensor) if e not in base.effects and not follows_temperature(e)]
    family.fold(test, targeted(model, obs, fit, ids) if fit.chi2 is not None else None)
    return test


def by_every_row(first, obs, groups, degree):
    """(base, model, fit, how, obs, steps) of the joint fit (thermal_select.select) of first's library
    effects, with `--add auto`'s choices made again on every row (module doc) where first's block
    records them (details['auto']); steps: those records, None where auto was not asked."""
    steps = [dict(s) for s in first.details["auto"]] if "auto" in first.details else None
    effects, p0 = first.library_effects(), dict(first.params)
    known = obs.sigma is not None and np.all(np.isfinite(obs.sigma))
    for s in (steps or []) if known else []:
        if s.get("twins"):
            effects = _twin_by_every_row(s, first.model, effects, obs, groups, degree, p0)
    base = AugmentedModel(first.model, effects)
    model, fit, how, obs = select(base, obs, groups, degree, p0)
    while steps is not None and len(steps) < MAX_TERMS and fit.chi2 is not None:
        test = joint_test(base, model, obs, fit)
        if "verdict" not in test.get("targeted", {}) or test["targeted"]["strongest"] not in EFFECTS:
            break
        eid = test["targeted"]["strongest"]
        trial = AugmentedModel(base.base, base.effects + (eid,))
        try:
            got = select(trial, obs, groups, degree, p0)
        except CalibrationError:
            break
        if got[1].chi2 > fit.chi2 - CANNOT_TELL:
            break
        base, (model, fit, how, obs) = trial, got
        steps.append({"id": eid, "estimate": fit.params[eid], "std": fit.std[eid], "unit": EFFECTS[eid].unit,
                      "chi2_after": fit.chi2, "chosen_by": "every plateau's rows: the joint model test's targeted "
                      f"test (statistic {test['targeted']['statistic']:.1f}), which the plateau nearest T_ref alone "
                      "did not pass"})
    return base, model, fit, how, obs, steps


def _twin_by_every_row(step: dict, model_name, effects, obs, groups, degree, p0) -> tuple:
    """effects with step's effect or one of its twins, whichever joint fit has the lower chi-square;
    step's record says which and why (its id, twins and twin_choice updated)."""
    chi2 = {}
    for e in [step["id"]] + [t for t in step["twins"] if t not in effects]:
        trial = tuple(e if x == step["id"] else x for x in effects)
        try:
            chi2[e] = select(AugmentedModel(model_name, trial), obs, groups, degree, p0)[1].chi2
        except CalibrationError:
            continue
    if len(chi2) < 2:
        return effects
    best = min(chi2, key=chi2.__getitem__)
    others = "; ".join(f"{k} {v:.1f}" for k, v in chi2.items() if k != best)
    if best != step["id"]:
        effects = tuple(best if x == step["id"] else x for x in effects)
        step.update(id=best, twins=[step["id"]] + [t for t in step["twins"] if t != best])
    step["twin_choice"] = (f"{best}, not its twin {', '.join(k for k in chi2 if k != best)}: the plateau nearest T_ref "
                           f"cannot tell them apart; every plateau's rows chose it (joint chi2 {chi2[best]:.1f} "
                           f"against {others})")
    return effects
