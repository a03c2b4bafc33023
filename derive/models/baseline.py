"""dong2018 eq. 5 (accelerometer) and eq. 9 (gyro): first-order models.

N = (I + L) u + b, L lower triangular: diagonal dK_i (scale-factor errors),
below it the misalignment angles of the sensor axes in the parameter frame
(theta_ij for accelerometers in b, phi_ij for gyros in d), b the biases.
The term order is the order of the paper's K vector (eq. 7, 11).
"""
from ..frames import f_b, omega_d
from . import ErrorModel, Term


def first_order_triad(name, sensor, u, mis, bias_unit, what):
    ux, uy, uz = u
    terms = [
        Term("dK_x", "x", ux, "1", f"x {what} scale-factor error"),
        Term("dK_y", "y", uy, "1", f"y {what} scale-factor error"),
        Term("dK_z", "z", uz, "1", f"z {what} scale-factor error"),
        Term(f"{mis}_yx", "y", ux, "rad", f"y {what} axis tilted toward x of the parameter frame"),
        Term(f"{mis}_zx", "z", ux, "rad", f"z {what} axis tilted toward x of the parameter frame"),
        Term(f"{mis}_zy", "z", uy, "rad", f"z {what} axis tilted toward y of the parameter frame"),
        Term("b_x", "x", 1, bias_unit, f"x {what} bias"),
        Term("b_y", "y", 1, bias_unit, f"y {what} bias"),
        Term("b_z", "z", 1, bias_unit, f"z {what} bias"),
    ]
    return ErrorModel(name, sensor, tuple(terms), f"dong2018 eq. {5 if sensor == 'acc' else 9}")


ACC_BASELINE = first_order_triad("acc_baseline", "acc", f_b, "theta", "g", "accelerometer")
GYRO_BASELINE = first_order_triad("gyro_baseline", "gyro", omega_d, "phi", "deg/h", "gyro")
