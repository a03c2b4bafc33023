"""The outer axis's tilt in the gyro's stds: a systematic the norm cannot see.

A rate run's mean input is the rate along the outer axis plus the Earth rate along it, which the
norm fit takes as w_e sin L (the axis vertical). An axis tilted by t toward north adds w_e cos L t
(1.5e-9 of a 10 deg/s rate per arcsec at 45 deg latitude), the same in every run: with one sense of
rotation it cannot be told from a common scale factor, so it moves every dK alike and no residual
shows it. Where meta.json states the table's levelling (table_tilt_arcsec, the std of the tilt
about each horizontal axis), its effect is added to the stds; where not, the calibration says how
large it could be against the stds.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from simucal.fit.norm_fit import fit_exact
from simucal.io import units

WELL_LEVELLED_ARCSEC = 5.0  # a levelled precision table; unstated, the note compares this tilt's effect with the stds
NOTE_ABOVE = 0.3  # ... and is written where it exceeds this share of a parameter's std


def earth_rate_sensitivity(model, fit, obs, segs, meta) -> np.ndarray:
    """dp per arcsec of tilt toward north: the fit repeated with every rate run's input norm
    |w_T + w_e sin L| moved by w_e cos L per arcsec, by the sign of w_T + w_e sin L (a tilt adds
    the same Earth rate along the axis to runs of either sense); a linear step."""
    lat = np.radians(meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(meta)
    sense = np.sign([s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat) if s.kind == "rate" else 0.0
                     for s in segs])  # a static row's input is the whole Earth rate, whatever the axis's tilt
    step = 1e3  # arcsec: far above round-off, still linear (a relative change of 1e-5 of the norm)
    shift = sense * w_e * np.cos(lat) * units.ARCSEC_RAD * step
    moved = fit_exact(model, replace(obs, rho=obs.rho + shift), fit.vector(model.params))
    return (moved.vector(model.params) - fit.vector(model.params)) / step


def _tilt(block, model, fit, obs, segs, meta, std):
    """The tilt's effect on each parameter where meta.json states table_tilt_arcsec (recorded in the
    block's details), else None after the note where a well-levelled table's tilt would move a
    parameter by NOTE_ABOVE std (std: the parameters' own)."""
    per_arcsec = earth_rate_sensitivity(model, fit, obs, segs, meta)
    stated = meta.get("table_tilt_arcsec")
    if stated is None:
        worst = float(np.max(np.abs(per_arcsec) * WELL_LEVELLED_ARCSEC / std))
        if worst > NOTE_ABOVE:
            block.details["tilt_note"] = (
                f"the outer axis's tilt is not stated (meta.json table_tilt_arcsec): a tilt of "
                f"{WELL_LEVELLED_ARCSEC:g} arcsec toward north would move every scale factor alike by up to "
                f"{worst:.2g} std, unseen by the norm with one sense of rotation; state the table's levelling to "
                "have it in the stds")
        return None
    block.details["table_tilt"] = {"stated_arcsec": float(stated),
                                   "per_arcsec": dict(zip(model.params, per_arcsec.tolist())),
                                   "note": "the stds include the outer axis's tilt (meta.json table_tilt_arcsec)"}
    return per_arcsec * float(stated)


def add_tilt(block, model, fit, obs, segs, meta, M_of_p, C_b_d=None):
    """Add the tilt's effect to a gyro block's stds (and std_M) where table_tilt_arcsec is stated,
    else write a note where a well-levelled table's tilt would move a parameter by NOTE_ABOVE std."""
    sys = _tilt(block, model, fit, obs, segs, meta, np.array([block.std[k] for k in model.params]))
    if sys is None:
        return
    block.std = {k: float(np.hypot(s, d)) for (k, s), d in zip(block.std.items(), sys)}
    p = fit.vector(model.params)
    dM = M_of_p(p + sys) - M_of_p(p)
    if C_b_d is not None:
        dM = dM @ C_b_d
    if block.details.get("std_M") is not None:
        block.details["std_M"] = np.hypot(np.array(block.details["std_M"]), dM).tolist()


def add_tilt_thermal(block, model, fit, obs, segs, meta):
    """add_tilt for the joint thermal fit (model: a ThermalModel): the tilt is the same at every
    temperature, so it moves the scale factors' constant terms c_0 alike. Stated, its effect s (per
    coefficient) joins every coefficient's std in quadrature and s s^T their covariance (which
    validate's floor propagates); unstated, the note."""
    sys = _tilt(block, model, fit, obs, segs, meta, np.array([fit.std[k] for k in model.params]))
    if sys is None:
        return
    th = block.thermal
    for name, d in zip(model.params, sys):
        base, _, k = name.partition(".T")
        f = th["parameters"][base]
        f["std"][int(k or 0)] = float(np.hypot(f["std"][int(k or 0)], d))
    block.std = {n: th["parameters"][n]["std"][0] for n in block.std}
    block.effects = {e: replace(v, std=block.std[e]) for e, v in block.effects.items()}
    th["covariance"]["matrix"] = (np.asarray(th["covariance"]["matrix"]) + np.outer(sys, sys)).tolist()
