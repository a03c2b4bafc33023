"""The model test as one family: the omnibus statistic and the library's targeted tests.

An omnibus chi-square over thousands of dof has little power against one direction: an effect at
18 of its own stds adds about 18^2 = 324 to a chi-square of 2115 dof, whose ALPHA tail starts 220
above its mean, so it passes. The library's candidates are tests in exactly those directions. The
model test is therefore one family of tests at the project's ALPHA (results.ALPHA), split in two:

- the omnibus (chi-square, or lack-of-fit F) at ALPHA * OMNIBUS_SHARE;
- the targeted tests, one per separable candidate, at ALPHA * (1 - OMNIBUS_SHARE) / n
  (Bonferroni over the n tested).

By Bonferroni's inequality the chance that a right model fails any of them is at most ALPHA. Half
and half: the omnibus keeps its power against what no candidate describes (an effect outside the
library) at the cost of a factor 2 in its level (chi2 tail 10.8 -> 12.1 on 1 dof; on 2000 dof
about 8 more), and the targeted tests keep theirs at a level ln(2n) smaller (about 2 of chi2's 1
dof tail at n = 30). The family's p-value is min(1, p_omnibus / OMNIBUS_SHARE,
n p_min / (1 - OMNIBUS_SHARE)): below ALPHA exactly where one of its tests is beyond its own level,
so every reader of a block's p_value (ModelTest.fails, the file's verdict) reads the family.

The targeted test of a candidate is its score test at the model's fit (Rao 1948): with Q an
orthonormal basis of the model's whitened Jacobian, r the whitened residual and c the candidate's
whitened column, the part of c the model cannot absorb is c_perp = c - Q Q^T c, and
(c_perp . r)^2 / |c_perp|^2 is chi-square on 1 dof where the noise is known (F(1, dof - 1) on the
residual variance where it is not). It needs the columns only, no refit, so the family costs a
calibration little; fit/ranking.rank's likelihood ratios (one refit per candidate) are asked only
where the family fails, to say which effect to add.
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence, TypedDict, cast

import numpy as np

from simucal.fit.distributions import chi2_sf, f_sf
from simucal.fit.results import ALPHA
from simucal.fit.twins import twins
from simucal.generated.effects import EFFECTS
from simucal.io import records

OMNIBUS_SHARE = 0.5  # the omnibus's share of ALPHA; the targeted tests share the rest (module doc)
COLLINEAR = 1e-3  # separable share of a column below which the plan cannot see the candidate at all


class OutsideLibrary(TypedDict):
    """A misfit most likely outside the library (outside_library): the best significant candidate's part of it."""
    id: str                           # the best significant candidate
    share: float                      # of the misfit (the chi-square's excess over its dof) it explains, 0 to 1
    chi2_after: float                 # the model's chi-square with it, on dof_after
    dof_after: int                    # one less than the model's
    p_after: float                    # the model's p-value with it
    text: str                         # the console's words


def separable(Q: np.ndarray, col: np.ndarray) -> tuple[np.ndarray, float, float]:
    """The part of a whitened column the model's span Q cannot absorb, its share of the column and
    the column's norm (share 0 for a zero column)."""
    norm = float(np.linalg.norm(col))
    perp = col - Q @ (Q.T @ col)
    return perp, (float(np.linalg.norm(perp)) / norm if norm else 0.0), norm


def candidate_level(n_tested: int) -> float:
    """The level each of n targeted tests is held to (Bonferroni over the family's share)."""
    return ALPHA * (1.0 - OMNIBUS_SHARE) / max(n_tested, 1)


def targeted(problem, ids, dof: int | None = None) -> records.Targeted:
    """The score test of each candidate in ids beside the problem's model (fit/ranking.Problem: basis,
    residual, column), the strongest named, and what the JOINT strongest beyond their level explain
    together (the residual projected on their columns: joint_statistic). dof: the residual's dof where its variance is
    estimated (the residual scale s2 != 1: an F test on dof - 1); None where s2 is a known scale or profiled out
    as the likelihood ratio does (chi-square on 1 dof of the statistic over s2). Returns {tested, strongest, statistic,
    p_value, level[, joint_statistic][, twins]}; strongest None where nothing is separable; twins: where the
    strongest is beyond its level, the candidates the data cannot tell from it (fit/twins.py)."""
    Q = problem.basis()
    r, s2 = problem.residual()
    rr, best = float(r @ r), None
    n, stats, kept = 0, [], []
    for cid in ids:
        perp, share, _ = separable(Q, problem.column(cid))
        if share < COLLINEAR:
            continue
        n += 1
        kept.append(cid)
        g2 = (float(perp @ r) / float(np.linalg.norm(perp))) ** 2  # normalised first: no overflow at absurd weights
        if s2 == 1.0 or not dof or dof < 2:  # known noise, or a scale the LR profiles out (s2 given)
            stat = g2 / s2
            p = float(chi2_sf(stat, 1))
        else:  # the residual variance left with the column in, on dof - 1
            stat = g2 / max((rr - g2) / (dof - 1), 1e-300)
            p = float(f_sf(stat, 1, dof - 1))
        stats.append((stat, p, perp))
        if best is None or stat > best[1]:  # by the statistic: p-values far out all underflow to 0
            best = (cid, stat, p)
    out: records.Targeted = {"tested": n, "strongest": best[0] if best else None,
                           "statistic": best[1] if best else None, "p_value": best[2] if best else None,
                           "level": candidate_level(n)}
    if best is not None and best[2] < out["level"]:  # the strongest's twins: the data cannot say which it is
        cols = {cid: perp / np.linalg.norm(perp) for cid, (_, _, perp) in zip(kept, stats)}
        tw = twins(best[0], cols, r, s2)
        if tw:
            out["twins"] = tw
    beyond = [perp for _, p, perp in sorted(stats, key=lambda x: -x[0]) if p < out["level"]][:JOINT]
    if beyond:  # what the strongest candidates beyond their level explain together (outside_library asks)
        Qc = np.linalg.qr(np.column_stack(beyond))[0]
        out["joint_statistic"] = float(np.sum((Qc.T @ r) ** 2)) / s2
    return out


def family_p(p_omnibus: float | None, tgt: records.Targeted | None) -> float | None:
    """The family's p-value (module doc); the omnibus's own where no candidate is tested (it then holds the
    whole ALPHA), None where neither part has a test."""
    if not tgt or tgt.get("p_value") is None:  # nothing to test beside it: the omnibus holds the whole ALPHA
        return p_omnibus
    ps = (([] if p_omnibus is None else [p_omnibus / OMNIBUS_SHARE])
          + [tgt["tested"] * cast(float, tgt["p_value"]) / (1.0 - OMNIBUS_SHARE)])
    return min(1.0, min(ps))


def fold(block: records.FamilyKeys, tgt: records.Targeted | None) -> None:
    """A test block (its p_value and test the omnibus's) made the family's: the omnibus's p kept as
    `omnibus_p_value`, the targeted tests as `targeted`, p_value the family's p and the test's words
    saying both, and where a targeted test fails the family, which."""
    p0 = block.get("p_value")
    block["omnibus_p_value"], block["omnibus_test"] = p0, block.get("test")
    if not tgt or not tgt["tested"]:
        block["p_value"] = family_p(p0, None)
        return
    block["targeted"] = tgt
    block["p_value"] = family_p(p0, tgt)
    block["test"] = (f"{block.get('test') or 'omnibus'} at {ALPHA * OMNIBUS_SHARE:g}, "
                     f"with {tgt['tested']} targeted tests of the library's effects at {tgt['level']:.2g} each "
                     f"(one family at {ALPHA:g})")
    if cast(float, tgt["p_value"]) < tgt["level"]:
        omnibus_passes = p0 is None or p0 >= ALPHA * OMNIBUS_SHARE
        tgt["verdict"] = (f"{tgt['strongest']} is beyond its targeted test (p = {tgt['p_value']:.2g} < "
                          f"{tgt['level']:.2g}): the model lacks it"
                          + ("; the omnibus alone passes, its power spread over every direction" if omnibus_passes
                             else "; the omnibus fails too"))


OUTSIDE_SHARE = 0.5  # share of the misfit the best library effect must explain to be advised while more is missing
JOINT = 3  # library effects missing at once that outside_library allows for (--add auto tries as many at a step)


def outside_library(base: Mapping[str, Any], cands: Sequence[Mapping[str, Any]]) -> OutsideLibrary | None:
    """Where the model fails and its best significant candidate would leave it failing while explaining
    less than OUTSIDE_SHARE of the misfit (the chi-square's excess over its dof), and the JOINT
    strongest candidates beyond their targeted level together (targeted's joint_statistic) explain less
    than that too, the missing effect is most likely outside the library: {id, share, chi2_after, dof_after, p_after,
    text}. The model with the candidate is one linear step: its chi-square less the candidate's likelihood ratio, on one
    dof less (tests whose noise is known and whose candidates' statistics are drops of that chi-square).
    None where the candidate explains enough, or nothing can say."""
    sig = [c for c in cands if c.get("significant") and c.get("statistic") is not None and c["id"] in EFFECTS]
    chi2, dof, test = base.get("chi2"), base.get("dof") or 0, base.get("omnibus_test") or ""
    # the candidates' statistics on the omnibus's scale: a chi-square drop over the same rows (the norm fit's,
    # the innovations'); a stream's moves rank by a likelihood ratio with their noise profiled out
    if not sig or chi2 is None or dof < 2 or chi2 <= dof or not (test == "chi-square" or test.startswith("NIS")):
        return None
    c = sig[0]
    c2 = max(chi2 - c["statistic"], 0.0)
    p = float(chi2_sf(c2, dof - 1))
    share = min(c["statistic"] / (chi2 - dof), 1.0)
    # a few library effects missing at once share the misfit, each explaining less than half of it: what the
    # JOINT strongest beyond their targeted level explain together (targeted's joint_statistic) says so; more
    # that explain half only together are absorbing what no one of them describes
    together = (base.get("targeted") or {}).get("joint_statistic", c["statistic"]) / (chi2 - dof)
    if p >= ALPHA * OMNIBUS_SHARE or share >= OUTSIDE_SHARE or together >= OUTSIDE_SHARE:
        return None
    return {"id": c["id"], "share": share, "chi2_after": c2, "dof_after": dof - 1, "p_after": p,
            "text": (f"no library effect explains the misfit: the best, {c['id']}, explains {100 * share:.0f} % of it "
                     f"and leaves the model failing (chi2 {c2:.1f} on {dof - 1} dof, p = {p:.2g}); what is missing is "
                     "most likely outside the library (simucal diagnose shows the residuals), and adding "
                     f"{c['id']} would only absorb part of it")}
