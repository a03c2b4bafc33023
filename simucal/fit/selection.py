"""`--add auto`: one forward selection for every fit that ranks candidates (issue 40, item 0).

The library effects a failing model needs, chosen one at a time, by one rule for the turntable's
and a stream's poses (the exact norm fit: fit.candidates.NormStep) and a stream's moves (the gyro
over the moves: handheld/moves_selection.MovesStep). While the model fails its test
(results.ModelTest.fails, p < ALPHA), a candidate is added only when
- it passes the ranking's Bonferroni gate (fit/ranking.gate: p < ALPHA / number tested), and
- the model with it predicts the data left out better than the model without it
  (cross_validation.paired_improvement: the paired squared held-out errors, one-sided
  p < HELD_OUT_ALPHA): on its own rows a model with one more term always fits better, on rows
  left out only where the term is real.
The strongest of up to AUTO_TRIES such candidates is taken and the model tested again. Where a
term outside the library explains more of the misfit than any library effect (the step's shape:
lack_of_fit.describe_shape), it stops and says so instead of chaining effects that only absorb it.
"""
from __future__ import annotations

from typing import Protocol

from simucal.fit.cross_validation import paired_improvement
from simucal.fit.results import ModelTest, Selection
from simucal.generated.effects import EFFECTS

HELD_OUT_ALPHA = 0.01  # one-sided level of "predicts the data left out better"
AUTO_TRIES = 3  # candidates passing the gate whose held-out errors are tried, strongest first


class Step(Protocol):
    """A model in the selection: its effects, its test, its ranked candidates, itself with one more
    effect, and its errors on data left out one piece at a time."""
    model: object  # the model as its kind holds it (an AugmentedModel; the moves' fit)
    effects: tuple[str, ...]

    def test(self) -> ModelTest:
        """The model's test."""

    def rank(self) -> tuple[list[dict], dict | None]:
        """The candidates as the diagnosis file holds them (results.Candidate.to_dict; fit/ranking.rank:
        gated, strongest first) and the generic term that explains
        the misfit better than any of them, if any (its description: text, catalog_id)."""

    def add(self, eid: str) -> Step | str:
        """The model refit with eid added, or why there is none."""

    def held_out(self) -> list[float] | None:
        """Each left-out piece's error predicted without it (a row's norm error, a move's residual)."""

    def after(self) -> dict:
        """What the step's record says of the model with the effect added (its test, residual rms, ...)."""


def forward_selection(start: Step, max_terms: int = 6) -> Selection:
    """The steps from start while its model fails (module doc). Returns the Selection: the last Step's model,
    the steps (id, estimate, std, unit, the step's after(), the held-out test's p, the twins where the
    data cannot tell the chosen one from another) and why it stopped."""
    steps: list[dict] = []
    step = start
    while step.test().fails:
        if len(steps) == max_terms:
            return Selection(step.model, steps, f"stopped at {max_terms} effects with the model still failing")
        cands, shape = step.rank()
        if shape and not shape.get("catalog_id"):
            return Selection(step.model, steps, f"a term outside the library explains more than any library effect: "
                             f"{shape['text']}; simucal diagnose writes it as a model file for --add FILE")
        sig = [c for c in cands if c.get("significant") and c["id"] in EFFECTS][:AUTO_TRIES]
        if not sig:
            return Selection(step.model, steps, "no library effect passes the candidate gate; the model still fails")
        for c in sig:
            trial = step.add(c["id"])
            p_cv = None if isinstance(trial, str) else paired_improvement(step.held_out(), trial.held_out())
            if not isinstance(trial, str) and (p_cv is None or p_cv < HELD_OUT_ALPHA):
                break
        else:
            return Selection(step.model, steps, f"the candidates passing the gate ({', '.join(c['id'] for c in sig)}) do "
                             "not predict the data left out better (they would only fit the misfit); the model "
                             "still fails")
        steps.append({"id": c["id"], "estimate": c["estimate"], "std": c["std"], "unit": c["unit"], **trial.after(),
                      "p_held_out_better": p_cv, **_twin_choice(c, cands)})
        step = trial
    return Selection(step.model, steps, "the model passes its test" if steps else "the model passes its test: nothing added")


def _twin_choice(c: dict, cands: list[dict]) -> dict:
    """Where the data cannot tell the chosen effect from a twin (fit/twins.py): the twins and why this
    one was taken (the larger likelihood ratio only), to say so rather than choose silently."""
    if not c.get("twins"):
        return {}
    tw = next(x for x in cands if x["id"] == c["twins"][0])
    return {"twins": list(c["twins"]), "twin_choice": (
        f"{c['id']}, not its twin {tw['id']}, only for the larger likelihood ratio ({c['statistic']:.1f} against "
        f"{tw['statistic']:.1f}): the data cannot tell them apart, so either may be the unit's; the positions that "
        f"would: simucal plan --score PLAN --separate {c['id']},{tw['id']} --sizes {c['estimate']:.2g},"
        f"{tw['estimate']:.2g}")}
