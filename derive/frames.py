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
from dataclasses import dataclass

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
# Gyro: angular rate in d, in deg/h.
f_b = sp.Matrix(sp.symbols("f_x f_y f_z", real=True))
omega_d = sp.Matrix(sp.symbols("w_x w_y w_z", real=True))


@dataclass(frozen=True)
class AuxInput:
    """An auxiliary input a term may use besides its sensor's own input, and where the
    runtime finds it (source): "column" a samples.csv column of that name, averaged over a
    position like the outputs; "specific force" what the accelerometers measure (gyro
    terms: g-sensitivity); "table rate" the outer-axis rate of a rate run (accelerometer
    terms: lever arms); "temperature rate" the smoothed derivative of temp_c in time
    (simucal.fit.thermal.temperature_rate)."""

    name: str
    unit: str
    meaning: str
    source: str = "column"

    @property
    def symbol(self) -> sp.Symbol:
        return sp.Symbol(self.name, real=True)


AUX_INPUTS = {a.name: a for a in (
    AuxInput("temp_c", "degC", "sensor temperature"),
    AuxInput("dtemp_c", "degC", "sensor temperature from the calibration's reference, temp_c - T_ref (the calibration "
             "file's t_ref_c)", "temperature from its reference"),
    AuxInput("t_s", "s", "time"),
    AuxInput("temp_rate_c_s", "degC/s",
             "the logged temperature's rate of change dT/dt, a smoothed derivative of temp_c "
             "(simucal.fit.thermal.temperature_rate)", "temperature rate"),
    AuxInput("f_x", "g", "specific force along x of b", "specific force"),
    AuxInput("f_y", "g", "specific force along y of b", "specific force"),
    AuxInput("f_z", "g", "specific force along z of b", "specific force"),
    AuxInput("w2", "1/m", "centripetal scale w_T^2 / g of the outer-axis rate (0 at rest)", "table rate"),
    *(AuxInput(f"wb_{a}", "rad/s", f"body rate about {a} of b, as the gyros measure it (0 at rest)", "body rate")
      for a in AXES),
    *(AuxInput(f"dwb_{a}", "rad/s^2", f"angular acceleration about {a} of b, the body rate's change", "body rate")
      for a in AXES),
)}
# each sensor's in the order its generated functions take them; a new input goes at the end, so that the
# others keep their places in the aux arrays of existing generated models
SENSOR_AUX = {"acc": ("temp_c", "dtemp_c", "t_s", "w2", "wb_x", "wb_y", "wb_z", "dwb_x", "dwb_y", "dwb_z",
                      "temp_rate_c_s"),
              "gyro": ("temp_c", "dtemp_c", "t_s", "f_x", "f_y", "f_z", "temp_rate_c_s")}
temp_c, dtemp_c, t_s, w2, temp_rate_c_s = (AUX_INPUTS[n].symbol for n in ("temp_c", "dtemp_c", "t_s", "w2",
                                                                         "temp_rate_c_s"))
omega_b = sp.Matrix([AUX_INPUTS[f"wb_{a}"].symbol for a in AXES])   # rad/s: what accelerometer terms see of the motion
domega_b = sp.Matrix([AUX_INPUTS[f"dwb_{a}"].symbol for a in AXES])  # rad/s^2
_COLUMN_INPUTS: dict[str, AuxInput] = {}


def column_input(name: str, unit: str = "", meaning: str = "") -> sp.Symbol:
    """A user's auxiliary input read from the samples.csv column `name` (for example
    column_input("supply_v", "V", "supply voltage")): its symbol, for a Term's regressor.
    The runtime averages the column over each position as it does temp_c."""
    if not name.isidentifier() or name in AUX_INPUTS or name in RESERVED:
        raise ValueError(f"column input {name!r}: choose an identifier that is not a built-in input "
                         f"({sorted(AUX_INPUTS)}) or a derivation symbol ({sorted(RESERVED)})")
    _COLUMN_INPUTS[name] = AuxInput(name, unit, meaning or f"samples.csv column {name}")
    return _COLUMN_INPUTS[name].symbol


def aux_input(symbol: sp.Symbol) -> AuxInput:
    """The AuxInput of a symbol: built-in, declared by column_input, or a plain symbol read as a column."""
    name = str(symbol)
    return AUX_INPUTS.get(name) or _COLUMN_INPUTS.get(name) or AuxInput(name, "", f"samples.csv column {name}")


# Outputs in physical units (pulse outputs divided by nominal scale factors):
# the paper's N_i^a = K_i^a Ntilde_i^a (g) and N_i^g (deg/h).
N_out = sp.Matrix(sp.symbols("N_x N_y N_z", real=True))

# Site and test constants.
lat, w_e, w_T, g = sp.symbols("L w_e w_T g", real=True)
# Symbols of the derivation that no term may read as an auxiliary input.
RESERVED = {str(s) for s in (*omega_d, *N_out, lat, w_e, w_T, g)}
