"""The page of a thermal calibration (`calibrate --thermal --html`): each parameter that follows
temperature against the plateaus' temperatures, its estimates with their stds and the fitted
polynomial with its 68 % band, then a table of every parameter."""
from __future__ import annotations

import html

import numpy as np

from simucal.io.calibration import Calibration

from simucal.fit.thermal import evaluate
from simucal.report.html import _png, plt


def _figure(sensor, name, f, unit, t_ref_c, T_k):
    T = np.asarray(T_k, float)
    grid = np.linspace(T.min() - 5, T.max() + 5, 200)
    cov_diag = np.asarray(f["std"]) ** 2  # the band from the coefficients' stds (their covariance is near-diagonal
    dT = grid - t_ref_c                   # around T_ref, the plateaus' mean)
    band = np.sqrt(sum(v * dT ** (2 * k) for k, v in enumerate(cov_diag)))
    y = evaluate(f["coefficients"], dT)
    fig, ax = plt.subplots(figsize=(5.2, 3.2))
    ax.fill_between(grid, y - band, y + band, alpha=0.25, label="fit, 68 %")
    ax.plot(grid, y, "-", lw=1)
    ax.errorbar(T, f["per_plateau"], yerr=f["per_plateau_std"], fmt="o", ms=4, capsize=3, label="plateaus")
    ax.axvspan(T.min(), T.max(), color="0.9", zorder=0)
    ax.set(xlabel="temperature (degC)", ylabel=f"{name} ({unit})",
           title=f"{sensor} {name}: degree {f['degree']}" + (f", chi2 {f['chi2']:.1f} on {f['dof']} dof"
                                                             if f["dof"] > 0 else ""))
    ax.legend(fontsize=7)
    return _png(fig)


def thermal_page(cal: Calibration) -> str:
    parts = ["<!doctype html><meta charset=utf-8><title>simucal thermal calibration</title>",
             f"<h1>Thermal calibration</h1><p>{html.escape(cal.method)}; T_ref {cal.t_ref_c:.4g} degC; "
             f"calibrated from {cal.temperature_range_c[0]:.4g} to {cal.temperature_range_c[1]:.4g} degC "
             "(grey; outside it the polynomials are extrapolated and apply warns).</p>"]
    for s, b in cal.blocks():
        if b.thermal is None:
            continue
        th, units = b.thermal, b.param_units
        parts.append(f"<h2>{s}</h2>")
        parts += [_figure(s, n, f, units.get(n, ""), th["t_ref_c"], th["plateaus_c"])
                  for n, f in th["parameters"].items() if f["degree"] > 0]
        rows = "".join(
            f"<tr><td>{html.escape(n)}</td><td>{html.escape(units.get(n, ''))}</td><td>{f['degree']}</td>"
            + "".join(f"<td>{c:.4g} &plusmn; {e:.2g}</td>" for c, e in zip(f["coefficients"], f["std"]))
            + "</tr>" for n, f in th["parameters"].items())
        parts.append("<table border=1 cellpadding=4><tr><th>parameter</th><th>unit</th><th>degree</th>"
                     "<th colspan=4>c_0 (at T_ref), c_1, ... per degC^k</th></tr>" + rows + "</table>")
    return "".join(parts)
