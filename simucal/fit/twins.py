"""Whether the data tell two candidate terms apart, and what would.

Two candidates are twins where these data cannot say which of them the misfit holds, judged by
the fit itself rather than by how alike their signatures look: with a and b each candidate's
column with the model's span projected out (unit length) and r the residual at the model's fit,
all whitened, each alone lowers the chi-square by s_a = (a.r)^2 and s_b = (b.r)^2 (the
linearised likelihood ratios) and both together by
    s_ab = ((a.r)^2 + (b.r)^2 - 2 c (a.r)(b.r)) / (1 - c^2),  c = a.b.
They are twins when a is seen at all (s_a >= CANNOT_TELL) and neither, added to the other, lowers
the chi-square by CANNOT_TELL (s_ab - s_b and s_ab - s_a: the nested test of each added to the
other; |s_a - s_b| >= CANNOT_TELL implies one of them, so it decides first). CANNOT_TELL is the
project's one test level (results.ALPHA = 1e-3, chi2 10.83 on 1 dof), not 3.84: where the twin b is
the truth, s_ab - s_b is a chi-square(1) draw, so at 3.84 the wrong twin, once it ranks first, was
called told apart one time in 20 per pair; on Table 1 with acc.quadratic.z = 3e-4 (twin
acc.scale_asymmetry.z, which `plan --separate` gives power 0.01) scale_asymmetry won 4 of seeds
10-17 and at LR gaps 3.9 and 4.7 (seeds 15, 17) no note said so. At 10.83 the note stands unless the
data reject the twin at the level every other test here uses (tests/test_diagnose.py checks both
plans over 20 seeds). A fixed cosine (0.99) called a temperature and a time term twins on a
ramp whose likelihood ratios differed by 70, and missed the same pair at a
cosine of 0.976 whose ratios were 82.5 and 84.0 (tests/test_diagnose.py). Where the noise is
unknown, s2 (the residual variance) scales the sums.
"""
from __future__ import annotations

from simucal.fit.distributions import chi2_isf
from simucal.fit.results import ALPHA
from simucal.generated.effects import EFFECTS, SEPARATE, SEPARATE_MOVES

CANNOT_TELL = chi2_isf(ALPHA, 1)  # 10.83: the one test level (module doc)


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
          "f_x": "the attitude to gravity", "f_y": "the attitude to gravity", "f_z": "the attitude to gravity",
          **{f"{q}_{c}": "the motion (body rate and its change)" for q in ("wb", "dwb") for c in "xyz"}}


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
        return (f"{sorted(aux)[0]} changing at the same inputs (not with the position): "
                f"{texts.get(fam, '')}").rstrip(": ")
    if fa == fb and eid_a.split(".")[2] != eid_b.split(".")[2]:
        return f"inputs where the two axes' regressors differ: {texts.get(fa, '')}"
    return "; ".join(dict.fromkeys(texts.get(f, "") for f in (fa, fb) if texts.get(f)))


def twins_note(tw, plan) -> str:
    """A candidate's note naming its twins and the plan that would separate them."""
    return (f"the data cannot tell it from {', '.join(tw)} (neither, added to the other, lowers the chi-square "
            f"by {CANNOT_TELL:.2f}, the test level p = {ALPHA:g}); to tell them apart: {plan}")
