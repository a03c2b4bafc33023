"""What a rotation sequence lets the filter see (`simucal plan --sequence`): each parameter's prior and
posterior std from one pass of the linearised filter over the sequence.

The Kalman filter's covariance does not depend on the measured values, only on what the linearised
model holds at each step (the attitudes, the specific force and rate in b, the step lengths, the
noise and the updates): its posterior P over the sequence is the inverse of the prior's information
plus the sequence's (the information form of the Kalman filter; Maybeck 1979, sec. 5.7). One pass
about the nominal (the parameters at zero, the commanded and levelled first attitude) therefore
gives the observability of each parameter: its std against its prior's. A parameter whose std stays
above UNOBSERVABLE of its prior is one the sequence does not see (the filter's own refusal).
"""
from __future__ import annotations

import numpy as np

from simucal.io import results
from simucal.systematic.calibrate import UNOBSERVABLE, run_filter

ETA = ("eta_x", "eta_y", "eta_z")


def names_and_units(sensors) -> list[tuple[str, str, str]]:
    """(sensor, parameter, unit) of every calibration state in the filter's order (the frame angles last)."""
    return ([("acc", n, u) for n, u in zip(sensors.acc.params, sensors.acc.param_units)]
            + [("gyro", n, u) for n, u in zip(sensors.gyro.params, sensors.gyro.param_units)]
            + [("gyro", n, "rad") for n in ETA])


def std_ratios(result) -> np.ndarray:
    """Each calibration state's posterior std over its prior std."""
    return np.sqrt(np.diag(result.cov) / result.prior_var[6:])


def observability(ms, acc_model="acc_baseline", gyro_model="gyro_baseline", ids=()) -> results.Observability:
    """One pass of the filter over the sequence ms (module doc): {parameters: [{sensor, parameter, unit,
    prior_std, std, ratio, observed}], unobserved: ["sensor parameter"], updates, steps}."""
    r = run_filter(ms, acc_model, gyro_model, ids, max_passes=1)
    ratio = std_ratios(r)
    rows: list[results.Observed] = [{"sensor": s, "parameter": n, "unit": u, "prior_std": float(np.sqrt(pv)), "std": float(np.sqrt(v)),
             "ratio": float(q), "observed": bool(q <= UNOBSERVABLE)}
            for (s, n, u), pv, v, q in zip(names_and_units(r.sensors), r.prior_var[6:], np.diag(r.cov), ratio)]
    return {"parameters": rows, "unobserved": [f"{x['sensor']} {x['parameter']}" for x in rows if not x["observed"]],
            "threshold": UNOBSERVABLE, "updates": sum(e.nu is not None for e in r.epochs), "steps": len(r.setting[0].dt),
            "noise_per_sample": {"gyro_dph": r.sigma[:3].tolist(), "acc_g": r.sigma[3:].tolist()}}
