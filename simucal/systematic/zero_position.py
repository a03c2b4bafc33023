"""Zero-position updates: a table that returns to a position it held before puts the unit
at the same attitude again, to its angular accuracy, which the zero-velocity updates alone cannot say (they
see the tilt, and the heading only through the Earth rate).

A rest whose commanded angles (segments.csv) equal an earlier rest's, modulo 360 deg, is a return. The
filter carries the attitude error of each position's first visit as a clone: three states c_i set to phi at
the last update of that visit, plus the table's error there (each visit's table angles of std sigma, meta.json's
table_accuracy_arcsec), and constant after. At the last update of each later visit j:

    z_j = log(C_i C_j^T) = phi_j - c_i + e_j,     H = [I 0 .. -I(c_i) ..],   R = sigma^2 J J^T

with C_i, C_j the nominal attitudes there (the true ones are equal: exp(phi_j) C_j = exp(phi_i) C_i, to
first order). The table errs in its three angles, each by sigma, and each angle turns the unit about its own
gimbal axis a_k in n (at the commanded angles): e = J d, J = [a_outer a_middle a_inner] (`attitude_cov`). That
is sigma^2 I only while the axes are perpendicular; with the middle axis at +-90 deg the inner axis lies along
the outer one (gimbal lock): their two errors add about the vertical (2 sigma^2) and one horizontal direction
holds none. The copy is part of the transition from the first visit's update to the next (x <- Phi T x, T
setting c_i = phi), and its table error part of that step's noise, so the smoother carries both; the clone of
the first visit holds its error e_i, so that two returns to one position share it rather than each counting
it anew. Without table_accuracy_arcsec there are no such updates (the weight would be a guess).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simucal.fit.rotations import log_so3
from simucal.generated import table
from simucal.io import units

ANGLE_STEP_RAD = 1e-7  # the gimbal axes by a difference of the table's kinematics (error in them ~1e-7)


@dataclass
class Returns:
    """Which updates copy phi into a clone and which measure phi against one (the updates numbered from 0 in
    time order), the table's angle std per visit (rad), each clone's attitude covariance per visit (rad^2,
    `attitude_cov`), and the nominal attitude of each clone's copy."""
    copy_after: dict[int, int]
    update_at: dict[int, int]
    sigma_rad: float
    slots: int
    n: int                                       # the state's size with the clones
    cov: dict[int, np.ndarray] = field(default_factory=dict)
    C_first: dict[int, np.ndarray] = field(default_factory=dict)

    def slot(self, k: int) -> slice:
        """The clone k's three states: the last of the state vector."""
        start = self.n - 3 * (self.slots - k)
        return slice(start, start + 3)

    def transition(self, u: int, Phi: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """(the transition into update u, the clone's noise to add there or None): Phi T where update u - 1
        copies phi into a clone."""
        k = self.copy_after.get(u - 1)
        if k is None:
            return Phi, None
        T = np.eye(self.n)
        s = self.slot(k)
        T[s] = 0.0
        T[s, :3] = np.eye(3)
        Q = np.zeros((self.n, self.n))
        Q[s, s] = self.cov[k]  # the first visit's own table error, in the clone
        return Phi @ T, Q

    def measurement(self, u: int, C_nominal: np.ndarray):
        """(H, z, R) of update u where it is a return, else None; where u is a first visit's copy, its nominal
        attitude C_nominal kept for the later visits' z."""
        if u in self.copy_after:
            self.C_first[self.copy_after[u]] = C_nominal
        k = self.update_at.get(u)
        if k is None:
            return None
        H = np.zeros((3, self.n))
        H[:, :3], H[:, self.slot(k)] = np.eye(3), -np.eye(3)
        return H, log_so3(self.C_first[k] @ C_nominal.T), self.cov[k]


def position(s) -> tuple:
    """A rest's commanded angles modulo 360 deg (segments.csv): two rests at one position hold the unit at one
    attitude, to the table's accuracy."""
    return tuple(round(float(a) % 360.0, 6) % 360.0 for a in (s.outer_deg, s.middle_deg, s.inner_deg))


def attitude_cov(s, sigma_rad: float) -> np.ndarray:
    """The covariance (rad^2, in n) of the unit's attitude at a rest s from its three commanded angles' errors,
    each of std sigma_rad: sigma^2 J J^T, J's columns the gimbal axes there (module doc)."""
    angles = np.radians([s.outer_deg, s.middle_deg, s.inner_deg])
    C = table.C_k_n(*angles, np.zeros(7))
    J = np.stack([log_so3(table.C_k_n(*angles, np.r_[np.zeros(4), ANGLE_STEP_RAD * e]) @ C.T) / ANGLE_STEP_RAD
                  for e in np.eye(3)], axis=1)
    return sigma_rad ** 2 * J @ J.T


def returns(ms, segments, update_segment: np.ndarray, n_states: int) -> Returns | None:
    """The returns of a sequence (module doc): update_segment, the segment of each update in time order;
    n_states, the filter's states without the clones. None
    where meta.json states no table_accuracy_arcsec, or no rest returns to an earlier one's angles."""
    accuracy = ms.meta.get("table_accuracy_arcsec")
    if accuracy is None:
        return None
    last = {int(s): u for u, s in enumerate(update_segment)}  # each rest's last update
    first_visit: dict[tuple, int] = {}
    copy_after: dict[int, int] = {}
    update_at: dict[int, int] = {}
    cov: dict[int, np.ndarray] = {}
    sigma = float(accuracy) * units.ARCSEC_RAD
    for s in segments:
        if s.kind != "static" or s.outer_deg is None or s.segment not in last:
            continue
        key = position(s)
        if key not in first_visit:
            first_visit[key] = last[s.segment]
            continue
        u0 = first_visit[key]
        k = copy_after.setdefault(u0, len(copy_after))
        update_at[last[s.segment]] = k
        cov[k] = attitude_cov(s, sigma)
    if not update_at:
        return None
    return Returns(copy_after, update_at, sigma, len(copy_after), n_states + 3 * len(copy_after), cov)
