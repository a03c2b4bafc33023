"""Whether the data tell two candidate terms apart, and what would (issue 38, item 5).

Two candidates are twins where these data cannot say which of them the misfit holds, judged by
the fit itself rather than by how alike their signatures look: with a and b each candidate's
column with the model's span projected out (unit length) and r the residual at the model's fit,
all whitened, each alone lowers the chi-square by s_a = (a.r)^2 and s_b = (b.r)^2 (the
linearised likelihood ratios) and both together by
    s_ab = ((a.r)^2 + (b.r)^2 - 2 c (a.r)(b.r)) / (1 - c^2),  c = a.b.
They are twins when a is seen at all (s_a >= CANNOT_TELL), their fits differ by less than
CANNOT_TELL (|s_a - s_b|, a chi-square(1) difference the noise makes one time in 20) and neither,
added to the other, lowers the chi-square by CANNOT_TELL (s_ab - s_b and s_ab - s_a: the test of
each added to the other). A fixed cosine (0.99) called a temperature and a time term twins on a
ramp whose likelihood ratios differed by 70 (as issue 38 reports), and missed the same pair at a
cosine of 0.976 whose ratios were 82.5 and 84.0 (tests/test_diagnose.py). Where the noise is
unknown, s2 (the residual variance) scales the sums.
"""
from __future__ import annotations

from simucal.fit.distributions import chi2_isf
from simucal.generated.effects import EFFECTS, SEPARATE, SEPARATE_MOVES

CANNOT_TELL = chi2_isf(0.05, 1)  # 3.84


def told_apart(a, b, r, s2=1.0) -> bool:
    """Whether the fits with unit columns a and b (model span projected out) differ beyond noise."""
    ar, br, c = float(a @ r), float(b @ r), float(a @ b)
    s_a, s_b = ar * ar / s2, br * br / s2
    if abs(s_a - s_b) >= CANNOT_TELL:
        return True
    s_ab = max(s_a, s_b) if 1 - c * c < 1e-12 else (ar * ar + br * br - 2 * c * ar * br) / (1 - c * c) / s2
    return s_ab - s_b >= CANNOT_TELL or s_ab - s_a >= CANNOT_TELL


def twins(key, cols: dict, r, s2=1.0) -> list:
    """The candidates of cols ({key: unit column}) the data cannot tell from cols[key]; none where
    cols[key] itself explains nothing beyond the noise."""
    a = cols[key]
    if float(a @ r) ** 2 / s2 < CANNOT_TELL:
        return []
    return [k for k, b in cols.items() if k != key and not told_apart(a, b, r, s2)]


INPUTS = {"t_s": "time", "dtemp_c": "temperature", "temp_c": "temperature", "w2": "the rate (centripetal term)",
          "f_x": "the attitude to gravity", "f_y": "the attitude to gravity", "f_z": "the attitude to gravity"}


def separating_plan(eid_a: str, eid_b: str, moves=False) -> str:
    """What a plan must vary to tell library effects a and b apart, from what their regressors read:
    two different inputs (temperature and time) must not follow each other; an input one reads and
    the other not must change where the other's regressor does not; two regressors of the input alone
    need the inputs where they differ (each family's own advice)."""
    texts = SEPARATE_MOVES if moves else SEPARATE
    fa, fb = eid_a.split(".")[1], eid_b.split(".")[1]
    ra = {INPUTS.get(x, x) for x in EFFECTS[eid_a].reads}
    rb = {INPUTS.get(x, x) for x in EFFECTS[eid_b].reads}
    if ra and rb and ra != rb:
        x, y = sorted(ra)[0], sorted(rb)[0]
        return (f"{x} changing independently of {y} (for temperature and time: a temperature that goes up and "
                f"down, or plateaus visited out of order, not one ramp)")
    if ra != rb:
        aux, fam = (ra, fa) if ra else (rb, fb)
        return f"{sorted(aux)[0]} changing at the same inputs (not with the position): {texts.get(fam, '')}".rstrip(": ")
    if fa == fb and eid_a.split(".")[2] != eid_b.split(".")[2]:
        return f"inputs where the two axes' regressors differ: {texts.get(fa, '')}"
    return "; ".join(dict.fromkeys(texts.get(f, "") for f in (fa, fb) if texts.get(f)))


def twins_note(tw, plan) -> str:
    """A candidate's note naming its twins and the plan that would separate them."""
    return (f"the data cannot tell it from {', '.join(tw)} (the fits with either differ by less than chi2 "
            f"{CANNOT_TELL:.2f}, and neither adds to the other); to tell them apart: {plan}")
