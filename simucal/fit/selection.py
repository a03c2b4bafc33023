"""`--add auto`: one forward selection for every fit that ranks candidates.

The library effects a failing model needs, chosen one at a time, by one rule for the turntable's
and a stream's poses (the exact norm fit: fit.candidates.NormStep) and a stream's moves (the gyro
over the moves: handheld/moves_selection.MovesStep). While the model fails its test
(results.ModelTest.fails, p < ALPHA), a candidate is added only when
- it passes the ranking's gate (fit/ranking.gate: p < ALPHA / 2 over the number tested, fit/family.py), and
- the model with it predicts the data left out better than the model without it
  (cross_validation.paired_improvement: the paired squared held-out errors, one-sided
  p < HELD_OUT_ALPHA): on its own rows a model with one more term always fits better, on rows
  left out only where the term is real. The gate already holds the model test's family at ALPHA;
  this check keeps out a term that fits a misfit without predicting it (its held-out p then spreads
  over (0, 1)), so its level is 0.05: at 0.01 it turned away 1 in 4 real effects at 10 std over a
  stream's moves (held-out p up to 0.035 over 20 seeds; benchmarks/bench_family.py).
The strongest of up to AUTO_TRIES such candidates is taken and the model tested again. Where a
term outside the library explains more of the misfit than any library effect (the step's shape:
lack_of_fit.describe_shape), it stops and says so instead of chaining effects that only absorb it.
"""
from __future__ import annotations

from typing import Protocol

from simucal.fit.cross_validation import paired_improvement
from simucal.fit.family import OUTSIDE_SHARE
from simucal.fit.results import CandidateRecord, ModelTest, Selection, Shape
from simucal.generated.effects import EFFECTS
from simucal.io import records

HELD_OUT_ALPHA = 0.05  # one-sided level of "predicts the data left out better" (module doc)
AUTO_TRIES = 3  # candidates passing the gate whose held-out errors are tried, strongest first


class SelectionStep(Protocol):
    """A model in the selection: its effects, its test, its ranked candidates, itself with one more
    effect, and its errors on data left out one piece at a time."""
    effects: tuple[str, ...]

    @property
    def model(self) -> object:
        """The model as its kind holds it (an AugmentedModel; the moves' fit). A property: read only, so
        that a step may hold a narrower type."""

    def test(self) -> ModelTest:
        """The model's test."""

    def rank(self) -> tuple[list[CandidateRecord], Shape | None]:
        """The candidates as the diagnosis file holds them (results.Candidate.to_dict; fit/ranking.rank:
        gated, strongest first) and the generic term that explains
        the misfit better than any of them, if any (its description: text, catalog_id)."""

    def add(self, eid: str) -> SelectionStep | str:
        """The model refit with eid added, or why there is none."""

    def held_out(self) -> list[float] | None:
        """Each left-out piece's error predicted without it (a row's norm error, a move's residual)."""

    def after(self) -> records.AutoStep:
        """What the step's record says of the model with the effect added (its test, residual rms, ...)."""

    def estimates(self) -> dict[str, tuple[float, float]]:
        """The baseline model's parameters, each (estimate, std), to see what the effects added moved."""

    def to_separate(self, chosen: CandidateRecord, twin: CandidateRecord) -> str:
        """What would tell the chosen candidate from its twin in this kind of data (a turntable's plan
        command, a stream's poses or moves to make)."""


def forward_selection(start: SelectionStep, max_terms: int = 6) -> Selection:
    """The steps from start while its model fails (module doc). Returns the Selection: the last SelectionStep's model,
    the steps (id, estimate, std, unit, the step's after(), the held-out test's p, the twins where the
    data cannot tell the chosen one from another) and why it stopped."""
    steps: list[dict] = []
    step = start
    while step.test().fails:
        if len(steps) == max_terms:
            return _still_failing(start, step, steps, f"stopped at {max_terms} effects with the model still failing")
        cands, shape = step.rank()
        if shape and not shape.get("catalog_id"):
            return _still_failing(start, step, steps, f"a term outside the library explains more than any library "
                                  f"effect: {shape['text']}; simucal diagnose writes it as a model file for --add FILE")
        sig = [c for c in cands if c.get("significant") and c["id"] in EFFECTS][:AUTO_TRIES]
        if not sig:
            return _still_failing(start, step, steps,
                                  "no library effect passes the candidate gate; the model still fails")
        if sig[0].get("twins_undecided"):  # no rows chose between its twins (turntable/model_test.choose_twin)
            return _still_failing(start, step, steps,
                                  f"{sig[0]['id']}: {sig[0]['twin_choice']}; --add auto adds neither")
        worse, refused = [], []
        for c in sig:
            trial = step.add(c["id"])
            if isinstance(trial, str):  # no fit with it: say so, not that it predicts worse
                refused.append(trial)
                continue
            p_cv = paired_improvement(step.held_out(), trial.held_out())
            if p_cv is None or p_cv < HELD_OUT_ALPHA:
                break
            worse.append(c["id"])
        else:
            why = ([f"the candidates passing the gate ({', '.join(worse)}) do not predict the data left out better "
                    "(they would only fit the misfit)"] if worse else []) + refused
            return _still_failing(start, step, steps, "; ".join(why) + "; the model still fails")
        steps.append({"id": c["id"], "estimate": c["estimate"], "std": c["std"], "unit": c["unit"], **trial.after(),
                      "p_held_out_better": p_cv, **_twin_choice(c, cands, step)})
        step = trial
    return Selection(step.model, steps,
                     "the model passes its test" if steps else "the model passes its test: nothing added")


def _still_failing(start: SelectionStep, step: SelectionStep, steps: list[dict], why: str) -> Selection:
    """The selection's end with the model still failing. Where the effects added explain less than
    family.OUTSIDE_SHARE of the start's misfit (its chi-square's excess over the dof) and moved a
    baseline parameter by more than its std, they are not kept: what fails is then most likely
    outside the library, and effects that only absorb part of it bend the parameters the user wants
    (a sequence's gyro bias went from 37 to 49 std off the truth). The start's model is
    returned; the reason names the effects tried."""
    t0, t1 = start.test(), step.test()
    if not steps or t0.chi2 is None or t1.chi2 is None or t0.chi2 <= t0.dof \
            or (t0.chi2 - t1.chi2) / (t0.chi2 - t0.dof) >= OUTSIDE_SHARE:
        return Selection(step.model, steps, why)
    before, after = start.estimates(), step.estimates()
    moved = sorted(((abs(after[k][0] - v) / s, k) for k, (v, s) in before.items() if k in after and s > 0),
                   reverse=True)
    if not moved or moved[0][0] <= 1.0:
        return Selection(step.model, steps, why)
    added = ", ".join(x["id"] for x in steps)
    share = (t0.chi2 - t1.chi2) / (t0.chi2 - t0.dof)
    return Selection(start.model, [], f"{why}; {added} would explain {100 * share:.0f} % of the misfit, leave it "
                     f"failing and move {moved[0][1]} by "
                     f"{moved[0][0]:.1f} std: not kept (what fails is most likely outside the library; simucal "
                     f"diagnose shows it)")


def _twin_choice(c: CandidateRecord, cands: list[CandidateRecord], step: SelectionStep) -> records.AutoStep:
    """Where the data cannot tell the chosen effect from a twin (fit/twins.py): the twins, why this
    one was taken (the larger likelihood ratio only, or the ranking's own choice on rows the fit does
    not use: a turntable gyro's static rows, turntable/model_test.choose_twin) and what would tell
    them apart (the step's kind of data says), to say so rather than choose silently."""
    if not c.get("twins"):
        return {}
    if c.get("twin_choice"):
        return {"twins": list(c["twins"]), "twin_choice": c["twin_choice"]}
    tw = next(x for x in cands if x["id"] == c["twins"][0])
    return {"twins": list(c["twins"]), "twin_choice": (
        f"{c['id']}, not its twin {tw['id']}, only for the larger likelihood ratio ({c['statistic']:.1f} against "
        f"{tw['statistic']:.1f}): the data cannot tell them apart, so either may be the unit's; "
        + step.to_separate(c, tw))}
