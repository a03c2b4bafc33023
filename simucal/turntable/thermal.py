"""A turntable unit over temperature: the rows of every plateau (or of one ramp) as one set of
observations, each at its own temperature (and its rate: aux_inputs.column_means), and the joint
thermal fit of them (fit/thermal_select.py, fit/thermal_auto.py) as each sensor's block of the calibration."""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray

from simucal.fit.aux_inputs import T_REF, AuxInputs, specific_force
from simucal.fit.norm_fit import Observations
from simucal.fit.thermal_select import RAMP_BANDS
from simucal.io import blocks, records, units
from simucal.io.calibration import SensorBlock
from simucal.io.details import SensorDetails, as_details
from simucal.io.segments import Segment
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
    return Observations(N, np.full(len(N), units.earth_rate_dph(ms.meta)), sig, aux,
                        [acc_segs[i].segment for i in rows]), \
        [acc_segs[i] for i in rows]


def joint_observations(sets, t_ref_c, acc_noise_g=None, gyro_noise_dph=None,
                       noise_curves=None) -> dict[str, tuple[Observations, NDArray[np.int_], list[Segment]]]:
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


def axes_following_temperature(obs) -> dict[str, float]:
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


def _own_fits(base, obs, groups) -> list:
    """Each plateau fitted alone by the model without temperature terms: the evidence beside the joint
    fit (its test, and its parameters at the plateau's temperature)."""
    from simucal.fit.lack_of_fit import fit_with_noise
    return [fit_with_noise(base, obs.take(np.nonzero(groups == g)[0]))[0] for g in np.unique(groups)]


def joint_block(obs, groups, first: SensorBlock, degree, labels, t_ref_c, plateaus: bool, segs,
                meta=None) -> SensorBlock:
    """One sensor's block from the joint fit of every row at its own temperature (fit/thermal_select.py):
    the block at T_ref (params = c_0), every parameter's polynomial, each group's test under the joint
    model beside its own fit's (plateaus; a ramp's bands have none); segs: the rows' segments; meta: the
    gyro's, for the outer axis's tilt in its stds (turntable/tilt.py)."""
    from dataclasses import replace

    from simucal.fit.thermal_auto import by_every_row, joint_test
    from simucal.fit.thermal_select import group_tests
    from simucal.turntable.model_test import rows_text
    base, model, fit, how, obs, auto = by_every_row(first, obs, groups, degree)
    own = _own_fits(base, obs, groups) if plateaus else None
    fits: dict[str, records.ThermalPolynomial] = {}
    for j, n in enumerate(base.params):
        names = [n] + [f"{n}.T{k}" for k in range(1, model.degrees[j] + 1)]
        fits[n] = {"degree": model.degrees[j], "degree_from": how["from"],
                   "coefficients": [fit.params[x] for x in names], "std": [fit.std[x] for x in names]}
        if own:
            fits[n].update({"per_plateau": [f.params[n] for f in own], "per_plateau_std": [f.std[n] for f in own]})
    M, bias = base.matrix_and_bias(fit.vector(base.params))
    T = obs.aux.column("temp_c", len(obs.N))
    T_g = [float(np.mean(T[groups == g])) for g in np.unique(groups)]
    details: SensorDetails = {
        "groups": [{"input": lab, "temp_c": t, "own_p_value": f.p_value if f else None, **test}
                   for lab, t, f, test in zip(labels, T_g, own or [None] * len(T_g),
                                              group_tests(model, obs, fit, groups))],
        "plateaus": plateaus}
    if first.C_b_model is not None:
        details["M_in_d"] = M.tolist()
    thermal: records.Thermal = {"t_ref_c": t_ref_c, "plateaus_c": T_g,
                                "temperature_range_c": [float(T.min()), float(T.max())],
                                "fit": "joint: every row at its own temp_c", "rows": rows_text(segs),
                                "parameters": fits, "dropped": how["dropped"],
                                "covariance": {"names": list(model.params), "matrix": fit.cov.tolist()}}
    test: Mapping[str, Any] = joint_test(base, model, obs, fit)  # its keys read by name below
    details.update(as_details({k: test[k] for k in ("omnibus_p_value", "omnibus_test", "targeted")
                                           if k in test}))
    if "verdict" in test.get("targeted", {}):  # a library effect beyond its test: the one to add
        details["advice"] = test["targeted"]["strongest"]
    if auto is not None:
        details["auto"] = auto
    block = replace(first, effects=blocks.effect_values(base, fit),  # auto may have changed them (thermal_auto)
                    params={n: fit.params[n] for n in base.params}, std={n: fit.std[n] for n in base.params},
                    M=M @ first.C, bias=bias, residual_rms=fit.residual_rms, chi2=fit.chi2, dof=fit.dof,
                    p_value=test["p_value"], thermal=thermal, details=details)
    if meta is not None:
        from simucal.turntable.tilt import add_tilt_thermal
        add_tilt_thermal(block, model, fit, obs, segs, meta)
    if blocks.inflate_if_failing(block) and fit.dof:  # the coefficients' stds too (covariance kept unscaled)
        k = float(np.sqrt(max(fit.chi2 / fit.dof, 1.0)))
        for f in fits.values():
            f["std"] = [e * k for e in f["std"]]
    return block


def joint_blocks(result, sets, cal, degree, t_ref, noise=None, acc_noise_g=None, gyro_noise_dph=None) -> None:
    """The sensors' blocks of a turntable unit by the joint fit (joint_block) set on result: sets, the plateaus
    (set, temperature), or one set whose bands of its ramp are the groups; cal, the plateau nearest T_ref's
    calibration (each sensor's model and frame); noise: a noise.json's path (fit/noise.load_curves)."""
    curves = None
    if noise is not None:
        from simucal.fit.noise import load_curves
        curves = load_curves(noise)
    obs = joint_observations([ms for ms, _ in sets], t_ref, acc_noise_g, gyro_noise_dph, curves)
    for s in cal.sensors:
        if s not in obs:
            continue
        o, groups, segs = obs[s]
        labels = [str(ms.path) for ms, _ in sets]
        if len(sets) == 1:
            groups = ramp_bands(o.aux.column("temp_c", len(o.N)))
            labels = [f"{sets[0][0].path}, band {g + 1}" for g in np.unique(groups)]
            result.warnings += ramp_warnings(s, o, segs)
        setattr(result, s, joint_block(o, groups, getattr(cal, s), degree, labels, t_ref, len(sets) > 1, segs,
                                       sets[0][0].meta if s == "gyro" else None))
