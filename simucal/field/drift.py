"""Three-position field calibration of gyro constant drift (ruan2019).

At each static position (a segment with heading_ref_deg, the azimuth an
external north reference gives, possibly several degrees wrong):
1. coarse alignment: pitch and roll from the mean specific force, heading
   from the reference;
2. two-stage alignment: a Kalman filter on the static-base error model
   (derive/field.py, generated/field.py) runs over the position, its level
   errors at the start are corrected in the attitude, and it runs again; the
   azimuth is kept from the reference because on a static base it cannot be
   told from the east drift (derived observability);
3. the final filter estimates the north gyro drift eps_N with its 1-sigma
   history (the paper's Fig. 4).
Then eps_N(k) = c_N(k)^T eps^b over the three positions, c_N the north
direction in b of each computed attitude, is solved by least squares for the
three body drifts with their covariance. Frames: NUE navigation, FUR body.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import TypedDict

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit.noise import white_noise_var
from simucal.fit.rotations import exp_so3
from simucal.generated import field as gen
from simucal.io import blocks, calibration, outputs, records, units

AXIS_NAMES = ("x (forward)", "y (up)", "z (right)")


def coarse_attitude(f_mean, heading_rad):
    """C_b^n from the mean specific force (pitch, roll) and a heading."""
    f = f_mean / np.linalg.norm(f_mean)
    pitch = np.arcsin(np.clip(f[0], -1, 1))
    roll = np.arctan2(-f[2], f[1])
    return gen.C_b_n(heading_rad, pitch, roll)


def attitude_angles(C):
    """(heading, pitch, roll) in rad of C_b^n = Ry(-psi) Rz(theta) Rx(gamma)."""
    fwd = C[:, 0]
    return (float(np.arctan2(fwd[2], fwd[0])), float(np.arcsin(np.clip(fwd[1], -1, 1))),
            float(np.arctan2(-C[1, 2], C[1, 1])))


def expm(A):
    """Matrix exponential by scaling and squaring of its Taylor series (the transition matrix
    Phi = exp(F dt) of an 8-state model; scipy.linalg would cost 0.19 s to import)."""
    s = max(0, int(np.ceil(np.log2(max(np.abs(A).sum(1).max(), 1e-300)))) + 1)
    B = A / 2.0 ** s
    E = term = np.eye(len(A))
    for k in range(1, 20):  # |B| < 1/2: 20 terms reach double precision
        term = term @ B / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


class StaticFilter:
    """Kalman filter of the static-base error model, constant gains per position.

    x = [dv_N, dv_E, phi_N, phi_U, phi_E, eps_N, eps_U, eps_E] (m/s, rad, rad/s);
    measurement: the horizontal velocity computed from the strapdown
    equations (the true velocity is zero).
    """

    def __init__(self, g, lat, w_e, dt, steps, arw, vrw, P0_diag, r_v=1e-4):
        self.F = gen.error_model(g, w_e, lat)
        self.Phi = expm(self.F * dt)
        self.H = gen.H
        Q = np.diag([vrw ** 2, vrw ** 2, arw ** 2, arw ** 2, arw ** 2, 0, 0, 0]) * dt
        R = np.eye(2) * r_v ** 2
        P = np.diag(P0_diag)
        self.gains: list[np.ndarray] = []
        sd: list[np.ndarray] = []
        for _ in range(steps):  # the covariance does not depend on the data: run it once
            P = self.Phi @ P @ self.Phi.T + Q          # predict: P = Phi P Phi^T + Q
            S = self.H @ P @ self.H.T + R               # innovation covariance: S = H P H^T + R
            K = P @ self.H.T @ np.linalg.inv(S)         # gain: K = P H^T S^-1
            I_KH = np.eye(8) - K @ self.H
            P = I_KH @ P @ I_KH.T + K @ R @ K.T         # Joseph form: stays symmetric and positive
            self.gains.append(K)
            sd.append(np.sqrt(np.diag(P)))
        self.sd = np.array(sd)

    def run(self, C0, f_b, w_b, dt, w_ie_n, g_n):
        """Strapdown on block means with the level fed back after every update.

        The level errors and velocity are reset into the attitude and velocity
        (an error-state reset, which leaves the covariance and gains alone),
        so phi_N, phi_E stay small while the unobservable east drift would
        otherwise tilt the platform by up to a degree in 300 s. Returns the
        state history and the computed north row of C_b^n at each step.
        """
        C, v = C0.copy(), np.zeros(3)
        x = np.zeros(8)
        earth = exp_so3(-w_ie_n * dt)
        steps = exp_so3(w_b * dt)  # every block's body rotation at once: they do not depend on the state
        xs, north = np.empty((len(f_b), 8)), np.empty((len(f_b), 3))
        for k in range(len(f_b)):
            C = earth @ C @ steps[k]
            v = v + (C @ f_b[k] + g_n) * dt
            v[1] = 0.0  # the vertical channel is not used
            x = self.Phi @ x
            x = x + self.gains[k] @ (np.array([v[0], v[2]]) - self.H @ x)
            xs[k] = x
            C = exp_so3(np.array([x[2], 0.0, x[4]])) @ C
            v[0] -= x[0]
            v[2] -= x[1]
            x[[0, 1, 2, 4]] = 0.0
            north[k] = C[0]
        return xs, north


def _noise(raw, dt_raw):
    """White-noise density from first differences of raw samples (units * sqrt(s))."""
    return float(np.sqrt(np.mean(white_noise_var(raw))) * np.sqrt(dt_raw))


class PositionFilter(TypedDict):
    """One position's alignment and north-drift filter (position_estimate); per filter step where an array."""
    C_b_n: np.ndarray          # the attitude, body to navigation (North-Up-East)
    c_N: np.ndarray            # north in the body frame, unit
    eps_N: np.ndarray          # the north drift's estimate, deg/h
    std: np.ndarray            # its std, deg/h
    t: np.ndarray              # s
    arw_dpsh: float            # the gyros' angle random walk, deg/sqrt(h)
    vrw_mps_sqrth: float       # the accelerometers' velocity random walk, m/s/sqrt(h)


def position_estimate(f_raw, w_raw, t, heading_rad, meta, block_s=1.0, stages=2) -> PositionFilter:
    """Alignment and north-drift filter at one position; SI units in, dict out."""
    lat = np.radians(meta["latitude_deg"])
    w_e = units.earth_rate_dph(meta) * units.RAD_S_PER_DPH
    dt_raw = float(np.median(np.diff(t)))
    per = max(int(round(block_s / dt_raw)), 1)
    k = len(t) // per
    if k < 30:
        raise CalibrationError(f"a field position needs at least {30 * block_s:.0f} s of samples; "
                               f"got {len(t) * dt_raw:.0f} s")
    f_b = f_raw[:k * per].reshape(k, per, 3).mean(1)
    w_b = w_raw[:k * per].reshape(k, per, 3).mean(1)
    dt = per * dt_raw
    g = float(np.linalg.norm(f_b.mean(0)))
    w_ie_n = gen.earth_rate_n(w_e, lat)
    g_n = np.array([0.0, -g, 0.0])
    arw, vrw = _noise(w_raw, dt_raw), _noise(f_raw, dt_raw)
    P0 = [0.01 ** 2, 0.01 ** 2, 0.01 ** 2, np.radians(10) ** 2, 0.01 ** 2,
          (20 * units.RAD_S_PER_DPH) ** 2, (20 * units.RAD_S_PER_DPH) ** 2, (20 * units.RAD_S_PER_DPH) ** 2]
    kf = StaticFilter(g, lat, w_e, dt, k, max(arw, 1e-9), max(vrw, 1e-6), P0)
    C0 = coarse_attitude(f_b.mean(0), heading_rad)
    for _ in range(stages):  # two-stage alignment: correct the level at the start, twice
        xs, _ = kf.run(C0, f_b, w_b, dt, w_ie_n, g_n)
        C0 = exp_so3(np.array([xs[0, 2], 0.0, xs[0, 4]])) @ C0  # the azimuth stays from the reference
    xs, north = kf.run(C0, f_b, w_b, dt, w_ie_n, g_n)
    # eps_N is the drift along the computed north, which turns slowly (up drift);
    # the estimate weighs the whole window, so project on the mean computed north.
    c_N = north.mean(0)
    return {"C_b_n": C0, "c_N": c_N / np.linalg.norm(c_N), "eps_N": xs[:, 5] / units.RAD_S_PER_DPH,
            "std": kf.sd[:, 5] / units.RAD_S_PER_DPH,
            "t": (np.arange(k) + 1) * dt, "arw_dpsh": arw * np.degrees(1) * 60, "vrw_mps_sqrth": vrw * 60}


def solve_drifts(north_rows, eps_N, std):
    """Least squares eps_N(k) = c_N(k)^T eps^b; refuses a geometry that hides a drift."""
    A = np.asarray(north_rows)
    s = np.linalg.svd(A, compute_uv=False)
    if len(A) < 3 or s[-1] < 0.05 * s[0]:
        _, _, Vt = np.linalg.svd(A)
        v = Vt[-1]
        main = int(np.argmax(np.abs(v)))
        raise CalibrationError(
            "the positions' north directions do not span the body: the drift along body direction "
            f"[{v[0]:+.2f}, {v[1]:+.2f}, {v[2]:+.2f}] (mostly the {AXIS_NAMES[main]} gyro) cannot be seen. "
            "Use three distinct positions, the third rolled (about 20 deg) from the second so that "
            "its up axis leans toward north")
    W = np.diag(1 / np.asarray(std) ** 2)
    cov = np.linalg.inv(A.T @ W @ A)
    est = cov @ A.T @ W @ np.asarray(eps_N)
    return est, np.sqrt(np.diag(cov))


def heading_term_dph(meta, accuracy_deg):
    """Std of the Earth rate left in the north channel by a heading error uniform in
    +-accuracy: w_e cos L (1 - cos dpsi) (derive.field.north_residual_earth_rate)."""
    worst = gen.north_residual_earth_rate(units.earth_rate_dph(meta), np.radians(meta["latitude_deg"]),
                                          np.radians(accuracy_deg))[0]
    return abs(float(worst)) / np.sqrt(3)


def field_drift(data, block_s=1.0, stages=2, heading_accuracy_deg=5.0) -> records.FieldRecord:
    """The three body drifts of the set `data` (a folder or a MeasurementSet) with their stds, each
    position's attitude and eps_N, and under history each position's filter estimate against time
    (the paper's Fig. 4: plot_history)."""
    ms = data if isinstance(data, io.MeasurementSet) else io.read_set(data)
    if not (ms.has_acc and ms.has_gyro):
        raise CalibrationError(f"{ms.path}: field calibration needs accelerometer and gyro columns")
    if ms.segments is None:
        raise CalibrationError(f"{ms.path}: field calibration needs segments.csv with one static segment per position")
    f_all = ms.acc_g() * units.gravity(ms.meta)
    w_all = ms.gyro_dph() * units.RAD_S_PER_DPH
    positions: list[records.FieldPosition] = []
    hist: list[records.FieldHistory] = []
    rows, eps, sds = [], [], []
    for s in ms.segments:
        if s.kind != "static":
            continue
        if s.heading_ref_deg is None:
            raise CalibrationError(f"{ms.path / 'segments.csv'}: segment {s.segment} has no heading_ref_deg; "
                                   "field calibration needs the north reference's heading at each position")
        sel = ms.rows(s.segment)
        est = position_estimate(f_all[sel], w_all[sel], ms.samples["t_s"][sel], np.radians(s.heading_ref_deg),
                                ms.meta, block_s, stages)
        c_N = est["c_N"]
        h, p, r = np.degrees(attitude_angles(est["C_b_n"]))
        positions.append({"segment": s.segment, "heading_ref_deg": s.heading_ref_deg,
                          "attitude_deg": {"heading": h, "pitch": p, "roll": r},
                          "eps_north_dph": float(est["eps_N"][-1]), "std_filter_dph": float(est["std"][-1]),
                          "north_in_body": c_N.tolist(), "arw_deg_per_sqrt_h": est["arw_dpsh"]})
        rows.append(c_N)
        eps.append(est["eps_N"][-1])
        sds.append(float(np.hypot(est["std"][-1], heading_term_dph(ms.meta, heading_accuracy_deg))))
        hist.append({"segment": s.segment, "t_s": est["t"].tolist(), "eps_N_dph": est["eps_N"].tolist(),
                     "std_dph": est["std"].tolist()})
    if len(rows) < 3:
        raise CalibrationError(f"{ms.path}: {len(rows)} static positions; the three body drifts need three")
    try:
        drift, std = solve_drifts(rows, eps, sds)
    except CalibrationError as e:
        heads = [p["heading_ref_deg"] for p in positions]
        if max(abs(h) for h in heads) <= 2 * np.pi:  # every heading within one turn in radians
            raise CalibrationError(f"{e}; the headings ({', '.join(f'{h:.3g}' for h in heads)}) are all within 2 pi: "
                                   "written in radians? heading_ref_deg is in degrees") from None
        raise
    return {"method": "ruan2019 three-position",
            "gyro_drift_dph": drift.tolist(), "std_dph": std.tolist(), "positions": positions,
            "frames": {"navigation": "North-Up-East", "body": "Forward-Up-Right (x, y, z of the gyro axes)"},
            "heading_accuracy_deg": heading_accuracy_deg,
            "std_note": "filter std per position combined with the heading-reference term for the stated accuracy",
            "history": hist}


def field_calibration(ms, heading_accuracy_deg=5.0) -> calibration.Calibration:
    """The calibration (io/calibration.py) of field_drift, so that `apply` corrects the drift:
    the gyro block holds it as its bias with M = I (ruan2019 estimates no scale factor or
    misalignment), the accelerometers stay at their nominal scale factors (a block marked
    nominal, and named under not_calibrated), the positions and the filter's figures under field."""
    r = field_drift(ms, heading_accuracy_deg=heading_accuracy_deg)
    cal = calibration.header("field", ms)
    cal.gyro = blocks.affine_block("gyro", np.eye(3), r["gyro_drift_dph"], {"bias": r["std_dph"]}, None,
                                        "ruan2019: constant drift only (M held at I)")
    cal.acc = blocks.affine_block("acc", np.eye(3), np.zeros(3), {}, None,
                                       "nominal scale factors (the field method calibrates no accelerometer)",
                                       nominal=True)
    cal.not_calibrated = {
        "acc": "the field method calibrates the gyro constant drift only; apply keeps the accelerometers at their "
               "nominal scale factors",
        "gyro scale factors and misalignments": "held at nominal (M = I); ruan2019 estimates the constant drift only"}
    cal.details["field"] = r
    return cal


def plot_formats() -> list[str]:
    """The file name endings plot_history can write (matplotlib's: png, pdf, svg, ...)."""
    from matplotlib.backend_bases import FigureCanvasBase
    return sorted(FigureCanvasBase.get_supported_filetypes())


def history_figure(hist):
    """The paper's Fig. 4: each position's eps_N estimate with its 1-sigma bounds (field_drift's history)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axs = plt.subplots(len(hist), 1, figsize=(7, 2.4 * len(hist)), sharex=True)
    for ax, h in zip(np.atleast_1d(axs), hist):
        t, eps, sd = (np.asarray(h[k], float) for k in ("t_s", "eps_N_dph", "std_dph"))
        ax.plot(t, eps, label="eps_N estimate")
        ax.fill_between(t, eps - sd, eps + sd, alpha=0.3, label="+-1 sigma")
        ax.set_ylabel("deg/h")
        ax.set_ylim(eps[-1] - 8 * max(sd[-1], 1e-3), eps[-1] + 8 * max(sd[-1], 1e-3))
        ax.set_title(f"position {h['segment']}: north gyro drift", fontsize=9)
        ax.legend(fontsize=7, loc="upper right")
    np.atleast_1d(axs)[-1].set_xlabel("time at the position (s)")
    fig.tight_layout()
    return fig, plt


def plot_history(hist: list[records.FieldHistory], path: str | os.PathLike[str]) -> None:
    """Fig. 4 as an image file (its format from path's ending)."""
    fig, plt = history_figure(hist)
    with outputs.replacing(path) as tmp:
        fig.savefig(tmp, dpi=90, format=Path(path).suffix.lstrip(".") or "png")
    plt.close(fig)
