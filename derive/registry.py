"""The models `simucal derive` generates by default.

`acc_baseline` and `gyro_baseline` are dong2018 eq. 5 and 9; `acc_extended`
and `gyro_extended` show user-extended models (three extra terms each; the
gyro one uses the specific force) and are what the tests and the benchmark use
for "a model with extra terms". A user's own model file is a
Python file defining MODELS = [ErrorModel, ...]; see README.
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

from .models import ErrorModel
from .models.baseline import ACC_BASELINE, GYRO_BASELINE
from .models.effects import CANDIDATES

ACC_EXTENDED = ACC_BASELINE.with_terms(
    "acc_extended", [CANDIDATES["acc.quadratic.z"], CANDIDATES["acc.cross_coupling.xy"],
                     CANDIDATES["acc.bias_drift_time.y"]])

GYRO_EXTENDED = GYRO_BASELINE.with_terms(
    "gyro_extended", [CANDIDATES["gyro.g_sensitivity.xz"], CANDIDATES["gyro.quadratic.y"],
                      CANDIDATES["gyro.bias_temperature.z"]])

BUILTIN = (ACC_BASELINE, GYRO_BASELINE, ACC_EXTENDED, GYRO_EXTENDED)


def load_model_file(path) -> list[ErrorModel]:
    """Read MODELS from a user's model file, with errors that name the file."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file")
    spec = importlib.util.spec_from_file_location(f"simucal_user_model_{path.stem}", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    models = getattr(mod, "MODELS", None)
    if not isinstance(models, (list, tuple)) or not models or not all(isinstance(m, ErrorModel) for m in models):
        raise ValueError(f"{path}: must define MODELS = [ErrorModel, ...] "
                         "(e.g. ACC_BASELINE.with_terms('my_model', [acc_quadratic('z')]))")
    return list(models)
