"""The auxiliary inputs of error-model terms, carried by name (derive/frames.py AUX_INPUTS).

Names are the models' symbols: temp_c (degC), dtemp_c = temp_c - T_ref (degC; T_ref is
carried as the scalar t_ref_c, the calibration's reference temperature, so that dtemp_c
follows temp_c wherever rows are taken) and t_s (s), f_x f_y f_z (the specific
force in b, g, that gyro terms see), w2 (w_T^2 / g, 1/m, that accelerometer terms see
under outer-axis rate), and any samples.csv column a user's term names (e.g. supply_v).
A generated model takes them as one array in its own order (its AUX); `array` builds it.
Adding an input is a symbol in the derivation and a column in the data: nothing here
names a particular one beyond the built-in defaults.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from simucal.errors import CalibrationError
from simucal.generated.effects import AUX as SENSOR_AUX
from simucal.io import SAMPLE_COLS, run_or_rows, units

DEFAULT_ZERO = set(SENSOR_AUX["acc"]) | set(SENSOR_AUX["gyro"])  # built-in inputs: 0 where the data have none
NOT_AUX_COLUMNS = ("segment",) + SAMPLE_COLS  # samples.csv's key and outputs
FORCE = ("f_x", "f_y", "f_z")  # the specific force in b, as gyro terms read it
T_REF = "t_ref_c"  # not an input: the reference temperature T_ref (degC) that dtemp_c is taken from


@dataclass(frozen=True)
class AuxInputs:
    """name -> a scalar, or one value per row (arrays broadcast against the rows)."""

    values: dict = field(default_factory=dict)

    def array(self, names, shape=None) -> np.ndarray:
        """(*shape, len(names)): the inputs in a model's order. shape defaults to the
        broadcast of the values' shapes. A built-in input left out is 0; a column a term
        needs but the data lack is refused, naming it."""
        missing = [n for n in names if n not in self.values and n not in DEFAULT_ZERO]
        if missing:
            raise CalibrationError(
                f"the model's terms read the auxiliary input(s) {missing}, which these data lack: add "
                f"{' and '.join(missing)} column(s) to samples.csv (a value per row), or drop the terms that use them")
        values = self.values
        if "dtemp_c" in names and "dtemp_c" not in values and "temp_c" in values:
            if T_REF not in values:  # a programming error: every reader of temp_c states its reference
                raise RuntimeError("temp_c without its reference t_ref_c (aux_inputs.T_REF)")
            values = {**values, "dtemp_c": np.asarray(values["temp_c"], float) - values[T_REF]}
        if shape is None:
            shape = np.broadcast_shapes(*(np.shape(v) for k, v in values.items() if k != T_REF))
        out = np.zeros(tuple(shape) + (len(names),))
        for j, n in enumerate(names):
            if n in values:
                out[..., j] = values[n]
        return out

    def column(self, name, n) -> np.ndarray:
        """One input (dtemp_c included) as n values."""
        return self.array((name,), (n,))[:, 0]

    def take(self, idx) -> AuxInputs:
        """The rows idx of every per-row input (scalars stay)."""
        return AuxInputs({k: (np.asarray(v)[idx] if np.ndim(v) else v) for k, v in self.values.items()})

    def with_values(self, **values) -> AuxInputs:
        return AuxInputs({**self.values, **values})

    def get(self, name, default=0.0):
        return self.values.get(name, default)


MOTION = tuple(f"{q}_{a}" for q in ("wb", "dwb") for a in "xyz")  # the body rate and its change, as acc terms read them


def motion(w_b_dph, dt_s) -> dict[str, NDArray[np.float64]]:
    """{wb_x.., dwb_x..}: a body rate (deg/h in, rad/s out) at each step and its rate of change (rad/s^2):
    what the accelerometers' lever arms and time delay read (derive/frames.py), from the gyros in the
    systematic filter and from the true motion in the sequence simulator. The change is the central
    difference (w_{k+1} - w_{k-1}) / (2 dt_k) over each step's own length dt_k: a sample of a move gets
    the central difference of the samples, and a block at rest (the filter's) the share that spills into
    its first and last samples, so that the steps' changes add up to each move's whole change of rate (a
    table's 0.2 s accelerations: differences taken over the blocks' centres, or a smoothed rate, lost
    part of it, which a lever arm turned into velocity errors 60 times the zero-velocity noise).
    Not smoothed: the differences of a MEMS gyro's noise are a fraction of its accelerometers' noise."""
    w = np.asarray(w_b_dph, float) * units.RAD_S_PER_DPH
    padded = np.concatenate([w[:1], w, w[-1:]])
    dw = (padded[2:] - padded[:-2]) / (2.0 * np.asarray(dt_s, float).reshape(-1, 1))
    return {**{f"wb_{a}": w[:, j] for j, a in enumerate("xyz")}, **{f"dwb_{a}": dw[:, j] for j, a in enumerate("xyz")}}


def specific_force(f_b_g) -> dict[str, NDArray[np.float64]]:
    """{f_x, f_y, f_z} of a specific force (..., 3) in g, for AuxInputs."""
    f = np.asarray(f_b_g, float)
    return {name: f[..., j] for j, name in enumerate(FORCE)}


def _with_reference(out: dict, t_ref_c) -> dict:
    """out with T_ref where it has temp_c (None: 0 degC, as files without t_ref_c meant)."""
    if "temp_c" in out:
        out[T_REF] = 0.0 if t_ref_c is None else float(t_ref_c)
    return out


def column_means(samples: dict, groups, *, t_ref_c) -> dict[str, NDArray[np.float64] | float]:
    """Each auxiliary samples.csv column (t_s, temp_c, a user's supply_v, ...: every column
    but the keys and outputs) averaged over each group of rows (boolean masks or index arrays),
    with T_ref (t_ref_c, degC) for dtemp_c, and each group's temperature rate (fit/thermal.group_rates)."""
    from simucal.fit.thermal import group_rates
    groups = [run_or_rows(g) if np.asarray(g).dtype.kind in "iu" else g for g in groups]  # a run: a view, no copy
    return _with_reference({**{c: np.array([np.mean(v[g]) for g in groups]) for c, v in samples.items()
                               if c not in NOT_AUX_COLUMNS}, **group_rates(samples, groups)}, t_ref_c)


def columns_at(samples: dict, idx, *, t_ref_c) -> dict[str, NDArray[np.float64] | float]:
    """Each auxiliary samples.csv column at the rows idx (any shape of indices), with T_ref."""
    return _with_reference({c: np.asarray(v)[idx] for c, v in samples.items() if c not in NOT_AUX_COLUMNS}, t_ref_c)
