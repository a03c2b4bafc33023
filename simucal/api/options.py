"""calibrate's options by their Python names, typed: `simucal.calibrate(data, **options)`
and `simucal.calibrate_each` take them as keyword arguments checked by a type checker (PEP 692), so that
`methd="exact"` or `add=3` is an error in the notebook's editor, not only at run time. Each is the
command line's option of the same name (docs/commands.md). The functions name it as
`**options: Unpack[CalibrateOptions]`, Unpack imported for the checker only (typing's is Python 3.11's;
the annotations are strings at run time, PEP 563)."""
from __future__ import annotations

import os
from typing import Literal, Sequence, TypedDict

from simucal.handheld.static_detect import DetectSettings

# "auto" and methods.NAMES (tests/test_api.py checks that they agree)
Method = Literal["auto", "exact", "linear", "multiposition", "ferraris", "handheld", "field", "systematic"]


class CalibrateOptions(TypedDict, total=False):
    """What `simucal calibrate` takes beside the data."""
    method: Method                        # --method
    add: str | Sequence[str]              # --add: effect ids, model files, "auto"; one as a string
    acc_model: str                        # --acc-model, --gyro-model: a built-in's name or a model file
    gyro_model: str
    acc_noise_g: float | None             # the noise of one row where the data cannot give it (g, deg/h)
    gyro_noise_dph: float | None
    heading_accuracy_deg: float | None    # a field set's north reference
    t_ref_c: float | None                 # T_ref of temperature terms, degC
    noise: str | os.PathLike[str] | None  # a noise.json of `simucal noise`
    detect: DetectSettings | None         # a stream's static detection
    timestamps: Literal["auto", "recorded", "nominal"]  # a stream's clock
    thermal: bool                         # --thermal: one set whose temperature ramps
    thermal_degree: int | None            # --thermal-degree
