"""What a rotation sequence lets the filter see (`simucal plan --sequence`): each parameter's prior and
posterior std from one pass of the linearised filter over the sequence.

The Kalman filter's covariance does not depend on the measured values, only on what the linearised
model holds at each step (the attitudes, the specific force and rate in b, the step lengths, the
noise and the updates): its posterior P over the sequence is the inverse of the prior's information
plus the sequence's (the information form of the Kalman filter; Maybeck 1979, sec. 5.7). One pass
therefore gives the observability of each parameter. A simulated unit's pass is linearised about its
truth, where the calibration's passes converge (each linearised about the estimates of the one before):
about the nominal (the parameters at zero) a unit's scale errors turn the nominal attitude away from the
true one by their size times each turn, and the pass reads information that is not there, or misses some (a
unit with 1e-2 scale errors and 100 deg/h gyro biases on psins19's moves at 60 deg/s: gyro dK_z's std 3.1
times too small, eta_x's 2.2 times too large; dK_z's 1.4 and 8.6 times at 3e-3 and 3e-2, 30 and 300 deg/h); about the
truth every std is the converged filter's to 3 digits.

A parameter is unobserved (calibrate refuses the sequence; `verdict`) where its std stays above
UNOBSERVABLE of its prior, or where the data see it only together with other states: its std over
INFLATION times the std it would have were the others known (the square root of its variance inflation
factor, from the inverse of the posterior's correlation matrix). The inflation does not depend on the
noise (a noisy unit's stds are large against their priors, its inflations are not: a tactical unit's reach
0.09 of their priors on psins19 with 10 s rests): on the built-in sequences and two designed ones it is at
most 9.2 for the default unit (psins19 with 10 s rests, gyro b_y), 2.3 for a tactical and a MEMS unit; in
calibrate's first pass, a sequence whose every move turns 360 deg (six at 10 deg/s, 30 s rests), which rests
the unit at one attitude only, inflates eight of the accelerometer's nine stds 1900-8200 times, a sequence of
outer-axis turns alone the z accelerometer's 9e4 times.
"""
from __future__ import annotations

from typing import TypedDict

import numpy as np

from simucal.io import results
from simucal.systematic.calibrate import UNOBSERVABLE, run_filter

ETA = ("eta_x", "eta_y", "eta_z")
INFLATION = 100.0  # a std over this many times the one it would have alone: seen only with other states


def names_and_units(sensors) -> list[tuple[str, str, str]]:
    """(sensor, parameter, unit) of every calibration state in the filter's order (the frame angles last)."""
    return ([("acc", n, u) for n, u in zip(sensors.acc.params, sensors.acc.param_units)]
            + [("gyro", n, u) for n, u in zip(sensors.gyro.params, sensors.gyro.param_units)]
            + [("gyro", n, "rad") for n in ETA])


def verdict(cov, prior_var) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(each calibration state's std over its prior std, its std over its std were the others known, whether
    it is observed: module doc) of a filter's covariance cov and the states' prior variances (phi and dv first)."""
    std = np.sqrt(np.diag(cov))
    ratio = std / np.sqrt(prior_var[6:])
    inflation = np.sqrt(np.abs(np.diag(np.linalg.inv(cov / np.outer(std, std)))))  # P spans decades: its correlations
    return ratio, inflation, (ratio <= UNOBSERVABLE) & (inflation <= INFLATION)


def unobserved(result, cov=None) -> dict[str, tuple[float, float]]:
    """{"sensor parameter": (std / prior std, std / its std alone)} of the states a filter's result (cov: its
    covariance, default result.cov) leaves unobserved (`verdict`), the worst first."""
    ratio, inflation, seen = verdict(result.cov if cov is None else cov, result.prior_var)
    names = [f"{s} {n}" for s, n, _ in names_and_units(result.sensors)]
    worst = np.argsort(-np.maximum(ratio / UNOBSERVABLE, inflation / INFLATION))
    return {names[i]: (float(ratio[i]), float(inflation[i])) for i in worst if not seen[i]}


class FilterStart(TypedDict):
    """Where run_filter starts (truth_start): each sensor's parameters by name (the model's units) and eta."""
    acc: dict[str, float]             # the accelerometer model's parameters
    gyro: dict[str, float]            # the gyro model's
    eta: list[float]                  # the gyro frame's angles, rad


def truth_start(truth) -> FilterStart:
    """A simulated unit's truth.json as run_filter's start: its parameters by name and the gyro frame's angles
    (eta: C_b^d = mounting(eta) = Rx Ry Rz, inverted)."""
    C = np.asarray(truth["gyro"]["C_b_d"])
    eta = [np.arctan2(-C[1, 2], C[2, 2]), np.arcsin(C[0, 2]), np.arctan2(-C[0, 1], C[0, 0])]
    return {"acc": truth["acc"]["params"], "gyro": truth["gyro"]["params"], "eta": eta}


def against_truth(cal, truth, rows) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[float, int]]]:
    """A simulated sequence's calibration cal against its truth.json: each row's (`observability`'s rows) reported
    std and error (estimate - truth), and per sensor the normalised estimation error squared e^T C^-1 e over its
    block's parameters (C the block's covariance; chi-square with their number of dof where the stds hold) and
    that number."""
    eta, eta_true = cal.gyro.details["eta_rad"], truth_start(truth)["eta"]
    std, err = [], []
    for r in rows:
        if r["parameter"] in ETA:
            j = ETA.index(r["parameter"])
            std.append(eta["std"][j])
            err.append(eta["value"][j] - eta_true[j])
        else:
            block = getattr(cal, r["sensor"])
            std.append(block.std[r["parameter"]])
            err.append(block.params[r["parameter"]] - truth[r["sensor"]]["params"][r["parameter"]])
    nees = {}
    for sensor in ("acc", "gyro"):
        block = getattr(cal, sensor)
        names = block.details["covariance"]["names"]
        C = np.asarray(block.details["covariance"]["matrix"])
        d = np.sqrt(np.diag(C))  # the covariance spans decades: solved as correlations
        e = np.array([block.params[n] - truth[sensor]["params"][n] for n in names]) / d
        nees[sensor] = (float(e @ np.linalg.solve(C / np.outer(d, d), e)), len(names))
    return np.array(std), np.array(err), nees


def observability(ms, acc_model="acc_baseline", gyro_model="gyro_baseline", ids=(),
                  truth=None) -> results.Observability:
    """One pass of the filter over the sequence ms (module doc), about the unit's truth (truth.json's) where
    given: {parameters: [{sensor, parameter, unit, prior_std, std, ratio, inflation, observed}], unobserved:
    ["sensor parameter"], updates, steps}."""
    r = run_filter(ms, acc_model, gyro_model, ids, max_passes=1, start=None if truth is None else truth_start(truth))
    ratio, inflation, seen = verdict(r.cov, r.prior_var)
    rows: list[results.Observed] = [
        {"sensor": s, "parameter": n, "unit": u, "prior_std": float(np.sqrt(pv)), "std": float(np.sqrt(v)),
         "ratio": float(q), "inflation": float(f), "observed": bool(o)}
        for (s, n, u), pv, v, q, f, o in zip(names_and_units(r.sensors), r.prior_var[6:], np.diag(r.cov), ratio,
                                             inflation, seen)]
    return {"parameters": rows, "unobserved": [f"{x['sensor']} {x['parameter']}" for x in rows if not x["observed"]],
            "threshold": UNOBSERVABLE, "inflation_threshold": INFLATION,
            "updates": sum(e.nu is not None for e in r.epochs), "steps": len(r.setting[0].dt),
            "noise_per_sample": {"gyro_dph": r.sigma[:3].tolist(), "acc_g": r.sigma[3:].tolist()}}
