"""One candidate ranking for every fit: a Problem says how its model sees an effect, rank() does the rest.

A Problem (the turntable and stream poses' exact norm fit: fit.candidates.NormProblem; the gyro
over a stream's moves: handheld/moves_selection.MovesProblem; a table's own terms:
turntable/table_fit.DirectionsProblem; a sequence's filter innovations: systematic/innovations.InnovationsProblem)
gives, at the model's fit, the whitened Jacobian of the
model (its span), the whitened residual and its variance scale s2 (1 where the noise is known),
each candidate's whitened column, and the fit with one candidate added (its estimate, std and
likelihood-ratio or F statistic). rank() then, for every problem alike:
- calls a candidate not separable where its column is zero (no input for it in these data) or
  lies within 1e-3 of the model's span, and says what would show it;
- fits the others, notes the nearly collinear ones (under 5 % of the signature separable);
- names the twins the data cannot tell apart (fit/twins.py);
- applies the gate (gate): a candidate is significant where its p-value beats its share of the model
  test's family (fit/family.py: ALPHA / 2 over the number tested) and the family fails, which its own
  targeted test beyond that level makes it do whether or not the omnibus fails.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Protocol

import numpy as np

from simucal import progress
from simucal.fit.family import COLLINEAR, candidate_level, separable
from simucal.fit.results import Candidate
from simucal.fit.twins import twins, twins_note

WEAK = 0.05       # separable share below which it is seen only weakly (noted)


@dataclass(frozen=True)
class Trial:
    """The fit with one candidate added: its estimate and std, the test statistic against the model
    (chi-square difference, or F where the noise is unknown) with its p-value, delta AIC where
    defined, and the residual rms with it."""
    estimate: float
    std: float
    statistic: float
    p_value: float | None
    delta_aic: float | None
    residual_rms_after: float


class Problem(Protocol):
    span: str      # what the model's Jacobian spans, in words ("the baseline model", "T and the bias")

    def info(self, cid: str) -> tuple[str, str, str]:
        """(parameter, unit, meaning) of candidate cid."""

    def basis(self) -> np.ndarray:
        """An orthonormal basis of the model's whitened Jacobian at its fit."""

    def residual(self) -> tuple[np.ndarray, float]:
        """The whitened residual at the fit and its variance scale s2."""

    def column(self, cid: str) -> np.ndarray:
        """Candidate cid's whitened column at the fit (zeros where these data hold no input for it)."""

    def fit_with(self, cid: str) -> Trial | str:
        """The fit with cid added, or why there is none."""

    def to_see(self, cid: str) -> str:
        """What a plan must hold to show cid."""

    def to_separate(self, cid: str, twin: str) -> str:
        """What a plan must vary to tell cid from its twin (fit/twins.separating_plan)."""


def rank(problem: Problem, ids, base_fails: bool, label: str, test: str | None = None,
         unseen: Callable[[str], str] | None = None, pair: Callable[[Candidate, str], str] | None = None
         ) -> list[Candidate]:
    """The candidates ids tried beside the problem's model, gated (module doc), strongest first, then
    the untested ones. unseen(cid): more to say about a candidate this plan cannot see (a turntable
    plan's positions); pair(candidate, twin): for the strongest candidate with a twin, how to tell
    the two apart. Both are asked only where the model fails (a misfit to explain)."""
    Q = problem.basis()
    r, s2 = problem.residual()
    out, cols = [], {}
    for cid in progress.steps(list(ids), label, "effect"):
        c = Candidate(cid, *problem.info(cid), separable=False, test=test)
        perp, share, norm_col = separable(Q, problem.column(cid))
        if share < COLLINEAR:
            why = ("no input for it in these data" if norm_col == 0 else
                   f"collinear with {problem.span} ({100 * share:.2g} % of its signature is separable)")
            c = replace(c, note=f"{why}; to see it: {problem.to_see(cid)}")
            out.append(c.with_note(unseen(cid)) if unseen and base_fails and norm_col > 0 else c)
            continue
        cols[cid] = perp / (share * norm_col)
        trial = problem.fit_with(cid)
        if isinstance(trial, str):
            out.append(replace(c, note=trial))
            continue
        c = replace(c, separable=True, **vars(trial))
        if share < WEAK:
            c = c.with_note(f"nearly collinear with {problem.span}: {100 * share:.2g} % of its signature is "
                            f"separable, so it is weakly seen; to see it: {problem.to_see(cid)}")
        out.append(c)
    advised, level = False, candidate_level(sum(c.separable for c in out))
    for k, c in sorted(enumerate(out), key=lambda kc: -_strength(kc[1])):
        tw = twins(c.id, cols, r, s2) if c.separable else []
        if tw:
            c = replace(c, twins=tuple(tw)).with_note(twins_note(tw, problem.to_separate(c.id, tw[0])))
            if pair and base_fails and not advised and c.p_value is not None and c.p_value < level:
                c, advised = c.with_note(pair(c, tw[0])), True  # the strongest pair only: the verdict rests on it
            out[k] = c
    return gate(out, base_fails)


def gate(out: list[Candidate], base_fails: bool) -> list[Candidate]:
    """The candidates' part of the model test's family (fit/family.py): a separable candidate is
    significant where its p-value beats family.candidate_level(number tested) and the model fails its
    test, the family's, which the candidates' own targeted tests are part of (a likelihood ratio can
    exceed its score test: the two then agree on the verdict). Returns the tested candidates,
    strongest first, then the ones that could not be tested."""
    tested = sorted([c for c in out if c.separable], key=lambda c: -_strength(c))
    level = candidate_level(len(tested))
    tested = [replace(c, significant=bool(base_fails and c.p_value is not None and c.p_value < level))
              for c in tested]
    sig = [c for c in tested if c.significant]
    if sig:  # each alone beats the gate; the strongest is the one to add, and the others say why not them
        best = sig[0]
        tested = [c if not c.significant or c is best else c.with_note(
            f"significant alone, but {best.id} explains more (LR {_strength(best):.1f} against {_strength(c):.1f}), "
            f"and one effect often makes its neighbours look significant: add {best.id}, then see whether this one "
            "is still needed") for c in tested]
    return tested + [c for c in out if not c.separable]


def _strength(c: Candidate) -> float:
    """The statistic a candidate is ranked by (-1 where it was not tested)."""
    return c.statistic if c.separable and c.statistic is not None else -1.0
