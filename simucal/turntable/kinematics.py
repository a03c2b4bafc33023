"""The table's kinematics for batches of simulated rows (derive/table.py): compiled from
generated/table.c into the cache where a C compiler is found, else the SymPy-printed numpy of
generated/table.py (the same derivation, the same numbers to round-off).

Angles in rad, broadcast against the rows of angle_err. table_err: (tilt_x, tilt_y, nonperp_om,
nonperp_mi) in rad, shared by the batch; angle_err (..., 3): (d_gamma, d_alpha, d_beta) in rad,
per row: together the TABLE_ERRORS of generated/table.py, in that order.
"""
from __future__ import annotations

import functools

import numpy as np

from simucal.fit.models import generated_dir
from simucal.io.cache import compile_c
from simucal.generated import table


@functools.lru_cache(maxsize=1)
def compiled():
    """The compiled library (ctypes), or None without a compiler (SIMUCAL_NO_COMPILE too)."""
    path = compile_c("table", (generated_dir() / "table.c").read_text())
    if path is None:
        return None
    import ctypes
    lib = ctypes.CDLL(str(path))
    d = np.ctypeslib.ndpointer(dtype=float, flags="C_CONTIGUOUS")
    lib.simucal_specific_force_k_batch.argtypes = [ctypes.c_int, d, d, d, d, d, d]
    lib.simucal_outer_axis_k_batch.argtypes = [ctypes.c_int, d, d, d, d, d]
    return lib


def errors(table_err, angle_err) -> np.ndarray:
    """The seven TABLE_ERRORS per row (..., 7)."""
    e = np.empty(np.shape(angle_err)[:-1] + (7,))
    e[..., :4] = table_err
    e[..., 4:] = angle_err
    return e


def _rows(angle_err, angles):
    shape = np.shape(angle_err)[:-1]
    flat = [np.ascontiguousarray(np.broadcast_to(a, shape), dtype=float).reshape(-1) for a in angles]
    return flat, np.ascontiguousarray(angle_err, dtype=float).reshape(-1, 3), shape


def specific_force_k(gamma, alpha, beta, table_err, angle_err) -> np.ndarray:
    """f^k at rest (g), (..., 3): C_n^k z at the reached angles."""
    lib = compiled()
    if lib is None:
        return table.specific_force_k(gamma, alpha, beta, errors(table_err, angle_err))
    (g, a, b), e, shape = _rows(angle_err, (gamma, alpha, beta))
    out = np.empty((len(e), 3))
    if lib.simucal_specific_force_k_batch(len(e), g, a, b, np.asarray(table_err, float), e, out):
        raise MemoryError("simucal_specific_force_k_batch: no memory for its work area")
    return out.reshape(shape + (3,))


def outer_axis_k(alpha, beta, table_err, angle_err) -> np.ndarray:
    """The outer axis in k, (..., 3): a rate run's mean input direction over whole revolutions."""
    lib = compiled()
    if lib is None:
        return table.outer_axis_k(alpha, beta, errors(table_err, angle_err))
    (a, b), e, shape = _rows(angle_err, (alpha, beta))
    out = np.empty((len(e), 3))
    if lib.simucal_outer_axis_k_batch(len(e), a, b, np.asarray(table_err, float), e, out):
        raise MemoryError("simucal_outer_axis_k_batch: no memory for its work area")
    return out.reshape(shape + (3,))


def specific_force_turning_k(k_rev, alpha, beta, table_err, angle_err, axis_k) -> np.ndarray:
    """f^k at rest at k_rev equally spaced outer angles 0, 2 pi / k_rev, ... (k_rev, ..., 3): f^k at
    the first, then turned about the outer axis in k (axis_k, outer_axis_k's) by Rodrigues' formula,
    one evaluation of the kinematics instead of k_rev. Exact: C_k_n = tilt Rz(gamma) gimbals, so a
    turn of the outer gimbal by d turns the vertical in k by -d about that axis."""
    v = specific_force_k(0.0, alpha, beta, table_err, angle_err)
    along = np.sum(axis_k * v, axis=-1, keepdims=True) * axis_k
    across, side = v - along, np.cross(axis_k, v)
    d = (np.arange(k_rev) * 2 * np.pi / k_rev).reshape((-1,) + (1,) * v.ndim)
    return along + np.cos(d) * across - np.sin(d) * side
