"""Candidate physical effects, each one Term to add to a baseline model.

CANDIDATES maps an effect id, `<sensor>.<family>.<axis>` (e.g.
`acc.quadratic.z`, `acc.cross_coupling.xy`), to its Term. `simucal derive`
generates their regressors and derivatives (generated/effects.py) so that
`simucal diagnose` can fit baseline + any candidate with the exact solver.
"""
import sympy as sp

from ..frames import AXES, domega_b, dtemp_c, f_b, omega_b, omega_d, skew, t_s, temp_rate_c_s, w2
from . import Term

DPS = 3600.0  # deg/h per deg/s: gyro rates enter nonlinear terms in deg/s to keep coefficients O(1)
G0 = 9.80665  # m/s^2 per g: a lever arm's acceleration in the accelerometers' unit (local g differs by < 0.3 %)


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


def acc_lever_arm(axis, component):
    """Lever arm of the `axis` accelerometer from the x accelerometer, its `component`, in m, under any
    motion the gyros measure (a rotation sequence's moves): the accelerometer feels
    domega x r + omega x (omega x r) beyond the x accelerometer, so its output gains
    [(domega x e_c)_a + omega_a omega_c - |omega|^2 delta_ac] r_c / g (omega_b, domega_b in rad/s, rad/s^2).
    The size effect's general form: on a rate run (omega = w_T u, domega = 0) it is size_effect's
    w2 (u_a u_c - delta_ac). Only the differences of the three accelerometers' positions show: a lever
    arm common to all three is the navigation point's own motion, which returns to rest with the table
    (zero-velocity updates cannot see it), so the x accelerometer is the reference point and its
    own arm is zero, as in PSINS' sysclbt."""
    a, c = AXES.index(axis), AXES.index(component)
    e_c = sp.Matrix([1 if k == c else 0 for k in range(3)])
    centripetal = omega_b[a] * omega_b[c] - (omega_b.dot(omega_b) if a == c else 0)
    return Term(f"r_{axis}{component}", axis, ((skew(domega_b) * e_c)[a] + centripetal) / G0, "m",
                f"{axis} accelerometer's lever arm from the x accelerometer, along {component} (size effect under any "
                "motion)")


def acc_time_delay(axis):
    """The `axis` accelerometer sampled tau later than the gyros (s): its sample stands for f(t - tau)
    = f - tau df/dt, and a body turning at omega in a still gravity field has df/dt = -omega x f
    (f in b), so the output gains tau (omega x f)_a (first order: tau^2 omega^2 is 1e-7 g at 5 ms and
    10 deg/s). omega_b in rad/s."""
    a = AXES.index(axis)
    return Term(f"tau_{axis}", axis, omega_b.cross(f_b)[a], "s",
                f"{axis} accelerometer sampled later than the gyros (time delay)")


def gyro_quadratic(axis):
    return Term(f"K2g_{axis}", axis, (_w(axis) / DPS) ** 2, "(deg/h)/(deg/s)^2",
                f"{axis} gyro scale factor depending on rate (second-order nonlinearity)")


def gyro_scale_asymmetry(axis):
    return Term(f"Kag_{axis}", axis, sp.Abs(_w(axis)), "1",
                f"{axis} gyro scale factor differs for positive and negative rates")


def gyro_g_sensitivity(axis, other):
    return Term(f"G_{axis}{other}", axis, _f(other), "(deg/h)/g",
                f"{axis} gyro output proportional to the specific force along {other} (g-sensitivity)")


ORDINAL = {1: "linearly", 2: "quadratically", 3: "cubically"}
UNIT = {"acc": "g", "gyro": "deg/h"}


def bias_temperature(sensor, axis, degree):
    """Bias b(T) = b + sum_k bT_k (T - T_ref)^k (IEEE 1293 / IEEE 952 thermal models; PX4 and
    ArduPilot fit the same polynomial): this term is the degree-k one. T_ref is the calibration's
    reference temperature (t_ref_c in its file), so the baseline bias is the bias at T_ref."""
    tag = "" if degree == 1 else str(degree)
    unit = f"{UNIT[sensor]}/degC" + (f"^{degree}" if degree > 1 else "")
    return Term(f"bT{tag}{'g' if sensor == 'gyro' else ''}_{axis}", axis, dtemp_c ** degree,
                unit if sensor == "acc" else f"({UNIT[sensor]})/degC" + (f"^{degree}" if degree > 1 else ""),
                f"{axis} {'accelerometer' if sensor == 'acc' else 'gyro'} bias changing {ORDINAL[degree]} "
                "with temperature (from T_ref)")


def scale_temperature(sensor, axis, degree):
    """Scale factor K(T) = K (1 + sum_k kT_k (T - T_ref)^k): the term kT_k u_axis (T - T_ref)^k,
    u the axis's own input (g, or deg/h so that kT_k is per degC^k, dimensionless otherwise)."""
    u = _f(axis) if sensor == "acc" else _w(axis)
    tag = "" if degree == 1 else str(degree)
    return Term(f"kT{tag}{'g' if sensor == 'gyro' else ''}_{axis}", axis, u * dtemp_c ** degree,
                "1/degC" + (f"^{degree}" if degree > 1 else ""),
                f"{axis} {'accelerometer' if sensor == 'acc' else 'gyro'} scale factor changing {ORDINAL[degree]} "
                "with temperature (from T_ref)")


def bias_temperature_rate(sensor, axis):
    """Bias b = bTr dT/dt (IEEE 952's temperature-gradient, or temperature-rate, sensitivity): the bias
    follows the temperature's rate of change. Its usual cause is a lag: the die warms after the
    thermistor that logs temp_c, with dT_s/dt = (T - T_s) / tau, so the sensor reads b(T_s) ~ b(T) -
    tau b'(T) dT/dt, a term bTr = -tau b'(T_ref) per degC/s beside the bias's polynomial in T (the
    change of b' over the range is left to second order). dT/dt is the input temp_rate_c_s, the slope
    of a least-squares line through the logged temp_c over a window centred on each time
    (simucal.fit.thermal.temperature_rate: RATE_WINDOW_S, or a whole block or segment where that is
    longer): a derivative smoothed against the thermistor's noise and steps. A single monotone warm-up
    shows it only where its rate changes at a temperature in a way no polynomial in T follows: where
    the rate is a smooth function of T (an exponential warm-up, a constant ramp) the lag is a
    polynomial in T too, and no data can tell the two apart."""
    unit = f"{UNIT[sensor]}/(degC/s)"
    return Term(f"bTr{'g' if sensor == 'gyro' else ''}_{axis}", axis, temp_rate_c_s,
                unit if sensor == "acc" else f"({UNIT[sensor]})/(degC/s)",
                f"{axis} {'accelerometer' if sensor == 'acc' else 'gyro'} bias following the temperature's rate of "
                "change dT/dt (the die lagging the thermistor)")


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
            if a != "x":
                out[f"acc.lever_arm.{a}{o}"] = acc_lever_arm(a, o)
        out[f"acc.time_delay.{a}"] = acc_time_delay(a)
        out[f"gyro.quadratic.{a}"] = gyro_quadratic(a)
        out[f"gyro.scale_asymmetry.{a}"] = gyro_scale_asymmetry(a)
        out[f"gyro.bias_drift_time.{a}"] = gyro_bias_drift_time(a)
        for o in AXES:
            out[f"gyro.g_sensitivity.{a}{o}"] = gyro_g_sensitivity(a, o)
        for sensor in ("acc", "gyro"):
            for k, tag in ((1, ""), (2, "2"), (3, "3")):
                out[f"{sensor}.bias_temperature{tag}.{a}"] = bias_temperature(sensor, a, k)
            for k, tag in ((1, ""), (2, "2")):
                out[f"{sensor}.scale_temperature{tag}.{a}"] = scale_temperature(sensor, a, k)
            out[f"{sensor}.temperature_rate.{a}"] = bias_temperature_rate(sensor, a)
    return dict(sorted(out.items()))


CANDIDATES = _catalog()

SEPARATE = {  # what a turntable plan needs for each family to be told apart from the baseline
    "quadratic": "static positions at several levels and both signs of the input on that axis "
                 "(e.g. --plan fibonacci48); for gyros rate runs at several rates (e.g. 5, 10, 20 deg/s)",
    "scale_asymmetry": "inputs of both signs on that axis (for gyros, rate runs of both signs)",
    "cross_coupling": "static positions where both axes carry input at once (e.g. --plan fibonacci48)",
    "bias_drift_time": "positions revisited at the start and the end of the test",
    "bias_temperature": "a temperature sweep across the positions (a temp_c column)",
    "bias_temperature2": "a temperature sweep across the positions at three or more temperatures",
    "bias_temperature3": "a temperature sweep across the positions at four or more temperatures",
    "scale_temperature": "inputs of both signs on that axis at several temperatures (a temp_c column)",
    "scale_temperature2": "inputs of both signs on that axis at three or more temperatures",
    "temperature_rate": "a temperature that changes at different rates while the positions repeat (a temp_c column "
                        "logged at the samples' rate; a still warm-up whose rate changes at a temperature)",
    "size_effect": "rate runs with the accelerometers recorded during them, at several attitudes and rates",
    "lever_arm": "a rotation sequence (the accelerometers recorded through moves about every axis, accelerating "
                 "and braking)",
    "time_delay": "a rotation sequence (the accelerometers recorded through moves about every axis)",
    "g_sensitivity": "rate runs of both signs at each attitude: the specific force keeps its direction while the "
                     "rate flips, which separates G f from the scale and misalignment",
}

SEPARATE_MOVES = {  # what a hand-placed session's moves need, per gyro family
    "quadratic": "moves at several rates, fast and slow, about that axis",
    "scale_asymmetry": "moves turning both ways about that axis",
    "bias_drift_time": "moves spread over a longer session",
    "bias_temperature": "a temp_c column, with the temperature changing over the session",
    "bias_temperature2": "a temp_c column, with the temperature spanning a wide range over the session",
    "bias_temperature3": "a temp_c column, with the temperature spanning a wide range over the session",
    "scale_temperature": "moves about that axis at several temperatures (a temp_c column)",
    "scale_temperature2": "moves about that axis at three or more temperatures",
    "temperature_rate": "a temp_c column, with the temperature's rate of change varying over the session",
    "g_sensitivity": "moves made with that axis at several attitudes to gravity",
}

