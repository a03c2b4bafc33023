"""The page of a lot (`simucal lot --html`): first the lot's verdict (how many units pass, which fail and
why, which are flagged) and the next command, then per group and sensor each parameter over the units
(each unit's value with its std, the lot's median, the band the outlier rule allows, the spec limits),
the table of every parameter's distribution, the units and the drifts. Reads the report
(simucal/api/lot_reporting.py)."""
from __future__ import annotations

import html

import numpy as np

from simucal.report.console import n_units
from simucal.report.numbers import eng_html
from simucal.report.lot_figures import LotReport
from simucal.report.page import page, plt, png, table


def _figure(group, sensor, limits) -> str:
    rows = [p for p in group["parameters"] if p["name"].startswith(sensor + ".")]
    cols, height_in = 3, 2.4 * -(-len(rows) // 3)
    fig, axes = plt.subplots(-(-len(rows) // cols), cols, figsize=(14.5, height_in), squeeze=False)
    for ax, p in zip(axes.flat, rows):
        x, s = np.asarray(p["values"]), np.asarray(p["stds"])
        i = np.arange(len(x))
        out = np.isin(group["units"], [o["unit"] for o in p["outliers"]])
        ax.errorbar(i[~out], x[~out], yerr=s[~out], fmt="o", ms=2.5, lw=0.8, label="unit +- std")
        if out.any():
            ax.errorbar(i[out], x[out], yerr=s[out], fmt="o", ms=4, color="red", label="outlier")
        ax.axhline(p["centre"], color="k", lw=0.8)
        if group["z_threshold"] is not None:
            half = group["z_threshold"] * np.sqrt(p["spread_of_units"] ** 2 + p["median_std"] ** 2)
            ax.axhspan(p["centre"] - half, p["centre"] + half, color="0.9", zorder=0, label="outlier rule")
        for k, v in limits.get(p["name"], {}).items():
            if k in ("min", "max"):
                ax.axhline(v, color="orange", ls="--", lw=1, label=f"spec {k}")
        ax.set_title(f"{p['name']} ({p['unit']})", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in list(axes.flat)[len(rows):]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7)
    fig.supxlabel("unit (file-name order)", fontsize=8)
    # margins in inches, not fractions, so that one row keeps room for its ticks and the label below them (not
    # tight_layout: it draws the figure twice)
    fig.subplots_adjust(hspace=0.5, wspace=0.35, bottom=0.65 / height_in, top=1 - 0.3 / height_in)
    return png(fig)


def _largest(drift, sensor) -> str:
    r = max((r for r in drift["parameters"] if r["name"].startswith(sensor + ".")), key=lambda r: abs(r["z"]))
    return f"{abs(r['z']):.3g} ({r['name']})"


def lot_page(report: LotReport) -> str:
    """The page (module doc) of a report of simucal.api.lot_reporting.lot, in the pages' one shell (report/page.py):
    the verdict's first line is the lot's, each further line a unit failing or flagged, or a note."""
    e = html.escape
    first, *rest = report["verdict"]
    failing = any(u["status"] != "passes" for u in report["units"])
    verdicts = [(not failing, first)] + [(not (" FAILS: " in v or " FLAGGED: " in v), v) for v in rest]
    parts = []
    for g in report["groups"]:
        parts.append(f"<h2>{e(g['key'])}: {n_units(len(g['units']))}</h2><p>Outliers: {e(g['outlier_rule'])}.</p>")
        for sensor in dict.fromkeys(p["name"].split(".")[0] for p in g["parameters"]):
            parts.append(f"<h3>{sensor}</h3>" + _figure(g, sensor, report["limits"]))
        parts.append(table(
            ["parameter", "the method's", "unit", "median", "spread (1.4826 MAD)", "spread of units", "median std",
             "outliers"],
            [[p["name"], p.get("own_name") or "-", p["unit"], eng_html(p["centre"], 6), p["spread"],
              p["spread_of_units"], p["median_std"], ", ".join(f"{o['unit']} (z {o['z']:.3g})" for o in p["outliers"])]
             for p in g["parameters"]]))
    parts.append("<h2>Units</h2>" + table(
        ["file", "serial", "status", "model tests", "why"],
        [[u["file"], u["serial"] or "-", u["status"],
          ", ".join(f"{s} {t['verdict']}" + (f" (p {t['p_value']:.2g})" if t["p_value"] is not None else "")
                    for s, t in u["tests"].items()), "; ".join(u["why"])] for u in report["units"]]))
    if report["drift"]:
        parts.append("<h2>Drift between calibrations of one unit</h2>" + table(
            ["serial", "earlier", "later", "sensor", "chi2 / dof", "p", "verdict", "largest |drift| / std"],
            [[d["serial"], d["earlier"], d["later"], s, f"{v['chi2']:.3g} / {v['dof']}", v["p_value"],
              v["verdict"], _largest(d, s)] for d in report["drift"] for s, v in d["sensors"].items()]))
    return page("simucal lot", f"Lot {report['folder']}", verdicts, report["next"], body=parts)
