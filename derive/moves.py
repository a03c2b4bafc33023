"""Gyro integration over a hand-placed move (Tedaldi et al. 2014, imu_tk), derived.

Between static poses i and i+1 the gyro gives omega_k (rad/s, in b) held over
each sample interval dt_k, so one interval turns the body by the rotation
vector v_k = omega_k dt_k and the whole move by
    R_i = exp([v_1 x]) exp([v_2 x]) ... exp([v_n x])      (b at the end -> b at the start),
composed as unit quaternions q(v_k). The cost compares the gravity direction
seen after the move with the one before, carried through the move:
    r_i = g_{i+1} - R_i^T g_i.
Its derivative needs, per sample, W_k = C_k J_r(v_k) dt_k, with C_k the product
up to and including sample k and J_r the right Jacobian of SO(3):
    exp([(v + dv) x]) = exp([v x]) exp([(J_r(v) dv) x])  to first order,
so a change d(omega_k) turns R_i by d(phi_i) = R_i^T sum_k W_k d(omega_k)
(right perturbation), and d(r_i) = -[(R_i^T g_i) x] d(phi_i).

J_r is derived here from q(v) by differentiation (right_jacobian_derived) and
generated in its closed form I - c1 [v x] + c2 [v x]^2 (right_jacobian), whose
coefficients are written to be exact and finite at v = 0: c1 = sinc(a/2)^2 / 2,
and c2 = (a - sin a)/a^3 by its series below a = 1e-2 rad. The test checks the
two forms against each other and against finite differences of exp.

Where this differs from imu_tk: imu_tk integrates with Runge-Kutta between
interpolated samples; here the rate is held over each interval (the exact
rotation of a piecewise-constant rate), which is what a rate-integrating
sampler delivers and keeps the Jacobian exact.
"""
import sympy as sp

from .frames import skew

v = sp.Matrix(sp.symbols("v_x v_y v_z", real=True))       # rotation vector of one interval (rad)
q = sp.Matrix(sp.symbols("q_w q_x q_y q_z", real=True))   # unit quaternion (w, x, y, z)
p = sp.Matrix(sp.symbols("p_w p_x p_y p_z", real=True))
dt = sp.Symbol("dt", nonnegative=True)                    # interval (s); the caller scales v already
angle = sp.sqrt(v.dot(v))
C2_SERIES_BELOW = sp.Float(1e-2)  # rad; series error a^6/9! < 3e-18 there


def quaternion_product(a, b):
    """Hamilton product a (x) b, so that C(a (x) b) = C(a) C(b): a, then b in the body axes."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return sp.Matrix([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                      aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


def step_quaternion():
    """q(v) of exp([v x]): (cos(a/2), v sin(a/2)/a), with sin(a/2)/a = sinc(a/2)/2 (finite at 0)."""
    return sp.Matrix([sp.cos(angle / 2), *(v * sp.sinc(angle / 2) / 2)])


def rotation_matrix(quat=q):
    """C(q) of a unit quaternion: C u = q (x) u (x) q*."""
    w, x, y, z = quat
    return sp.Matrix([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def right_jacobian_derived():
    """J_r(v) from its definition: column j is 2 vec(q(v)* (x) dq/dv_j), with q(v) in plain sin/cos.
    (Singular as printed at v = 0; used only to check the closed form.)"""
    a = angle
    qv = sp.Matrix([sp.cos(a / 2), *(v * sp.sin(a / 2) / a)])
    conj = sp.Matrix([qv[0], *(-qv[1:, 0])])
    J = sp.zeros(3, 3)
    for j in range(3):
        J[:, j] = 2 * quaternion_product(conj, qv.diff(v[j]))[1:, 0]
    return J


def right_jacobian():
    """J_r(v) = I - c1 [v x] + c2 [v x]^2, written finite at v = 0."""
    a = angle
    c1 = sp.sinc(a / 2) ** 2 / 2                       # (1 - cos a)/a^2
    a_safe = sp.Max(a, C2_SERIES_BELOW)
    c2 = sp.Piecewise((sp.Rational(1, 6) - a ** 2 / 120 + a ** 4 / 5040, a < C2_SERIES_BELOW),
                      ((a_safe - sp.sin(a_safe)) / a_safe ** 3, True))  # (a - sin a)/a^3
    K = skew(v)
    return sp.eye(3) - c1 * K + c2 * K * K


def integration_jacobian():
    """W = C(q) J_r(v) dt: one sample's weight in d(phi) = R^T sum_k W_k d(omega_k) (q: prefix to k)."""
    return rotation_matrix(q) * right_jacobian() * dt
