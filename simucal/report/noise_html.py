"""The page of `simucal noise --html`: the verdicts and the next step as the console prints them
(report/console.py), then each sensor's Allan deviation with the fit of the terms seen and its 68 % band, and
the terms' table, in one unit system per table (the spec's data-sheet units, or SI)."""
from __future__ import annotations

import html

import numpy as np

from simucal.fit import allan_fit
from simucal.fit.allan_terms import SHEET
from simucal.fit.noise import allan_deviation
from simucal.io.units import in_units
from simucal.report import units as shown
from simucal.report.console import noise_next, noise_verdicts
from simucal.report.numbers import eng_html
from simucal.report.page import FULL_IN, figure, page, png


def _term_cell(t) -> str:
    """One term in the table (its unit in the column's head): value +- std where seen, else its bound, or the
    length it needs."""
    if t["status"] == "seen":
        return f"{eng_html(t['value'])} &plusmn; {eng_html(t['std'], 2)}"
    if t["status"] == "not seen":
        return f"not seen (&lt; {eng_html(t['bound_95'], 2)}, 95 %)"
    return f"record too short (needs {eng_html(t['needs_s'], unit='s')})"


def _figure(sensor, b, units, g) -> str:
    """Each axis's Allan deviation (points), the fit of the terms seen and its 68 % band, in the table's unit."""
    fig, ax = figure(FULL_IN, 5)  # the body's width
    _, scale, adev_unit = SHEET[sensor]["B"]  # the bias instability's unit: the table's (ug, deg/h)
    if units != "spec":
        scale, adev_unit = in_units(1.0, b["unit"], units, g)
    for (a, axd), color in zip(b["axes"].items(), ("C0", "C1", "C2")):
        if "stuck" in axd:
            continue
        t, r = np.array(axd["tau_s"]), np.array(axd["rel_err"])
        s, fit = np.array(axd["adev"]) * scale, allan_deviation(axd["terms"], t) * scale
        ax.fill_between(t, fit * (1 - r), fit * (1 + r), color=color, alpha=0.2)
        ax.loglog(t, s, "o", ms=3, color=color, label=f"{a}")
        ax.loglog(t, fit, "-", color=color, lw=1)
    ax.set(xlabel="tau (s)", ylabel=f"Allan deviation ({adev_unit})",
           title=f"{sensor}: points, the fit of the terms seen and its 68 % band")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    return png(fig)


def noise_page(report, units: str = "spec", written=None) -> str:
    """The page (module doc); written: as noise_next's ({"-o": ..., "--kalibr": ...}, the files the command
    wrote), so that the page's next step is the console's."""
    parts, g = [], shown.gravity_of(report.get("data"))
    sheets = shown.noise_in(report, units, g)  # the tables' and verdicts' numbers; the plot's scaled in _figure
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        axes = sheets[sensor]["axes"]
        head = "".join(f"<th>{name} ({html.escape(in_units(1.0, unit, units, g)[1])})</th>"
                       for name, _, unit in SHEET[sensor].values())
        rows = "".join(f"<tr><td>{a}</td>" + ("".join(f"<td>{html.escape(axd['stuck']) if k == 'Q' else ''}</td>"
                                                      for k in SHEET[sensor]) if "stuck" in axd else
                       "".join(f"<td>{_term_cell(t)}</td>" for t in axd["sheet"].values())) + "</tr>"
                       for a, axd in axes.items())
        parts.append(f"<h2>{sensor}</h2>{_figure(sensor, report[sensor], units, g)}<table><tr><th>axis</th>{head}</tr>"
                     f"{rows}</table><p>Terms fitted by generalised least squares with the covariance of the "
                     f"overlapping estimates; a term is shown where beyond {allan_fit.SEEN:g} std, otherwise "
                     "with its 95 % upper bound.</p>")
    cmd, notes = noise_next(report, written)
    return page("simucal noise", f"Noise of {report['data']}", noise_verdicts(sheets), cmd, notes, parts)
