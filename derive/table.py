"""Three-axis turntable with its errors, and the exact sensor inputs it makes.

Outer axis (gamma) nominally vertical, middle (alpha) carried by it, inner
(beta) by the middle; k fixed to the inner frame (spec, "Frames and angles").
Errors, all angles in rad:
- tilt_x, tilt_y: outer-axis tilt (dong2018's dtheta_x0, dtheta_y0), applied
  in n as in eq. 14: Rx(tilt_x) Ry(tilt_y) Rz(gamma) ...;
- nonperp_om: middle axis not perpendicular to the outer one (a rotation
  about y between the outer and middle gimbals);
- nonperp_mi: inner axis not perpendicular to the middle one (about z between
  the middle and inner gimbals);
- d_gamma, d_alpha, d_beta: the angle actually reached minus the commanded
  one (zero-position error plus that position's angular position error).
"""
import sympy as sp

from .frames import UP, lat, mounting, rot_x, rot_y, rot_z, w_e

gamma, alpha, beta = sp.symbols("gamma alpha beta", real=True)
tilt_x, tilt_y, nonperp_om, nonperp_mi = sp.symbols("tilt_x tilt_y nonperp_om nonperp_mi", real=True)
d_gamma, d_alpha, d_beta = sp.symbols("d_gamma d_alpha d_beta", real=True)
theta4 = sp.symbols("theta_x4 theta_y4 theta_z4", real=True)   # C_b^k mounting (eq. 13)
lambda4 = sp.symbols("lambda_x4 lambda_y4 lambda_z4", real=True)  # C_d^k mounting (eq. 18)

ANGLES = (gamma, alpha, beta)
TABLE_ERRORS = (tilt_x, tilt_y, nonperp_om, nonperp_mi, d_gamma, d_alpha, d_beta)


def tilt():
    return rot_x(tilt_x) * rot_y(tilt_y)


def gimbals():
    """The middle and inner gimbals with their errors: k in the outer-axis frame."""
    return rot_y(nonperp_om) * rot_x(alpha + d_alpha) * rot_z(nonperp_mi) * rot_y(beta + d_beta)


def C_k_n():
    """Exact attitude of the table frame k in n at commanded (gamma, alpha, beta)."""
    return tilt() * rot_z(gamma + d_gamma) * gimbals()


def outer_axis_k():
    """The outer axis in k at (alpha, beta). Over a whole revolution a vector v^n fixed in n
    averages, in k, to this axis times v's component along the (tilted) outer axis, since
    Rz(gamma)^T averages to diag(0, 0, 1): a rate run's mean input direction."""
    return gimbals().T * UP


def C_b_k():
    return mounting(*theta4)


def C_d_k():
    return mounting(*lambda4)


def specific_force_k():
    """f^k at rest, in g: C_n^k [0, 0, 1]."""
    return C_k_n().T * UP


def earth_rate_n():
    return sp.Matrix([0, w_e * sp.cos(lat), w_e * sp.sin(lat)])


def outer_axis_n():
    """Unit vector of the (tilted) outer axis in n."""
    return tilt() * UP


def up_in_b():
    """The vertical (specific force at rest, g) in b at commanded angles: C_k^b C_n^k z,
    as a function of the table errors and the mounting angles theta_4."""
    return C_b_k().T * specific_force_k()


TABLE_FIT_PARAMS = TABLE_ERRORS + theta4  # what a table fit can estimate from gravity directions
