"""A term simucal diagnose found, as the text of a model file that `--add FILE` accepts (the term's
numbers: fit/lack_of_fit.describe_shape)."""
from __future__ import annotations

from simucal.fit.models import manifest


def model_file_text(base_model: str, effect_ids, shape: dict, sensor: str) -> str:
    """A model file (MODELS = [...]) with the found term added to the base model and effects."""
    const = {"acc_baseline": "ACC_BASELINE", "gyro_baseline": "GYRO_BASELINE",
             "acc_extended": "ACC_EXTENDED", "gyro_extended": "GYRO_EXTENDED"}
    if base_model not in const or base_model not in manifest()["models"]:
        base_model = f"{sensor}_baseline"
    src = "simucal.derive.models.baseline" if base_model.endswith("baseline") else "simucal.derive.registry"
    extra = "".join(f"    CANDIDATES[{e!r}],\n" for e in effect_ids)
    meaning = f"{shape['axis']} output {shape['parity']} (found by simucal diagnose)"
    return (f'"""A model with the term simucal diagnose found: {shape["text"]}.\n\n'
            f"Use it: simucal calibrate DIR --add THIS_FILE (or diagnose --add THIS_FILE).\n"
            '"""\n'
            "from simucal.derive.frames import column_input, dtemp_c, f_b, omega_d, t_s, temp_c, w2  # noqa: F401\n"
            "from simucal.derive.models import Term\n"
            "from simucal.derive.models.effects import CANDIDATES  # noqa: F401\n"
            f"from {src} import {const[base_model]}\n\n"
            f"MODELS = [{const[base_model]}.with_terms({sensor + '_found_' + shape['parameter']!r}, [\n"
            f"{extra}"
            f"    Term({shape['parameter']!r}, {shape['axis']!r}, {shape['sympy']}, {shape['unit']!r},\n"
            f"         {meaning!r}),\n"
            "])]\n")
