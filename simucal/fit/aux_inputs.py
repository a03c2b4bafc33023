"""The auxiliary inputs of error-model terms, carried by name (derive/frames.py AUX_INPUTS).

Names are the models' symbols: temp_c (degC) and t_s (s), f_x f_y f_z (the specific
force in b, g, that gyro terms see), w2 (w_T^2 / g, 1/m, that accelerometer terms see
under outer-axis rate), and any samples.csv column a user's term names (e.g. supply_v).
A generated model takes them as one array in its own order (its AUX); `array` builds it.
Adding an input is a symbol in the derivation and a column in the data: nothing here
names a particular one beyond the built-in defaults.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simucal.errors import CalibrationError
from simucal.generated.effects import AUX as SENSOR_AUX
from simucal.io import SAMPLE_COLS

DEFAULT_ZERO = set(SENSOR_AUX["acc"]) | set(SENSOR_AUX["gyro"])  # built-in inputs: 0 where the data have none
NOT_AUX_COLUMNS = ("segment",) + SAMPLE_COLS  # samples.csv's key and outputs
FORCE = ("f_x", "f_y", "f_z")  # the specific force in b, as gyro terms read it


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
        if shape is None:
            shape = np.broadcast_shapes(*(np.shape(v) for v in self.values.values()))
        out = np.zeros(tuple(shape) + (len(names),))
        for j, n in enumerate(names):
            if n in self.values:
                out[..., j] = self.values[n]
        return out

    def take(self, idx) -> AuxInputs:
        """The rows idx of every per-row input (scalars stay)."""
        return AuxInputs({k: (np.asarray(v)[idx] if np.ndim(v) else v) for k, v in self.values.items()})

    def with_values(self, **values) -> AuxInputs:
        return AuxInputs({**self.values, **values})

    def get(self, name, default=0.0):
        return self.values.get(name, default)


def specific_force(f_b_g) -> dict:
    """{f_x, f_y, f_z} of a specific force (..., 3) in g, for AuxInputs."""
    f = np.asarray(f_b_g, float)
    return {name: f[..., j] for j, name in enumerate(FORCE)}


def column_means(samples: dict, groups) -> dict:
    """Each auxiliary samples.csv column (t_s, temp_c, a user's supply_v, ...: every column
    but the keys and outputs) averaged over each group of rows (boolean masks or index arrays)."""
    return {c: np.array([np.mean(v[g]) for g in groups]) for c, v in samples.items() if c not in NOT_AUX_COLUMNS}


def columns_at(samples: dict, idx) -> dict:
    """Each auxiliary samples.csv column at the rows idx (any shape of indices)."""
    return {c: np.asarray(v)[idx] for c, v in samples.items() if c not in NOT_AUX_COLUMNS}
