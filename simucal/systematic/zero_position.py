"""Zero-position updates: a table that returns to a position it held before puts the unit
at the same attitude again, to its angular accuracy, which the zero-velocity updates alone cannot say (they
see the tilt, and the heading only through the Earth rate).

A rest whose commanded angles (segments.csv) equal an earlier rest's, modulo 360 deg, is a return. The
filter carries the attitude error of each position's first visit as a clone: three states c_i set to phi at
the last update of that visit, plus the table's error there (each visit's attitude std sigma, meta.json's
table_accuracy_arcsec), and constant after. At the last update of each later visit j:

    z_j = log(C_i C_j^T) = phi_j - c_i + e_j,     H = [I 0 .. -I(c_i) ..],   R = sigma^2 I

with C_i, C_j the nominal attitudes there (the true ones are equal: exp(phi_j) C_j = exp(phi_i) C_i, to
first order). The copy is part of the transition from the first visit's update to the next (x <- Phi T x,
T setting c_i = phi), and its table error part of that step's noise, so the smoother carries both; the
clone of the first visit holds its error e_i, so that two returns to one position share it rather than each
counting it anew. Without table_accuracy_arcsec there are no such updates (the weight would be a guess).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from simucal.fit.rotations import log_so3
from simucal.io import units


@dataclass
class Returns:
    """Which updates copy phi into a clone and which measure phi against one (the updates numbered from 0 in
    time order), the table's attitude std per visit (rad), and the nominal attitude of each clone's copy."""
    copy_after: dict[int, int]
    update_at: dict[int, int]
    sigma_rad: float
    slots: int
    n: int                                       # the state's size with the clones
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
        Q[s, s] = np.eye(3) * self.sigma_rad ** 2  # the first visit's own table error, in the clone
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
        return H, log_so3(self.C_first[k] @ C_nominal.T), np.eye(3) * self.sigma_rad ** 2


def position(s) -> tuple:
    """A rest's commanded angles modulo 360 deg (segments.csv): two rests at one position hold the unit at one
    attitude, to the table's accuracy."""
    return tuple(round(float(a) % 360.0, 6) % 360.0 for a in (s.outer_deg, s.middle_deg, s.inner_deg))


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
    if not update_at:
        return None
    return Returns(copy_after, update_at, float(accuracy) * units.ARCSEC_RAD, len(copy_after), n_states + 3 * len(copy_after))
