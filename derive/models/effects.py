"""Candidate physical effects, each one Term to add to a baseline model.

Every effect is a function of the axis (and, where it matters, a second axis)
returning a Term with its unit and a one-line physical meaning.
"""
from ..frames import AXES, f_b, omega_d, t_s, temp_c
from . import Term


def _f(axis):
    return f_b[AXES.index(axis)]


def _w(axis):
    return omega_d[AXES.index(axis)]


def acc_quadratic(axis):
    return Term(f"K2_{axis}", axis, _f(axis) ** 2, "1/g",
                f"{axis} accelerometer second-order nonlinearity (pendulum/servo loop)")


def acc_cross_coupling(axis, other):
    return Term(f"Kc_{axis}{other}", axis, _f(axis) * _f(other), "1/g",
                f"{axis} accelerometer output proportional to f_{axis} f_{other} (cross-axis coupling)")


def acc_bias_drift_time(axis):
    return Term(f"bt_{axis}", axis, t_s, "g/s", f"{axis} accelerometer bias drifting linearly in time")


def gyro_quadratic(axis):
    return Term(f"K2g_{axis}", axis, _w(axis) ** 2, "1/(deg/h)",
                f"{axis} gyro scale factor depending on rate (second-order nonlinearity)")


def gyro_bias_temperature(axis):
    return Term(f"bT_{axis}", axis, temp_c, "(deg/h)/degC", f"{axis} gyro bias changing with temperature")


def gyro_bias_drift_time(axis):
    return Term(f"btg_{axis}", axis, t_s, "(deg/h)/s", f"{axis} gyro bias drifting linearly in time")
