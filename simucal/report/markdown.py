"""Plain-text reports: calibrations beside the truth, in the paper's layout."""
from __future__ import annotations

import numpy as np

ENTRIES = [  # (label, sensor, getter of M and bias) in dong2018 Table 3's order
    ("dK_x^g", "gyro", lambda M, b: M[0][0] - 1), ("dK_y^g", "gyro", lambda M, b: M[1][1] - 1),
    ("dK_z^g", "gyro", lambda M, b: M[2][2] - 1),
    ("b_x^g deg/h", "gyro", lambda M, b: b[0]), ("b_y^g deg/h", "gyro", lambda M, b: b[1]),
    ("b_z^g deg/h", "gyro", lambda M, b: b[2]),
    ("m_12^g", "gyro", lambda M, b: M[0][1]), ("m_13^g", "gyro", lambda M, b: M[0][2]),
    ("m_21^g", "gyro", lambda M, b: M[1][0]), ("m_23^g", "gyro", lambda M, b: M[1][2]),
    ("m_31^g", "gyro", lambda M, b: M[2][0]), ("m_32^g", "gyro", lambda M, b: M[2][1]),
    ("dK_x^a", "acc", lambda M, b: M[0][0] - 1), ("dK_y^a", "acc", lambda M, b: M[1][1] - 1),
    ("dK_z^a", "acc", lambda M, b: M[2][2] - 1),
    ("b_x^a g", "acc", lambda M, b: b[0]), ("b_y^a g", "acc", lambda M, b: b[1]),
    ("b_z^a g", "acc", lambda M, b: b[2]),
    ("theta_yx rad", "acc", lambda M, b: M[1][0]), ("theta_zx rad", "acc", lambda M, b: M[2][0]),
    ("theta_zy rad", "acc", lambda M, b: M[2][1]),
]


def header(cells) -> str:
    """The two header lines of a markdown table."""
    return "| " + " | ".join(cells) + " |\n" + "|---" * len(cells) + "|"


def _linear(result, sensor):
    """(M, bias) of a sensor: a Calibration's block, or the simulator's truth (a dict)."""
    b = result[sensor] if isinstance(result, dict) else getattr(result, sensor)
    return (np.asarray(b["M"]), np.asarray(b["bias"])) if isinstance(b, dict) else (b.M, b.bias)


def entries(result) -> np.ndarray:
    """ENTRIES of a calibration or of the truth, in Table 3's order."""
    return np.array([get(*_linear(result, s)) for _, s, get in ENTRIES])


def compare_table(results: dict, truth: dict) -> str:
    """Markdown table: truth and each method's estimate and error."""
    t = entries(truth)
    methods = list(results)
    lines = [header(["entry", "truth"] + [c for m in methods for c in (m, f"{m} error")])]
    est = {m: entries(results[m]) for m in methods}
    for i, (label, _, _) in enumerate(ENTRIES):
        cells = [label, f"{t[i]:.6g}"]
        for m in methods:
            cells += [f"{est[m][i]:.6g}", f"{est[m][i] - t[i]:+.2e}"]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
