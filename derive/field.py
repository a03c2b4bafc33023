"""Field calibration of gyro constant drift on a static base (ruan2019), derived.

Frames as in the paper: navigation n = North-Up-East (x=N, y=U, z=E, right
handed: N x U = E), body b = Forward-Up-Right. Attitude
    C_b^n = Ry(-psi) Rz(theta) Rx(gamma)
(heading psi from north toward east, pitch theta nose up, roll gamma about
forward), so the forward axis is [cos(theta) cos(psi), sin(theta), cos(theta) sin(psi)].

Static-base error model (psi-angle form, v = 0, no transport rate):
    d(phi)/dt = -w_ie^n x phi - eps^n,        eps^n = C_b^n eps^b
    d(dv)/dt  =  f^n x phi + nabla^n,         f^n = [0, g, 0]
with the horizontal velocity errors (N, E) measured (zero velocity).
State x = [dv_N, dv_E, phi_N, phi_U, phi_E, eps_N, eps_U, eps_E]: the
accelerometer biases are left out because they are indistinguishable from the
level errors (they only shift phi_N, phi_E).

What one position sees (observability, derived below): eps_N is observable;
eps_E is not, it enters only with phi_U as w_e cos L phi_U + eps_E; eps_U is
observable in theory but only through the azimuth's slow coupling, so in
300 s it is not usefully seen. Hence one drift component per position, the
one along north, eps_N = c_N^T eps^b with c_N the north direction in b (row N
of C_b^n), and three positions with independent c_N give eps^b by least
squares. With a wrong heading psi' = psi + dpsi the computed frame's north
still sees C_b^n' eps^b, so the geometry stays consistent; the Earth rate
left in the north channel is w_e cos L (cos dpsi - 1), second order in dpsi.
"""
import sympy as sp

from .frames import lat, rot_x, rot_y, rot_z, w_e

g_s = sp.Symbol("g", positive=True)
psi, theta, gamma = sp.symbols("psi theta gamma", real=True)
STATES = sp.symbols("dv_N dv_E phi_N phi_U phi_E eps_N eps_U eps_E", real=True)


def C_b_n(heading=psi, pitch=theta, roll=gamma):
    return rot_y(-heading) * rot_z(pitch) * rot_x(roll)


def earth_rate_n():
    return sp.Matrix([w_e * sp.cos(lat), w_e * sp.sin(lat), 0])


def error_model():
    """(F, H): d(x)/dt = F x, z = H x, for the state STATES."""
    dvN, dvE, phN, phU, phE, eN, eU, eE = STATES
    phi = sp.Matrix([phN, phU, phE])
    eps = sp.Matrix([eN, eU, eE])
    f_n = sp.Matrix([0, g_s, 0])
    dphi = -earth_rate_n().cross(phi) - eps
    dv = f_n.cross(phi)
    rates = sp.Matrix([dv[0], dv[2], dphi[0], dphi[1], dphi[2], 0, 0, 0])
    F = rates.jacobian(STATES)
    H = sp.Matrix([[1, 0, 0, 0, 0, 0, 0, 0], [0, 1, 0, 0, 0, 0, 0, 0]])
    return F, H


def observability():
    """Rank of the observability matrix and its null space (unobservable directions)."""
    F, H = error_model()
    n = F.shape[0]
    O = sp.Matrix.vstack(*[H * F ** k for k in range(n)])
    O = O.subs({lat: sp.pi / 4})  # any latitude away from the poles and equator gives the same structure
    null = [sp.simplify(v.T) for v in O.nullspace()]
    return O.rank(), null


dpsi = sp.Symbol("dpsi", real=True)  # heading error of the external north reference, rad


def north_residual_earth_rate(dpsi=dpsi):
    """Earth rate left in the computed north channel when the heading is off by dpsi."""
    return w_e * sp.cos(lat) * (sp.cos(dpsi) - 1)
