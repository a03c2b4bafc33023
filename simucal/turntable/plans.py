"""Test plans: commanded table angles (degrees).

Table 1 of dong2018: 12 positions whose gravity (or outer-axis) directions
in k are the vertices of a regular icosahedron; Table 2: the four positions
for frame unification. Generated plans: spherical Fibonacci sets.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from simucal.errors import InputError
from simucal.generated import unify

# (outer gamma, middle alpha, inner beta), dong2018 Table 1. The paper prints
# 148.282 and 31.717 for positions 3 and 4; the icosahedron needs
# atan(m/n) = 31.7175 deg exactly (see the audit), used here.
ICO = float(np.degrees(np.arctan2(np.sqrt(50 - 10 * np.sqrt(5)), np.sqrt(50 + 10 * np.sqrt(5)))))
TABLE1 = [
    (30, 0, -ICO), (60, 0, 180 + ICO), (90, 0, 180 - ICO), (120, 0, ICO),
    (150, 90 - ICO, 0), (180, 90 + ICO, 0), (210, -(90 - ICO), 0), (240, 180 + 90 - ICO, 0),
    (270, 180 - ICO, 90), (300, 180 + ICO, 90), (330, ICO, 90), (0, -ICO, 90),
]
TABLE2 = [(g, a, 0.0) for a, g in unify.TABLE2]  # (gamma, alpha, beta): dong2018 Table 2, from derive/unify.py


def angles_for(f_k):
    """Commanded (gamma, alpha, beta) putting f^k on the given unit directions.

    f^k = Ry(-beta) Rx(-alpha) z = [-cos(a) sin(b), sin(a), cos(a) cos(b)];
    gamma only turns the Earth rate, so it is spread evenly.
    """
    f = np.asarray(f_k, float)
    f = f / np.linalg.norm(f, axis=1, keepdims=True)
    alpha = np.degrees(np.arcsin(np.clip(f[:, 1], -1, 1)))
    beta = np.degrees(np.arctan2(-f[:, 0], f[:, 2]))
    gamma = (np.arange(len(f)) * 360.0 / len(f)) % 360
    return [tuple(map(float, x)) for x in zip(gamma, alpha, beta)]


def fibonacci_directions(n: int) -> np.ndarray:
    """n unit vectors spread evenly on the sphere (a spherical Fibonacci set)."""
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5 ** 0.5) * i
    r = np.sqrt(1 - z ** 2)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def fibonacci(n: int) -> list[tuple[float, ...]]:
    """n positions with f^k on a spherical Fibonacci set."""
    return angles_for(fibonacci_directions(n))


def dodecahedron() -> list[tuple[float, ...]]:
    """20 positions with f^k on the vertices of a regular dodecahedron."""
    g = (1 + 5 ** 0.5) / 2
    v: list[tuple[float, float, float]] = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    for a in (-1 / g, 1 / g):
        for b in (-g, g):
            v += [(0, a, b), (a, b, 0), (b, 0, a)]
    return angles_for(np.array(v))


def read_csv(path) -> list:
    """A user's plan: CSV with columns outer_deg, middle_deg, inner_deg."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"plan {path}: no such file; a plan is one of {sorted(PLANS)} or a CSV file with "
                         "columns outer_deg, middle_deg, inner_deg")
    out = []
    with path.open(newline="") as fh:
        reader = csv.DictReader(fh)
        need = {"outer_deg", "middle_deg", "inner_deg"}
        if not need <= set(reader.fieldnames or []):
            raise InputError(f"{path}, line 1: plan needs columns {sorted(need)}")
        for line, row in enumerate(reader, start=2):
            try:
                angles = tuple(float(row[c]) for c in ("outer_deg", "middle_deg", "inner_deg"))
            except (TypeError, ValueError):
                raise InputError(f"{path}, line {line}: angles must be numbers") from None
            if not all(math.isfinite(a) and abs(a) <= 3600 for a in angles):
                raise InputError(f"{path}, line {line}: angles {angles} must be finite, in degrees (|angle| <= 3600)")
            out.append(angles)
    if not out:
        raise InputError(f"{path}: the plan has no positions; give one row per position under the header")
    return out


PLANS: dict[str, Callable[[], Sequence[Sequence[float]]]] = {"table1": lambda: TABLE1, "dodecahedron20": dodecahedron,
         "fibonacci24": lambda: fibonacci(24), "fibonacci48": lambda: fibonacci(48)}
