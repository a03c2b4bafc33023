"""Is the model enough, and which effect is missing: one test for every diagnosis.

- test_model: the exact fit with the noise the data give (lack_of_fit.fit_with_noise),
  a chi-square test where the noise is known, the lack-of-fit F test always, and one
  p-value for the verdict (the chi-square's where every row's noise is known, the F
  test's where none is, the smaller of the two, Bonferroni-doubled, where some is), made one
  family with the targeted (score) tests of every library effect not in the model (fit/family.py).
- rank_candidates: every candidate effect of generated/effects.py fit as model +
  candidate by the same exact solver (NormProblem), ranked by fit/ranking.rank: the
  likelihood ratio (chi-square difference; an F ratio where the noise is unknown), the
  family's gate, the candidates this plan cannot separate and what would.
- A model fails its test at p < ALPHA (fit/results.ModelTest.fails), everywhere.
- shape: when no candidate explains the misfit, the generic term that does
  (lack_of_fit.describe_shape).
- NormStep, forward_selection: the norm fit in `--add auto`'s one forward selection
  (fit/selection.py).
The verdict in words is report/verdicts.py's. Used by calibrate, diagnose (turntable sets and
streams' poses), diagnose_moves and table_fit.
"""
from __future__ import annotations

import functools

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel, effect_ids, regressor
from simucal.fit.cross_validation import leave_one_out
from simucal.fit.distributions import chi2_sf, f_sf
from simucal.fit.lack_of_fit import describe_shape, fit_with_noise, lack_of_fit
from simucal.fit.norm_fit import Fit, Observations, dense_jacobian, fit_exact
from simucal.fit import family, ranking, selection
from simucal.fit.results import ALPHA, CandidateRecord, ModelTest, Selection, Shape
from simucal.fit.twins import separating_plan
from simucal.generated.effects import EFFECTS, SEPARATE
from simucal.io import records
from simucal.io.details import ModelTestBlock

NOISE_TOO_LARGE = 1e-3  # P(chi2 below the value found): residuals this far under the stated noise
NOISE_TOO_SMALL = 10.0  # residual rms / stated noise above which a misfit with no structure is the noise's


class NormProblem:
    """The exact norm fit (turntable rows, a stream's poses) as a ranking Problem (fit/ranking.py): each
    candidate's column is its regressor at the fitted directions, whitened by the rows' sigma."""
    span = "the baseline model"

    def __init__(self, model: AugmentedModel, obs: Observations, fit: Fit):
        self.model, self.obs, self.fit = model, obs, fit
        self.J, self.sig = dense_jacobian(model, obs, fit)
        self.u = fit.directions * obs.rho[:, None]

    def info(self, eid):
        return EFFECTS[eid].parameter, EFFECTS[eid].unit, EFFECTS[eid].meaning

    @functools.cached_property
    def Q(self):
        """An orthonormal basis of J's span, block by block: each row's two direction columns (J's (3, 2)
        blocks, orthonormalised row by row), then the parameters' columns with those projected out (the
        exact fit's Schur complement, gauss_newton.py): a QR of (3n, m) for one of (3n, m + 2n)."""
        n, m = len(self.u), len(self.model.params)
        rows = self.J.reshape(n, 3, -1)
        U = np.linalg.qr(rows[np.arange(n)[:, None, None], np.arange(3)[None, :, None],
                              (m + 2 * np.arange(n))[:, None, None] + np.arange(2)])[0]  # (n, 3, 2)
        A = rows[:, :, :m]
        Qa = np.linalg.qr((A - U @ (U.transpose(0, 2, 1) @ A)).reshape(3 * n, m))[0]
        Ud = np.zeros((3 * n, 2 * n))
        for i in range(n):
            Ud[3 * i:3 * i + 3, 2 * i:2 * i + 2] = U[i]
        return np.hstack([Ud, Qa])

    def basis(self):
        return self.Q

    def residual(self):
        r = (self.fit.residuals / self.sig).ravel()
        # unknown noise: the residuals' variance scales the likelihood ratios
        return r, 1.0 if self.fit.chi2 is not None else float(r @ r) / max(self.fit.dof, 1)

    def column(self, eid):
        col = np.zeros((len(self.u), 3))
        col[:, EFFECTS[eid].axis] = regressor(eid, self.u, self.obs.aux)
        return (col / self.sig).ravel()

    def to_see(self, eid):
        return SEPARATE[eid.split(".")[1]]

    def to_separate(self, eid, twin):
        return separating_plan(eid, twin)

    def fit_with(self, eid):
        fit, model = self.fit, self.model
        try:
            f1 = fit_exact(AugmentedModel(model.base, model.effects + (eid,)), self.obs,
                           p0=np.r_[fit.vector(model.params), 0.0])
        except CalibrationError as e:
            return f"augmented fit failed: {e}"
        p: float | None
        if f1.chi2 is not None and fit.chi2 is not None:  # both or neither: the same rows' noise
            stat = max(fit.chi2 - f1.chi2, 0.0)
            p, daic = float(chi2_sf(stat, 1)), stat - 2.0
        else:  # unknown noise: F test on the residual sums of squares
            rss0, rss1 = fit.residual_rms ** 2, f1.residual_rms ** 2
            stat = max((rss0 - rss1) / max(rss1 / max(f1.dof, 1), 1e-300), 0.0) if f1.dof > 0 else 0.0
            p, daic = (float(f_sf(stat, 1, f1.dof)) if f1.dof > 0 else None), None
        return ranking.Trial(f1.params[eid], f1.std[eid], float(stat), p, daic, f1.residual_rms)


def rank_candidates(model: AugmentedModel, obs: Observations, fit: Fit, base_fails: bool,
                    advisor=None) -> list[CandidateRecord]:
    """Every library effect not in the model, ranked beside it (fit/ranking.rank). advisor: where the
    data come from a plan that can grow (turntable/plan_design.TableAdvice), the positions to add for
    a candidate this plan cannot see, and for the strongest pair of candidates it cannot tell apart."""
    problem = norm_problem(model, obs, fit)
    unseen = None if advisor is None else lambda eid: advisor.reveal(model, eid, fit, obs, problem.sig)
    pair = None if advisor is None else lambda c, twin: advisor.separate(model, c, twin, fit, obs, problem.sig)
    ids = [e for e in effect_ids(model.sensor) if e not in model.effects]
    return [c.to_dict() for c in ranking.rank(problem, ids, base_fails, f"{model.sensor} candidates", unseen=unseen,
                                              pair=pair)]


def test_model(model, obs: Observations, p0=None) -> tuple[Fit, Observations, ModelTestBlock]:
    """Fit and test the model. Returns (fit, observations with the sigma used, baseline block)."""
    fit, obs, noise = fit_with_noise(model, obs, p0)
    n, m = len(obs.N), len(model.params)
    lof = lack_of_fit(model, obs, fit)
    block: ModelTestBlock = {"residual_rms": fit.residual_rms, "residual_unit": model.unit, "dof": fit.dof,
                             "model": fit.model, "noise": noise, "lack_of_fit": lof, "chi2": fit.chi2,
                             "cross_validation": leave_one_out(model, obs, fit)}
    if fit.chi2 is not None:
        assert obs.sigma is not None  # a chi-square: the fit had every row's noise (fit_exact)
        noise_std = float(np.sqrt(np.mean(obs.sigma ** 2)))
        # expected residual rms if the model is right: chi2 has n - m dof over 3n components
        block.update({"noise_floor": noise_std * float(np.sqrt(max(n - m, 0) / (3 * n))),
                      "noise_std_of_mean": noise_std})
        if noise.get("rows_estimated"):
            ps = [p for p in (fit.p_value, lof["p_value"]) if p is not None]
            block.update({"p_value": min(1.0, 2 * min(ps)) if ps else None,
                          "test": "chi-square (noise partly estimated) and lack-of-fit F, the smaller p doubled"})
        else:
            block.update({"p_value": fit.p_value, "test": "chi-square"})
            # the advice is to check a stated noise: where the data's own scatter gave every sigma it cannot help
            if obs.sigma_stated and fit.dof > 0 and 1.0 - chi2_sf(fit.chi2, fit.dof) < NOISE_TOO_LARGE:
                block["noise_warning"] = (
                    f"the residuals are {np.sqrt(fit.chi2 / fit.dof):.2g} times the noise used ({noise['source']}): "
                    "a stated noise this much larger than the data's scatter leaves the test unable to fail and "
                    "every std too large; check acc_noise_g / gyro_noise_dph (or the option), or leave them out to "
                    "have the noise estimated from the fit")
            elif fit.dof > 0 and fit.chi2 > NOISE_TOO_SMALL ** 2 * fit.dof and (lof.get("p_value") or 0.0) >= ALPHA:
                block["noise_too_small"] = True
                block["noise_warning"] = (
                    f"the residuals are {np.sqrt(fit.chi2 / fit.dof):.3g} times the noise used "
                    f"({noise['source']}), yet the generic terms find no structure in them "
                    f"(lack-of-fit p = {lof['p_value']:.2g}): the stated noise is likely too small "
                    "(else an effect outside the library and the generic terms is missing), "
                    "and an effect ranked against it may only absorb scatter; check acc_noise_g / gyro_noise_dph "
                    "(or the option), or leave them out to have the noise estimated")
    else:
        block.update({"noise_floor": None, "noise_std_of_mean": None, "p_value": lof["p_value"],
                      "test": "lack-of-fit F (no noise in the data or stated)"})
    family.fold(block, targeted(model, obs, fit))
    return fit, obs, block  # tests/test_calibration_file.py checks its keys


def targeted(model: AugmentedModel, obs: Observations, fit: Fit, ids=None) -> records.Targeted | None:
    """The targeted tests of the model test's family (fit/family.py) on the norm fit: each effect of ids
    (default every library effect not in the model) by its score test at fit (None where there is none
    to test, or no chi-square and no dof to test against)."""
    ids = [e for e in effect_ids(model.sensor) if e not in model.effects] if ids is None else ids
    return family.targeted(norm_problem(model, obs, fit), ids, fit.dof) if ids and fit.dof > 0 else None


def norm_problem(model: AugmentedModel, obs: Observations, fit: Fit) -> NormProblem:
    """The fit's ranking Problem, built once per fit: the family's targeted tests and the ranking share
    its Jacobian and basis (kept on the fit, for these model and observations)."""
    p = fit.__dict__.get("_problem")
    if p is None or p.model is not model or p.obs is not obs:
        p = fit.__dict__["_problem"] = NormProblem(model, obs, fit)
    return p


class NormStep:
    """A norm-fit model in `--add auto`'s forward selection (fit/selection.py): test_model's test and
    leave-one-position-out errors. rank(model, obs, fit, base) -> (candidates, shape): the ranking the
    caller's diagnosis uses (turntable/model_test.rank); default rank_candidates and
    shape_if_unexplained. Only library effects are added (a table's own terms in the ranking are not).
    table: the rows are a turntable's (twins are told apart by `simucal plan --separate`), not a
    stream's poses (by the poses a user takes)."""

    def __init__(self, model: AugmentedModel, obs: Observations, rank=None, table=True):
        self.model, self.obs, self._rank, self.table = model, obs, rank or _rank, table
        self.effects = model.effects
        self.fit, self.obs_used, self.base = test_model(model, obs)

    def test(self):
        return ModelTest.of(self.base)

    def rank(self) -> tuple[list[CandidateRecord], Shape | None]:
        return self._rank(self.model, self.obs_used, self.fit, self.base)

    def add(self, eid):
        return NormStep(AugmentedModel(self.model.base, self.model.effects + (eid,)), self.obs, self._rank, self.table)

    def held_out(self):
        cv = self.base["cross_validation"]
        return cv["held_out"] if cv else None

    def after(self) -> records.AutoStep:
        cv = self.base["cross_validation"]
        return {"p_value_after": self.base["p_value"], "residual_rms_after": self.fit.residual_rms,
                "held_out_rms_after": cv["held_out_rms"] if cv else None}

    def estimates(self) -> dict[str, tuple[float, float]]:
        return {k: (self.fit.params[k], self.fit.std[k]) for k in self.model.base.params}

    def to_separate(self, chosen, twin):
        if not self.table:
            return "poses that would: " + separating_plan(chosen["id"], twin["id"])
        return positions_that_separate(chosen, twin)


def positions_that_separate(chosen: CandidateRecord, twin: CandidateRecord) -> str:
    """The plan command that finds the table positions telling candidate `chosen` from its twin (a gyro's on
    the gyro's model: plan scores the accelerometer's by default)."""
    model = " --model gyro_baseline" if EFFECTS[chosen["id"]].sensor == "gyro" else ""
    return (f"the positions that would: simucal plan --score PLAN --separate {chosen['id']},{twin['id']} --sizes "
            f"{chosen['estimate']:.2g},{twin['estimate']:.2g}{model}")


def forward_selection(model: AugmentedModel, obs: Observations, rank=None, max_terms=6, table=True) -> Selection:
    """`--add auto` on the norm fit (fit/selection.forward_selection from NormStep): the Selection with
    its model the AugmentedModel chosen."""
    return selection.forward_selection(NormStep(model, obs, rank, table), max_terms)


def _rank(model, obs, fit, base) -> tuple[list[CandidateRecord], Shape | None]:
    cands = rank_candidates(model, obs, fit, True)
    return cands, shape_if_unexplained(model, obs, fit, base, cands)


def advice_text(cands, shape, base) -> str | None:
    """What a failing model lacks, as calibrate names it: the generic term where it beats every library
    effect (the verdict leads with it), else the strongest significant candidate unless it leaves the
    model failing having explained little (family.outside_library: then that, in words) or has twins
    no rows could choose between (then all of them and the plan that would tell), else None."""
    sig = [c for c in cands if c.get("significant")]
    if shape and not shape.get("catalog_id"):
        return "a term " + shape["text"]
    outside = family.outside_library(base, cands)
    if outside:
        return outside["text"]
    if sig and sig[0].get("twins_undecided"):  # the rows that judge twins could not choose: name none alone
        return undecided_twins(sig[0], cands)
    return sig[0]["id"] if sig else None


def undecided_twins(lead: CandidateRecord, cands: list[CandidateRecord]) -> str:
    """A candidate and its twins that no rows of these data could choose between, and the plan that would."""
    twin = next(c for c in cands if c["id"] in lead["twins"])
    return f"{' or '.join([lead['id'], *lead['twins']])}, which these data cannot tell apart: " + \
        positions_that_separate(lead, twin)


def advice(model: AugmentedModel, obs: Observations) -> str | None:
    """advice_text of the one model test and ranking (diagnose's for a stream's poses), None where the
    model passes."""
    fit, obs2, base = test_model(model, obs)
    if not ModelTest.of(base).fails:
        return None
    return advice_text(*_rank(model, obs2, fit, base), base)


MIN_SHARE = 0.5  # a generic term named as the missing one must explain at least half the misfit


def shape_if_unexplained(model, obs, fit, base, cands) -> Shape | None:
    """The generic term's description when the model fails, the term explains at least MIN_SHARE of
    the misfit (less is no single term: several effects, or one outside the generic basis), and no
    candidate explains the misfit as well (no significant candidate, or the generic term's
    likelihood ratio is more than 1.5 times the best candidate's)."""
    if not ModelTest.of(base).fails:
        return None
    shape = describe_shape(model, obs, fit)
    if shape is None or shape["share_of_misfit"] < MIN_SHARE:
        return None
    sig = [c for c in cands if c.get("significant")]
    if sig:
        best_share = 1 - (sig[0]["residual_rms_after"] / max(fit.residual_rms, 1e-300)) ** 2
        if shape["share_of_misfit"] <= 1.5 * max(best_share, 0.0):
            return None
    return shape
