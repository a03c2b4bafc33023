"""Candidate physical effects, each one Term to add to a baseline model.

CANDIDATES maps an effect id, `<sensor>.<family>.<axis>` (e.g.
`acc.quadratic.z`, `acc.cross_coupling.xy`), to its Term. `simucal derive`
generates their regressors and derivatives (generated/effects.py) so that
`simucal diagnose` can fit baseline + any candidate with the exact solver.
"""
import sympy as sp

from ..frames import AXES, f_b, omega_d, t_s, temp_c, w2
from . import Term

DPS = 3600.0  # deg/h per deg/s: gyro rates enter nonlinear terms in deg/s to keep coefficients O(1)


def _f(axis):
    return f_b[AXES.index(axis)]


def _w(axis):
    return omega_d[AXES.index(axis)]


def acc_quadratic(axis):
    return Term(f"K2_{axis}", axis, _f(axis) ** 2, "g/g^2",
                f"{axis} accelerometer second-order nonlinearity (output grows with f_{axis}^2)")


def acc_cross_coupling(axis, other):
    return Term(f"Kc_{axis}{other}", axis, _f(axis) * _f(other), "g/g^2",
                f"{axis} accelerometer output proportional to f_{axis} f_{other} (cross-axis coupling)")


def acc_scale_asymmetry(axis):
    return Term(f"Ka_{axis}", axis, sp.Abs(_f(axis)), "1",
                f"{axis} accelerometer scale factor differs for positive and negative inputs")


def acc_bias_drift_time(axis):
    return Term(f"bt_{axis}", axis, t_s, "g/s", f"{axis} accelerometer bias drifting linearly in time")


def acc_size_effect(axis, component):
    """Lever arm r of the `axis` accelerometer, `component` of it, in m: under a rate
    w_T about the vertical (the input's direction u) the accelerometer feels
    w x (w x r), i.e. (w_T^2 / g) (u_a u_c - delta_ac) r_c in g."""
    u_a, u_c = _f(axis), _f(component)
    return Term(f"r_{axis}{component}", axis, w2 * (u_a * u_c - (1 if axis == component else 0)), "m",
                f"{axis} accelerometer {component} lever arm (size effect under rotation)")


def gyro_quadratic(axis):
    return Term(f"K2g_{axis}", axis, (_w(axis) / DPS) ** 2, "(deg/h)/(deg/s)^2",
                f"{axis} gyro scale factor depending on rate (second-order nonlinearity)")


def gyro_scale_asymmetry(axis):
    return Term(f"Kag_{axis}", axis, sp.Abs(_w(axis)), "1",
                f"{axis} gyro scale factor differs for positive and negative rates")


def gyro_g_sensitivity(axis, other):
    return Term(f"G_{axis}{other}", axis, _f(other), "(deg/h)/g",
                f"{axis} gyro output proportional to the specific force along {other} (g-sensitivity)")


def gyro_bias_temperature(axis):
    return Term(f"bT_{axis}", axis, temp_c, "(deg/h)/degC", f"{axis} gyro bias changing with temperature")


def gyro_bias_drift_time(axis):
    return Term(f"btg_{axis}", axis, t_s, "(deg/h)/s", f"{axis} gyro bias drifting linearly in time")


def _catalog():
    out = {}
    for a in AXES:
        out[f"acc.quadratic.{a}"] = acc_quadratic(a)
        out[f"acc.scale_asymmetry.{a}"] = acc_scale_asymmetry(a)
        out[f"acc.bias_drift_time.{a}"] = acc_bias_drift_time(a)
        for o in AXES:
            if o != a:
                out[f"acc.cross_coupling.{a}{o}"] = acc_cross_coupling(a, o)
            out[f"acc.size_effect.{a}{o}"] = acc_size_effect(a, o)
        out[f"gyro.quadratic.{a}"] = gyro_quadratic(a)
        out[f"gyro.scale_asymmetry.{a}"] = gyro_scale_asymmetry(a)
        out[f"gyro.bias_temperature.{a}"] = gyro_bias_temperature(a)
        out[f"gyro.bias_drift_time.{a}"] = gyro_bias_drift_time(a)
        for o in AXES:
            out[f"gyro.g_sensitivity.{a}{o}"] = gyro_g_sensitivity(a, o)
    return dict(sorted(out.items()))


CANDIDATES = _catalog()

SEPARATE = {  # what a turntable plan needs for each family to be told apart from the baseline
    "quadratic": "static positions at several levels and both signs of the input on that axis "
                 "(e.g. --plan fibonacci48); for gyros rate runs at several rates (e.g. 5, 10, 20 deg/s)",
    "scale_asymmetry": "inputs of both signs on that axis (for gyros, rate runs of both signs)",
    "cross_coupling": "static positions where both axes carry input at once (e.g. --plan fibonacci48)",
    "bias_drift_time": "positions revisited at the start and the end of the test",
    "bias_temperature": "a temperature sweep across the positions (a temp_c column)",
    "size_effect": "rate runs with the accelerometers recorded during them, at several attitudes and rates",
    "g_sensitivity": "rate runs of both signs at each attitude: the specific force keeps its direction while the "
                     "rate flips, which separates G f from the scale and misalignment",
}

SEPARATE_MOVES = {  # what a hand-placed session's moves need, per gyro family
    "quadratic": "moves at several rates, fast and slow, about that axis",
    "scale_asymmetry": "moves turning both ways about that axis",
    "bias_drift_time": "moves spread over a longer session",
    "bias_temperature": "a temp_c column, with the temperature changing over the session",
    "g_sensitivity": "moves made with that axis at several attitudes to gravity",
}

