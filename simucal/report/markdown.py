"""Plain-text reports: calibrations beside the truth, in the paper's layout."""
from __future__ import annotations

import numpy as np

ENTRIES = [  # (label, sensor, getter) in dong2018 Table 3's order
    ("dK_x^g", "gyro", lambda r: r["M"][0][0] - 1), ("dK_y^g", "gyro", lambda r: r["M"][1][1] - 1),
    ("dK_z^g", "gyro", lambda r: r["M"][2][2] - 1),
    ("b_x^g deg/h", "gyro", lambda r: r["bias"][0]), ("b_y^g deg/h", "gyro", lambda r: r["bias"][1]),
    ("b_z^g deg/h", "gyro", lambda r: r["bias"][2]),
    ("m_12^g", "gyro", lambda r: r["M"][0][1]), ("m_13^g", "gyro", lambda r: r["M"][0][2]),
    ("m_21^g", "gyro", lambda r: r["M"][1][0]), ("m_23^g", "gyro", lambda r: r["M"][1][2]),
    ("m_31^g", "gyro", lambda r: r["M"][2][0]), ("m_32^g", "gyro", lambda r: r["M"][2][1]),
    ("dK_x^a", "acc", lambda r: r["M"][0][0] - 1), ("dK_y^a", "acc", lambda r: r["M"][1][1] - 1),
    ("dK_z^a", "acc", lambda r: r["M"][2][2] - 1),
    ("b_x^a g", "acc", lambda r: r["bias"][0]), ("b_y^a g", "acc", lambda r: r["bias"][1]),
    ("b_z^a g", "acc", lambda r: r["bias"][2]),
    ("theta_yx rad", "acc", lambda r: r["M"][1][0]), ("theta_zx rad", "acc", lambda r: r["M"][2][0]),
    ("theta_zy rad", "acc", lambda r: r["M"][2][1]),
]


def header(cells) -> str:
    """The two header lines of a markdown table."""
    return "| " + " | ".join(cells) + " |\n" + "|---" * len(cells) + "|"


def entries(result: dict) -> np.ndarray:
    return np.array([get(result[s]) for _, s, get in ENTRIES])


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
