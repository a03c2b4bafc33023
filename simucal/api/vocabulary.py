"""`simucal.parameters` and `simucal.compare`: the one vocabulary (simucal/report/vocabulary.py: a
sensor's M, bias and effects with their stds whatever the method, its own names beside them) as the API's tables."""
from __future__ import annotations

from typing import Any, Mapping, NamedTuple, cast

import numpy as np

from simucal.arguments import checked
from simucal.api.tables import table
from simucal.errors import InputError
from simucal.fit.augmented import AugmentedModel
from simucal.fit.thermal import terms as thermal_terms
from simucal.io.calibration import Calibration, SensorBlock
from simucal.report.vocabulary import Entry, entries, in_accelerometer_frame


@checked
def compare(calibrations: Mapping[str, Calibration]) -> Any:
    """Calibrations of one unit side by side in the one vocabulary: a row per sensor and entry (M_xx ..
    bias_z, effects), for each calibration its value and std (columns ``LABEL`` and ``LABEL std``), and
    the unit; every M in the accelerometers' own frame (module doc), so that the misalignments of a
    method that works in the table's frame line up with the norm methods'.

    Parameters
    ----------
    calibrations : mapping of str to Calibration
        ``{label: calibration}``, e.g. ``{"exact": cal1, "multiposition": cal2}``.

    Returns
    -------
    pandas.DataFrame or list of dict
        A DataFrame indexed by (sensor, name) where pandas is installed, else the rows as dicts.

    Examples
    --------
    >>> import simucal
    >>> ms = simucal.simulate(seed=1)
    >>> t = simucal.compare({m: simucal.calibrate(ms, method=m) for m in ("exact", "multiposition")})
    >>> d = t["exact"] - t["multiposition"]
    >>> bool((d.abs() < 4 * t["multiposition std"]).loc["acc"].all())
    True
    """
    rows: dict[tuple[str, str], dict[str, Any]] = {}
    for label, cal in calibrations.items():
        for e in in_accelerometer_frame([e for s, block in cal.blocks() for e in entries(s, block)]):
            row = rows.setdefault((e.sensor, e.name), {"sensor": e.sensor, "name": e.name, "unit": e.unit})
            row[label], row[f"{label} std"] = e.value, e.std
    out = list(rows.values())
    try:
        import pandas as pd
    except ImportError:
        return out
    return pd.DataFrame(out).set_index(["sensor", "name"])


class Parameter(NamedTuple):
    """One row of `simucal.parameters(cal, vocabulary="own")`."""
    name: str
    sensor: str
    value: float
    std: float
    unit: str
    meaning: str


def _model_rows(sensor: str, block: SensorBlock) -> list[Parameter]:
    """Each parameter at T_ref; for a thermal calibration also each coefficient of its polynomial
    in (T - T_ref) (name.T1, name.T2, ...), in unit per degC^k."""
    model = AugmentedModel(block.model, block.library_effects())
    rows = []
    for n, u, m in zip(model.params, model.param_units, model.meanings):
        unit = block.param_units.get(n, u)
        rows.append(Parameter(n, sensor, float(block.params[n]), float(cast(float, block.std.get(n, np.nan))), unit,
                              m + (f" (at T_ref = {block.thermal['t_ref_c']:.4g} degC)" if block.thermal else "")))
        rows += [Parameter(term, sensor, c, e, term_unit, f"{m}: coefficient of (T - T_ref)^{k}")
                 for term, k, c, e, term_unit in thermal_terms(block.thermal, n, unit)]
    return rows


def _affine_rows(sensor: str, block: SensorBlock) -> list[Parameter]:
    """An affine block (multiposition, a stream's gyro): M's (or the fitted T's) entries and the bias,
    their stds where the method gave them (as M- and bias-shaped arrays)."""
    name, A = "M", block.M
    if "T" in block.std and "T" in block.details:  # a stream's gyro fits T = M^-1 (input = T (output - bias))
        name, A = "T", np.asarray(block.details["T"], float)
    sd = np.asarray(block.std.get(name, np.full((3, 3), np.nan)), float)
    b_sd = np.asarray(block.std.get("bias", np.full(3, np.nan)), float)
    per = "output {} per input {}" if name == "M" else "input {} per output {} (T = M^-1)"
    rows = [Parameter(f"{name}_{'xyz'[i]}{'xyz'[j]}", sensor, float(A[i, j]), float(sd[i, j]), "1",
                      f"row {'xyz'[i]}, column {'xyz'[j]} of {name}: " + per.format('xyz'[i], 'xyz'[j]))
            for i in range(3) for j in range(3)]
    return rows + [Parameter(f"bias_{c}", sensor, float(block.bias[i]), float(b_sd[i]), block.bias_unit,
                             f"{c} output at zero input") for i, c in enumerate("xyz")]


@checked
def parameters(cal: Calibration, vocabulary: str = "common", units: str = "spec") -> Any:
    """Every sensor's parameters of calibration `cal` as a table, in one vocabulary for every method: each
    sensor's M entries (M_xx .. M_zz: output per input, frame b) and bias (bias_x .. bias_z) with their stds,
    the library effects by their ids, and the method's own name for each (``own_name``: dK_x, theta_yx, b_x
    for dong2018's methods; M_xx, bias_x for the multi-position method). A thermal calibration gives them
    at T_ref and below them each one's coefficient of (T - T_ref)^k that the data hold (``bias_x.T1`` in
    unit/degC, ``M_yy.T2`` in 1/degC^2), M and bias through the model of every parameter's polynomial.
    `simucal.compare` sets calibrations side by side so.

    With ``vocabulary="own"``, the method's own parameters instead: `Parameter` rows ``(name, sensor,
    value, std, unit, meaning)``; an affine model (the multi-position method, a stream's gyro) gives M's
    entries (or T's, T = M^-1) and the bias, a thermal calibration each parameter's coefficients
    (``b_x.T1``). std is the file's (inflated by the misfit where the model fails its test).

    With ``units="si"``, each value and std with its unit in SI (a bias in g in m/s^2 with the set's
    gravity_mps2 where its meta.json is at hand, else 9.80665; deg/h in rad/s; a scale factor or an angle
    unchanged), as `simucal calibrate --units si` prints them; the calibration file keeps the spec's.

    Parameters
    ----------
    cal : Calibration
        A calibration (`simucal.calibrate`, `simucal.load`).
    vocabulary : {"common", "own"}
        Every method's M and bias (default), or the method's own parameters.
    units : {"spec", "si"}
        The spec's units (g, deg/h, arcsec) or SI (m/s^2, rad/s, rad).

    Returns
    -------
    pandas.DataFrame or list of Entry (or of Parameter)
        A DataFrame where pandas is installed, else a list of NamedTuple rows: ``(sensor, name, value, std,
        unit, own_name)`` (``vocabulary="own"``: ``(name, sensor, value, std, unit, meaning)``).

    Examples
    --------
    >>> p = simucal.parameters(cal)  # doctest: +SKIP
    >>> p.set_index(["sensor", "name"]).loc[("acc", "bias_z"), ["value", "std", "own_name"]]  # doctest: +SKIP
    """
    from simucal.report.units import calibration_in
    shown = calibration_in(cal, units)
    if vocabulary == "common":
        return table([e for s, b in shown.blocks() for e in entries(s, b, shown.temperature_range_c)], Entry._fields)
    if vocabulary != "own":
        raise InputError(f"vocabulary {vocabulary!r}: 'own' (each method's parameters) or 'common' (M and bias)")
    return table([r for s, b in shown.blocks() for r in (_model_rows(s, b) if b.params else _affine_rows(s, b))],
                  Parameter._fields)
