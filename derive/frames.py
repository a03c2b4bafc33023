"""Frames, rotations and symbols: the one place for conventions.

Conventions (spec ``measurement-set.md``, section "Frames and angles"):
- n: East-North-Up. Specific force at rest f^n = [0, 0, +g]; Earth rate
  omega_ie^n = [0, w_e cos L, w_e sin L].
- Rotations are active and right-handed, rot_x(a) = [[1,0,0],[0,c,-s],[0,s,c]].
- C_k^n = rot_z(gamma) rot_x(alpha) rot_y(beta) for an ideal table.
- b (accelerometer parameter frame, dong2018 section 1): x_b along the x
  accelerometer, y_b in the x_a y_a plane. d: the same for the gyros.
- Mounting: C_b^k = rot_x(theta_x4) rot_y(theta_y4) rot_z(theta_z4), so
  C_k^b = I - [theta x] to first order. This sign is the one under which the
  paper's eq. 17 and 21 hold (its eq. 13 and 18 print other signs; see audit).
"""
import sympy as sp


def rot_x(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])


def rot_y(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rot_z(a):
    c, s = sp.cos(a), sp.sin(a)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def skew(v):
    """[v x]: skew(v) @ u == v.cross(u)."""
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def mounting(ax, ay, az):
    """Exact mounting rotation C_b^k (or C_d^k) from three small angles."""
    return rot_x(ax) * rot_y(ay) * rot_z(az)


AXES = ("x", "y", "z")
UP = sp.Matrix([0, 0, 1])

# Inputs of the sensor models. Accelerometer: specific force in b, in g.
# Gyro: angular rate in d, in deg/h. Auxiliary inputs any term may use.
f_b = sp.Matrix(sp.symbols("f_x f_y f_z", real=True))
omega_d = sp.Matrix(sp.symbols("w_x w_y w_z", real=True))
temp_c, t_s = sp.symbols("temp_c t_s", real=True)
AUX = (temp_c, t_s)
# Accelerometers under outer-axis rate w_T: the centripetal scale w2 = w_T^2 / g (1/m; 0 at rest).
w2 = sp.Symbol("w2", real=True)

# Outputs in physical units (pulse outputs divided by nominal scale factors):
# the paper's N_i^a = K_i^a Ntilde_i^a (g) and N_i^g (deg/h).
N_out = sp.Matrix(sp.symbols("N_x N_y N_z", real=True))

# Site and test constants.
lat, w_e, w_T, g = sp.symbols("L w_e w_T g", real=True)
