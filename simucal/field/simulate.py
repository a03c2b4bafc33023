"""Field simulation for ruan2019: a low-grade IMU static at three positions.

Position 1 about level with x about north, 2 yawed about 90 deg, 3 rolled
about 20 deg from 2; each held `duration_s` at `rate_hz`. Truth: exact
attitudes (generated/field.py), Earth rate at the latitude, gyro constant
drift, angle random walk, accelerometer bias and noise. The north
reference's heading per position, with its error, goes to segments.csv
(heading_ref_deg).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from simucal import io
from simucal.generated import field as gen
from simucal.io import units


@dataclass
class FieldScenario:
    latitude_deg: float = 34.0
    attitudes_deg: tuple = ((0.0, 0.4, -0.3), (90.0, 0.3, 0.5), (90.0, -0.2, 20.0))  # heading, pitch, roll
    attitude_jitter_deg: float = 2.0       # random change of each nominal angle ("about")
    heading_error_deg: float = 5.0         # the reference's error, uniform +- this, per position
    duration_s: float = 300.0
    rate_hz: float = 100.0
    drift_dph: tuple | None = None         # None: random, 1-10 deg/h each, random sign
    arw_deg_per_sqrt_h: float = 0.01
    acc_bias_mps2: float = 0.01
    acc_noise_mps2: float = 5e-4           # per sample
    gravity_mps2: float = 9.7966


def _unit(sc: FieldScenario, rng):
    """The unit's own truth: its gyro drift (deg/h) and accelerometer bias (m/s^2)."""
    drift = (np.array(sc.drift_dph) if sc.drift_dph is not None
             else rng.uniform(1, 10, 3) * rng.choice([-1, 1], 3))
    return drift, rng.uniform(-1, 1, 3) * sc.acc_bias_mps2


def simulate_field(sc: FieldScenario, seed: int = 0, unit_seed: int | None = None):
    """(meta, samples, segments, truth): the unit drawn from unit_seed (default seed), the attitudes, the
    heading reference's error and the noise from seed (two seeds, one unit_seed: two recordings of one unit)."""
    rng = np.random.default_rng(seed)
    lat = np.radians(sc.latitude_deg)
    w_e = np.radians(units.DEFAULT_EARTH_RATE_DPH / units.DPH_PER_DPS)
    w_ie_n = gen.earth_rate_n(w_e, lat)
    drift, acc_bias = _unit(sc, rng)  # drawn in any case, so that unit_seed = seed is the recording of seed alone
    if unit_seed is not None:
        drift, acc_bias = _unit(sc, np.random.default_rng(unit_seed))
    n = int(round(sc.duration_s * sc.rate_hz))
    dt = 1 / sc.rate_hz
    sigma_w = np.radians(sc.arw_deg_per_sqrt_h / 60) / np.sqrt(dt)  # rad/s per sample
    segments, true_att = [], []
    cols: dict[str, list[np.ndarray]] = {c: [] for c in ("segment", "t_s", "ax", "ay", "az", "gx", "gy", "gz")}
    t0 = 0.0
    for k, (h, p, r) in enumerate(sc.attitudes_deg, start=1):
        att = np.array([h, p, r]) + rng.uniform(-1, 1, 3) * sc.attitude_jitter_deg * np.array([1, 0.2, 1])
        C = gen.C_b_n(*np.radians(att))
        f_b = C.T @ np.array([0.0, sc.gravity_mps2, 0.0]) + acc_bias
        w_b = C.T @ w_ie_n + np.radians(drift / units.DPH_PER_DPS)
        f = f_b + rng.normal(0, sc.acc_noise_mps2, (n, 3))
        w = w_b + rng.normal(0, sigma_w, (n, 3))
        ref = att[0] + rng.uniform(-1, 1) * sc.heading_error_deg
        segments.append(io.Segment(k, "static", None, None, None, 0.0, float(ref)))
        true_att.append({"segment": k, "heading_deg": att[0], "pitch_deg": att[1], "roll_deg": att[2],
                         "heading_ref_error_deg": ref - att[0]})
        cols["segment"].append(np.full(n, k))
        cols["t_s"].append(t0 + np.arange(n) * dt)
        for j, c in enumerate("xyz"):
            cols["a" + c].append(f[:, j])
            cols["g" + c].append(np.degrees(w[:, j]))
        t0 += sc.duration_s + 60.0
    samples = {c: np.concatenate(v) for c, v in cols.items()}
    meta = {"latitude_deg": sc.latitude_deg, "gravity_mps2": sc.gravity_mps2,
            "earth_rate_dph": units.DEFAULT_EARTH_RATE_DPH, "acc_unit": "m/s^2", "gyro_unit": "deg/s",
            "description": "simucal field simulation (ruan2019 three positions); body axes Forward-Up-Right"}
    truth = {"gyro_drift_dph": drift.tolist(), "acc_bias_mps2": acc_bias.tolist(), "positions": true_att,
             "arw_deg_per_sqrt_h": sc.arw_deg_per_sqrt_h, "seed": seed,
             "unit_seed": seed if unit_seed is None else unit_seed}
    return meta, samples, segments, truth


def write_field(folder, sc: FieldScenario, seed: int = 0):
    meta, samples, segments, truth = simulate_field(sc, seed)
    io.write_set(folder, meta, samples, segments, {"truth.json": truth})
    return truth
