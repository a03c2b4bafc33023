"""A calibration's certificate (`simucal certificate CAL.json`): the page a lab hands over with a unit, every
number read from the calibration file (and its validation, where one was made), none typed by hand.

It gives the unit, the calibration file's sha256 and the measurement set's, the method and each sensor's
model with its test, each entry of the one vocabulary (report/vocabulary.py: M, bias, effects, every method's, the
method's own name beside it) with its standard uncertainty u (the file's stds through M(p)), its expanded
uncertainty U = k u (k = 2, GUM's coverage factor for about 95 %) and its budget, the validation on
independent data, and the version of simucal that wrote the certificate. The budget splits u^2 into the
parts the file records, in the order the methods build the std (turntable/tilt.py, io/blocks
.inflate_if_failing):
    table   = |dp / dtilt| * the stated tilt      (the outer axis's levelling, meta.json table_tilt_arcsec)
    misfit  = sqrt(u^2 - u_raw^2)                 (where the model failed its test: u = u_raw sqrt(chi2/dof))
    noise   = sqrt(u_raw^2 - table^2)             (the fit's own: the data's noise through the plan)
where u_raw is the std before the misfit's inflation (u where the model passed). The temperatures the data
spanned are stated (the calibration holds there). A thermal model's entries are given at T_ref, their
temperature coefficients in a table of their own, and beside u its temperature part, what using an entry
anywhere in the calibrated range adds to u (sqrt(max_T u(T)^2 - u(T_ref)^2), u(T) from the coefficients'
covariance); no temperature part is invented for a model without one. A model-based block's parts reach its
entries through the Jacobian of M(p) and bias(p) (budget).
"""
from __future__ import annotations

import html
import math
from typing import Any, Mapping, TypedDict

import numpy as np

from simucal.fit.augmented import AugmentedModel
from simucal.io.calibration import Calibration, SensorBlock
from simucal.report.lot_figures import model_name
from simucal.report.vocabulary import TERM, entries, is_determined, linearised, temperature_parts
from simucal.report.numbers import eng_html, value_digits
from simucal.report.page import page, table

K = 2.0  # the coverage factor of the expanded uncertainty


class BudgetRow(TypedDict):
    """One entry's uncertainty budget (budget), in its unit."""
    name: str                         # the one vocabulary's (report/vocabulary.py): M_xx, bias_x, an effect's id
    own_name: str | None              # the method's own parameter of it
    value: float
    unit: str
    u: float                          # the standard uncertainty (the entry's std, as the file's stds give it)
    U: float                          # the expanded one, K u
    noise: float | None               # u's parts (None: the file does not split u)
    table: float | None               # the table's stated angle errors' share (None: not in u)
    misfit: float | None
    temperature: float | None         # beside u, not in it (vocabulary.temperature_parts)


def _affine_raw(block: SensorBlock, name: str) -> float:
    """An affine block's std of entry M_xy or bias_x before the misfit's share (std_raw's M or bias), else NaN."""
    raw = block.details.get("std_raw") or {}
    M, b = np.asarray(raw.get("M", np.nan), float), np.asarray(raw.get("bias", np.nan), float)
    if name.startswith("M_") and M.shape == (3, 3):
        return float(M["xyz".index(name[2]), "xyz".index(name[3])])
    if name.startswith("bias_") and b.shape == (3,):
        return float(b["xyz".index(name[5])])
    return math.nan


def budget(sensor: str, block: SensorBlock) -> list[BudgetRow]:
    """Each entry the file determines (vocabulary.entries at T_ref, a finite std above 0) with its value, unit, u,
    U = K u, u's parts (module doc) and the temperature part (beside u, not in it). A model-based block's parts go
    from its parameters to the entries through their Jacobian J (vocabulary.linearised): the table's |J dp/dtilt|
    times the stated tilt, u_raw = u sqrt(diag(J D C D J^T) / diag(J C J^T)), D each parameter's std before the
    misfit's share over its std."""
    lin = linearised(block, AugmentedModel(block.model, block.library_effects())) if block.params else None
    rows = entries(sensor, block, terms=False, lin=lin)
    keep = [i for i, e in enumerate(rows) if is_determined(e)]
    tilt = block.details.get("table_tilt")
    if lin is not None:
        cov = np.nan_to_num(lin.cov)
        full = np.einsum("ij,jk,ik->i", lin.J, cov, lin.J)
        D = lin.raw[:, None] * cov * lin.raw[None, :]
        ratio = np.sqrt(np.einsum("ij,jk,ik->i", lin.J, D, lin.J) / np.where(full > 0, full, 1.0))
        per_arcsec = (lin.J @ np.array([tilt["per_arcsec"].get(n, 0.0) for n in lin.params]) if tilt
                      else np.full(len(rows), np.nan))
        warm = temperature_parts(block, lin)
    else:
        raw = np.array([_affine_raw(block, e.name) for e in rows])
        ratio = np.where(np.isfinite(raw), np.minimum(raw / np.array([e.std if is_determined(e) else 1.0
                                                                       for e in rows]), 1.0), 1.0)
        per_arcsec, warm = np.full(len(rows), np.nan), None
    out: list[BudgetRow] = []
    for i in keep:
        e = rows[i]
        table_part = abs(float(per_arcsec[i])) * tilt["stated_arcsec"] if tilt else None  # None: not in u
        noise: float | None = None  # None: the file does not split u (splits)
        misfit: float | None = None
        if splits(block):
            u_raw = e.std * float(ratio[i])
            noise = math.sqrt(max(u_raw ** 2 - (table_part or 0.0) ** 2, 0.0))
            misfit = math.sqrt(max(e.std ** 2 - u_raw ** 2, 0.0))
        out.append({"name": e.name, "own_name": e.own_name, "value": e.value, "unit": e.unit, "u": e.std,
                    "U": K * e.std, "noise": noise, "table": table_part, "misfit": misfit,
                    "temperature": None if warm is None else float(warm[i])})
    return out


def splits(block: SensorBlock) -> bool:
    """Whether u's budget can be split: a model that passed (u is the noise's and the table's), or a failing one
    whose file keeps the stds before the misfit's share (std_raw, or a hand session's std_noise)."""
    return block.verdict != "fails" or bool(block.details.get("std_raw") or block.details.get("std_noise"))


def coefficients(sensor: str, block: SensorBlock) -> list[list[Any]]:
    """A thermal block's temperature coefficients in the one vocabulary (vocabulary.thermal_entries: name.Tk,
    of (T - T_ref)^k, k >= 1): [name.Tk, the method's own, value, unit/degC^k, u, U]."""
    return [[e.name, e.own_name, e.value, e.unit, e.std, K * e.std] for e in entries(sensor, block)
            if TERM.search(e.name)]


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
        rows = budget(s, b)
        thermal = any(r["temperature"] is not None for r in rows)
        body.append(table(["entry", "method's name", "value", "unit", "u (std)", f"U (k = {K:g})", "u: noise",
                           "u: table", "u: model misfit"] + (["temperature: over the range, beside u"] if thermal
                                                              else []),
                          [[r["name"], r["own_name"] or "", eng_html(r["value"], value_digits(r["value"], r["u"])),
                            r["unit"], r["u"], r["U"], r["noise"], r["table"], r["misfit"]]
                           + ([r["temperature"]] if thermal else []) for r in rows]))
        terms = coefficients(s, b)
        if b.thermal and terms:
            body.append(f"<p>{s}'s temperature coefficients, of (T - T_ref), T_ref = {b.thermal['t_ref_c']:g} degC "
                        "(the value at T is the polynomial's: simucal apply evaluates it at each row's "
                        "temperature):</p>")
            body.append(table(["coefficient", "method's name", "value", "unit", "u (std)", f"U (k = {K:g})"],
                              [[n, own or "", *rest] for n, own, *rest in terms]))
    if validation:
        body.append("<h2>Validation on independent data</h2>")
        body.append(table(["sensor", "check", "n", "unit", "at nominal (rms)", "calibrated (rms)", "floor (rms)",
                           "verdict"], _validation_rows(validation)))
    else:
        body.append("<p>No validation on independent data was given (simucal validate CAL.json DATA -o "
                    "validation.json; then --validation validation.json).</p>")
    return page(f"certificate {serial}", f"Calibration certificate: unit {serial}", verdicts,
                apply_line, body=body)
