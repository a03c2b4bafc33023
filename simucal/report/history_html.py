"""The page of a unit's history (`simucal history SERIAL --html`): first whether a calibration moved beyond its
stds and when the unit is due, then per sensor each parameter's values over time with their k = 2 bands, the
trend line with its band and the spec's limits, the table of every parameter's trend, and the calibrations.
Reads the report (simucal/store/history.py, trend.py)."""
from __future__ import annotations

from datetime import datetime, timedelta
import matplotlib.dates as mdates
import numpy as np

from simucal.report.numbers import words_html
from simucal.report.page import CELL_IN, grid, page, plt, png, table
from simucal.report.unit_history import History, ParameterTrend


def _dates(t0: datetime, years) -> np.ndarray:
    """Years since t0 as matplotlib's date numbers (its axis then reads them as dates)."""
    return np.asarray(mdates.date2num([t0 + timedelta(days=365.25 * float(y)) for y in years]), float)


def _figure(p: ParameterTrend, t0: datetime, k: float, legend: bool) -> str:
    """One parameter: its values +- k std, its line with the line's k band (to its due date), the spec's limits."""
    fig, ax = plt.subplots(figsize=(CELL_IN, 2.6))
    t, v, s = np.array(p["t_years"]), np.array(p["values"]), np.array(p["stds"])
    ax.errorbar(_dates(t0, t), v, yerr=k * s, fmt="o", ms=3, lw=0.9, capsize=2, label=f"calibration +- {k:g} std")
    if p.get("slope_per_year") is not None:
        end = max(t[-1] + max(0.5 * np.ptp(t), 0.5), p.get("expected_years") or 0.0)
        tt = np.linspace(0.0, end, 100)
        X = np.column_stack([np.ones_like(tt), tt])
        line = p["intercept"] + p["slope_per_year"] * tt
        band = k * np.sqrt(np.einsum("ij,jk,ik->i", X, np.asarray(p["covariance"]), X))
        ax.plot(_dates(t0, tt), line, color="k", lw=0.8, label="trend")
        ax.fill_between(_dates(t0, tt), line - band, line + band, color="0.88", zorder=0, label=f"trend +- {k:g} std")
    for bound, limit in _limits(p):
        ax.axhline(limit, color="orange", ls="--", lw=1, label=f"spec {bound}")
    if p.get("earliest_years") is not None:
        ax.axvline(float(_dates(t0, [p["earliest_years"]])[0]), color="red", lw=1, label="due (band reaches the spec)")
    ax.set_title(f"{p['name']} ({p['unit']})", fontsize=9)
    ax.xaxis.set_major_formatter(mdates.DateFormatter("%Y-%m"))
    ax.tick_params(labelsize=7)
    if legend or p.get("earliest_years") is not None:
        ax.legend(fontsize=7, loc="best")
    fig.subplots_adjust(left=0.14, right=0.98, bottom=0.14, top=0.88)
    return png(fig)


def _limits(p: ParameterTrend) -> list[tuple[str, float]]:
    """The spec's (bound, value) of a parameter, min before max, none without a spec."""
    spec = p.get("spec") or {}
    return [(b, v) for b, v in (("min", spec.get("min")), ("max", spec.get("max"))) if v is not None]


def _trend_row(p: ParameterTrend) -> list:
    slope, sd = p.get("slope_per_year"), p.get("slope_std")
    z = None if slope is None or not sd else slope / sd
    spec = ", ".join(f"{b} {v:.4g}" for b, v in _limits(p))
    return [p["name"], p["unit"], len(p["values"]), p["values"][-1], p["stds"][-1], p.get("slope_per_year"),
            p.get("slope_std"), z, p.get("p_value"), spec or "-", p.get("expected_utc") or "-",
            p.get("earliest_utc") or "-"]


def _verdicts(report: History) -> list[tuple[bool, str]]:
    """Per sensor: whether a calibration moved it beyond its stds, and when its first parameter is due."""
    tr, out = report["trend"], []
    for sensor in sorted({p["name"].split(".")[0] for p in tr["parameters"]}):
        moved = [str(e["id"]) for e in report["records"] if any(w.startswith(sensor) for w in e["why"])]
        due = sorted((p["earliest_utc"], p["name"]) for p in tr["parameters"]
                     if p["name"].startswith(sensor + ".") and p["earliest_utc"])
        text = (f"{sensor}: moved beyond its stds at record {', '.join(moved)}" if moved else
                f"{sensor}: no change beyond its stds over {len(report['records'])} calibrations")
        out.append((not moved and not due, text + (f"; {due[0][1]} due by {due[0][0][:10]} (its trend's k = "
                                                   f"{tr['k']:g} band reaches the spec)" if due else "")))
    return out


def history_page(report: History) -> str:
    tr = report["trend"]
    t0 = datetime.fromisoformat(tr["first_utc"].replace("Z", "+00:00"))
    serial, due = report["serial"], tr["due_utc"]
    next_cmd = (f"simucal calibrate DATA -o calibration.json --store {report['store']} (before {due[:10]})" if due
                else f"simucal history {serial} --spec spec.json (the lab's limits give a due date)"
                if not any(p["spec"] for p in tr["parameters"]) else "simucal certificate calibration.json")
    body = [f"<p>{words_html(report['verdict'])}.<br>{words_html(tr['verdict'])}.</p>",
            "<p>" + words_html(f"Store {report['store']}; the trend is of the unit's calibrations by {tr['method']} "
                               f"({tr['model']}), times in years since {tr['first_utc']}; bands at k = {tr['k']:g}.")
            + "</p>"]
    for sensor in sorted({p["name"].split(".")[0] for p in tr["parameters"]}):
        body.append(f"<h2>{sensor}</h2>")
        mine = [p for p in tr["parameters"] if p["name"].startswith(sensor + ".")]
        body.append(grid([_figure(p, t0, tr["k"], i == 0) for i, p in enumerate(mine)]))
    body.append("<h2>Trends</h2>")
    body.append(table(["parameter", "unit", "n", "last value", "last std", "slope / year", "its std", "z",
                       "line p", "spec", "expected to leave", f"k = {tr['k']:g} band reaches"],
                      [_trend_row(p) for p in tr["parameters"]]))
    body.append("<h2>Calibrations</h2>")
    body.append(table(["record", "calibrated", "station", "method", "flagged"],
                      [[e["id"], e["calibrated_utc"], e["station"], e["method"],
                        words_html("; ".join(e["why"])) if e["flagged"] else "-"] for e in report["records"]]))
    return page(f"history {serial}", f"Unit {serial}: its calibrations and their trend", _verdicts(report), next_cmd,
                body=body)
