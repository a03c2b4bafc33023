"""A continuous rotation sequence on the turntable: the data of systematic calibration.

The table rests, turns one axis through an angle (a trapezoidal rate profile: accelerating at
ACCEL_DPS2 to the step's rate, cruising, braking), rests, and so on; the IMU's raw outputs at every
sample, moves included (`simucal simulate --sequence NAME|FILE`). The truth is the turntable
simulator's (simulate.py: the same unit, error models, mounting, table errors and noise) and is
written where it writes it. Each sample covers the interval (t - dt, t]: the gyro reads the mean
rate over it (the rotation between the attitudes at its ends, as an integrating gyro's pulses do),
the accelerometer the specific force at its middle. segments.csv marks each rest (`static`, with
its commanded angles) and each move (`move`: the rows of the table turning; methods that need
rests skip them).

A sequence file is a CSV with the header axis,angle_deg,rate_dps,rest_s: one row per move, the
table axis (outer, middle or inner), the angle turned (deg, signed), the cruising rate (deg/s) and
the rest after it (s); the first rest, before any move, lasts the first row's rest_s. Built in:
psins19, sysclbt19 (PSINS' published 19 positions) and dong2018.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from simucal.errors import InputError
from simucal import io
from simucal.fit.aux_inputs import AuxInputs, motion, specific_force
from simucal.generated import table
from simucal.io import outputs, units
from simucal.io.results import SequenceStep
from simucal.turntable import forward, kinematics, plans
from simucal.turntable.simulate import Scenario, meta_of, models, truth_of

AXES = ("outer", "middle", "inner")
ACCEL_DPS2 = 50.0     # the table's angular acceleration and braking, deg/s^2
MAX_RATE_DPS = 400.0  # no three-axis test table turns faster (outer axis, loaded)
MAX_REST_S = 36000.0
MIN_REST_S = 5.0      # a rest fitted to a time budget: the filter's noise and zero-velocity updates need seconds
DEFAULT_RATE_HZ = 100.0


@dataclass(frozen=True)
class Step:
    """One move and the rest after it."""
    axis: str          # outer, middle or inner
    angle_deg: float   # signed
    rate_dps: float    # cruising rate, > 0
    rest_s: float      # the rest after the move


def psins19(rest_s=100.0, rate_dps=10.0) -> list[Step]:
    """19 positions, 18 turns of 90 deg (in the manner of PSINS' sysclbt demo, not its path):
    the inner axis round twice (once level, once with the middle axis at 90 deg), the middle axis
    round, the outer axis round. On this table the inner axis is the unit's y, so z turns only
    while vertical: its scale factor is seen through the heading alone (gyro dK_z's std is about
    100 times the other scale factors'; sysclbt19 turns z while horizontal)."""
    turns = [("inner", 90.0)] * 4 + [("middle", 90.0)] * 4 + [("middle", 90.0)] + [("inner", 90.0)] * 4 \
        + [("middle", -90.0)] + [("outer", 90.0)] * 4
    return [Step(a, ang, rate_dps, rest_s) for a, ang in turns]


def dong2018(rest_s=60.0, rate_dps=10.0) -> list[Step]:
    """dong2018's Table 1 positions visited in order, each reached by turning the outer, middle and
    inner axes in turn (a rest after the last of them), then back to the first."""
    steps, at = [], np.zeros(3)
    for pos in list(plans.TABLE1) + [plans.TABLE1[0]]:
        moves = [(a, (float(x) - y + 180.0) % 360.0 - 180.0) for a, x, y in zip(AXES, pos, at)]
        moves = [(a, d) for a, d in moves if abs(d) > 1e-9]
        at = np.asarray(pos, float)
        steps += [Step(a, d, rate_dps, rest_s if k == len(moves) - 1 else 1.0) for k, (a, d) in enumerate(moves)]
    return steps


def sysclbt19(rest_s=40.0, rate_dps=10.0) -> list[Step]:
    """PSINS' published 19-position scheme (test_SINS_sysclbt19, after Xie et al. 2011: 18 turns of 90
    deg about the unit's own axes, +y three times and back, +z, +x three times and back, +z twice and
    -z three times; 90 deg in 9 s, rests of 20 s before and after each turn). PSINS' x, y, z are this
    table's z, x, y (a cyclic relabelling, so that its first position, x up, is the table's zero with
    z up), and each of its turns is then one axis of this table: the middle axis while it lies along
    the unit's x or z, the inner axis (the unit's y)."""
    turns = [("middle", 90.0)] * 3 + [("middle", -90.0)] * 3 + [("inner", 90.0)] + [("middle", 90.0)] * 3 \
        + [("middle", -90.0)] * 3 + [("inner", 90.0)] * 2 + [("inner", -90.0)] * 3
    return [Step(a, ang, rate_dps, rest_s) for a, ang in turns]


SEQUENCES = {"psins19": psins19, "sysclbt19": sysclbt19, "dong2018": dong2018}


def duration_s(steps) -> float:
    """The sequence's table time (s): the first rest, then each move and the rest after it."""
    return steps[0].rest_s + sum(move_angle(s.angle_deg, s.rate_dps, 0.0)[1] + s.rest_s for s in steps)


def in_minutes(steps, minutes, name="the sequence") -> list[Step]:
    """The same moves with every rest of MIN_REST_S or more scaled by one factor so that the sequence
    lasts `minutes` (nominally: the simulator rounds each rest and move to samples): a lab's way of
    fitting a sequence to its table time; dong2018's 1 s pauses between one position's axes stay as
    they are. Refused where the moves and pauses leave a rest under MIN_REST_S."""
    rests = np.array([steps[0].rest_s] + [s.rest_s for s in steps])
    long = rests >= MIN_REST_S
    if not long.any():
        raise InputError(f"{name}: no rest of {MIN_REST_S:g} s or more to fit to {minutes:g} min: rest longer")
    scale = (60.0 * minutes - (duration_s(steps) - rests[long].sum())) / rests[long].sum()
    if scale * rests[long].min() < MIN_REST_S:
        raise InputError(f"{name}: its {len(steps)} moves leave rests under {MIN_REST_S:g} s in {minutes:g} min "
                         f"(it lasts {duration_s(steps) / 60:.3g} min as written): give more minutes or fewer moves")
    return [Step(s.axis, s.angle_deg, s.rate_dps, s.rest_s * scale if s.rest_s >= MIN_REST_S else s.rest_s)
            for s in steps]


def write_sequence(path, steps) -> None:
    """A sequence file (module doc) of the steps, every number as Python writes it back exactly."""
    outputs.write_text(path, "axis,angle_deg,rate_dps,rest_s\n" + "".join(
        f"{s.axis},{float(s.angle_deg)!r},{float(s.rate_dps)!r},{float(s.rest_s)!r}\n" for s in steps))


def read_sequence(path) -> list[Step]:
    """A sequence file's steps (module doc), each row checked: refused in one line naming the file,
    the line and the fix."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"--sequence {path}: neither a built-in sequence ({', '.join(SEQUENCES)}) nor a file")
    with path.open(newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows or [c.strip() for c in rows[0]] != ["axis", "angle_deg", "rate_dps", "rest_s"]:
        raise InputError(f"{path}, line 1: the header must be axis,angle_deg,rate_dps,rest_s")
    steps = []
    for line, row in enumerate(rows[1:], start=2):
        steps.append(_step(path, line, row))
    if not steps:
        raise InputError(f"{path}: no moves; write one row per move under the header")
    return steps


def _step(path, line, row) -> Step:
    where = f"{path}, line {line}"
    if len(row) != 4 or row[0].strip() not in AXES:
        raise InputError(f"{where}: write AXIS,ANGLE_DEG,RATE_DPS,REST_S with AXIS one of {', '.join(AXES)}")
    try:
        angle, rate, rest = (float(x) for x in row[1:])
    except ValueError:
        raise InputError(f"{where}: angle_deg, rate_dps and rest_s must be numbers") from None
    if not (math.isfinite(angle) and 0 < abs(angle) <= 3600):
        raise InputError(f"{where}: angle_deg {angle:g} must be non-zero and at most 3600 deg in size")
    if not 0 < rate <= MAX_RATE_DPS:
        raise InputError(f"{where}: rate_dps {rate:g} is not a table's rate: give 0 < rate <= {MAX_RATE_DPS:g} deg/s")
    if not 0 < rest <= MAX_REST_S:
        raise InputError(f"{where}: rest_s {rest:g} must be within 0 < rest_s <= {MAX_REST_S:g} s")
    return Step(row[0].strip(), angle, rate, rest)


def resolve(sequence) -> tuple[str, list[Step]]:
    """(name, steps) of a built-in sequence's name, a sequence file or a list of steps (a design's)."""
    if isinstance(sequence, list):
        return "designed", sequence
    if isinstance(sequence, str) and sequence in SEQUENCES:
        return sequence, SEQUENCES[sequence]()
    return str(sequence), read_sequence(sequence)


def move_angle(total_deg, rate_dps, t) -> tuple[np.ndarray, float]:
    """The angle turned (deg) at the times t (s) from a move's start, and its duration (s):
    a trapezoidal rate profile at ACCEL_DPS2 (a triangle where the move is too short to cruise)."""
    a, d = ACCEL_DPS2, abs(total_deg)
    v = min(rate_dps, math.sqrt(a * d))
    t_acc = v / a
    T = 2 * t_acc + (d - v * t_acc) / v
    t = np.clip(np.asarray(t, float), 0.0, T)
    up, down = np.minimum(t, t_acc), np.clip(t - (T - t_acc), 0.0, t_acc)
    angle = 0.5 * a * up ** 2 + v * np.clip(t - t_acc, 0.0, T - 2 * t_acc) + v * down - 0.5 * a * down ** 2
    return math.copysign(1.0, total_deg) * angle, T


def _timeline(sc: Scenario, steps, rng, rate_hz):
    """The segments, each sample's segment id, and the table's true angles (rad, (n + 1, 3)) at the
    sample ends and (n, 3) at their middles (sample k covers (t_k - dt, t_k], t_0 = 0)."""
    commanded = np.zeros(3)
    reached = commanded + sc.angle_errors_rad(rng, (len(steps) + 1,))  # each rest's true angles (rad)
    ends, middles, seg_ids = [np.radians(commanded) + reached[0]], [], []
    segments: list[io.Segment] = []
    dt = 1.0 / rate_hz

    def phase(kind, n, angles_at, angles):
        outer, middle, inner = angles if kind == "static" else (None, None, None)
        segments.append(io.Segment(len(segments) + 1, kind, outer, middle, inner, 0.0))
        k = np.arange(1, n + 1) * dt
        ends.extend(angles_at(k))
        middles.extend(angles_at(k - dt / 2))
        seg_ids.extend([segments[-1].segment] * n)

    def at_rest(i):
        return lambda t: np.repeat(np.radians(commanded)[None] + reached[i], len(t), 0)

    phase("static", int(round(steps[0].rest_s * rate_hz)), at_rest(0), commanded.tolist())
    for i, s in enumerate(steps):
        j = AXES.index(s.axis)
        start, goal = np.radians(commanded) + reached[i], None
        commanded[j] += s.angle_deg
        goal = np.radians(commanded) + reached[i + 1]
        turn = math.degrees(goal[j] - start[j])
        T = move_angle(turn, s.rate_dps, 0.0)[1]

        def moving(t, start=start, goal=goal, j=j, turn=turn, rate=s.rate_dps, T=T):
            frac = move_angle(turn, rate, t)[0] / turn  # every axis's error goes from start to goal with it
            return start[None] + frac[:, None] * (goal - start)[None]
        phase("move", int(math.ceil(T * rate_hz)), moving, None)
        phase("static", int(round(s.rest_s * rate_hz)), at_rest(i + 1), ((commanded + 180) % 360 - 180).tolist())
    return segments, np.asarray(seg_ids), np.asarray(ends), np.asarray(middles)


def _rotation_vectors(R):
    """log(R) of rotations (n, 3, 3) below 90 deg, vectorised."""
    v = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], -1)
    s = np.linalg.norm(v, axis=-1, keepdims=True)
    return v * np.where(s > 1e-12, np.arcsin(np.minimum(s, 1.0)) / np.where(s > 1e-12, s, 1.0), 1.0)


def inputs(sc: Scenario, ends, middles, rate_hz):
    """The true inputs per sample: f_b (g) at the middle, the mean w_d (deg/h) over the interval,
    f_d (g, the gyro's g-sensitivity input), and the motion the accelerometers' lever arms and time
    delay see (aux_inputs.motion: the body rate in b and its change)."""
    err = kinematics.errors(sc.table_errors_rad(), np.zeros(3))
    C_end = table.C_k_n(*ends.T, err)
    C_mid = table.C_k_n(*middles.T, err)
    C_b_k, C_d_k = table.mounting(np.array(sc.theta4_rad)), table.mounting(np.array(sc.lambda4_rad))
    w_ie_n = table.earth_rate_n(units.DEFAULT_EARTH_RATE_DPH, np.radians(sc.latitude_deg))
    turned = _rotation_vectors(np.swapaxes(C_end[:-1], 1, 2) @ C_end[1:])  # in k, rad per sample
    w_k = np.degrees(turned) * rate_hz * units.DPH_PER_DPS + np.einsum("nji,j->ni", C_mid, w_ie_n)
    up_k = C_mid[:, 2, :]  # C_n^k [0, 0, 1]
    return up_k @ C_b_k, w_k @ C_d_k, up_k @ C_d_k, motion(w_k @ C_b_k, np.full(len(w_k), 1.0 / rate_hz))


MAX_TURN_PER_SAMPLE_DEG = 90.0  # a sample's rotation is taken below this (_rotation_vectors)


def sampled(name, steps, rate_hz):
    """Refuse, in one line naming the row, a step that the sample rate cannot hold: a rest shorter
    than one sample (no rows: the table never stops), a rate turning MAX_TURN_PER_SAMPLE_DEG or more
    in one sample."""
    if not rate_hz > 0:
        raise InputError(f"--rate-hz {rate_hz}: the sample rate must be positive")
    for line, s in enumerate(steps, start=2):
        where = f"{name}, line {line}" if name not in SEQUENCES else f"--sequence {name}"
        if round(s.rest_s * rate_hz) < 1:
            raise InputError(f"{where}: rest_s {s.rest_s:g} is shorter than one sample at {rate_hz:g} Hz: rest at "
                             f"least {1 / rate_hz:g} s (systematic calibration measures the noise on rests of over "
                             "10 samples) or raise --rate-hz")
        if s.rate_dps / rate_hz >= MAX_TURN_PER_SAMPLE_DEG:
            raise InputError(f"{where}: rate_dps {s.rate_dps:g} turns {s.rate_dps / rate_hz:g} deg per sample at "
                             f"{rate_hz:g} Hz: give --rate-hz above {s.rate_dps / MAX_TURN_PER_SAMPLE_DEG:g} or a "
                             "lower rate")


def simulate_sequence(sc: Scenario, sequence, seed: int = 0):
    """(meta, samples, segments, truth) of a sequence (module doc) at sc.rate_hz (default 100 Hz)."""
    name, steps = resolve(sequence)
    rate_hz = sc.rate_hz or DEFAULT_RATE_HZ
    sampled(name, steps, rate_hz)
    rng = np.random.default_rng(seed)
    acc, p_acc, gyro, p_gyro = models(sc)
    segments, seg_ids, ends, middles = _timeline(sc, steps, rng, rate_hz)
    f_b, w_d, f_d, motion = inputs(sc, ends, middles, rate_hz)
    t = np.arange(1, len(seg_ids) + 1) / rate_hz
    aux = AuxInputs({"t_s": t})
    meta = meta_of(sc, seed)
    N_a = forward.output(acc, p_acc, f_b, aux.with_values(**motion)) + rng.normal(0, sc.acc_noise_g, f_b.shape)
    N_g = forward.output(gyro, p_gyro, w_d, aux.with_values(**specific_force(f_d))) + rng.normal(0, sc.gyro_noise_dph,
                                                                                               w_d.shape)
    N_a, N_g = units.g_to_acc(N_a, meta), units.dph_to_gyro(N_g, meta)
    samples = {"segment": seg_ids, "t_s": t, **{f"a{c}": N_a[:, j] for j, c in enumerate("xyz")},
               **{f"g{c}": N_g[:, j] for j, c in enumerate("xyz")}}
    truth = truth_of(sc, acc, p_acc, gyro, p_gyro, seed)
    truth["sequence"] = {"name": name, "rate_hz": rate_hz, "steps": [cast(SequenceStep, vars(s)) for s in steps]}
    return meta, samples, segments, truth
