"""A calibration's certificate (`simucal certificate CAL.json`): the page a lab hands over with a unit, every
number read from the calibration file (and its validation, where one was made), none typed by hand.

It gives the unit, the calibration file's sha256 and the measurement set's, the method and each sensor's
model with its test, each parameter with its standard uncertainty u (the file's std), its expanded
uncertainty U = k u (k = 2, GUM's coverage factor for about 95 %) and its budget, the validation on
independent data, and the version of simucal that wrote the certificate. The budget splits u^2 into the
parts the file records, in the order the methods build the std (turntable/tilt.py, io/blocks
.inflate_if_failing):
    table   = |dp / dtilt| * the stated tilt      (the outer axis's levelling, meta.json table_tilt_arcsec)
    misfit  = sqrt(u^2 - u_raw^2)                 (where the model failed its test: u = u_raw sqrt(chi2/dof))
    noise   = sqrt(u_raw^2 - table^2)             (the fit's own: the data's noise through the plan)
where u_raw is the std before the misfit's inflation (u where the model passed). The temperatures the data
spanned are stated (the calibration holds there). A thermal model's parameters are given at T_ref, its
temperature coefficients in a table of their own, and beside u its temperature part, what using a parameter
anywhere in the calibrated range adds to u (sqrt(max_T u(T)^2 - u(T_ref)^2), u(T) from the coefficients'
covariance); no temperature part is invented for a model without one.
"""
from __future__ import annotations

import html
import math
from typing import Any, Mapping, TypedDict

import numpy as np

from simucal.fit.thermal import std_at, terms
from simucal.io.calibration import Calibration, SensorBlock
from simucal.report.lot_figures import block_parameters, model_name
from simucal.report.numbers import eng_html, value_digits
from simucal.report.page import page, table

K = 2.0  # the coverage factor of the expanded uncertainty


def _entry(stds: dict, name: str) -> float:
    """A parameter's std in a std dict: its own key, or an affine block's entry of M (M_xy) or bias (b_x)."""
    v = stds.get(name)
    if isinstance(v, (int, float)):
        return float(v)
    M, b = np.asarray(stds.get("M", np.nan), float), np.asarray(stds.get("bias", np.nan), float)
    if name.startswith("M_") and M.shape == (3, 3):
        return float(M["xyz".index(name[2]), "xyz".index(name[3])])
    if name.startswith("b_") and b.shape == (3,):
        return float(b["xyz".index(name[2])])
    return math.nan


def temperature_part(block: SensorBlock, name: str) -> float | None:
    """What using parameter `name` anywhere in the calibrated temperature range adds to its u at T_ref:
    sqrt(max_T u(T)^2 - u(T_ref)^2), u(T) its polynomial's std (fit/thermal.std_at); 0 where the data showed
    no temperature term of it; None without a temperature model (the value holds at the data's temperatures)."""
    th = block.thermal
    if not th or name not in th.get("parameters", {}) or "temperature_range_c" not in th:
        return None
    lo, hi = th["temperature_range_c"]
    u_T = std_at(th, name, np.linspace(lo, hi, 201) - th["t_ref_c"])
    return float(np.sqrt(max(float(np.max(u_T)) ** 2 - float(std_at(th, name, 0.0)) ** 2, 0.0)))


class BudgetRow(TypedDict):
    """One parameter's uncertainty budget (budget), in its unit."""
    name: str
    value: float
    unit: str
    u: float                          # the standard uncertainty (the file's std)
    U: float                          # the expanded one, K u
    noise: float | None               # u's parts (None: the file does not split u)
    table: float | None               # the table's stated angle errors' share (None: not in u)
    misfit: float | None
    temperature: float | None         # beside u, not in it (temperature_part)


def budget(block: SensorBlock) -> list[BudgetRow]:
    """Each parameter of the block with its value, unit, u, U = K u, u's parts (module doc) and the temperature
    part (temperature_part: beside u, not in it)."""
    tilt = block.details.get("table_tilt")
    raw = block.details.get("std_raw") or block.details.get("std_noise")  # u before the misfit's share
    rows: list[BudgetRow] = []
    for name, (value, u, unit) in block_parameters(block).items():
        u_raw = min(_entry(raw, name), u) if raw else u
        table_part = abs(tilt["per_arcsec"].get(name, 0.0)) * tilt["stated_arcsec"] if tilt else None  # None: not in u
        noise: float | None = None  # None: the file does not split u (splits)
        misfit: float | None = None
        if splits(block):
            noise = math.sqrt(max(u_raw ** 2 - (table_part or 0.0) ** 2, 0.0))
            misfit = math.sqrt(max(u ** 2 - u_raw ** 2, 0.0))
        rows.append({"name": name, "value": value, "unit": unit, "u": u, "U": K * u, "noise": noise,
                     "table": table_part, "misfit": misfit, "temperature": temperature_part(block, name)})
    return rows


def splits(block: SensorBlock) -> bool:
    """Whether u's budget can be split: a model that passed (u is the noise's and the table's), or a failing one
    whose file keeps the stds before the misfit's share (std_raw, or a hand session's std_noise)."""
    return block.verdict != "fails" or bool(block.details.get("std_raw") or block.details.get("std_noise"))


def coefficients(block: SensorBlock) -> list[list[Any]]:
    """A thermal block's temperature coefficients: [name.Tk, value, unit/degC^k, u, U] of every term the data
    hold (k >= 1), from the block's `thermal` polynomials."""
    return [[term, c, unit, u, K * u] for name, (_, _, param_unit) in block_parameters(block).items()
            for term, _, c, u, unit in terms(block.thermal, name, param_unit)]


# each verdict of a block (io/calibration.SensorBlock.verdict) as the certificate states it, and its colour:
# True passes, False fails, None neither (a method that gives no test: its stds hold only if the model does)
VERDICTS = {"passes": ("the model passes its test", True), "fails": ("THE MODEL FAILS its test", False),
            "untested": ("the model is untested: the method gives no test of it, and its stds hold only if the "
                         "model does", None),
            "nominal": ("not calibrated: kept at the nominal scale factors", None)}


def _test_line(block: SensorBlock) -> str:
    said = VERDICTS[block.verdict][0]
    if block.verdict == "untested":
        return said
    test = block.details.get("test") or "no model test"
    stat = (f"chi2 = {block.chi2:.4g} on {block.dof:g} dof, p = {block.p_value:.3g}" if block.p_value is not None
            and block.chi2 is not None and block.dof else "")
    lof = block.details.get("lack_of_fit")
    lof_text = f"; lack-of-fit F = {lof['F']:.3g}, p = {lof['p_value']:.3g}" if lof and "p_value" in lof else ""
    return f"{said} ({test}{'; ' + stat if stat else ''}{lof_text})"


def _validation_rows(validation: dict) -> list[list]:
    return [[sensor, c["what"], c["n"], c["unit"], c["before_rms"], c["after_rms"], c["floor_rms"], c["verdict"]]
            for sensor, checks in validation["checks"].items() for c in checks]


def certificate_page(cal: Calibration, file_name: str, file_sha256: str, validation: dict | None,
                     version: str, apply_line: str, record: Mapping[str, Any] | None = None) -> str:
    """The certificate of `cal` (module doc); file_sha256: the file's bytes', validation: validate's report,
    apply_line: the next command; record: a store's row of it (its serial the lab's, its time and station)."""
    serial = ((record or {}).get("serial") or cal.layout.get("unit_serial")
              or "(no unit_serial in the set's meta.json)")
    shas = cal.input_sha256 if isinstance(cal.input_sha256, list) else [cal.input_sha256]
    data_sha = [sha or "(not recorded)" for sha in shas]
    verdicts: list[tuple[bool | None, str]] = [(VERDICTS[b.verdict][1], f"{s}: {_test_line(b)}")
                                                for s, b in cal.blocks()]
    if validation:
        verdicts += [(v == "at the noise floor", f"{s} on independent data ({validation['data']}): {v}")
                     for s, v in validation["verdict"].items()]
    facts = [("unit", serial), ("calibration file", f"{file_name} (sha256 {file_sha256})"),
             ("measurement set", f"{cal.input if isinstance(cal.input, str) else ', '.join(cal.input)}"),
             ("its files' sha256", ", ".join(data_sha)), ("method", cal.method), ("model", model_name(cal)),
             ("file format", cal.format), ("certificate written by", f"simucal {version}")]
    if record:
        facts.insert(2, ("recorded", f"calibrated {record['calibrated_utc']} at station {record['station']}, "
                                     f"by simucal {record['tool_version']}"))
    if cal.temperature_range_c:
        lo, hi = cal.temperature_range_c
        facts.append(("temperature", f"the data spanned {lo:.2f} to {hi:.2f} degC"
                      + (f"; temperature terms read T - {cal.t_ref_c:g} degC" if cal.t_ref_c is not None else "")))
    body = ["<table>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>" for k, v in facts)
            + "</table>"]
    for s, b in cal.blocks():
        tilt = b.details.get("table_tilt")
        body.append(f"<h2>{s}</h2><p>{html.escape(_test_line(b))}"
                    + (f"; the table's stated tilt {tilt['stated_arcsec']:g} arcsec is in u" if tilt else "")
                    + (f"; {html.escape(b.details['std_note'])}" if b.details.get("std_note") else "")
                    + ("" if splits(b) else "; u includes the model's misfit, which the file does not split from the "
                       "noise") + ".</p>")
        rows = budget(b)
        thermal = any(r["temperature"] is not None for r in rows)
        body.append(table(["parameter", "value", "unit", "u (std)", f"U (k = {K:g})", "u: noise", "u: table",
                           "u: model misfit"] + (["temperature: over the range, beside u"] if thermal else []),
                          [[r["name"], eng_html(r["value"], value_digits(r["value"], r["u"])), r["unit"], r["u"],
                            r["U"], r["noise"], r["table"], r["misfit"]] + ([r["temperature"]] if thermal else [])
                           for r in rows]))
        if b.thermal and coefficients(b):
            body.append(f"<p>{s}'s temperature coefficients, of (T - T_ref), T_ref = {b.thermal['t_ref_c']:g} degC "
                        "(the value at T is the polynomial's: simucal apply evaluates it at each row's "
                        "temperature):</p>")
            body.append(table(["coefficient", "value", "unit", "u (std)", f"U (k = {K:g})"], coefficients(b)))
    if validation:
        body.append("<h2>Validation on independent data</h2>")
        body.append(table(["sensor", "check", "n", "unit", "at nominal (rms)", "calibrated (rms)", "floor (rms)",
                           "verdict"], _validation_rows(validation)))
    else:
        body.append("<p>No validation on independent data was given (simucal validate CAL.json DATA -o "
                    "validation.json; then --validation validation.json).</p>")
    return page(f"certificate {serial}", f"Calibration certificate: unit {serial}", verdicts,
                apply_line, body=body)
