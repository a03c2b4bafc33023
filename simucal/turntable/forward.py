"""The unit's outputs from its truth, written by hand for the simulators.

The calibration fits the models derived in derive/ and printed into generated/; a simulator that wrote
its sets with those same functions would make the loop's tests self-consistent by construction (a wrong
sign in a derived model would be simulated and fitted alike). The turntable's and the sequences'
simulators write the outputs with this module instead, from the physics as dong2018 states it:

    N = (I + L) u + b + sum_e q_e phi_e(u, aux) e_axis(e)              (eq. 5 and 9, and each effect)

L lower triangular: the scale-factor errors dK on its diagonal, the misalignment angles (theta_ij for the
accelerometers, phi_ij for the gyros: axis i tilted toward j) below it; b the biases; and each library
effect's regressor phi_e in numpy below (its family's physics: a quadratic u_a^2, a scale asymmetry |u_a|,
a cross coupling u_a u_o, a bias drifting in time t, a lever arm on a rate run (w_T^2/g)(u_a u_c - delta_ac) r_c
and under any motion (domega x r + omega x (omega x r))_a / g, a time delay tau (omega x f)_a, a
g-sensitivity f_o, a bias or scale changing with temperature, a bias following its rate dT/dt). A gyro's
rates enter the nonlinear terms in deg/s. A model this module does not know (a user's model file) is simulated by its
own generated output, which is then the only forward model there is.
"""
from __future__ import annotations

import numpy as np

from simucal.generated.effects import EFFECTS

DPS = 3600.0  # deg/h per deg/s: a gyro's rate enters its nonlinear terms in deg/s
BASELINE = {"acc": ("acc_baseline", "acc_extended"), "gyro": ("gyro_baseline", "gyro_extended")}
AXIS = {"x": 0, "y": 1, "z": 2}
G0 = 9.80665  # m/s^2 per g (a lever arm's acceleration in g)


def _regressor(family: str, pair: str, sensor: str, u: np.ndarray, aux) -> np.ndarray:
    """phi_e of a library effect of `family` on `pair` (its axis, and the other axis where it has one)."""
    a, o = AXIS[pair[0]], AXIS[pair[-1]]
    n = len(u)
    ua = u[:, a] / (DPS if sensor == "gyro" else 1.0)  # a gyro's rate in deg/s in its nonlinear terms
    if family == "quadratic":
        return ua ** 2
    if family == "scale_asymmetry":
        return np.abs(u[:, a])
    if family == "cross_coupling":
        return u[:, a] * u[:, o]
    if family == "bias_drift_time":
        return aux.column("t_s", n)
    if family == "size_effect":
        return aux.column("w2", n) * (u[:, a] * u[:, o] - (1.0 if a == o else 0.0))
    if family in ("lever_arm", "time_delay"):
        w, dw = (np.stack([aux.column(f"{q}_{x}", n) for x in "xyz"], -1) for q in ("wb", "dwb"))
        if family == "time_delay":  # sampled tau late: f(t - tau) = f + tau (omega x f), to first order
            return np.cross(w, u)[:, a]
        e_c = np.eye(3)[o]  # the a accelerometer r_c from the x one: (domega x e_c)_a + (omega x (omega x e_c))_a, in g
        return (np.cross(dw, e_c)[:, a] + np.cross(w, np.cross(w, e_c))[:, a]) / G0
    if family == "g_sensitivity":
        return aux.column(f"f_{pair[-1]}", n)
    if family == "temperature_rate":  # a bias following dT/dt (the die lagging the thermistor)
        return aux.column("temp_rate_c_s", n)
    if "temperature" in family:  # bias_temperature{,2,3}: dT^k; scale_temperature{,2}: u_a dT^k
        dT_k = aux.column("dtemp_c", n) ** int(family[-1] if family[-1].isdigit() else 1)
        return dT_k if family.startswith("bias") else u[:, a] * dT_k
    raise KeyError(f"no forward model of the family {family!r}")  # a new family needs its physics here


def output(model, p: np.ndarray, u: np.ndarray, aux) -> np.ndarray:
    """The outputs (n, 3) of `model` (an AugmentedModel) with parameters p at inputs u (n, 3: g, or deg/h in the
    gyro's frame d) and auxiliary inputs aux (module doc)."""
    if model.base.name not in BASELINE[model.sensor]:
        return model.output(u, p, aux)  # a user's model: its own derivation is its only forward model
    values = dict(zip(model.params, np.asarray(p, float)))
    mis = "theta" if model.sensor == "acc" else "phi"
    M = np.eye(3)
    for i, c in enumerate("xyz"):
        M[i, i] += values[f"dK_{c}"]
        for j, r in enumerate("xyz"[:i]):
            M[i, j] = values[f"{mis}_{c}{r}"]
    N = u @ M.T + np.array([values[f"b_{c}"] for c in "xyz"])
    by_parameter = {EFFECTS[e].parameter: e for e in EFFECTS if EFFECTS[e].sensor == model.sensor}
    base_names = {f"dK_{c}" for c in "xyz"} | {f"b_{c}" for c in "xyz"} | {f"{mis}_{c}{r}" for c, r in
                                                                          (("y", "x"), ("z", "x"), ("z", "y"))}
    for name, q in values.items():
        if name in base_names or q == 0.0:
            continue
        eid = by_parameter[name] if name in by_parameter else name  # an extended model's term, or an added id
        _, family, pair = eid.split(".")
        N[:, AXIS[pair[0]]] += q * _regressor(family, pair, model.sensor, u, aux)
    return N
