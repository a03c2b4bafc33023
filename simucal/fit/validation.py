"""A calibration's error on independent data, the pieces every kind of data's checks share
(`simucal validate`; the checks themselves: turntable/validation.py, handheld/validation.py).

A check compares a norm's error against what physics says the unit felt, at the nominal scale
factors (before) and calibrated (after), with the floor of that error: the noise of each row (a
segment's or pose's mean) and the calibration's own uncertainty, its parameters' covariance
propagated to the calibrated norm, d|u|/dp = (u/|u|)' (dh/du)^-1 dh/dp, added in quadrature
(`calibration_sd`; a file without a covariance adds nothing, and the check says so).
"""
from __future__ import annotations

from typing import TypedDict

import numpy as np

from simucal.fit.noise import mean_and_sigma
from simucal.io.stream_records import Timestamps

FAR_OFF = 10.0  # a row this many floors (and medians) off is named


class CheckRecord(TypedDict, total=False):
    """One check of `simucal validate`: a calibrated error against physics (norm_block, each kind's checks)."""
    what: str                         # the error checked, in words
    unit: str                         # of the rms values
    n: int                            # the rows (segments, poses, moves) it is taken over
    before_rms: float                 # at the nominal scale factors
    after_rms: float                  # calibrated
    floor_rms: float | None           # what the noise (and the table's stated errors) leave; None: unknown
    far_off: list[str]                # the rows far off where the rest agree
    far_off_hint: str                 # what to check there
    limited_by_table: bool            # the floor lacks the table's angle errors (meta.json states none)
    ratio_after_before: float | None  # the report's (api's validation_report), as its verdict
    verdict: str                      # at the noise floor, improved, ..., in words


class ValidationReport(TypedDict, total=False):
    """What `simucal validate -o` writes (simucal.validation/1; api/validating.validation_report)."""
    format: str
    calibration: str                  # the calibration file, or what names one in memory
    calibration_sha256: str | None    # its bytes' (None: in memory), which the certificate matches
    data: str                         # the set validated on
    independent: bool                 # not the rows the calibration was made from
    checks: dict[str, list[CheckRecord]]  # per sensor
    verdict: dict[str, str]           # per sensor, in words
    verdict_notes: dict[str, str]
    warnings: list[str]               # apply's: rows outside the calibrated temperatures
    note: str | None                  # why the data are not independent
    nominal: list[str]                # how the nominal outputs were read
    skipped: list[str]                # the sensors not validated, and why
    timestamps: Timestamps            # a stream's clock


def rms(x):
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(x ** 2))) if x.size else None


def segment_means(data, groups, stated, angles=None):
    """Mean of each group of rows (n, 3) and the std of each mean (n,) along the norm, the rms over
    the axes of mean_and_sigma's: a rate run's (angles: each row's outer angle) as the
    calibration takes it, the constant of its outer angle's harmonics and their residuals' scatter
    (first differences would count the turning Earth rate as noise: at 20 Hz 3x it, a floor 3-5x too
    high), a static group's from first differences (blind to a slow drift); the stated noise of one
    row where a group has fewer than three."""
    out = [mean_and_sigma(data[rows], stated, varying=True, angle_rad=None if angles is None else a)
           for rows, a in zip(groups, angles or [None] * len(groups))]
    return np.array([m for m, _ in out]), np.array([np.sqrt(np.mean(sd ** 2)) for _, sd in out], float)


def norm_block(unit, before, after, floor_sd, what, labels) -> CheckRecord:
    """Errors of a norm against its known value, before and after, with the floor; labels name
    the rows (segments or poses) for the ones far off (far_off)."""
    ok = np.isfinite(floor_sd)
    return {"what": what, "unit": unit, "n": int(len(after)), "before_rms": rms(before), "after_rms": rms(after),
            "floor_rms": rms(floor_sd[ok]) if ok.all() and ok.any() else None,
            "far_off": far_off(after, floor_sd, labels)}


def far_off(after, floor_sd, labels, k=FAR_OFF):
    """The rows whose calibrated error is k floors and k times the median error or more: a few
    rows far off, where the rest agree, are mislabelled or disturbed, not a model's failing."""
    e = np.abs(np.asarray(after, float))
    fl = np.broadcast_to(np.asarray(floor_sd, float), e.shape)
    if len(e) < 4 or not np.all(np.isfinite(fl)):
        return []
    far = (e > k * fl) & (e > k * np.median(e))
    return [labels[i] for i in np.nonzero(far)[0]] if far.sum() <= len(e) // 4 else []


def block_model(block, t_ref_c):
    """(model, p, covariance) of a block for the propagation, or None without a covariance."""
    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.thermal import ThermalModel
    if block.model == "affine":
        return None
    model: AugmentedModel | ThermalModel = AugmentedModel(block.model, block.library_effects())
    th = block.thermal
    cov = th.get("covariance") if th else block.details.get("covariance")
    if not cov:
        return None
    if th:
        model = ThermalModel(model, [th["parameters"][n]["degree"] for n in model.params])
        p = np.array([th["parameters"][n.split(".T")[0]]["coefficients"][int(n.split(".T")[1]) if ".T" in n else 0]
                      for n in model.params])
    else:
        p = np.array([block.params[n] for n in model.params])
    if list(cov["names"]) != list(model.params):
        return None
    raw = block.details.get("std_raw")  # a failing model's stds inflated by its misfit: the covariance too
    k2 = (block.std[model.params[0]] / raw[model.params[0]]) ** 2 if raw and raw.get(model.params[0]) else 1.0
    return model, p, np.asarray(cov["matrix"], float) * k2


def input_change(cal, sensor, u_b, aux_values: dict):
    """(u (n, 3) the calibrated inputs at rows u_b (n, 3) in b, du (n, 3, m) their change per parameter,
    the parameters' covariance, their names), or None where the file holds no covariance."""
    from simucal.fit.aux_inputs import T_REF, AuxInputs
    block = getattr(cal, sensor)
    found = block_model(block, cal.t_ref_c)
    if found is None:
        return None
    model, p, cov = found
    t_ref = block.thermal["t_ref_c"] if block.thermal else cal.t_ref_c
    values = dict(aux_values)
    if "temp_c" in values:
        values[T_REF] = 0.0 if t_ref is None else t_ref
    u = u_b @ block.C.T
    _, Ju, Jp = model.jacobians(u, p, AuxInputs(values))
    return u, -np.linalg.solve(Ju, Jp), cov, list(model.params)


def calibration_sd(cal, sensor, u_b, aux_values: dict) -> np.ndarray | None:
    """The std of the calibrated norm |u| at each row (segment means u_b (n, 3) in b, with their
    auxiliary inputs: temp_c, f_x..) from the calibration's covariance (module doc); None where the
    file holds none."""
    found = input_change(cal, sensor, u_b, aux_values)
    if found is None:
        return None
    u, du, cov, _ = found
    g = np.einsum("ni,nim->nm", u / np.linalg.norm(u, axis=1, keepdims=True), du)
    return np.sqrt(np.maximum(np.einsum("nm,mk,nk->n", g, cov, g), 0.0))


def direction_var(cal, sensor, u_b, aux_values: dict) -> np.ndarray | None:
    """The variance of the calibrated direction u/|u| at each row, summed over its two components
    across u (rad^2), from the calibration's covariance: d(u/|u|)/dp = (I - d d') (du/dp) / |u|.
    None where the file holds none."""
    found = input_change(cal, sensor, u_b, aux_values)
    if found is None:
        return None
    u, du, cov, _ = found
    n = np.linalg.norm(u, axis=1)
    d = u / n[:, None]
    G = (du - d[:, :, None] * np.einsum("ni,nim->nm", d, du)[:, None, :]) / n[:, None, None]
    return np.maximum(np.einsum("nim,mk,nik->n", G, cov, G), 0.0)


def with_calibration(floor_sd, cal, sensor, means, groups, ms, f_means=None):
    """The noise floor per row and the calibration's std added in quadrature (None: the noise alone)."""
    aux = {}
    if "temp_c" in ms.samples:
        aux["temp_c"] = np.array([np.mean(ms.samples["temp_c"][g]) for g in groups])
    if f_means is not None:
        from simucal.fit.aux_inputs import specific_force
        aux.update(specific_force(f_means @ getattr(cal, sensor).C.T))
    sd = calibration_sd(cal, sensor, means, aux)
    return floor_sd if sd is None else np.hypot(floor_sd, sd), sd is not None


FLOOR = {True: " (floor: the noise and the calibration's own uncertainty)",
          False: " (floor: the noise alone; the file holds no covariance of its parameters)"}


