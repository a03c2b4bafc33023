"""Simulated hand-placed session (the Tedaldi / imu_tk workflow), raw counts.

An initial rest, then random static poses joined by smooth hand-like moves:
R(t) = R_i exp(s(t) theta k) with s a smooth step, so the body rate is exactly
s'(t) theta k. Outputs: counts = nominal * (M f + b) + noise, clipped at the
full scale; accelerometer in g through acc M_a (lower triangular, b frame),
gyro through a full M_g (so omega is in b). Translational acceleration during
moves and the Earth rate are left out. Gyro effects of generated/effects.py
can be planted (gyro_effects), evaluated at the true rate and specific force, and accelerometer
effects (acc_effects) at the true specific force.
`simulate_still`: a unit at rest (the stream `simucal noise` characterises); `simulate_warmup`: a
still board warming up (the thermal calibration's record).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from simucal.errors import InputError
from simucal import io
from simucal.fit.augmented import regressor
from simucal.fit.aux_inputs import AuxInputs, specific_force
from simucal.fit.rotations import exp_so3, log_so3
from simucal.generated.effects import EFFECTS
from simucal.generated.moves import rotation_matrix
from simucal.io.units import DPH_PER_DPS


@dataclass
class HandheldScenario:
    poses: int = 30
    rest_s: float = 30.0
    pose_s: float = 5.0
    move_s: float = 3.0
    peak_rate_dps: float = 200.0
    rate_hz: float = 100.0
    acc_counts_per_g: float = 4096.0
    gyro_counts_per_dps: float = 16.4
    offset_counts: float = 32768.0
    acc_noise_g: float = 1e-3
    gyro_noise_dps: float = 0.1
    full_scale_dps: float = 2000.0
    clip_moves: int = 0          # this many moves peak beyond full scale
    flip_gyro: bool = False      # gyro sign reversed (a wrong convention)
    gyro_effects: dict = field(default_factory=dict)  # planted candidate effects: {effect id: value in its unit}
    acc_effects: dict = field(default_factory=dict)   # the same for the accelerometer (e.g. acc.quadratic.z, g/g^2)
    coplanar_poses: bool = False  # every pose turned about body x only: gravity directions in one plane
    dead_gyro_axis: int | None = None  # this gyro output does not respond to rate (a dead channel)
    weak_axis: int | None = None  # the moves turn about axes perpendicular to this body axis, never about it


def _random_rotation(rng):
    """A uniformly random rotation: C(q) of a uniformly random unit quaternion."""
    q = rng.normal(size=4)
    return rotation_matrix(q / np.linalg.norm(q))


def _motion(sc: HandheldScenario, rng):
    """The true specific force f (g) and rate w (deg/s) of the session, sample by sample: an initial
    rest, then poses joined by minimum-jerk moves (some whirled beyond full scale: their indices), and
    each rest's and pose's gravity direction in b."""
    if sc.coplanar_poses:
        Rs = [exp_so3(np.array([a, 0.0, 0.0])) for a in np.r_[0.0, rng.uniform(-np.pi, np.pi, sc.poses)]]
    else:
        Rs = [np.eye(3)] + [_random_rotation(rng) for _ in range(sc.poses)]
    f_list, w_list, held = [], [], []

    def hold(R, secs):
        n = int(round(secs * sc.rate_hz))
        held.append(R.T @ np.array([0, 0, 1.0]))
        f_list.append(np.tile(held[-1], (n, 1)))
        w_list.append(np.zeros((n, 3)))

    hold(Rs[0], sc.rest_s)
    clip = set(rng.choice(sc.poses, sc.clip_moves, replace=False).tolist()) if sc.clip_moves else set()
    for i in range(sc.poses):
        v = log_so3(Rs[i].T @ Rs[i + 1])
        if sc.weak_axis is not None:  # the same angle, about an axis in the plane perpendicular to it
            norm = np.linalg.norm(v)
            v[sc.weak_axis] = 0.0
            v *= norm / max(float(np.linalg.norm(v)), 1e-12)
        theta = np.linalg.norm(v)
        if i in clip:  # a fast whirl: one extra full turn in 0.1 s, far beyond full scale
            v = v * (theta + 2 * np.pi) / max(float(theta), 1e-9)
            T = 0.1
        else:
            T = max(sc.move_s, 1.875 * np.degrees(theta) / sc.peak_rate_dps)  # s' peaks at 1.875/T
        n = int(round(T * sc.rate_hz)) | 1  # odd: a sample at the peak
        T = n / sc.rate_hz
        u = (np.arange(n) + 0.5) / n
        s = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
        ds = (30 * u ** 2 - 60 * u ** 3 + 30 * u ** 4) / T
        R_t = Rs[i] @ exp_so3(s[:, None] * v)
        f_list.append(np.einsum("nji,j->ni", R_t, np.array([0, 0, 1.0])))
        w_list.append(np.degrees(ds[:, None] * v))
        Rs[i + 1] = Rs[i] @ exp_so3(v)  # the pose the move really reaches
        hold(Rs[i + 1], sc.pose_s)
    return np.vstack(f_list), np.vstack(w_list), clip, np.array(held)


def _unit(rng):
    """The unit's own truth: (M_a, b_a g, M_g, b_g deg/s)."""
    M_a = np.eye(3) + np.tril(rng.uniform(-0.01, 0.01, (3, 3)))
    b_a = rng.uniform(-0.05, 0.05, 3)
    M_g = np.eye(3) + rng.uniform(-0.01, 0.01, (3, 3)) + np.diag(rng.uniform(-0.03, 0.03, 3))
    return M_a, b_a, M_g, rng.uniform(-2, 2, 3)


def simulate_handheld(sc: HandheldScenario, seed=0, unit_seed=None):
    """(meta, samples, truth) of a simulated hand-placed session in counts: the unit drawn from unit_seed
    (default seed), the poses, moves and noise from seed (two seeds, one unit_seed: two sessions of one unit)."""
    rng = np.random.default_rng(seed)
    M_a, b_a, M_g, b_g = _unit(rng)  # drawn in any case, so that unit_seed = seed is the recording of seed alone
    if unit_seed is not None:
        M_a, b_a, M_g, b_g = _unit(np.random.default_rng(unit_seed))
    if sc.dead_gyro_axis is not None:
        M_g[sc.dead_gyro_axis] = 0.0
    dt = 1 / sc.rate_hz
    f, w, clip, pose_f = _motion(sc, rng)
    n = len(f)
    out_g = f @ M_a.T + b_a
    gsign = -1.0 if sc.flip_gyro else 1.0
    out_dps = gsign * (w @ M_g.T) + b_g
    for sensor, planted, out, u, scale in (("acc", sc.acc_effects, out_g, f, 1.0),
                                          ("gyro", sc.gyro_effects, out_dps, w * DPH_PER_DPS, DPH_PER_DPS)):
        aux = AuxInputs({"t_s": np.arange(n) * dt, **specific_force(f)})
        for eid, value in planted.items():
            effect = EFFECTS[eid]
            if effect.sensor != sensor:
                raise InputError(f"{eid}: not a {sensor} effect (plant it under {effect.sensor}_effects)")
            out[:, effect.axis] += value * regressor(eid, u, aux) / scale
    acc = sc.offset_counts + sc.acc_counts_per_g * (out_g + rng.normal(0, sc.acc_noise_g, (n, 3)))
    gyro = sc.offset_counts + sc.gyro_counts_per_dps * (out_dps + rng.normal(0, sc.gyro_noise_dps, (n, 3)))
    lo = sc.offset_counts - sc.full_scale_dps * sc.gyro_counts_per_dps
    hi = sc.offset_counts + sc.full_scale_dps * sc.gyro_counts_per_dps
    gyro = np.clip(np.round(gyro), lo, hi)
    acc = np.round(acc)
    meta = {"acc_unit": "counts", "gyro_unit": "counts", "latitude_deg": 45.0,
            "acc_counts_per_g": [sc.acc_counts_per_g] * 3, "gyro_counts_per_dps": [sc.gyro_counts_per_dps] * 3,
            "full_scale": {"gyro": [lo, hi]}, "description": "simucal hand-placed session simulation"}
    # output = M f + bias with outputs in physical units: counts / nominal, offset in the bias
    truth = {"acc": {"M": M_a.tolist(), "bias": (b_a + sc.offset_counts / sc.acc_counts_per_g).tolist(),
                     "params": {EFFECTS[e].parameter: v for e, v in sc.acc_effects.items()}},
             "gyro": {"M": M_g.tolist(), "T": None if sc.dead_gyro_axis is not None else np.linalg.inv(M_g).tolist(),
                      "bias_dps": (b_g + sc.offset_counts / sc.gyro_counts_per_dps).tolist(),
                      "params": {EFFECTS[e].parameter: v for e, v in sc.gyro_effects.items()}},
             "clipped_moves": sorted(clip), "pose_directions_b": pose_f.tolist(), "seed": seed,
             "unit_seed": seed if unit_seed is None else unit_seed}
    samples = {"t_s": np.arange(n) * dt, "ax": acc[:, 0], "ay": acc[:, 1], "az": acc[:, 2],
               "gx": gyro[:, 0], "gy": gyro[:, 1], "gz": gyro[:, 2]}
    return meta, samples, truth


def write_handheld(folder, sc: HandheldScenario, seed=0):
    meta, samples, truth = simulate_handheld(sc, seed)
    io.write_set(folder, meta, samples, None, {"truth.json": truth})
    return truth


def simulate_still(seconds=1800.0, dt=0.01, arw_deg_sqrt_h=0.1, rrw_dph_sqrt_s=5 / 60, vrw_g_sqrt_s=50e-6,
                   seed=0, move=False):
    """A still stream in g and deg/h: white noise (angle random walk arw_deg_sqrt_h, velocity random
    walk vrw_g_sqrt_s) and a gyro rate random walk rrw_dph_sqrt_s (deg/h per sqrt(s)), the unit level
    (f = +1 g on z); `move`: it tips over half-way (a recording `simucal noise` refuses).
    (meta, samples, truth): truth the noise terms, in these units."""
    rng = np.random.default_rng(seed)
    n = int(seconds / dt)
    w = (arw_deg_sqrt_h * 60 / np.sqrt(dt) * rng.standard_normal((n, 3))
         + np.cumsum(rrw_dph_sqrt_s * np.sqrt(dt) * rng.standard_normal((n, 3)), axis=0) + [1.0, 2.0, 3.0])
    f = vrw_g_sqrt_s / np.sqrt(dt) * rng.standard_normal((n, 3)) + [0.0, 0.0, 1.0]
    if move:
        f[n // 2:] = f[n // 2:, [2, 1, 0]]
    samples = {"t_s": np.arange(n) * dt, **{c: f[:, j] for j, c in enumerate(("ax", "ay", "az"))},
               **{c: w[:, j] for j, c in enumerate(("gx", "gy", "gz"))}}
    meta = {"acc_unit": "g", "gyro_unit": "deg/h", "latitude_deg": 45.0,
            "description": f"simucal still stream, seed {seed}"}
    truth = {"noise": {"acc": {"vrw_g_sqrt_s": vrw_g_sqrt_s},
                       "gyro": {"arw_deg_sqrt_h": arw_deg_sqrt_h, "rrw_dph_sqrt_s": rrw_dph_sqrt_s}}}
    return meta, samples, truth


def write_still(folder: str | os.PathLike[str], seconds: float = 1800.0, dt: float = 0.01, arw_deg_sqrt_h: float = 0.1,
                rrw_dph_sqrt_s: float = 5 / 60, vrw_g_sqrt_s: float = 50e-6, seed: int = 0,
                move: bool = False) -> str | os.PathLike[str]:
    """simulate_still's stream written to `folder` (samples.csv and meta.json; no truth.json)."""
    meta, samples, _ = simulate_still(seconds, dt, arw_deg_sqrt_h, rrw_dph_sqrt_s, vrw_g_sqrt_s, seed, move)
    io.write_set(folder, meta, samples, None)
    return folder


WARMUP_T_REF_C = 37.5
# a MEMS board's bias per axis, coefficients of (T - WARMUP_T_REF_C)^0..3: g per degC^k and deg/h per degC^k
WARMUP_ACC_G = ((2e-3, 4e-5, -2e-6, 1e-6), (-1e-3, -3e-5, 1e-6, 2e-6), (1.5e-3, 2e-5, 3e-6, -1.5e-6))
WARMUP_GYRO_DPH = ((360.0, 5.0, -0.1, 0.04), (-180.0, -4.0, 0.08, 0.03), (90.0, 3.0, 0.05, -0.04))


def simulate_warmup(seed=0, seconds=1500.0, hz=50.0, wander=True):
    """A still board (z down) warming from 15 to 58 degC (a time constant of 500 s): a cubic bias in
    (T - WARMUP_T_REF_C) on every axis, white noise and (wander) a random walk of the bias in time, as a
    MEMS unit's; temp_c with 0.02 degC of noise. (meta, samples, truth): truth the curves' coefficients."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, seconds, 1 / hz)
    T = 15 + 45 * (1 - np.exp(-t / 500.0)) + rng.normal(0, 0.02, len(t))
    powers = (T - WARMUP_T_REF_C)[:, None] ** np.arange(4)

    def walk(step: float) -> np.ndarray | float:
        return np.cumsum(rng.normal(0, step, (len(t), 3)), axis=0) if wander else 0.0

    acc = np.array([0, 0, -1.0]) + powers @ np.array(WARMUP_ACC_G).T + rng.normal(0, 2e-3, (len(t), 3)) + walk(2e-6)
    gyro = powers @ np.array(WARMUP_GYRO_DPH).T + rng.normal(0, 180.0, (len(t), 3)) + walk(0.05)
    samples = {"t_s": t, **{c: acc[:, j] for j, c in enumerate(("ax", "ay", "az"))},
               **{c: gyro[:, j] for j, c in enumerate(("gx", "gy", "gz"))}, "temp_c": T}
    meta = {"acc_unit": "g", "gyro_unit": "deg/h", "latitude_deg": 47.0,
            "description": f"simucal warm-up of a still board, seed {seed}"}
    truth = {"t_ref_c": WARMUP_T_REF_C,
             "acc": {"bias_g": {f"b_{a}": list(WARMUP_ACC_G[i]) for i, a in enumerate("xyz")}},
             "gyro": {"bias_dph": {f"b_{a}": list(WARMUP_GYRO_DPH[i]) for i, a in enumerate("xyz")}}}
    return meta, samples, truth
