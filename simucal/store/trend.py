"""A unit's drift: each parameter's trend over its calibrations, and the date it is expected to leave its spec.

Each parameter's values v_i at times t_i (years since the unit's first calibration of the line: its last
calibration's method and model), with their stds s_i, are fitted by the weighted straight line

    v(t) = a + b t,   weights 1 / s_i^2,   cov(a, b) = (X^T W X)^-1,

each calibration an independent measurement of the unit (its std the file's, inflated where its model
failed). The slope's std is the fit's alone, not scaled by the line's misfit: with two calibrations the
line passes through both and nothing can test it; from three on, chi^2 of the line on n - 2 dof and its p
say whether a steady drift explains the values (a jump, or stds too small, fail it).

Due dates, from the lab's spec (limits.json as `simucal lot --limits` reads it: each parameter's min, max
or both, in its unit): `expected_utc` is the first time after the last calibration at which the line
crosses a limit, and `earliest_utc` the first at which its k = 2 band (2 sqrt(x^T C x), x = (1, t))
reaches one; a parameter outside already is due at its last calibration; neither within HORIZON_YEARS is
None. The unit's due date is the earliest of its parameters'. A parameter no line can be fitted through
(one calibration, all at one time, a std of 0 or none in a record) has `no_trend` saying why, and the verdict
names it; a value of it measured outside the spec is still due at its last calibration.
"""
from __future__ import annotations

from datetime import datetime, timedelta, timezone
import numpy as np
from scipy.optimize import brentq
from scipy.stats import chi2 as chi2_dist

from simucal.errors import StoreError
from simucal.report.lot_figures import Limit
from simucal.report.unit_history import ParameterTrend, Trend
from simucal.store import queries
from simucal.store.schema import ParameterRow, shown

FORMAT = "simucal.trend/1"
YEAR_S = 365.25 * 86400.0
HORIZON_YEARS = 10.0  # a crossing further than this is not a due date a lab plans by
K = 2.0  # the band's coverage factor (GUM's expanded uncertainty)


def _time(utc: str) -> datetime:
    return datetime.fromisoformat(utc.replace("Z", "+00:00")).astimezone(timezone.utc)


def _utc(t0: datetime, years: float) -> str:
    return (t0 + timedelta(seconds=years * YEAR_S)).strftime("%Y-%m-%dT%H:%M:%SZ")


def line(t_yr: np.ndarray, v: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The weighted line through (t_yr, v +- s): [a, b], their covariance, and chi^2 of the line."""
    X = np.column_stack([np.ones_like(t_yr), t_yr])
    w = 1.0 / s ** 2
    cov = np.linalg.inv(X.T @ (X * w[:, None]))  # (X^T W X)^-1
    ab = cov @ (X.T @ (w * v))                   # (X^T W X)^-1 X^T W v
    return ab, cov, float(np.sum(w * (v - X @ ab) ** 2))


def _crossing(f, start: float) -> float | None:
    """The first t in [start, start + HORIZON_YEARS] where f(t) >= 0 (f continuous), else None."""
    ts = np.linspace(start, start + HORIZON_YEARS, 2001)
    fs = np.array([f(t) for t in ts])
    above = np.nonzero(fs >= 0)[0]
    if not len(above):
        return None
    i = int(above[0])
    return float(ts[0]) if i == 0 else float(brentq(f, ts[i - 1], ts[i]))


def due(ab: np.ndarray, cov: np.ndarray, lim: Limit, t_last: float) -> tuple[float | None, float | None]:
    """(expected, earliest): the years at which the line, and its k = 2 band, first reach a limit (module doc)."""
    def value(t):
        return ab[0] + ab[1] * t

    def band(t):
        x = np.array([1.0, t])
        return K * float(np.sqrt(x @ cov @ x))

    def beyond(width):
        return lambda t: max(value(t) + width(t) - lim.get("max", np.inf),
                             lim.get("min", -np.inf) - value(t) + width(t))
    return _crossing(beyond(lambda t: 0.0), t_last), _crossing(beyond(band), t_last)


def _no_trend(rows: list[ParameterRow], t: np.ndarray, s: np.ndarray) -> str | None:
    """Why no weighted line can be fitted through a parameter's values (None: it can)."""
    if len(rows) < 2:
        return "one calibration: no trend before a second"
    if np.ptp(t) <= 0:
        return "every calibration at one time: no trend"
    bad = [r["calibration_id"] for r, si in zip(rows, s) if not (np.isfinite(si) and si > 0)]
    if bad:
        return (f"a std of 0 or none in record {', '.join(map(str, bad))}: a weighted line cannot be fitted "
                "(a parameter held fixed has no std; recalibrate with it estimated)")
    return None


def _parameter(rows: list[ParameterRow], t0: datetime, spec: dict[str, Limit]) -> ParameterTrend:
    """One parameter's trend: rows are its values over the calibrations, in time order."""
    t = np.array([(_time(r["calibrated_utc"]) - t0).total_seconds() / YEAR_S for r in rows])
    v = np.array([r["value"] for r in rows], float)
    s = np.array([np.nan if r["std"] is None else r["std"] for r in rows], float)  # none recorded: no weight
    name, unit = f"{rows[0]['sensor']}.{rows[0]['name']}", rows[0]["unit"]
    out: ParameterTrend = {"name": name, "own_name": rows[-1]["own_name"], "unit": unit, "t_years": t.tolist(),
                           "values": v.tolist(), "stds": s.tolist(), "records": [r["calibration_id"] for r in rows],
                           "spec": spec.get(name)}
    lim: Limit = spec.get(name) or {}
    outside = bool(lim) and bool(v[-1] > lim.get("max", np.inf) or v[-1] < lim.get("min", -np.inf))
    no_trend = _no_trend(rows, t, s)
    if no_trend:  # said, and a value measured outside its spec still due now
        now = _utc(t0, float(t[-1])) if outside else None
        return {**out, "slope_per_year": None, "slope_std": None, "chi2": None, "dof": 0, "p_value": None,
                "no_trend": no_trend, "expected_utc": now, "earliest_utc": now,
                **({"expected_years": float(t[-1]), "earliest_years": float(t[-1])} if outside else {})}
    ab, cov, c2 = line(t, v, s)
    dof = len(rows) - 2
    out.update({"intercept": float(ab[0]), "slope_per_year": float(ab[1]), "slope_std": float(np.sqrt(cov[1, 1])),
                "covariance": cov.tolist(), "chi2": c2, "dof": dof,
                "p_value": float(chi2_dist.sf(c2, dof)) if dof else None, "expected_utc": None, "earliest_utc": None})
    if lim:
        expected, earliest = due(ab, cov, lim, float(t[-1]))
        if outside:  # measured outside: due now
            expected = earliest = float(t[-1])
        out["expected_utc"] = None if expected is None else _utc(t0, expected)
        out["earliest_utc"] = None if earliest is None else _utc(t0, earliest)
        out["expected_years"], out["earliest_years"] = expected, earliest
    return out


def trend(engine, url: str, serial: str, spec: dict[str, Limit]) -> Trend:
    """The unit's trend (module doc; Trend); spec: read_limits' {name: {min, max, unit}} (may be empty)."""
    recs = queries.records(engine, url, serial=serial)
    if not recs:
        raise StoreError(f"{shown(url)}: no calibration of unit {serial!r}; record one: simucal store add CAL.json "
                         f"--serial {serial}")
    method, model = recs[-1]["method"], recs[-1]["model"]  # the unit's line: its last calibration's
    ids = {r["id"] for r in recs if (r["method"], r["model"]) == (method, model)}
    rows = [p for p in queries.parameters(engine, url, serial=serial, method=method, model=model)
            if p["calibration_id"] in ids]
    t0 = _time(min(r["calibrated_utc"] for r in recs if r["id"] in ids))
    by_name: dict[str, list[ParameterRow]] = {}
    for p in rows:
        by_name.setdefault(f"{p['sensor']}.{p['name']}", []).append(p)
    params = [_parameter(ps, t0, spec) for ps in by_name.values()]
    dated = [(p["expected_utc"], p["earliest_utc"], p["name"]) for p in params if p["earliest_utc"]]
    first = min(dated, key=lambda d: d[1]) if dated else None
    untrended = [p for p in params if p.get("no_trend") and (p["name"] in spec or len(p["values"]) > 1)]
    verdict = (f"unit {serial}: {len(ids)} calibrations by {method} ({model}); "
               + (f"{first[2]} is expected to leave its spec on {first[0] or 'no date within the horizon'} "
                  f"(its k = {K:g} band reaches it on {first[1]})" if first else
                  "no parameter is expected to leave its spec within "
                  f"{HORIZON_YEARS:g} years" if spec else "no spec given (--spec limits.json): no due date")
               + (f"; NO TREND for {len(untrended)} parameter(s), no date from a line for them: "
                  + "; ".join(f"{p['name']}: {p['no_trend']}" for p in untrended[:3]) if untrended else ""))
    return {"format": FORMAT, "store": shown(url), "serial": serial, "method": method, "model": model,
            "first_utc": t0.strftime("%Y-%m-%dT%H:%M:%SZ"), "k": K, "horizon_years": HORIZON_YEARS,
            "parameters": params, "due_utc": first[1] if first else None,
            "due_parameter": first[2] if first else None, "verdict": verdict}
