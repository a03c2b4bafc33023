"""One vocabulary for every method: a sensor's M (output per input, frame b) and bias,
with their stds, whatever the method fitted, and the method's own names beside them.

Each method fits its own parameters: the exact and linear norm fits dK_x, theta_yx, b_x (dong2018 eq. 5,
9), the multi-position method M_xx and bias_x, a stream's gyro T = M^-1 and its bias. Every calibration
file holds the same M and bias (output = M input + bias, README "the calibration file"), so two
calibrations of one unit line up entry by entry there:
- the model-based methods' stds by the parameters' covariance through M(p) and bias(p) (a central
  difference of the model's generated matrix_and_bias), scaled as the file's stds are (inflated where
  the model fails); a gyro tied to b through C_b^d takes the unification's std of M (std_M), which
  carries C_b^d's own;
- an affine block's stds are its own (M's, or T's through dM = -M dT M, entries taken independent);
- library effects keep their ids (they are the same term in every method).
Frame b is each method's: the norm methods' is the accelerometers' own (x along the x accelerometer, y
in the plane of x and y: M_acc lower triangular, dong2018 eq. 5), the multi-position method's the
table's k (its commanded attitudes). in_accelerometer_frame (simucal.compare's) puts a calibration in the
accelerometers' frame: M_acc = L Q (L lower triangular with a positive diagonal, Q a rotation: an LQ
decomposition), so M_acc in that frame is L and every other M is M Q^T; the stds go through the same map (its
Jacobian, the entries of M taken independent, as an affine block's stds are given).
"""
from __future__ import annotations

import re
from typing import Callable, Mapping, NamedTuple, Sequence, cast

import numpy as np
from numpy.typing import NDArray

from simucal.fit.augmented import AugmentedModel
from simucal.fit.rotations import skew
from simucal.fit.thermal import terms as thermal_terms
from simucal.generated.effects import EFFECTS
from simucal.io.calibration import SensorBlock
from simucal.io.records import Thermal

AXES = "xyz"
TERM = re.compile(r"\.T(\d+)$")  # a temperature term's name: its entry's, then .Tk (k >= 1; thermal_entries)


class Entry(NamedTuple):
    """One row of `simucal.parameters(cal)`, of `compare`, of the thermal page's table and the lot report's."""
    sensor: str
    name: str              # M_xx .. M_zz, bias_x .. bias_z, or a library effect's id
    value: float
    std: float
    unit: str
    own_name: str | None   # the method's own parameter for this entry (dK_x, theta_yx, b_x, M_xx, G_xz), if one
    meaning: str


def entries(sensor: str, block: SensorBlock, temperature_range_c: Sequence[float] | None = None,
            terms: bool = True, lin: Linearised | None = None) -> list[Entry]:
    """The sensor's M, bias and effects in the one vocabulary (module doc); a thermal block's also their
    temperature terms (thermal_entries; terms=False: at T_ref alone), over its calibrated range (the file's
    temperature_range_c where the block does not hold its own); lin: the block's linearised, where the caller
    has it."""
    model = AugmentedModel(block.model, block.library_effects()) if block.params else None
    M_std, b_std, own = _model_stds(lin or linearised(block, model), model) if model else _affine_stds(block)
    if block.details.get("std_M") is not None:  # the gyro in b: C_b^d's uncertainty included
        M_std = np.asarray(block.details["std_M"], float)
    elif block.C_b_model is not None and block.params:  # tied to b by a C_b^d without a std (dong2018 eq. 25-27)
        M_std = np.full((3, 3), np.nan)
    at_ref = f" (at T_ref = {block.thermal['t_ref_c']:.4g} degC)" if block.thermal else ""
    rows = [Entry(sensor, LABELS[3 * i + j], float(block.M[i, j]), float(M_std[i, j]), "1", own.get(LABELS[3 * i + j]),
                  MEANINGS[3 * i + j] + at_ref) for i in range(3) for j in range(3)]
    rows += [Entry(sensor, LABELS[9 + i], float(block.bias[i]), float(b_std[i]), block.bias_unit,
                   own.get(LABELS[9 + i]), MEANINGS[9 + i] + at_ref) for i in range(3)]
    for eid, v in block.effects.items():  # a model file's own term is named by itself
        rows.append(Entry(sensor, eid, float(v.value), float(v.std), v.unit,
                          eid if v.term_of else EFFECTS[eid].parameter, v.meaning))
    if model and block.thermal and terms:
        rows += thermal_entries(sensor, block, model, own, temperature_range_c)
    return rows


Stds = tuple[NDArray[np.float64], NDArray[np.float64], dict[str, str]]  # of M, of bias, own names
LABELS = [f"M_{AXES[i]}{AXES[j]}" for i in range(3) for j in range(3)] + [f"bias_{c}" for c in AXES]
MEANINGS = [f"row {AXES[i]}, column {AXES[j]} of M: output {AXES[i]} per input {AXES[j]}" for i in range(3)
            for j in range(3)] + [f"{c} output at zero input" for c in AXES]


def _matrix_and_bias(model: AugmentedModel, block: SensorBlock) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """p -> (M C as 9 entries, bias): the block's M and bias at parameters p (..., n), in its frame b, (..., 12)."""
    def mb(q: NDArray[np.float64]) -> NDArray[np.float64]:
        M, b = model.matrix_and_bias(q)
        lead = np.shape(q)[:-1]
        return np.concatenate([(np.asarray(M) @ block.C).reshape(*lead, 9), np.asarray(b).reshape(*lead, 3)], -1)
    return mb


class Linearised(NamedTuple):
    """A model-based block's entries (M C's 9, bias's 3, then its effects, in block.effects' order) as a linear
    function of its own parameters at their values: entries(p + dp) = entries(p) + J dp."""
    params: list[str]          # the model's parameters, J's columns
    J: NDArray[np.float64]     # (12 + effects, parameters)
    cov: NDArray[np.float64]   # the parameters' covariance, scaled to the file's stds (inflated where the model fails)
    raw: NDArray[np.float64]   # each parameter's std before the misfit's inflation over its std (<= 1; 1: none)


def linearised(block: SensorBlock, model: AugmentedModel) -> Linearised:
    """The block's Linearised: J a central difference of the model's M(p) C and bias(p) (identity rows for the
    effects); the covariance the file's, scaled to its stds, and where the table's stated tilt is in them
    (turntable/tilt.py: s, each parameter's shift by the tilt, joined the stds in quadrature) s s^T, one angle
    moving them all; where the file holds no covariance (a warm-up's, each axis alone) its stds taken
    independent."""
    names = list(model.params)
    p = np.array([block.params[n] for n in names])
    filed = np.array([block.std.get(n, np.nan) for n in names], float)
    tilt = block.details.get("table_tilt")
    s = (np.array([tilt["per_arcsec"].get(n, 0.0) for n in names]) * tilt["stated_arcsec"] if tilt
         else np.zeros(len(names)))
    cov_block = block.details.get("covariance")
    if not (cov_block and all(n in cov_block["names"] for n in names)) and block.thermal:
        cov_block = block.thermal.get("covariance")  # a joint thermal fit's: its k = 0 terms, the parameters at T_ref
        s = np.zeros(len(names))  # whose covariance holds s s^T already (tilt.add_tilt_thermal)
    if cov_block and all(n in cov_block["names"] for n in names):
        k = [cov_block["names"].index(n) for n in names]
        cov = np.asarray(cov_block["matrix"], float)[np.ix_(k, k)]
        own = np.sqrt(np.maximum(np.diag(cov), 0.0))
        ratio = np.sqrt(np.maximum(filed ** 2 - s ** 2, 0.0))[own > 0] / own[own > 0]  # the fit's share of the std
        ratio = ratio[np.isfinite(ratio)]
        cov = cov * (float(np.median(ratio)) ** 2 if ratio.size else 1.0) + np.outer(s, s)
    else:
        cov = np.diag(filed ** 2)
        own = np.nan_to_num(filed)
    held = filed == 0  # a parameter the file holds fixed: nothing of it in any entry
    cov[held, :], cov[:, held] = 0.0, 0.0
    steps = np.maximum(own * 1e-3, 1e-9)
    at = _matrix_and_bias(model, block)(np.concatenate([p + np.diag(steps), p - np.diag(steps)]))  # one batch
    J = ((at[:len(p)] - at[len(p):]) / (2 * steps)[:, None]).T
    effects = np.array([[float(n == eid) for n in names] for eid in block.effects]).reshape(-1, len(names))
    before = block.details.get("std_raw") or block.details.get("std_noise") or {}  # the stds before the misfit's
    raw = np.array([min(v / std, 1.0) if isinstance(v := before.get(n), (int, float)) and std > 0 else 1.0
                    for n, std in zip(names, filed)])
    return Linearised(names, np.vstack([J, effects]), cov, raw)


def _model_stds(lin: Linearised, model: AugmentedModel) -> Stds:
    """(std of M (3, 3), of bias (3,), {entry: the parameter that moves it most}) of a model-based block: its
    parameters' covariance through M(p) and bias(p) (lin: the block's linearised)."""
    J = lin.J[:12]
    std = np.sqrt(np.maximum(_propagated(J, lin.cov), 0.0))
    own = {}
    for j, n in enumerate(lin.params[:len(model.base.params)]):  # each parameter to the entry it moves most
        at = int(np.argmax(np.abs(J[:, j])))
        if np.abs(J[at, j]) > 0 and LABELS[at] not in own:
            own[LABELS[at]] = n
    return std[:9].reshape(3, 3), std[9:], own


def is_determined(e: Entry) -> bool:
    """Whether the file determines an entry: a finite std above 0 (an entry the model fixes, as the norm methods'
    M_xy, has 0; one tied through a C_b^d without a std, NaN)."""
    return bool(np.isfinite(e.std) and e.std > 0)


def covariance(sensor: str, block: SensorBlock, phi_std_rad: Sequence[float] | None = None
               ) -> tuple[list[Entry], NDArray[np.float64]]:
    """The entries at T_ref (entries, terms=False) that the file determines, and their covariance: a model-based
    block's linearised J C J^T; an affine block's stds squared (taken independent, as they are given). A gyro tied
    to b through C_b^d = C (I + [phi x]) (dong2018 eq. 25-27 derived exactly, turntable/unification.py) adds to
    its M's block G diag(phi_std_rad^2) G^T, G_k = M_d C [e_k x] the change of M by phi_k (phi_std_rad: the file's
    unification std_rad; phi taken independent of the gyro's parameters: the diagonal agrees with the file's std_M
    within 0.2 % on the simulated table); what std_M holds beyond it (a tilt's share, or all of it without
    phi_std_rad) is taken independent, entry by entry."""
    if not block.params:
        rows = entries(sensor, block, terms=False)
        keep = [i for i, e in enumerate(rows) if is_determined(e)]
        return [rows[i] for i in keep], np.diag([rows[i].std ** 2 for i in keep])
    lin = linearised(block, AugmentedModel(block.model, block.library_effects()))
    rows = entries(sensor, block, terms=False, lin=lin)
    keep = [i for i, e in enumerate(rows) if is_determined(e)]
    C = lin.J @ np.nan_to_num(lin.cov) @ lin.J.T
    if block.details.get("std_M") is not None:
        if phi_std_rad is not None and block.details.get("M_in_d") is not None:
            M_d = np.asarray(block.details["M_in_d"], float)
            G = np.column_stack([(M_d @ block.C @ skew(e)).ravel() for e in np.eye(3)])
            C[:9, :9] += G @ np.diag(np.asarray(phi_std_rad, float) ** 2) @ G.T
        beyond = np.asarray(block.details["std_M"], float).ravel() ** 2 - np.diag(C)[:9]
        C[range(9), range(9)] += np.maximum(beyond, 0.0)
    return [rows[i] for i in keep], C[np.ix_(keep, keep)]


def _propagated(J: NDArray[np.float64], cov: NDArray[np.float64]) -> NDArray[np.float64]:
    """diag(J cov J^T), where a std the file does not know (NaN) spoils only the entries it moves."""
    unknown = ~np.isfinite(np.diag(cov))
    var = np.einsum("ij,jk,ik->i", J, np.nan_to_num(cov), J)
    var[np.any(J[:, unknown] != 0, axis=1)] = np.nan
    return cast("NDArray[np.float64]", var)


def thermal_entries(sensor: str, block: SensorBlock, model: AugmentedModel, own: Mapping[str, str],
                    temperature_range_c: Sequence[float] | None) -> list[Entry]:
    """A thermal block's M entries, biases and library effects over temperature in the one vocabulary: name.Tk,
    the coefficient of (T - T_ref)^k in unit/degC^k. M and bias are not linear in the parameters, so their
    polynomials are the least-squares fit of M(p(T)) and bias(p(T)), p(T) every parameter's polynomial, at
    Chebyshev nodes over the calibrated range, of the block's highest degree and held to M and bias at T_ref;
    their stds through the Jacobian of that map by every coefficient, with the coefficients' covariance where the
    block holds it (fit/thermal.std_at's, else their stds taken independent). Entries that no temperature term
    moves are left out."""
    thermal = block.thermal
    assert thermal is not None
    fits = thermal.get("parameters", {})
    names = list(model.params)
    degree = max((len(fits[n]["coefficients"]) - 1 for n in names if n in fits), default=0)
    span = thermal.get("temperature_range_c") or temperature_range_c or thermal.get("plateaus_c")
    if degree < 1 or not span or max(span) <= min(span):
        return []
    t_ref = float(thermal["t_ref_c"])
    labels, x0, x_std, cov = _coefficients(thermal, names)
    lo, hi = min(span) - t_ref, max(span) - t_ref
    nodes = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(2 * degree + 3) + 0.5) / (2 * degree + 3))
    V = np.vander(nodes, degree + 1, increasing=True)[:, 1:]
    fitted = np.array([n in fits for n in names])
    p_fixed = np.where(fitted, 0.0, [block.params[n] for n in names])  # a parameter without a polynomial: its value
    S = np.array([[float(m == n) for m, _ in labels] for n in names])  # p(dT) = p_fixed + S (x dT^k)
    powers = np.array([k for _, k in labels])
    mb = _matrix_and_bias(model, block)

    def terms(x: NDArray[np.float64]) -> NDArray[np.float64]:
        """(degree, 12): the coefficients of (T - T_ref)^1.. of M C's entries and the bias, given coefficients x."""
        G = np.array([mb(p_fixed + S @ (x * dT ** powers)) for dT in nodes]) - mb(p_fixed + S @ (x * 0.0 ** powers))
        return cast("NDArray[np.float64]", np.linalg.lstsq(V, G, rcond=None)[0])
    a = terms(x0)
    steps = np.maximum(np.nan_to_num(x_std) * 1e-3, 1e-12)
    J = np.stack([(terms(x0 + s * e) - terms(x0 - s * e)) / (2 * s) for s, e in zip(steps, np.eye(len(x0)))], -1)
    rows = []
    for k in range(1, degree + 1):
        var = _propagated(J[k - 1], cov)
        for i, label in enumerate(LABELS):
            if np.any(J[k - 1, i] != 0):
                unit = "1" if i < 9 else block.bias_unit
                rows.append(Entry(sensor, f"{label}.T{k}", float(a[k - 1, i]), float(np.sqrt(max(var[i], 0.0))),
                                  f"{unit}/degC" + (f"^{k}" if k > 1 else ""),
                                  f"{own[label]}.T{k}" if label in own else None,
                                  f"{MEANINGS[i]}: coefficient of (T - T_ref)^{k}"))
    for eid, v in block.effects.items():  # an effect's terms are its own, named by its id in both vocabularies
        rows += [Entry(sensor, term, c, e, unit, term, f"{v.meaning}: coefficient of (T - T_ref)^{k}")
                 for term, k, c, e, unit in thermal_terms(thermal, eid, v.unit)]
    return rows


def _coefficients(thermal: Thermal, names: Sequence[str]) -> tuple[list[tuple[str, int]], NDArray[np.float64],
                                                                     NDArray[np.float64], NDArray[np.float64]]:
    """The polynomials of the parameters `names` that have one: their (name, k) labels, coefficients, stds and
    covariance (the block's where it holds it, scaled to the file's stds, inflated by the misfit where the model
    fails; else the stds taken independent)."""
    fits = thermal.get("parameters", {})
    labels = [(n, k) for n in names if n in fits for k in range(len(fits[n]["coefficients"]))]
    x0 = np.array([fits[n]["coefficients"][k] for n, k in labels], float)
    x_std = np.array([fits[n]["std"][k] for n, k in labels], float)
    cov_block = thermal.get("covariance")
    keys = [n if k == 0 else f"{n}.T{k}" for n, k in labels]
    if cov_block and all(key in cov_block["names"] for key in keys):
        at = [cov_block["names"].index(key) for key in keys]
        cov = np.asarray(cov_block["matrix"], float)[np.ix_(at, at)]
        raw = np.sqrt(np.maximum(np.diag(cov), 0.0))
        scale = np.where((raw > 0) & np.isfinite(x_std), x_std / np.where(raw > 0, raw, 1.0), 1.0)
        cov = cov * np.outer(scale, scale)
    else:
        cov = np.diag(x_std ** 2)
    return labels, x0, x_std, cov


def temperature_parts(block: SensorBlock, lin: Linearised) -> NDArray[np.float64] | None:
    """What using each entry (lin.J's rows) anywhere in the calibrated temperature range adds to its u at T_ref:
    sqrt(max_T u(T)^2 - u(T_ref)^2), u(T)^2 = diag(J S(T) C S(T)^T J^T), S(T) the polynomials' (T - T_ref)^k and
    C their coefficients' covariance (_coefficients); J at T_ref. None without a temperature model (the values hold
    at the data's temperatures)."""
    th = block.thermal
    if not th or "temperature_range_c" not in th:
        return None
    labels, _, _, cov = _coefficients(th, lin.params)
    lo, hi = th["temperature_range_c"]
    var = []
    for dT in np.linspace(lo, hi, 101) - th["t_ref_c"]:
        S = np.array([[float(m == n) * dT ** k for m, k in labels] for n in lin.params]).reshape(len(lin.params), -1)
        JS = lin.J @ S
        var.append(np.einsum("ij,jk,ik->i", JS, np.nan_to_num(cov), JS))
    S0 = np.array([[float(m == n and k == 0) for m, k in labels] for n in lin.params]).reshape(len(lin.params), -1)
    at_ref = np.einsum("ij,jk,ik->i", lin.J @ S0, np.nan_to_num(cov), lin.J @ S0)
    return cast("NDArray[np.float64]", np.sqrt(np.maximum(np.max(var, axis=0) - at_ref, 0.0)))


def _affine_stds(block: SensorBlock) -> Stds:
    """(std of M, of bias, own names) of an affine block: M's own, or a stream gyro's T's through M = T^-1."""
    b_std = np.asarray(block.std.get("bias", np.full(3, np.nan)), float)
    if "T" in block.std:
        T_var = np.asarray(block.std["T"], float) ** 2
        M = block.M
        M_var = np.einsum("ik,lj,kl->ij", M ** 2, M ** 2, T_var)  # dM = -M dT M, entries of T independent
        return np.sqrt(M_var), b_std, {f"bias_{c}": f"bias_{c}" for c in AXES}
    M_std = np.asarray(block.std.get("M", np.full((3, 3), np.nan)), float)
    own = {f"M_{AXES[i]}{AXES[j]}": f"M_{AXES[i]}{AXES[j]}" for i in range(3) for j in range(3)}
    return M_std, b_std, {**own, **{f"bias_{c}": f"bias_{c}" for c in AXES}}


def in_accelerometer_frame(rows: list[Entry]) -> list[Entry]:
    """rows (one calibration's entries) with every M in the accelerometers' frame (module doc): M_acc Q^T = L
    lower triangular, the gyro's M Q^T; stds mapped by the Jacobian of that map (entries independent)."""
    by = {(e.sensor, e.name): e for e in rows}
    if ("acc", "M_xx") not in by:
        return rows
    M = {s: np.array([[by[(s, f"M_{a}{b}")].value for b in AXES] for a in AXES]) for s in ("acc", "gyro")
         if (s, "M_xx") in by}
    sd = {s: np.array([[by[(s, f"M_{a}{b}")].std for b in AXES] for a in AXES]) for s in M}
    if np.abs(np.triu(M["acc"], 1)).max() < 1e-12:  # already the accelerometers' own frame
        return rows

    def mapped(A_acc: NDArray[np.float64], A: NDArray[np.float64]) -> NDArray[np.float64]:
        return A @ _rotation_to_lower(A_acc).T
    out = dict(by)
    for s in M:
        value = mapped(M["acc"], M[s])
        var = np.zeros((3, 3))
        for src in {"acc", s}:  # the map's Jacobian by each entry of the matrices it reads
            for i in range(3):
                for j in range(3):
                    h = max(abs(sd[src][i, j]) * 1e-3, 1e-12) if np.isfinite(sd[src][i, j]) else 1e-12
                    d = np.zeros((3, 3))
                    d[i, j] = h
                    acc_p, acc_m = M["acc"] + (d if src == "acc" else 0), M["acc"] - (d if src == "acc" else 0)
                    own_p, own_m = ((acc_p, acc_m) if s == "acc"
                                    else (M[s] + (d if src == s else 0), M[s] - (d if src == s else 0)))
                    var += ((mapped(acc_p, own_p) - mapped(acc_m, own_m)) / (2 * h) * sd[src][i, j]) ** 2
        for i in range(3):
            for j in range(3):
                key = (s, f"M_{AXES[i]}{AXES[j]}")
                out[key] = by[key]._replace(value=float(value[i, j]), std=float(np.sqrt(var[i, j])))
    return list(out.values())


def _rotation_to_lower(M_acc: NDArray[np.float64]) -> NDArray[np.float64]:
    """Q of M_acc = L Q (L lower triangular, positive diagonal; Q a rotation): a QR of M_acc^T."""
    Qt, R = np.linalg.qr(M_acc.T)
    signs = np.sign(np.diag(R))
    return cast("NDArray[np.float64]", (Qt * signs).T)
