"""A turntable unit over temperature: the rows of every plateau (or of one ramp) as one set of
observations, each at its own temperature (and its rate: aux_inputs.column_means), for the joint
thermal fit (fit/thermal_select.py)."""
from __future__ import annotations

import numpy as np

from simucal.fit.aux_inputs import T_REF, AuxInputs, specific_force
from simucal.fit.norm_fit import Observations
from simucal.fit.thermal_select import RAMP_BANDS
from simucal.io import units
from simucal.turntable.consistency import static_gyro_rows
from simucal.turntable.model_test import ROWS
from simucal.turntable.observations import read_observations, segment_duration_s


def _concatenate(parts: list[Observations], t_ref_c: float) -> Observations:
    """Observations of several sets as one (aux columns that every set has; dtemp_c from t_ref_c)."""
    keys = set.intersection(*(set(o.aux.values) for o in parts)) - {T_REF}
    aux: dict[str, np.ndarray | float] = {
        k: np.concatenate([np.broadcast_to(o.aux.values[k], len(o.N)) for o in parts]) for k in keys}
    aux[T_REF] = t_ref_c
    sig = None if any(o.sigma is None for o in parts) else np.concatenate([o.sigma for o in parts])
    return Observations(np.concatenate([o.N for o in parts]), np.concatenate([o.rho for o in parts]), sig,
                        AuxInputs(aux), [lab for o in parts for lab in o.labels], parts[0].sigma_source)


STATIC_SNR = 20.0  # the Earth rate over a static row's noise above which its norm is Gaussian enough to fit


def static_gyro_observations(ms, acc, acc_segs, gyro_noise_dph=None, curve=None):
    """(Observations, segments) of the gyro at the static positions, each row's input norm the Earth
    rate w_e (the norm fit's |M^-1 (N - b)| = w_e: a sphere whose centre is the bias at the row's
    temperature, which the scale factors move by w_e dK only), or (None, []) where the rows' noise is
    unknown or not STATIC_SNR times below w_e. At rest the gyro sees its bias at every temperature
    the static positions reach and barely any scale-factor drift: the rows that tell a bias's curvature
    from a scale factor's drift where the rate runs' inputs follow the temperature (a ramp in the
    plan's order). curve: the Allan curve of `calibrate --noise`, which gives each row's noise at its
    length as it does the rate runs'."""
    if acc is None:
        return None, []
    rows, static = static_gyro_rows(ms, acc_segs, gyro_noise_dph)
    if not rows:
        return None, []
    N, sig, aux = static
    if curve is not None:
        sig = np.array([curve(segment_duration_s(ms, ms.rows(acc_segs[i].segment), acc_segs[i].segment))
                        for i in rows]) * np.ones((len(rows), 3))
    if sig is None or units.earth_rate_dph(ms.meta) < STATIC_SNR * float(np.median(sig)):
        return None, []
    aux = aux.with_values(**specific_force(acc.N[rows]))
    return Observations(N, np.full(len(N), units.earth_rate_dph(ms.meta)), sig, aux, [acc_segs[i].segment for i in rows]), \
        [acc_segs[i] for i in rows]


def joint_observations(sets, t_ref_c, acc_noise_g=None, gyro_noise_dph=None, noise_curves=None) -> dict:
    """{sensor: (observations of every set's rows, each row's set index, each row's segment)} for the
    sensors the sets hold; the gyro's rows are its rate runs and its static positions
    (static_gyro_observations)."""
    per: dict[str, list] = {"acc": [], "gyro": []}  # per set: its observations, None where it has none
    segs: dict[str, list] = {"acc": [], "gyro": []}
    for ms in sets:
        ms.temperature_ref_c = t_ref_c
        _, (acc, acc_segs, gyro, gyro_segs) = read_observations(ms, "exact", ROWS, acc_noise_g, gyro_noise_dph,
                                                                 noise_curves)
        if gyro is not None:
            st, st_segs = static_gyro_observations(ms, acc, acc_segs, gyro_noise_dph, (noise_curves or {}).get("gyro"))
            if st is not None:
                gyro, gyro_segs = _concatenate([gyro, st], t_ref_c), list(gyro_segs) + st_segs
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


def ramp_warnings(sensor, obs, segs) -> list[str]:
    """A ramp's WARNING for each axis whose input follows its temperature (axes_following_temperature),
    where nothing else tells that axis's bias curvature from its scale factor's drift: none for a gyro
    fitted with its static rows (static_gyro_observations: at rest it sees its bias at every temperature
    they reach, and its scale factors barely)."""
    if sensor == "gyro" and any(s.kind == "static" for s in segs):
        return []
    return [f"{sensor}: the {a} input follows the ramp's temperature (R^2 {r2:.2f} of a line in T over the "
            f"{len(obs.N)} rows): its bias curvature and its scale factor's drift look alike there and are not told "
            f"apart; record the plan in an order whose directions do not follow the temperature (shuffled), or at "
            f"plateaus" + (", or static positions with a gyro quiet enough to see the Earth rate's norm at rest "
                           f"({STATIC_SNR:g} times its noise)" if sensor == "gyro" else "")
            for a, r2 in axes_following_temperature(obs).items()]


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
