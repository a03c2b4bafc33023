"""Test plans: commanded table angles (degrees).

Table 1 of dong2018: 12 positions whose gravity (or outer-axis) directions
in k are the vertices of a regular icosahedron; Table 2: the four positions
for frame unification. Generated plans: spherical Fibonacci sets.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

# (outer gamma, middle alpha, inner beta), dong2018 Table 1. The paper prints
# 148.282 and 31.717 for positions 3 and 4; the icosahedron needs
# atan(m/n) = 31.7175 deg exactly (see the audit), used here.
ICO = float(np.degrees(np.arctan2(np.sqrt(50 - 10 * np.sqrt(5)), np.sqrt(50 + 10 * np.sqrt(5)))))
TABLE1 = [
    (30, 0, -ICO), (60, 0, 180 + ICO), (90, 0, 180 - ICO), (120, 0, ICO),
    (150, 90 - ICO, 0), (180, 90 + ICO, 0), (210, -(90 - ICO), 0), (240, 180 + 90 - ICO, 0),
    (270, 180 - ICO, 90), (300, 180 + ICO, 90), (330, ICO, 90), (0, -ICO, 90),
]
TABLE2 = [(0, 0, 0), (0, 90, 0), (180, 0, 0), (180, 90, 0)]  # (gamma, alpha, beta)


def fibonacci(n: int):
    """n angles (gamma, alpha, beta) putting f^k on a spherical Fibonacci set."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    r = np.sqrt(1 - z ** 2)
    f = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    # f^k = Ry(-beta) Rx(-alpha) z = [-cos(a) sin(b), sin(a), cos(a) cos(b)]
    alpha = np.degrees(np.arcsin(np.clip(f[:, 1], -1, 1)))
    beta = np.degrees(np.arctan2(-f[:, 0], f[:, 2]))
    gamma = (np.arange(n) * 360.0 / n) % 360
    return [tuple(map(float, x)) for x in zip(gamma, alpha, beta)]


def read_csv(path) -> list:
    """A user's plan: CSV with columns outer_deg, middle_deg, inner_deg."""
    path = Path(path)
    out = []
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        need = {"outer_deg", "middle_deg", "inner_deg"}
        if not need <= set(reader.fieldnames or []):
            raise ValueError(f"{path}, line 1: plan needs columns {sorted(need)}")
        for line, row in enumerate(reader, start=2):
            try:
                out.append(tuple(float(row[c]) for c in ("outer_deg", "middle_deg", "inner_deg")))
            except (TypeError, ValueError):
                raise ValueError(f"{path}, line {line}: angles must be numbers") from None
    return out


PLANS = {"table1": lambda: TABLE1, "fibonacci24": lambda: fibonacci(24), "fibonacci48": lambda: fibonacci(48)}
