"""dong2018 eq. 17, 21, 25-27 and the norm expansion, term by term at the section-4 values.

For every printed row, each additive term of the printed formula and of the
derived first order is matched; each term's size is its largest value at the
paper's positions (Table 2: (alpha, gamma) for eq. 17, alpha = 0, 90 deg for
eq. 21) with the section-4 values (given by the caller: the simulator's
defaults). Terms printed but not derived are "should not be there", terms
derived but not printed are "neglected" (or lost to the OCR, where the row is
truncated), and the printed row is compared with the exact outputs: static
outputs with every table error, or for rate runs the mean over a whole
revolution computed numerically (720 steps of gamma), tilt and Earth rate
included. The solutions (eq. 25-27) are evaluated on those exact outputs and
compared with the true angles; the share of the error that the scale-factor
products dK * angle make is the change when dK is set to zero.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from . import norm, table, unify
from .frames import UP, lat, w_T, w_e
from .models.baseline import ACC_BASELINE, GYRO_BASELINE


@dataclass
class TermRow:
    eq: str
    row: str
    term: str
    size: float
    unit: str
    verdict: str


def _terms(expr):
    return list(sp.Add.make_args(sp.expand(expr)))


def _size(expr, positions, subs):
    """Largest |expr| over the positions, with subs (section-4 values) applied."""
    vals = [abs(float(sp.N(expr.subs(p).subs(subs)))) for p in positions]
    return max(vals)


def section4_subs(values, sensor):
    """{symbol: value} of the section-4 values for one sensor's model and the table."""
    model = ACC_BASELINE if sensor == "acc" else GYRO_BASELINE
    subs = {s: values[sensor][str(s)] for s in model.params}
    subs.update(zip(table.theta4, values["theta4"]))
    subs.update(zip(table.lambda4, values["lambda4"]))
    subs.update({table.tilt_x: values["tilt"][0], table.tilt_y: values["tilt"][1],
                 table.nonperp_om: values["nonperp"][0], table.nonperp_mi: values["nonperp"][1],
                 table.d_gamma: values["zero"][0], table.d_alpha: values["zero"][1], table.d_beta: values["zero"][2],
                 w_T: values["w_T_dph"], w_e: values["w_e_dph"], lat: np.radians(values["latitude_deg"])})
    return subs


@functools.cache
def _exact_outputs(sensor):
    """(f, symbols): a sensor's exact outputs with every table error, inner angle zero, as one numpy function
    f(alpha, gamma, *values of symbols). Derived and printed once: substituting the section-4 values into the
    symbolic outputs for each variant took seconds per call."""
    if sensor == "acc":
        model, vector = ACC_BASELINE, table.C_b_k().T * table.C_k_n().T * UP
    else:
        model = GYRO_BASELINE
        vector = table.C_d_k().T * table.C_k_n().T * (table.earth_rate_n() + w_T * table.outer_axis_n())
    out = model.output().subs(dict(zip(model.inputs, vector)), simultaneous=True).subs({table.beta: 0})
    symbols = sorted(out.free_symbols - {table.alpha, table.gamma}, key=str)
    return sp.lambdify((table.alpha, table.gamma, *symbols), list(out), "numpy", cse=True), symbols


def _exact(sensor, values, alpha, gamma):
    """The sensor's exact outputs, (3,) or (3, n), at the section-4 values."""
    f, symbols = _exact_outputs(sensor)
    subs = section4_subs(values, sensor)
    out = f(alpha, gamma, *(float(subs[s]) for s in symbols))
    return np.array([np.broadcast_to(np.asarray(o, float), np.shape(gamma)) for o in out])


def exact_static_acc(values, positions):
    """Exact accelerometer outputs (g) at (alpha, gamma), inner at zero, every table error."""
    return [_exact("acc", values, float(p[table.alpha]), float(p[table.gamma])) for p in positions]


def exact_mean_gyro(values, alphas_deg, k=720):
    """Mean gyro outputs (deg/h) over one whole revolution of the outer axis at each middle angle."""
    gam = np.arange(k) * 2 * np.pi / k
    return [_exact("gyro", values, np.radians(a), gam).mean(axis=1) for a in alphas_deg]


def _row_terms(rep, eq, row, printed, derived, positions, subs, unit, printed_only_why, truncated=False):
    """Match printed and derived first order monomial by monomial (coefficients compared)."""
    P, D = sp.expand(printed).as_coefficients_dict(), sp.expand(derived).as_coefficients_dict()
    seen = printed.free_symbols
    for m in list(P) + [m for m in D if m not in P]:
        p, d = P.get(m, 0), D.get(m, 0)
        if p == d:
            rep.append(TermRow(eq, row, str(p * m), _size(p * m, positions, subs), unit, "agrees"))
            continue
        if d != 0 and p != 0:
            rep.append(TermRow(eq, row, str(d * m), _size(d * m, positions, subs), unit, "agrees"))
        if p != d and p != 0:
            extra = (p - d) * m
            rep.append(TermRow(eq, row, str(extra), _size(extra, positions, subs), unit, printed_only_why(extra)))
        elif d != 0:
            # in a truncated row, a term whose error quantity the visible part never shows was lost
            lost = truncated and not ((m.free_symbols - {w_T, w_e, lat, table.alpha, table.gamma}) & seen)
            rep.append(TermRow(eq, row, str(d * m), _size(d * m, positions, subs), unit,
                               "OCR damage: lost with the rest of the row" if lost else
                               "neglected term (in the first-order derivation, not printed)"))


def _no_gimbal(values):
    return {**values, "tilt": [0.0, 0.0], "nonperp": [0.0, 0.0], "zero": [0.0, 0.0, 0.0]}


def _row_vs_exact(rep, eq, row, printed, positions, subs, exact, exact_ideal, unit, truncated=False):
    """The printed row against the exact outputs, the share of the table's gimbal errors split off."""
    at = [float(sp.N(printed.subs(p).subs(subs))) for p in positions]
    diff = max(abs(a - e) for a, e in zip(at, exact))
    gimbal = max(abs(e - i) for e, i in zip(exact, exact_ideal))
    rep.append(TermRow(eq, row, "printed row - exact output" + (" (mean over a revolution)" if eq == "21" else ""),
                       diff, unit, "OCR damage and the errors above" if truncated else
                       f"neglected term: the table's gimbal errors (tilt, non-perpendicularity, zero errors) make "
                       f"{gimbal:.3g} {unit} of it, the rest is second order" if diff < 10 * max(gimbal, 1e-12) else
                       "error in the paper (see the terms above)"))


def eq17(rep, values, printed17):
    """Accelerometer outputs at the Table 2 positions: printed rows vs derived first order vs exact."""
    lin = unify.acc_outputs(ACC_BASELINE)
    pos = [{table.alpha: sp.rad(a), table.gamma: sp.rad(c)} for a, c in unify.TABLE2]
    subs = section4_subs(values, "acc")
    exact, ideal = exact_static_acc(values, pos), exact_static_acc(_no_gimbal(values), pos)
    for i, ax in enumerate("xyz"):
        _row_terms(rep, "17", f"N_{ax}^a", printed17[i], lin.first[i], pos, subs, "g",
                   lambda t: "error in the paper: not in the derivation")
        _row_vs_exact(rep, "17", f"N_{ax}^a", printed17[i], pos, subs, [e[i] for e in exact],
                      [e[i] for e in ideal], "g")


def eq21(rep, values, printed21):
    """Gyro mean outputs at alpha = 0, 90 deg: printed rows vs derived first order vs the exact mean."""
    lin = unify.gyro_outputs(GYRO_BASELINE)
    pos = [{table.alpha: sp.rad(a)} for a in unify.GYRO_ALPHAS]
    subs = section4_subs(values, "gyro")
    exact, ideal = exact_mean_gyro(values, unify.GYRO_ALPHAS), exact_mean_gyro(_no_gimbal(values), unify.GYRO_ALPHAS)

    def why(t):
        if t.has(sp.cos(lat)):
            return ("error in the paper: the horizontal Earth rate turns with gamma and averages out over a "
                    "whole revolution (eq. 19 drops the outer-axis rotation)")
        return "error in the paper or OCR: a term the derivation does not have (double-counted)"
    for i, (ax, (text, truncated)) in enumerate(zip("xyz", printed21)):
        _row_terms(rep, "21", f"N_{ax}^g", text, lin.first[i], pos, subs, "deg/h", why, truncated)
        _row_vs_exact(rep, "21", f"N_{ax}^g", text, pos, subs, [e[i] for e in exact], [e[i] for e in ideal], "deg/h",
                      truncated)


def solutions(rep, values, printed25, printed27):
    """eq. 25-27 on the exact outputs against the true angles; the dK * angle products' share."""
    pos = [{table.alpha: sp.rad(a), table.gamma: sp.rad(c)} for a, c in unify.TABLE2]
    def truth(v):
        return {**dict(zip(["theta_x4", "theta_y4", "theta_z4"], v["theta4"])),
                **dict(zip(["lambda_x4", "lambda_y4", "lambda_z4"], v["lambda4"])),
                "tilt_x": v["tilt"][0], "tilt_y": v["tilt"][1]}
    no_dK = {**values, "acc": {**values["acc"], "dK_x": 0.0, "dK_y": 0.0, "dK_z": 0.0},
             "gyro": {**values["gyro"], "dK_x": 0.0, "dK_y": 0.0, "dK_z": 0.0}}
    variants = (values, no_dK, _no_gimbal(values))
    acc_out = {id(v): exact_static_acc(v, pos) for v in variants}
    gyro_out = {id(v): exact_mean_gyro(v, unify.GYRO_ALPHAS) for v in variants}

    def acc_eval(expr, vals):
        out = acc_out[id(vals)]
        N = {sp.Symbol(f"N{i + 1}{ax}"): out[i][j] for i in range(4) for j, ax in enumerate("xyz")}
        return float(sp.N(expr.subs(N).subs({s: vals["acc"][str(s)] for s in ACC_BASELINE.params})))

    def gyro_eval(expr, vals):
        out = gyro_out[id(vals)]
        N = {sp.Symbol(f"N{i + 1}{ax}"): out[i][j] for i in range(2) for j, ax in enumerate("xyz")}
        return float(sp.N(expr.subs(N).subs({s: vals["gyro"][str(s)] for s in GYRO_BASELINE.params})
                          .subs({w_T: vals["w_T_dph"], w_e: vals["w_e_dph"], lat: np.radians(vals["latitude_deg"])})))
    for eq, items, ev in (("25-26", printed25, acc_eval), ("27", printed27, gyro_eval)):
        for label, target, expr, note in items:
            err = [ev(expr, v) - truth(v)[target] for v in variants]
            parts = (f"neglected: the products dK * angle make {abs(err[0] - err[1]):.2g} rad, "
                     f"the table's gimbal errors {abs(err[0] - err[2]):.2g} rad")
            rep.append(TermRow(eq, label, f"{expr} - true {target}", abs(err[0]), "rad",
                               f"{note}; {parts}" if note else parts))


def norm_constant(rep, values):
    """The constant the first-order norm expansion drops (eq. 6-7 and 10-11): sum b_i^2 / (1 + dK_i)^2,
    and its effect on the fitted scale (the regression absorbs it into K_1..K_3)."""
    for sensor, model, rho in (("acc", ACC_BASELINE, 1.0),
                               ("gyro", GYRO_BASELINE, values["w_T_dph"] + values["w_e_dph"] *
                                np.sin(np.radians(values["latitude_deg"])))):
        reg = norm.derive_norm_regression(model)
        N = sp.Matrix(sp.symbols("N_x N_y N_z", real=True))
        exact_sq = sum(e ** 2 for e in norm.exact_input(model))
        dropped = (exact_sq - reg.norm_sq_first).subs({n: 0 for n in N})  # = |(I + L)^-1 b|^2
        subs = {s: values[sensor][str(s)] for s in model.params}
        c = float(sp.N(dropped.subs(subs)))
        unit = "g^2" if sensor == "acc" else "(deg/h)^2"
        rep.append(TermRow("6-7" if sensor == "acc" else "10-11", f"|{sensor} input|^2 expansion",
                           "dropped constant |(I + L)^-1 b|^2", abs(c), unit,
                           f"neglected term: relative to rho^2 = {rho ** 2:.6g} it is {abs(c) / rho ** 2:.2g}, "
                           "which the regression takes into the scale factors K_1..K_3 (a scale error of about "
                           f"{abs(c) / rho ** 2 / 2:.2g})"))


def table2_rank(rep):
    """Are the Table 2 positions enough? Rank of the first-order system for the unknowns."""
    for name, lin, pos, unknowns in (
            ("theta_4, tilt from Table 2 (eq. 25-26)", unify.acc_outputs(ACC_BASELINE),
             [{table.alpha: sp.rad(a), table.gamma: sp.rad(c)} for a, c in unify.TABLE2], unify.ACC_UNIFY_UNKNOWNS),
            ("lambda_4 from alpha = 0, 90 deg (eq. 27)", unify.gyro_outputs(GYRO_BASELINE),
             [{table.alpha: sp.rad(a)} for a in unify.GYRO_ALPHAS], unify.GYRO_UNIFY_UNKNOWNS)):
        rows = [lin.first.subs(p)[i] for p in pos for i in range(3)]
        A = sp.Matrix([[sp.diff(r, u) for u in unknowns] for r in rows])
        A_num = np.array(A.subs({w_T: 36000.0, w_e: 15.04107, lat: np.radians(45.0)})
                         .subs({s: 0 for s in A.free_symbols}), float)
        rank = int(np.linalg.matrix_rank(A_num))
        s = np.linalg.svd(A_num / np.abs(A_num).max(), compute_uv=False)
        rep.append(TermRow("Table 2", name, f"rank {rank} of {len(unknowns)} unknowns, condition {s[0] / s[-1]:.3g}",
                           float(rank), "", "agrees: sufficient" if rank == len(unknowns) else
                           f"error in the paper: leaves {len(unknowns) - rank} combination(s) unobservable"))
