"""Candidate effects on a stream's gyro moves: the ranking Problem and the forward selection's Step.

Candidates: every gyro effect of generated/effects.py, evaluated along each move at the
calibrated rate (u, deg/h), the calibrated specific force (f, g, motion included), time and
temperature, enters the output model
    y = M omega + b + sum_j p_j phi_j e_axis(j),  so  omega = T (y - b - sum_j p_j phi_j e_axis(j)),
and is fit with T, the bias and the effects already chosen by the same Gauss-Newton
(moves.fit_gyro_moves). MovesProblem ranks them by the likelihood ratio with the noise variance
profiled out, LR = 2m ln(RSS_0 / RSS_1) ~ chi2(1) (2m: the residuals' degrees of freedom), under
the same gate as the poses (one ranking: fit/ranking.py). moves_family is the moves' model test:
their chi-square (gyro_moves.chi2_test) with the candidates' score tests, one family (fit/family.py).
MovesStep puts the moves' fit into `--add auto`'s one forward selection (fit/selection.py): its
test is moves_family's, its held-out errors each move's residual predicted without it
(moves.held_out_moves). select_effects gives the diagnosis file's `misfit_shares`: what each
chosen effect explains of the misfit.
"""
from __future__ import annotations

import functools

import numpy as np

from simucal.fit import family
from simucal.fit.augmented import effect_ids
from simucal.fit.distributions import chi2_sf
from simucal.fit.ranking import Trial, rank
from simucal.fit.results import CandidateRecord, MisfitShares, ModelTest, Shape
from simucal.fit.selection import forward_selection
from simucal.fit.twins import separating_plan
from simucal.generated.effects import EFFECTS, SEPARATE_MOVES
from simucal.handheld.gyro_moves import GyroMoves, chi2_test, has_input, move_covariances, with_term_added, with_terms
from simucal.handheld.moves import (GyroFit, Integrated, Moves, decimate, effect_column, fit_gyro_moves, free_entries,
                                    held_out_moves, integrated, jacobian, move_residuals, with_effect)
from simucal.io import records
from simucal.io.details import FamilyTest


class MovesProblem:
    """The gyro's fit over a stream's moves, with the effects already chosen, as a ranking Problem
    (fit/ranking.py): each candidate's column is its regressor integrated along the moves (the
    gravity directions' residual per unit coefficient), the statistic the likelihood ratio with the
    direction noise profiled out, 2 m log(rss0 / rss1)."""
    span = "T's estimated entries and the bias"

    def __init__(self, gm: GyroMoves, fit: GyroFit, inputs, effects=(), fixed=(), at=None):
        """fixed: the entries of vec(T) the chosen gyro model leaves at nominal (moves.GYRO_MODELS), left so
        in each trial fit and out of the basis: a candidate is credited with what it explains alone. The
        bias stays free, held by the rest's prior: an effect with a value at the rest (a g-sensitivity:
        gravity is there) moves the rest's reading, and a bias fixed at it pinned the effect. at: the moves
        integrated at fit and their Jacobian where at hand (MovesStep.at)."""
        self.gm, self.fit, self.inputs, self.effects = gm, fit, inputs, list(effects)
        if at is not None:
            self.at = at
        self.rss0, self.m, self.k = float(np.sum(fit.r ** 2)), len(fit.r), 12 + len(self.effects)
        self.fixed, self.free = tuple(fixed), free_entries(self.k, fixed)
        self.mv: dict[str, Moves] = {}  # per candidate: the moves with its regressor (column)
        self.columns: dict[str, np.ndarray] = {}  # per candidate: its column at the base fit
        # each trial fits the moves in blocks of 4 samples (a quarter of the cost) with their defect
        # against full resolution at this fit added (as fit_gyro's coarse levels): the composition
        # error of the blocks (~1e-3 rad) then cancels where the candidate's coefficient is 0
        self.mv0 = mv0 = with_terms(gm.mv, self.effects, inputs) if self.effects else gm.mv
        self.mv4 = decimate(mv0, 4)  # every trial's moves: these with the candidate's regressor averaged alone
        self.defect = (move_residuals(fit.T, mv0, gm.g_dirs, jac=False, db=fit.db, p=fit.p)[0]
                       - move_residuals(fit.T, self.mv4, gm.g_dirs, jac=False, db=fit.db, p=fit.p)[0])

    def info(self, eid):
        return EFFECTS[eid].parameter, EFFECTS[eid].unit, EFFECTS[eid].meaning

    @functools.cached_property
    def at(self) -> tuple[Integrated, np.ndarray]:
        """The moves integrated at the base fit and their Jacobian: every candidate's column (whose coefficient
        is zero there) comes from this one integration."""
        return integrated_with_jacobian(self.fit, self.mv0, self.gm.g_dirs)

    @functools.cached_property
    def at4(self) -> tuple[Integrated, np.ndarray]:
        """The same in blocks of 4 samples: every trial fit's first point (moves.with_effect)."""
        return integrated_with_jacobian(self.fit, self.mv4, self.gm.g_dirs)

    def basis(self):
        return np.linalg.qr(self.at[1].reshape(-1, self.k)[:, self.free])[0]

    def residual(self):
        return self.fit.r.ravel(), self.rss0 / (2 * self.m)  # the noise profiled out as in the LR

    def column(self, eid):  # asked by the family's targeted tests and again by the ranking: kept per problem
        if eid not in self.columns:
            if not has_input(eid, self.inputs):  # a temperature term without temp_c: no move to integrate
                self.columns[eid] = np.zeros(self.fit.r.size)
            else:
                self.mv[eid] = mv = with_term_added(self.mv0, eid, self.inputs)
                assert mv.phi is not None  # with_term_added gives the term's column
                self.columns[eid] = effect_column(self.at[0], self.fit.T, mv.phi[-1], mv.phi_axes[-1]).ravel()
        return self.columns[eid]

    def to_see(self, eid):
        return SEPARATE_MOVES[eid.split(".")[1]]

    def to_separate(self, eid, twin):
        return separating_plan(eid, twin, moves=True)

    def fit_with(self, eid):
        f, mv4 = self.fit, decimate(self.mv[eid], 4, self.mv4)
        f1 = fit_gyro_moves(mv4, self.gm.g_dirs, np.r_[f.T.ravel(), f.db, f.p, 0.0], self.gm.bias_std,
                            offset=self.defect, fixed=self.fixed, start=with_effect(*self.at4, f.T, mv4))
        if not f1.converged:
            return f"the fit with it did not converge in {f1.iterations} steps"
        stat = max(2 * self.m * np.log(self.rss0 / float(np.sum(f1.r ** 2))), 0.0)
        k = self.k
        return Trial(float(f1.p[-1]), float(np.sqrt(f1.cov[k, k])), float(stat), float(chi2_sf(stat, 1)),
                     float(stat - 2.0), float(np.sqrt(np.mean(f1.r ** 2))))


def integrated_with_jacobian(fit: GyroFit, mv: Moves, g_dirs) -> tuple[Integrated, np.ndarray]:
    """The moves mv integrated at a fit, and their Jacobian there (moves.move_residuals' two halves)."""
    it = integrated(fit.T, mv, g_dirs, fit.db, fit.p)
    return it, jacobian(it, fit.T, mv)


def rank_move_candidates(gm: GyroMoves, fit: GyroFit, inputs, base_fails, effects=(), fixed=(),
                         problem: MovesProblem | None = None) -> list[CandidateRecord]:
    """Every library gyro effect not yet in the model, ranked beside T, the bias and effects over the
    moves (fit/ranking.rank); fixed: the entries the fit's gyro model leaves at nominal. problem: the
    MovesProblem of these arguments where one is at hand (moves_family's)."""
    problem = problem or MovesProblem(gm, fit, inputs, effects, fixed)
    ids = [e for e in effect_ids("gyro") if e not in effects]
    return [c.to_dict() for c in rank(problem, ids, base_fails, "gyro candidates over the moves")]


def moves_family(gm: GyroMoves, fit: GyroFit, inputs, omnibus: tuple, effects=(), fixed=(),
                 at=None) -> tuple[FamilyTest, MovesProblem]:
    """The moves' model test as one family (fit/family.py): omnibus (chi2, dof, p) the moves' chi-square
    (gyro_moves.chi2_test), with the score test of every library gyro effect not in the model along the
    moves (MovesProblem; at: its moves integrated at fit where at hand). Returns a test block (chi2, dof,
    p_value the family's, test, omnibus_p_value, targeted) and the problem, for rank_move_candidates."""
    chi2, dof, p = omnibus
    block: FamilyTest = {"chi2": chi2, "dof": dof, "p_value": p,
                         "test": "chi-square of the moves against the rests' white noise"}
    ids = [e for e in effect_ids("gyro") if e not in effects]
    problem = MovesProblem(gm, fit, inputs, effects, fixed, at)
    family.fold(block, family.targeted(problem, ids) if ids else None)
    return block, problem  # tests/test_calibration_file.py checks its keys


class MovesStep:
    """The moves' fit with some effects in `--add auto`'s forward selection (fit/selection.py)."""

    def __init__(self, gm: GyroMoves, inputs, sigma_g, fit: GyroFit, effects=(), ranked=None):
        self.gm, self.inputs, self.sigma_g, self.fit, self.ranked = gm, inputs, sigma_g, fit, ranked
        self.effects = self.model = tuple(effects)
        self.mv = with_terms(gm.mv, list(self.effects), inputs) if self.effects else gm.mv
        self.chi2, self.dof, self.omnibus_p = chi2_test(fit, move_covariances(gm, fit, sigma_g), gm.bias_std, self.mv)
        self._held_out = None

    @functools.cached_property
    def family(self) -> tuple[FamilyTest, MovesProblem]:
        """moves_family's test and problem, made when first asked: a trial step the selection turns
        away is never tested."""
        return moves_family(self.gm, self.fit, self.inputs, (self.chi2, self.dof, self.omnibus_p), self.effects,
                            at=self.at)

    @functools.cached_property
    def at(self) -> tuple[Integrated, np.ndarray]:
        """The moves integrated at the fit and their Jacobian: the held-out errors', the family's and each
        trial's first point (add) from one integration."""
        return integrated_with_jacobian(self.fit, self.mv, self.gm.g_dirs)

    @property
    def p_value(self):
        return self.family[0]["p_value"]

    def test(self):
        return ModelTest(self.chi2, self.dof, self.p_value)

    def rank(self) -> tuple[list[CandidateRecord], Shape | None]:
        if self.ranked is None:
            self.ranked = rank_move_candidates(self.gm, self.fit, self.inputs, self.test().fails, self.effects,
                                               problem=self.family[1])
        return self.ranked, None

    def add(self, eid):
        f, mv = self.fit, with_term_added(self.mv, eid, self.inputs)
        f1 = fit_gyro_moves(mv, self.gm.g_dirs, np.r_[f.T.ravel(), f.db, f.p, 0.0], self.gm.bias_std,
                            start=with_effect(*self.at, f.T, mv))
        if not f1.converged:
            return f"the fit with {eid} did not converge in {f1.iterations} steps"
        return MovesStep(self.gm, self.inputs, self.sigma_g, f1, self.effects + (eid,))

    def held_out(self):
        if self._held_out is None:  # asked once per candidate tried against this step
            self._held_out = held_out_moves(self.mv, self.gm.g_dirs, self.fit, self.gm.bias_std,
                                            at=(self.at[0].r, self.at[1])).tolist()
        return self._held_out

    def estimates(self) -> dict[str, tuple[float, float]]:
        std = np.sqrt(np.diag(self.fit.cov))
        names = [f"T_{a}{b}" for a in "xyz" for b in "xyz"] + [f"b_{a}" for a in "xyz"]
        return {k: (float(v), float(s)) for k, v, s in zip(names, np.r_[self.fit.T.ravel(), self.fit.db], std)}

    def to_separate(self, chosen, twin):
        return "moves that would: " + separating_plan(chosen["id"], twin["id"], moves=True)

    def after(self) -> records.AutoStep:
        return {"chi2_after": self.chi2, "dof_after": self.dof, "p_value_after": self.p_value,
                "residual_rms_after": float(np.sqrt(np.mean(self.fit.r ** 2)))}


def select_effects(gm: GyroMoves, base: GyroFit, sigma_g, inputs, ranked=None, max_terms=9) -> MisfitShares:
    """`--add auto` over the moves (fit/selection.forward_selection from the fit without effects), as
    the diagnosis file's `misfit_shares`: each step's share, its chi-square drop over the baseline's
    excess (chi2 - dof); `unexplained` what the chosen effects leave of that excess; `stopped` why.
    ranked: the candidates already ranked at base (diagnose's), not ranked again."""
    start = MovesStep(gm, inputs, sigma_g, base, ranked=ranked)
    sel = forward_selection(start, max_terms)
    excess0, prev = max(start.chi2 - start.dof, 1e-300), start.chi2
    for s in sel.steps:
        s["share"], prev = float((prev - s["chi2_after"]) / excess0), s["chi2_after"]
    last_dof = sel.steps[-1]["dof_after"] if sel.steps else start.dof
    return {"chi2": start.chi2, "dof": start.dof, "residual_rms": float(np.sqrt(np.mean(base.r ** 2))),
            "steps": sel.steps, "effects": list(sel.model), "stopped": sel.stopped,
            "unexplained": float(max(prev - last_dof, 0.0) / excess0)}
