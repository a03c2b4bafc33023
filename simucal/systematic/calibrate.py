"""Systematic calibration (method `systematic`): a rotation sequence's raw samples through the
strapdown navigation and the error-state Kalman filter + RTS smoother of filter.py, every parameter
of the chosen models (and the gyro frame's three angles against b) with its std.

The set is a sequence (`simucal simulate --sequence`): static segments (rests, with their commanded
angles) and move segments between them, raw samples throughout. Only the first rest's commanded
angles are used (the initial heading, refined by the filter); the others are not needed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel, for_sensor
from simucal.fit.aux_inputs import AuxInputs
from simucal.generated import table
from simucal.io import SENSOR_COLS, timestamps, units
from simucal.fit.rotations import exp_so3, log_so3
from simucal.systematic.filter import Epoch, Sensors, composed, kalman, level, nominal, smooth
from simucal.systematic.zero_position import Returns, position, returns

BLOCK_S = 1.0           # zero-velocity updates at rest every this many seconds
ZUPT_STD_MPS = 1e-6     # the table at rest: its velocity is zero to this (m/s)
# prior stds by a parameter's unit: wide against any unit this tool calibrates (the data decide)
PRIOR_STD = {"1": 1e-2, "rad": 1e-2, "g": 1e-2, "deg/h": 10.0}
PRIOR_OTHER = 1e-2
PRIOR_ATTITUDE_RAD = 1e-2
GRADE_DPH = 100.0       # a gyro bias at rest above this widens the priors in proportion (a MEMS unit's 0.5 deg/s: 18x)
PRIOR_CAP = 0.1         # the widened priors of dimensionless, rad and g parameters stop here
MAX_PASSES = 30        # a MEMS unit on fast turns can take 20 (each pass a Gauss-Newton step of the smoother)
STEP_STD = 0.05         # a pass that moves no estimate by more than this many stds ends the iteration
UNOBSERVABLE = 0.5      # a std above this fraction of its prior: the sequence did not see the parameter


def rests_and_moves(ms):
    """The segments in recording order, refused in one line where the set is no sequence."""
    if not any(s.kind == "move" for s in ms.segments or ()):
        raise CalibrationError(f"{ms.path}: systematic calibration needs a rotation sequence (segments.csv with "
                               "static and move segments, raw samples throughout): record one, or simulate it "
                               "with `simucal simulate --sequence psins19`")
    rates = [s.segment for s in ms.segments if s.kind == "rate"]
    if rates:
        moves = [s.segment for s in ms.segments if s.kind == "move"]
        raise CalibrationError(
            f"{ms.path / 'segments.csv'}: mixes a turntable test's rate runs (segment{'s' * (len(rates) > 1)} "
            f"{', '.join(map(str, rates[:6]))}{' ...' if len(rates) > 6 else ''}) with move segments (segment"
            f"{'s' * (len(moves) > 1)} {', '.join(map(str, moves[:6]))}{' ...' if len(moves) > 6 else ''}): a rotation "
            "sequence is rests (static) and the moves between them, in recording order, raw samples throughout; a "
            "turntable test is static positions and rate runs. If this is a turntable test, label those moves rate "
            "(then calibrate takes --method exact); else record the sequence's turns as moves")
    if len(ms.sensors) < 2:  # the gyro's attitude carries gravity into the accelerometers' frame, and back
        lacking = "gyro" if ms.has_acc else "acc"
        raise CalibrationError(f"{ms.path / 'samples.csv'}: has no {' '.join(SENSOR_COLS[lacking])} columns; "
                               "systematic calibration navigates through the sequence with both sensors: record both")
    if ms.meta.get("latitude_deg") is None:
        raise CalibrationError(f"{ms.path / 'meta.json'}: latitude_deg is missing; the navigation needs the "
                               "site's latitude (the Earth rate's direction): add \"latitude_deg\": <deg>")
    order = np.argsort([ms.rows(s.segment)[0] if len(ms.rows(s.segment)) else np.inf for s in ms.segments])
    segments = [ms.segments[i] for i in order if len(ms.rows(ms.segments[i].segment))]
    if segments[0].kind != "static" or segments[0].outer_deg is None:
        raise CalibrationError(f"{ms.path / 'segments.csv'}: the sequence must open with a rest at commanded "
                               "angles (a static segment with outer_deg, middle_deg and inner_deg)")
    return segments


def white_noise(ms, segments, rows_of):
    """Each axis's white-noise std per sample, gyro (deg/h) then accelerometer (g): the rests'
    first differences (std / sqrt 2), the median over the rests."""
    per_rest = []
    for s in segments:
        r = rows_of(s)
        if s.kind == "static" and len(r) > 10:
            d = np.diff(np.c_[ms.gyro_dph()[r], ms.acc_g()[r]], axis=0)
            per_rest.append(d.std(axis=0) / np.sqrt(2))
    if not per_rest:
        raise CalibrationError(f"{ms.path / 'segments.csv'}: no rest holds more than 10 samples; the filter takes the "
                               "white noise from the rests: rest at least 11 samples (the built-in sequences rest "
                               "30-100 s)")
    return np.median(per_rest, axis=0)


def _prior(model, grade=1.0):
    """Each parameter's prior std by its unit, widened by the unit's grade (start_from_rest) up to PRIOR_CAP
    (deg/h priors: the grade's own scale)."""
    return [PRIOR_STD["deg/h"] * grade if u == "deg/h" else min(PRIOR_STD.get(u, PRIOR_OTHER) * grade, PRIOR_CAP)
            for u in model.param_units]


def start_from_rest(ms, gyro, first, C):
    """(the gyro's parameters at the start, the unit's grade): its biases from the first rest's mean rate less the
    Earth rate along the levelled attitude C (C_b^n), the rest at their nominal; the grade max(1, the largest
    bias / GRADE_DPH) scales the priors, so that a MEMS unit's 0.5 deg/s bias and 1e-2 scale errors start near
    the data and inside the linearisation rather than 180 priors away (a navigation-grade unit: grade 1)."""
    p = np.zeros(len(gyro.params))
    names = [f"b_{a}" for a in "xyz"]
    if not all(n in gyro.params for n in names):
        return p, 1.0  # a user's model without the baseline's biases: start at nominal
    w_ie_b = C.T @ table.earth_rate_n(units.earth_rate_dph(ms.meta), np.radians(ms.meta["latitude_deg"]))
    b = ms.gyro_dph()[ms.rows(first.segment)].mean(0) - w_ie_b
    for n, v in zip(names, b):
        p[gyro.params.index(n)] = v
    return p, max(1.0, float(np.abs(b).max()) / GRADE_DPH)


def _levelled(ms, sensors, first, rows):
    """The first rest's commanded attitude, levelled by the accelerometers (the prior's centre)."""
    C0 = table.C_k_n(*np.radians([first.outer_deg, first.middle_deg, first.inner_deg]), np.zeros(7))
    f_b, _, _ = sensors.compensate(ms.acc_g()[rows].mean(0, keepdims=True), ms.gyro_dph()[rows].mean(0, keepdims=True),
                                AuxInputs(), AuxInputs())
    return level(C0, f_b[0])


@dataclass
class Result:
    """The filter's result: the sensors at the estimates, their covariance (the parameters' block of
    the smoothed P at the start), the last pass's epochs, the noise found, the passes run."""
    sensors: Sensors
    cov: np.ndarray
    epochs: list
    prior_var: np.ndarray
    sigma: np.ndarray
    passes: int
    step_std: float
    rate_hz: float                  # the samples' (1 / their median step)
    C: np.ndarray | None = None  # C_b^n at the start about the estimates, and what another pass over the data
    setting: tuple = ()          # needs, (steps, q, w_ie, g0): the innovations' candidates (innovations.py)
    returns: Returns | None = None  # the zero-position updates made (zero_position.py)
    first_cov: np.ndarray | None = None  # cov after the first pass: the observability check's (observability.py)
    diverged: str = ""           # where a pass diverged (`divergence`), else empty
    positions: int = 0           # the rests' distinct commanded positions (zero_position.position)

    @property
    def converged(self) -> bool:
        """Whether the last pass moved no estimate by STEP_STD of its std (False where a pass diverged)."""
        return not self.diverged and self.step_std < STEP_STD


def run_filter(ms, acc_model="acc_baseline", gyro_model="gyro_baseline", ids=(), block_s=BLOCK_S,
               max_passes=MAX_PASSES, zero_position=True, start=None, stop_if=None) -> Result:
    """The filter and smoother over the whole sequence, pass after pass, each linearised about the
    estimates of the one before (iterated extended Kalman smoother), until a pass moves no
    estimate by more than STEP_STD of its std, or diverges (`divergence`: the passes stop there). zero_position:
    with the zero-position updates where the table returns to a position and meta.json states its accuracy
    (zero_position.py). start: {"acc": {name: value}, "gyro": {..}, "eta": [3]}, the estimates the first pass is
    linearised about (names it lacks at nominal; observability.py gives a simulated unit's truth, where the
    passes converge); stop_if: a test of the first pass's (cov, prior_var) that stops the passes there."""
    segments = rests_and_moves(ms)
    acc, gyro = AugmentedModel(acc_model, for_sensor(ids, "acc")), AugmentedModel(gyro_model, for_sensor(ids, "gyro"))
    sensors = Sensors(acc, gyro, np.zeros(len(acc.params)), np.zeros(len(gyro.params)), np.zeros(3))
    t = ms.samples["t_s"]
    dt = float(np.median(np.diff(t[ms.rows(segments[0].segment)])))
    g0, lat = units.gravity(ms.meta), np.radians(ms.meta["latitude_deg"])
    w_ie = table.earth_rate_n(units.earth_rate_dph(ms.meta) * units.RAD_S_PER_DPH, lat)
    sigma = white_noise(ms, segments, lambda s: ms.rows(s.segment))
    q = np.r_[(sigma[:3] * units.RAD_S_PER_DPH) ** 2, (sigma[3:] * g0) ** 2] * dt  # spectral densities
    steps = steps_of(ms, segments, block_s, dt)
    if start is not None:
        _move(sensors, np.r_[[start["acc"].get(n, 0.0) for n in acc.params],
                             [start["gyro"].get(n, 0.0) for n in gyro.params], start["eta"]])
    C_prior = C = _levelled(ms, sensors, segments[0], ms.rows(segments[0].segment))
    p_gyro, grade = start_from_rest(ms, gyro, segments[0], C)
    sensors.p_gyro = sensors.p_gyro if start is not None else p_gyro
    p_prior = sensors.vector()
    prior_var = np.r_[[PRIOR_ATTITUDE_RAD] * 3, [ZUPT_STD_MPS] * 3, _prior(acc, grade), _prior(gyro, grade),
                      [PRIOR_STD["rad"]] * 3] ** 2
    zero = returns(ms, segments, steps.segment[steps.zupt], len(prior_var)) if zero_position else None
    p = slice(6, len(prior_var))  # the constants; the clones of zero-position updates after them
    clones = 0 if zero is None else 3 * zero.slots
    first, where = None, ""
    for k in range(1, max_passes + 1):
        x0 = np.r_[log_so3(C_prior @ C.T), np.zeros(3), sensors.vector() - p_prior, np.zeros(clones)]  # the prior's
        P0 = np.diag(np.r_[prior_var, np.ones(clones)])  # mean as errors; a clone's value is set at its copy
        epochs = _one_pass(steps, sensors, C, x0, P0, q, w_ie, g0, zero)
        x, P = epochs[-1].x, epochs[-1].P  # the constants: the filter's at the end (the smoother's at the start
        step = np.abs(x[p]) / np.sqrt(np.abs(np.diag(P)[p]))  # equal them in exact arithmetic)
        first = P[p, p] if first is None else first
        if not (np.isfinite(x).all() and np.isfinite(P).all() and (np.diag(P) >= 0).all()):
            where = divergence(epochs, steps, segments, k)  # a NaN carries forward: the end shows it
            break
        _move(sensors, sensors.vector() - x[p])
        if step.max() < STEP_STD or k == max_passes or (k == 1 and stop_if is not None and stop_if(first, prior_var)):
            break
        x_s = smooth(epochs, covariance=False)[0]
        if not np.isfinite(x_s[0]).all():  # and back through the smoother to the start
            where = divergence(epochs, steps, segments, k, x_s)
            break
        C = exp_so3(x_s[0][:3]) @ C  # the next pass's attitude at the start
    return Result(sensors, P[p, p], epochs, prior_var, sigma, k, float(step.max()), 1.0 / dt, C, (steps, q, w_ie, g0),
                  zero, first, where, len({position(s) for s in segments if s.kind == "static"}))


def _bad(e) -> bool:
    """Whether an epoch's state or covariances are not finite or hold a negative variance (a diverged filter)."""
    return not (np.isfinite(e.x).all() and np.isfinite(e.P).all() and np.isfinite(e.P_pred).all()) \
        or bool((np.diagonal(e.P_pred) < 0).any() or (np.diagonal(e.P) < 0).any())


def divergence(epochs, steps, segments, k, x_s=None) -> str:
    """Where pass k diverged: the first epoch that is `_bad`; where none is, the smoother's (x_s, its states),
    the last whose smoothed state is not finite (it runs from the end back); named by its update, time and the
    move before it."""
    u = next((i for i, e in enumerate(epochs) if _bad(e)), None)
    what = "the filter"
    if u is None:
        u, what = (len(epochs) - 1, what) if x_s is None else \
            (int(np.flatnonzero(~np.isfinite(x_s).all(axis=1))[-1]), "the smoother")
    if u == 0:
        return f"pass {k}, {what} at its start"
    i = np.flatnonzero(steps.zupt)[u - 1]
    seg = int(steps.segment[i])
    moves = sum(s.kind == "move" for s in segments[:[s.segment for s in segments].index(seg)])
    return (f"pass {k}, {what} at update {u} of {len(epochs) - 1} (t = {steps.t[i]:.1f} s, segment {seg}: the rest "
            + (f"after move {moves})" if moves else "before the first move)"))


def _move(sensors, p):
    na, ng = len(sensors.p_acc), len(sensors.p_gyro)
    sensors.p_acc, sensors.p_gyro, sensors.eta = p[:na], p[na:na + ng], p[na + ng:]


@dataclass
class Steps:
    """The filter's steps: the moves' samples and the rests' blocks (their means), each with its
    outputs (g, deg/h), time (s, the middle), length dt (s), whether a zero-velocity update ends it, and
    its segment."""
    N_a: np.ndarray
    N_g: np.ndarray
    t: np.ndarray
    dt: np.ndarray
    zupt: np.ndarray
    segment: np.ndarray


def steps_of(ms, segments, block_s, dt) -> Steps:
    """The rows grouped into steps: every sample of a move, blocks of block_s at rest."""
    starts, zupt = [], []
    for s in segments:
        rows = ms.rows(s.segment)
        if s.kind == "static":
            n_block = max(1, int(round(block_s / dt)))
            first = rows[::n_block]
            zupt += [True] * len(first)
        else:
            first = rows
            zupt += [False] * len(rows)
        starts.append(first)
    order = np.concatenate([ms.rows(s.segment) for s in segments])
    start = np.concatenate(starts)
    if not np.array_equal(order, np.arange(order[0], order[0] + len(order))):
        raise CalibrationError(f"{ms.path / 'samples.csv'}: a sequence's rows must run segment after segment in "
                               "time order, as recorded")
    found = timestamps.gaps(ms.samples["t_s"][order], order)
    if found:  # every step is one median step long here: a gap would be spread, and the turn in it lost
        seg = ms.samples["segment"][found[0]["after_row"] + 1]
        raise CalibrationError(f"{ms.path / 'samples.csv'}: {timestamps.gap_text(found)}, the first in segment "
                               f"{int(seg)} (line {found[0]['after_row'] + 3}): the filter integrates every sample "
                               "at the recorded rate and cannot bridge missing samples; record the sequence again, "
                               "or cut it at the gap into sequences of their own")
    counts = np.diff(np.r_[start, order[-1] + 1])
    mean = [np.add.reduceat(x[order[0]:order[-1] + 1], start - order[0], axis=0) / counts[:, None]
            for x in (ms.acc_g(), ms.gyro_dph())]
    t = np.add.reduceat(ms.samples["t_s"][order[0]:order[-1] + 1], start - order[0]) / counts
    return Steps(mean[0], mean[1], t, counts * dt, np.asarray(zupt), ms.samples["segment"][start])


def _one_pass(steps, sensors, C, x0, P0, q, w_ie, g0, zero=None):
    """One pass of the filter over the sequence about the nominal of sensors' estimates and C: the
    epochs (the first the prior at the start). The steps between two updates are composed into one
    transition (filter.composed); zero: the zero-position updates (zero_position.Returns) or None."""
    R = np.eye(3) * ZUPT_STD_MPS ** 2
    aux = AuxInputs({"t_s": steps.t})
    f_b, w_b, aux_a = sensors.compensate(steps.N_a, steps.N_g, aux, aux, steps.dt)
    D_a, D_g = sensors.sensitivities(f_b, w_b, aux_a, aux)
    Cs, v_at = nominal(C, w_b * units.RAD_S_PER_DPH * steps.dt[:, None], f_b, steps.dt, steps.zupt, w_ie, g0)
    epochs = [Epoch(np.eye(len(P0)), P0, P0, x0, x0)]
    x, P = x0, P0
    ends = np.flatnonzero(steps.zupt)
    # the nominal attitude at the end of each update's step (Cs holds the steps' starts), where phi is
    C_end = exp_so3(-w_ie[None] * steps.dt[ends, None]) @ Cs[ends] @ exp_so3(
        w_b[ends] * units.RAD_S_PER_DPH * steps.dt[ends, None]) if zero is not None else None
    for i, A, B, Q in composed(Cs, f_b, D_a, D_g, steps.dt, steps.zupt, q, w_ie, g0):
        x, P = kalman(x, P, A, B, Q, v_at[ends[i]], R, steps.t[ends[i]], epochs, zero,
                      None if C_end is None else C_end[i])
    return epochs
