"""Systematic calibration's error-state model, derived (the Kalman filter of simucal/systematic/).

The unit runs a strapdown navigation solution in n (East-North-Up, frames.py) at a fixed place on
the table; b, the body frame, is the accelerometers' parameter frame. The psi-angle error model
(Titterton & Weston, Strapdown Inertial Navigation Technology, eq. 12.6-12.21; the same form as
ruan2019's static base in field.py), with C = C_b^n the computed attitude:

    C_computed = (I - [phi x]) C_b^n                            (attitude error phi, rad)
    d(phi)/dt = -w_ie^n x phi - C dw_b                           (dw_b: the rate error in b, rad/s)
    d(dv)/dt  =  f^n x phi + C df_b - 2 w_ie^n x dv              (dv = v_computed - v, m/s)

The sensor errors are the error models themselves: the navigation reads u_hat = h^-1(N; p_hat),
the inverse of the sensor model N = h(u; p), so to first order in dp = p_hat - p

    du = u_hat - u = -(dh/du)^-1 (dh/dp) dp                      (D = -A^-1 J)

with, for the gyro, h(u_b) = h_gyro(C_b^d(eta) u_b; p) and C_b^d(eta) = mounting(eta) (frames.py):
the gyro's own parameters and the three angles of its frame d against b are all states. So the
states are x = [phi, dv, p_acc, p_gyro, eta]: 6 + the two models' parameters + 3, and adding a term
to a model adds its state. Measurements at rest: zero velocity, z = v_computed = dv (H).

`error_state_model` gives the whole F, G and H of any two models; the runtime assembles the same F
from the generated blocks below and the models' generated Jacobians (tests hold the two equal).
"""
from __future__ import annotations

import sympy as sp

from .frames import mounting
from .models import ErrorModel

C = sp.Matrix(3, 3, sp.symbols("C_11 C_12 C_13 C_21 C_22 C_23 C_31 C_32 C_33", real=True))  # C_b^n
f_b = sp.Matrix(sp.symbols("fb_x fb_y fb_z", real=True))       # specific force in b, g
w_b = sp.Matrix(sp.symbols("wb_x wb_y wb_z", real=True))       # angular rate in b, deg/h
w_ie = sp.Matrix(sp.symbols("wie_E wie_N wie_U", real=True))   # Earth rate in n, rad/s
eta = sp.Matrix(sp.symbols("eta_x eta_y eta_z", real=True))    # C_b^d = mounting(eta), rad
g0 = sp.Symbol("g0", positive=True)                            # local gravity, m/s^2 per g
phi = sp.Matrix(sp.symbols("phi_E phi_N phi_U", real=True))
dv = sp.Matrix(sp.symbols("dv_E dv_N dv_U", real=True))
dw = sp.Matrix(sp.symbols("dw_x dw_y dw_z", real=True))        # rate error in b, deg/h
df = sp.Matrix(sp.symbols("df_x df_y df_z", real=True))        # specific-force error in b, g
noise = sp.Matrix(sp.symbols("n_gx n_gy n_gz n_ax n_ay n_az", real=True))  # white noise: rad/s, m/s^2
RAD_S_PER_DPH = sp.pi / 180 / 3600
NAV_STATES = tuple(phi) + tuple(dv)


def navigation_rates(sensor_error=(dw, df), white=noise) -> sp.Matrix:
    """d[phi, dv]/dt of the psi-angle model (module doc), the sensor errors in their units (deg/h, g)
    and the sensors' white noise (rad/s, m/s^2) added to them."""
    f_n = C * f_b * g0
    dphi = -w_ie.cross(phi) - C * (sensor_error[0] * RAD_S_PER_DPH + sp.Matrix(white[:3]))
    ddv = f_n.cross(phi) + C * (sensor_error[1] * g0 + sp.Matrix(white[3:])) - 2 * w_ie.cross(dv)
    return sp.Matrix.vstack(dphi, ddv)


def navigation_blocks():
    """(F_nav (6, 6), B (6, 6), G (6, 6), H (3, 6)): d[phi, dv]/dt = F_nav [phi, dv] + B [dw, df] + G noise,
    and the zero-velocity measurement z = H [phi, dv]."""
    rates = navigation_rates()
    return (rates.jacobian(sp.Matrix(NAV_STATES)), rates.jacobian(sp.Matrix.vstack(dw, df)),
            rates.jacobian(noise), sp.Matrix(NAV_STATES[3:]).jacobian(sp.Matrix(NAV_STATES)))


def frame_rate_sensitivity(angles=eta, u=w_b) -> sp.Matrix:
    """d(C_b^d(eta) w_b)/d(eta) (3, 3): how the gyro's input moves with its frame's angles."""
    return (mounting(*angles) * u).jacobian(angles)


def sensor_params(model: ErrorModel) -> tuple:
    """The model's parameters as the filter's symbols, named with the sensor (acc_b_x, gyro_b_x: the two
    models share names)."""
    return tuple(sp.Symbol(f"{model.sensor}_{p}", real=True) for p in model.params)


def sensor_sensitivity(model: ErrorModel, u_b, frame=None) -> tuple[sp.Matrix, tuple]:
    """D = -A^-1 J (module doc) of one model at the input u_b in b, and its parameters (sensor_params;
    the frame's angles eta after them where `frame` is given: the gyro, h(C_b^d(eta) u_b), whose A is
    the model's dh/du times the rotation, inverted as its transpose)."""
    named = dict(zip(model.params, sensor_params(model)))
    N = model.output().subs(named, simultaneous=True)
    u = sp.Matrix(model.inputs)
    D_model = -N.jacobian(u).LUsolve(N.jacobian(sp.Matrix(sensor_params(model))))
    if frame is None:
        return D_model.subs(dict(zip(model.inputs, u_b)), simultaneous=True), sensor_params(model)
    R = mounting(*frame)
    D_model = D_model.subs(dict(zip(model.inputs, R * u_b)), simultaneous=True)
    return (sp.Matrix.hstack(R.T * D_model, -R.T * frame_rate_sensitivity(frame, u_b)),
            sensor_params(model) + tuple(frame))


def error_state_model(acc: ErrorModel, gyro: ErrorModel):
    """(F, G, H, states) of the whole filter for two models: d(x)/dt = F x + G noise, z = H x."""
    D_a, p_a = sensor_sensitivity(acc, f_b)
    D_g, p_g = sensor_sensitivity(gyro, w_b, eta)
    d_a = sp.Matrix(sp.symbols([f"d_{s}" for s in p_a], real=True))
    d_g = sp.Matrix(sp.symbols([f"d_{s}" for s in p_g], real=True))
    states = sp.Matrix(NAV_STATES + tuple(d_a) + tuple(d_g))
    nav = navigation_rates((D_g * d_g, D_a * d_a))
    rates = sp.Matrix.vstack(nav, sp.zeros(len(d_a) + len(d_g), 1))  # the parameters are constants
    H = sp.Matrix(NAV_STATES[3:]).jacobian(states)
    return rates.jacobian(states), rates.jacobian(noise), H, tuple(states)

