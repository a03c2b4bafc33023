"""The page of a thermal calibration (`calibrate --thermal --html`): first a verdict per sensor (the one
model's test over every row at its own temperature, each plateau or band under it beside each plateau
alone, and the validation where one is given), then each parameter that follows temperature with its
polynomial and 68 % band (from the coefficients' covariance) beside each plateau's own estimate, then a
table of every parameter."""
from __future__ import annotations

import html
import math

import numpy as np

from simucal.fit.thermal import evaluate, std_at
from simucal.io.calibration import ALPHA, Calibration
from simucal.fit.augmented import AugmentedModel
from simucal.report.numbers import Html, eng_html, value_digits
from simucal.report.page import CELL_IN, figure, grid, page, png, table
from simucal.report.vocabulary import TERM, Entry, entries


def _figure(sensor, name, f, unit, th):
    """The polynomial over temperature (above) and, below, its 68 % band about it, each plateau's own estimate
    less the polynomial beside it: the band is far thinner than the curve's change, so it has an axis of its own."""
    T = np.asarray(th.get("plateaus_c", th.get("temperature_range_c")), float)  # a warm-up has no plateaus
    lo, hi = th.get("temperature_range_c", [T.min(), T.max()])
    grid = np.linspace(lo - 5, hi + 5, 200)
    dT = grid - th["t_ref_c"]
    y, band = evaluate(f["coefficients"], dT), std_at(th, name, dT)
    fig, (ax, low) = figure(CELL_IN, 4.4, 2, 1, sharex=True, height_ratios=(3, 2))
    ax.plot(grid, y, "-", lw=1, label="fit")
    low.fill_between(grid, -band, band, alpha=0.35, label="fit's 68 % band")
    low.axhline(0.0, color="C0", lw=1)
    if "per_plateau" in f:
        ax.errorbar(T, f["per_plateau"], yerr=f["per_plateau_std"], fmt="o", ms=4, capsize=3,
                    label="each plateau alone")
        low.errorbar(T, np.asarray(f["per_plateau"]) - evaluate(f["coefficients"], T - th["t_ref_c"]),
                     yerr=f["per_plateau_std"], fmt="o", ms=4, capsize=3, color="C1")
    for a in (ax, low):
        a.axvspan(lo, hi, color="0.9", zorder=0)
    ax.set(ylabel=f"{name} ({unit})", title=f"{sensor} {name}: degree {f['degree']}")
    low.set(xlabel="temperature (degC)", ylabel="less the fit")
    ax.legend(fontsize=7)
    low.legend(fontsize=7)
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
        return [f"{sensor}: each plateau fitted alone, p = "
                + ", ".join(_p(x["p_value"]) for x in b.details["plateaus"])]
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


def _meanings(b) -> dict[str, str]:
    """Each parameter's meaning, the model's words: theta_ij (an accelerometer's axis, in frame b) and phi_ij (a
    gyro's, in frame d) both read as "the y ... axis tilted toward x of the parameter frame"."""
    if b.model == "affine":
        return {}
    model = AugmentedModel(b.model, b.library_effects())
    return dict(zip(model.params, model.meanings))


def _table(b) -> str:
    """Every parameter with its meaning, unit and polynomial (a constant says so, not degree 0), a column per
    coefficient: every row as long as the highest degree's."""
    params, meaning = b.thermal["parameters"], _meanings(b)
    n = max(len(f["coefficients"]) for f in params.values())
    rows = "".join(
        f"<tr><td>{html.escape(name)}</td><td>{html.escape(meaning.get(name, ''))}</td>"
        f"<td>{html.escape(b.param_units.get(name, ''))}</td><td>{f['degree'] or 'constant'}</td>"
        + "".join(f"<td>{eng_html(c)} &plusmn; {eng_html(e, 2)}</td>" for c, e in zip(f["coefficients"], f["std"]))
        + "<td></td>" * (n - len(f["coefficients"])) + "</tr>" for name, f in params.items())
    head = "".join(f"<th>c_{k}" + (" (at T_ref)" if k == 0 else f" (per degC^{k})" if k > 1 else " (per degC)")
                   + "</th>" for k in range(n))
    return f"<table><tr><th>parameter</th><th>meaning</th><th>unit</th><th>degree</th>{head}</tr>{rows}</table>"


NO_STD_DIGITS = 7  # a value without a std: as many digits as a scale factor's ppm need


def _stated(e: Entry) -> Html:
    """An entry's value, down to its std's second digit, and its std; without one (the file gives none), more
    digits and "no std" (NO_STD)."""
    if not math.isfinite(e.std):
        return Html(f"{eng_html(e.value, NO_STD_DIGITS)} (no std)")
    return Html(f"{eng_html(e.value, value_digits(e.value, e.std))} &plusmn; {eng_html(e.std, 2)}")


NO_STD = ("<p>no std: the file gives none for this entry (as for a gyro's M tied to b through a C_b^d whose "
          "uncertainty it does not hold), so neither this page nor `simucal lot` states or judges one; the "
          "method's own parameters below carry theirs.</p>")


def _common_table(sensor: str, b, span) -> str:
    """The sensor's M, bias and effects over temperature in the one vocabulary (report/vocabulary.py): each at
    T_ref and its temperature terms name.Tk (per degC^k), with the method's own parameter beside it."""
    rows = entries(sensor, b, span)
    terms: dict[str, dict[int, Entry]] = {}
    for e in rows:
        if (m := TERM.search(e.name)) is not None:
            terms.setdefault(e.name[:m.start()], {})[int(m.group(1))] = e
    n = max((max(t) for t in terms.values()), default=0)
    head = ["entry", "the method's", "meaning", "unit", "at T_ref"] + [f"per degC{'' if k == 1 else f'^{k}'}"
                                                                     for k in range(1, n + 1)]
    cells = [[e.name, e.own_name, e.meaning, e.unit, _stated(e)]
             + [_stated(t) if (t := terms.get(e.name, {}).get(k)) else None for k in range(1, n + 1)]
             for e in rows if TERM.search(e.name) is None]
    return table(head, cells) + (NO_STD if any(not math.isfinite(e.std) for e in rows) else "")


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
            parts.append(grid([_figure(s, n, f, b.param_units.get(n, ""), b.thermal)
                               for n, f in b.thermal["parameters"].items() if f["degree"] > 0]))
            parts.append(_common_table(s, b, cal.temperature_range_c))
            parts.append(f"<h3>{s}: the method's own parameters</h3>")
            parts.append(_table(b))
    cmd, notes = thermal_next(cal, cal_path, validations)
    return page("simucal thermal calibration", "Thermal calibration", verdicts, cmd, notes, parts)
