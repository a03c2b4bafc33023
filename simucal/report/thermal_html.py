"""The page of a thermal calibration (`calibrate --thermal --html`): first a verdict per sensor (the one
model's test over every row at its own temperature, each plateau or band under it beside each plateau
alone, and the validation where one is given), then each parameter that follows temperature with its
polynomial and 68 % band (from the coefficients' covariance) beside each plateau's own estimate, then a
table of every parameter."""
from __future__ import annotations

import html

import numpy as np

from simucal.fit.thermal import evaluate
from simucal.io.calibration import ALPHA, Calibration
from simucal.report.page import page, plt, png


def _band(th, name, f, dT):
    """The polynomial's std at dT: its coefficients' covariance where the file holds it (else their stds)."""
    V = np.vander(dT, len(f["coefficients"]), increasing=True)
    cov = th.get("covariance")
    names = [name] + [f"{name}.T{k}" for k in range(1, len(f["coefficients"]))]
    if cov and all(n in cov["names"] for n in names):
        idx = [cov["names"].index(n) for n in names]
        C = np.asarray(cov["matrix"])[np.ix_(idx, idx)]
    else:
        C = np.diag(np.asarray(f["std"]) ** 2)
    return np.sqrt(np.maximum(np.einsum("ik,kl,il->i", V, C, V), 0.0))


def _figure(sensor, name, f, unit, th):
    T = np.asarray(th.get("plateaus_c", th.get("temperature_range_c")), float)  # a warm-up has no plateaus
    lo, hi = th.get("temperature_range_c", [T.min(), T.max()])
    grid = np.linspace(lo - 5, hi + 5, 200)
    dT = grid - th["t_ref_c"]
    y, band = evaluate(f["coefficients"], dT), _band(th, name, f, dT)
    fig, ax = plt.subplots(figsize=(5.2, 3.2))
    ax.fill_between(grid, y - band, y + band, alpha=0.25, label="fit, 68 %")
    ax.plot(grid, y, "-", lw=1)
    if "per_plateau" in f:
        ax.errorbar(T, f["per_plateau"], yerr=f["per_plateau_std"], fmt="o", ms=4, capsize=3,
                    label="each plateau alone")
    ax.axvspan(lo, hi, color="0.9", zorder=0)
    ax.set(xlabel="temperature (degC)", ylabel=f"{name} ({unit})", title=f"{sensor} {name}: degree {f['degree']}")
    ax.legend(fontsize=7)
    return png(fig)


def _p(x):
    return "-" if x is None else f"{x:.2g}"


def verdict_lines(sensor, b, validations=()) -> list[str]:
    """The sensor's verdict in words: the joint test, each group under it (and alone), each validation."""
    groups = b.details.get("groups")
    if groups is None and "warmup" in b.thermal:  # one still warm-up: each axis's curve and its test
        verdict = "UNTESTED" if b.p_value is None else "PASSES" if b.p_value >= ALPHA else "FAILS"
        axes = ", ".join(f"{n} p = {_p(f.get('p_value'))}" for n, f in b.thermal["parameters"].items())
        out = [f"{sensor}: {verdict}: {b.details.get('test', 'the model test')}, chi2 {b.chi2:.4g} on {b.dof} dof, "
               f"p = {_p(b.p_value)} ({axes})"]
    elif groups is None:  # each plateau alone, then the polynomials
        return [f"{sensor}: each plateau fitted alone, p = " + ", ".join(_p(x["p_value"]) for x in b.details["plateaus"])]
    else:
        out = _joint_verdict(sensor, b, groups)
    for v in validations:
        for c in v["checks"].get(sensor, [])[:1]:
            fl = "" if c["floor_rms"] is None else f", floor {c['floor_rms']:.3g}"
            out.append(f"{sensor}: validated on {v['data']}: {c['what'].split(' (')[0]} {c['after_rms']:.3g} "
                       f"{c['unit']} rms{fl}: {c['verdict']}")
    return out


def _joint_verdict(sensor, b, groups) -> list[str]:
    """The joint fit's test over every row, each plateau or band under it."""
    failing = [g for g in groups if g["p_value"] is not None and g["p_value"] < ALPHA]
    passes = b.p_value is not None and b.p_value >= ALPHA and not failing
    return [f"{sensor}: {'PASSES' if passes else 'FAILS'}: the one model over every row at its own temperature, "
            f"chi2 {b.chi2:.4g} on {b.dof} dof, p = {_p(b.p_value)}; each "
            + ("plateau" if b.details.get("plateaus") else "band") + " under it p = "
            + ", ".join(_p(g["p_value"]) for g in groups)
            + ("; each plateau alone (at one temperature) p = " + ", ".join(_p(g["own_p_value"]) for g in groups)
               if b.details.get("plateaus") else "")]


def thermal_next(cal: Calibration, cal_path: str, validations=()) -> tuple[str, list[str]]:
    """(the command after a thermal calibration, why): validate on a set it was not made from, at another
    temperature; where a validation is given and holds, apply; where a sensor fails, diagnose a plateau."""
    fails = [s for s, b in cal.blocks() if b.thermal is not None and b.p_value is not None and b.p_value < ALPHA]
    if fails:
        return (f"simucal diagnose {cal.input[0] if isinstance(cal.input, list) else cal.input} -o diagnosis.json "
                "--html diagnosis.html", [f"{', '.join(fails)}: the one model fails; the diagnosis of a plateau shows "
                                          "what it lacks"])
    held = [v for v in validations if all(c["verdict"] in ("better", "at the noise floor")
                                          for cs in v["checks"].values() for c in cs)]
    if held:
        return f"simucal apply {cal_path} {held[0]['data']} -o calibrated", []
    return (f"simucal validate {cal_path} OTHER_SET -o validation.json --html validation.html",
            ["OTHER_SET: a recording of the same unit at a temperature between the plateaus, which the fit did not see"]
            if not validations else ["the validation above does not hold: see its checks"])


def _table(b) -> str:
    """Every parameter with its unit and polynomial (a constant says so, not degree 0)."""
    rows = "".join(
        f"<tr><td>{html.escape(n)}</td><td>{html.escape(b.param_units.get(n, ''))}</td>"
        f"<td>{f['degree'] or 'constant'}</td>"
        + "".join(f"<td>{c:.4g} &plusmn; {e:.2g}</td>" for c, e in zip(f["coefficients"], f["std"]))
        + "</tr>" for n, f in b.thermal["parameters"].items())
    return ("<table><tr><th>parameter</th><th>unit</th><th>degree</th>"
            "<th colspan=4>c_0 (at T_ref), c_1, ... per degC^k</th></tr>" + rows + "</table>")


def thermal_page(cal: Calibration, validations=(), cal_path="thermal_calibration.json") -> str:
    """The page; validations: `simucal validate` reports of this calibration, shown in the verdicts; cal_path:
    the file it is saved in (for the next command)."""
    assert cal.temperature_range_c is not None  # a thermal calibration's
    lo, hi = cal.temperature_range_c
    verdicts = [(not any(w in line for w in ("FAILS", "WORSE", "no better", "UNTESTED")), line)
                for s, b in cal.blocks() if b.thermal is not None for line in verdict_lines(s, b, validations)]
    parts = [f"<p>{html.escape(cal.method)}; T_ref {cal.t_ref_c:.4g} degC; calibrated from {lo:.4g} to {hi:.4g} degC "
             "(grey; outside it the polynomials are extrapolated and apply and validate warn).</p>"]
    for s, b in cal.blocks():
        if b.thermal is not None:
            parts.append(f"<h2>{s}</h2>")
            parts += [_figure(s, n, f, b.param_units.get(n, ""), b.thermal)
                      for n, f in b.thermal["parameters"].items() if f["degree"] > 0]
            parts.append(_table(b))
    cmd, notes = thermal_next(cal, cal_path, validations)
    return page("simucal thermal calibration", "Thermal calibration", verdicts, cmd, notes, parts)
