"""A simulated production lot: units of one design whose error parameters scatter about the design's
values (each unit its own draw, its own noise seed and unit_serial), for `simucal lot`'s checks and
`benchmarks/bench_lot.py`. Planted outliers are offsets added to named parameters of named units."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from simucal import io
from simucal.turntable.simulate import Scenario, simulate

# The unit-to-unit std of each parameter about Scenario's values (a lot of one design): scale
# factors and biases a few hundred ppm / ug, misalignments 50 urad; the gyro bias 0.02 deg/h.
SPREAD = {"acc": {"dK": 2e-4, "theta": 5e-5, "b": 2e-4}, "gyro": {"dK": 2e-4, "phi": 5e-5, "b": 0.02}}


def unit_scenario(base: Scenario, rng, planted=None, spread: float = 1.0) -> Scenario:
    """base with each parameter drawn about its value with spread x SPREAD; planted: {"acc.b_x": offset} added."""
    planted = planted or {}
    drawn = {}
    for s in ("acc", "gyro"):
        params = dict(getattr(base, f"{s}_params"))
        for name, v in params.items():
            scatter = spread * SPREAD[s][name.split("_")[0]] * rng.standard_normal()
            params[name] = v + scatter + planted.get(f"{s}.{name}", 0.0)
        drawn[f"{s}_params"] = params
    return replace(base, acc_params=drawn["acc_params"], gyro_params=drawn["gyro_params"])


def _write(folder, sc, noise_seed, serial) -> Path:
    meta, samples, segments, truth = simulate(sc, seed=noise_seed)
    meta["unit_serial"] = serial
    io.write_set(folder, meta, samples, segments, {"truth.json": truth})
    return Path(folder)


def write_lot(folder, n: int, seed: int = 0, planted=None, again: int = 0, drift=None,
              base: Scenario | None = None) -> list[Path]:
    """n simulated units, each a set unitNNNN with meta.json's unit_serial SN-<seed>-NNNN and its truth.json;
    planted: {unit index: {"acc.b_x": offset}}; the first `again` units recorded a second time
    (unitNNNN_b, the same unit with other noise), drift: {unit index: {"gyro.b_z": offset}} added to
    that second recording's truth. Returns the sets' folders."""
    base = base or Scenario()
    rng = np.random.default_rng([seed, 41])
    planted, drift = planted or {}, drift or {}
    out = []
    for i in range(n):
        sc = unit_scenario(base, rng, planted.get(i))
        serial, name = f"SN-{seed}-{i:04d}", Path(folder) / f"unit{i:04d}"
        out.append(_write(name, sc, seed * 100_003 + i, serial))
        if i < again:
            moved = unit_scenario(sc, rng, drift.get(i), spread=0.0)
            out.append(_write(f"{name}_b", moved, seed * 100_003 + 50_000 + i, serial))
    return out
