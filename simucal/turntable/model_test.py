"""One model test per sensor on a turntable set, shared by calibrate and diagnose (issue 23, item 3).

The rows: for accelerometers the static positions and the rate runs (a rate run's mean
specific force is gravity's component along the outer axis plus, with lever arms, a
centripetal term: the rows where size effects show); for gyros the rate runs. The statistic:
fit.candidates.test_model (chi-square where the noise is known, the lack-of-fit F where it is
not). The ranking: the library's candidates, with the positions that would reveal the ones
this plan cannot see (plan_design.TableAdvice), and for accelerometers the table's own error
terms fitted to the static directions (table_fit), ordered by p-value. calibrate's advice and
diagnose's verdict are read from the same list, so they name the same effect.
"""
from __future__ import annotations

from collections import Counter

from simucal.fit.candidates import ALPHA, rank_candidates, shape_if_unexplained, test_model
from simucal.turntable.plan_design import TableAdvice

ROWS = {"acc": {"static", "rate"}, "gyro": {"rate"}}  # the segment kinds each sensor's test fits
MIN_TABLE_POSITIONS = 6  # static positions with middle/inner angles for the table's own terms


def rows_text(segs) -> str:
    """Which rows a test used, in words: '16 static positions and 14 rate runs'."""
    n = Counter(s.kind for s in segs)
    return " and ".join(f"{n[k]} {name}" for k, name in (("static", "static positions"), ("rate", "rate runs")) if n[k])


def test_and_rank(model, obs, segs=None, only_if_failing=False, ranked=True):
    """The fit, the observations with the noise used, the test block (with `rows`), and rank's
    three (no candidates where only_if_failing and the model passes, or ranked is False). segs: the turntable
    segments of obs's rows; None for a stream's static poses (no plan to grow, no table angles)."""
    fit, obs, base = test_model(model, obs)
    if segs is not None:
        base["rows"] = rows_text(segs)
    if (only_if_failing and not fails(base)) or not ranked:
        return fit, obs, base, [], None, None
    return (fit, obs, base, *rank(model, obs, fit, base, segs))


def fails(base) -> bool:
    return base["p_value"] is not None and base["p_value"] < ALPHA


def rank(model, obs, fit, base, segs=None):
    """The ranked candidates, the generic shape where it explains more than they do (or None),
    and the table's fit (or None)."""
    cands = rank_candidates(model, obs, fit, fails(base), advisor=TableAdvice() if segs is not None else None)
    table_info = None
    if segs is not None:
        idx = [i for i, s in enumerate(segs) if s.kind == "static" and s.middle_deg is not None
               and s.inner_deg is not None]
        if model.sensor == "acc" and len(idx) >= MIN_TABLE_POSITIONS:
            from simucal.turntable.table_fit import table_candidates
            ang = [[segs[i].outer_deg or 0.0, segs[i].middle_deg, segs[i].inner_deg] for i in idx]
            tc, table_info = table_candidates(fit.directions[idx], ang, ALPHA)
            both = cands + tc
            cands = sorted([c for c in both if c["separable"]],
                           key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0, -c["statistic"])) + \
                [c for c in both if not c["separable"]]
    return cands, shape_if_unexplained(model, obs, fit, base, cands), table_info
