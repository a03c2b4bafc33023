"""A turntable unit over temperature: the rows of every plateau (or of one ramp) as one set of
observations, each at its own temperature, for the joint thermal fit (fit/thermal_select.py)."""
from __future__ import annotations

import numpy as np

from simucal.fit.aux_inputs import T_REF, AuxInputs
from simucal.fit.norm_fit import Observations
from simucal.fit.thermal_select import RAMP_BANDS
from simucal.turntable.model_test import ROWS
from simucal.turntable.observations import read_observations


def _concatenate(parts: list[Observations], t_ref_c: float) -> Observations:
    """Observations of several sets as one (aux columns that every set has; dtemp_c from t_ref_c)."""
    keys = set.intersection(*(set(o.aux.values) for o in parts)) - {T_REF}
    aux = {k: np.concatenate([np.broadcast_to(o.aux.values[k], len(o.N)) for o in parts]) for k in keys}
    aux[T_REF] = t_ref_c
    sig = None if any(o.sigma is None for o in parts) else np.concatenate([o.sigma for o in parts])
    return Observations(np.concatenate([o.N for o in parts]), np.concatenate([o.rho for o in parts]), sig,
                        AuxInputs(aux), [lab for o in parts for lab in o.labels], parts[0].sigma_source)


def joint_observations(sets, t_ref_c, acc_noise_g=None, gyro_noise_dph=None, noise_curves=None) -> dict:
    """{sensor: (observations of every set's rows, each row's set index, each row's segment)} for the
    sensors the sets hold."""
    per, segs = {"acc": [], "gyro": []}, {"acc": [], "gyro": []}
    for ms in sets:
        ms.temperature_ref_c = t_ref_c
        _, (acc, acc_segs, gyro, gyro_segs) = read_observations(ms, "exact", ROWS, acc_noise_g, gyro_noise_dph,
                                                                 noise_curves)
        for s, o, sg in (("acc", acc, acc_segs), ("gyro", gyro, gyro_segs)):
            per[s].append(o)
            segs[s] += sg or []
    out = {}
    for s, parts in per.items():
        if parts and all(o is not None for o in parts):
            groups = np.concatenate([np.full(len(o.N), k) for k, o in enumerate(parts)])
            out[s] = (_concatenate(parts, t_ref_c), groups, segs[s])
    return out


def ramp_bands(temp_c, bands=RAMP_BANDS) -> np.ndarray:
    """Each row's band of a ramp's temperature range (equal widths): the groups left out in turn."""
    T = np.asarray(temp_c, float)
    edges = np.linspace(T.min(), T.max(), bands + 1)[1:-1]
    return np.searchsorted(edges, T)


FOLLOWS_R2 = 0.5  # an input axis whose share of the rows' directions a line in temperature explains beyond this


def axes_following_temperature(obs) -> dict:
    """{axis: R^2} of the axes whose input (the rows' unit directions) a line in the rows' temperature
    explains beyond FOLLOWS_R2: on a ramp recorded in the plan's order (fibonacci48's rate runs turn from
    +z to -z as it heats: R^2 0.73 on z; 0.02 in a shuffled order) an axis's bias curvature and its
    scale factor's drift act alike there, and the fit cannot tell them apart (b_z.T2 and dK_z.T1 lowered
    chi^2 by 14.64 and 14.65), so the one kept misleads on another plan."""
    T = obs.aux.column("temp_c", len(obs.N))
    u = obs.N / np.linalg.norm(obs.N, axis=1, keepdims=True)
    X = np.column_stack([np.ones_like(T), T - T.mean()])
    res = u - X @ np.linalg.lstsq(X, u, rcond=None)[0]
    r2 = 1 - np.sum(res ** 2, 0) / np.maximum(np.sum((u - u.mean(0)) ** 2, 0), 1e-300)
    return {"xyz"[k]: float(r2[k]) for k in range(3) if r2[k] > FOLLOWS_R2}
