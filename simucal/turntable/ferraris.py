"""Ferraris et al. (1995), as imucal runs it: six static poses in antiparallel pairs (+x/-x, +y/-y, +z/-z,
placed by hand) and the turns between them. Method `ferraris`, the default for such a set.

Accelerometer, in g (|f| = 1 at rest). Pair j: the poses whose commanded verticals in the body frame are
+u_j and -u_j, their mean outputs y_j+ and y_j-, and f = M^-1 (y - b):
- Ferraris eq. 21-23: h_j = (y_j+ - y_j-) / 2 = M u_j, so M = H U^-1 (H = [h_j], U = [u_j]).
- The bias from the norms, not the attitudes: for the true M and b, |f_j+| = |f_j-| = 1 whatever the poses'
  tilts, so (M^-1 (y_j+ - y_j-)) . (M^-1 (y_j+ + y_j- - 2 b)) = 0, one linear equation in b a pair, three
  for b. Ferraris's eq. 19-20 (and imucal) take b_i = (y_i+ + y_i-)_i / 2, this equation to first order for
  a pair along axis i. Both are off by the tilt's second order (M's misalignments carry the tilt's first);
  over simulated hand placements the two are as near the truth (tests/test_ferraris.py). The multi-position
  method's mean over all six poses with the commanded attitudes taken as exact reads the hand's tilt in the
  four poses where an axis reads zero into that axis's bias, at first order (on imucal's example session
  |f| - g at the poses comes out 23x larger that way).
- Nor does the scale: M^-1 h_j = (f_j+ - f_j-) / 2 and m_j = (f_j+ + f_j-) / 2 are perpendicular with
  |M^-1 h_j|^2 + |m_j|^2 = 1 exactly, so the half difference's true length is sqrt(1 - |m_j|^2), not eq.
  21's 1: two poses tilted apart by 2 deg shorten it by 1.5e-4, which eq. 23 reads as the scale factor.
  Here M u_j sqrt(1 - |m_j|^2) = h_j. With both, |f| = 1 at all six poses (the six norms fix three biases
  and three scales, the poses' differences the misalignments): |f| - g at the poses is no test here.
- What six poses cannot separate: a pose's tilt across its vertical moves M's column j (a misalignment)
  exactly as much as it moves the pair's mismatch m_j = (f_j+ + f_j-) / 2 across u_j. The mismatch's six
  components (beyond the noise) measure the placement's tilt, which is carried into M's and b's stds: a
  variance component with 6 degrees of freedom, as the project does wherever a noise is not stated.

Gyro, in deg/h: y = M w + b with w in the accelerometer's calibrated frame, by weighted least squares over
the poses (the Earth rate's vertical part, its horizontal part of unknown heading a noise of its own) and
the turns (each a rate run at its protocol's angle over its duration, plus the Earth rate's vertical part).
A hand turns the unit about the vertical it sits on, tilted as the pose is: each turn's axis is the
gravity direction the accelerometer measures in the rest beside it (the static segment just before or after
it with the turn's commanded vertical), and a pose's vertical its own. Their errors (the poses' noise, and
their tilt through the accelerometer's M and b: the gyro is in that frame) go into the gyro's stds; a turn
with no rest beside it (imucal's sessions: the turns last) takes its commanded axis, off by a placement's
tilt. Its model test: the weighted residuals against the raw samples' noise (a turn's: the poses' white
noise per sample over its rows). The accelerometer's: |f| - 1 of the turns beside a rest, where gravity
stays put in the body (six poses fix the affine model exactly).
"""
from __future__ import annotations

from typing import Mapping, TypedDict, cast

import numpy as np
from numpy.typing import NDArray

from simucal.errors import CalibrationError
from simucal.fit.distributions import chi2_sf
from simucal.fit.noise import mean_and_sigma, moving_sample_var
from simucal.io import blocks, calibration, units
from simucal.turntable.multiposition import AffineFit
from simucal.turntable.observations import (commanded_up_k, outer_angle_rad, read_observations, saturated_segments,
                                            segment_duration_s)
from simucal.turntable.plans import angles_for

OPPOSITE = -1 + 1e-6  # cosine between two commanded verticals that make a pair
OFF_DEG = 20.0  # a pose whose gravity direction is this far from its commanded one is commanded wrong
SPAN = 0.1  # the turns' axes span space where their third singular value is this or more (6 deg out of a plane)


class AccFit(AffineFit):
    """The accelerometer's affine fit y = M f + b of the opposite poses (acc_fit), in g; residual_rms of |f| - 1
    at the poses."""
    placement_tilt_deg: float         # the hand placement's tilt, a std per pose
    mismatch_g: list[list[float]]     # each pair's mean of its two poses' f: what a tilt moves
    tilt2: float                      # rad^2 a pose, per component across its vertical
    pose_var: NDArray[np.float64]     # (2, 3, 3: side, pair, axis) the poses' error variance, g^2


class TurnTest(TypedDict, total=False):
    """The accelerometer's model test at the turns (acc_turn_test): chi2 of |f| - 1 on a dof a turn."""
    chi2: float                       # of |f| - 1 at the turns against their means' noise
    dof: int                          # one a turn
    p_value: float                    # chi2's
    test: str                         # in words
    rows: str                         # the turns tested


class TurnsFit(AffineFit, total=False):
    """The gyro's affine fit y = M w + b of the turns and poses (gyro_fit), in deg/h; its test where the noise is
    known."""
    chi2: float                       # of the rows' residuals against their noise, on dof
    dof: int                          # 3 (rows - 4): 3 a row less the 12 parameters
    p_value: float                    # chi2's


def _pairing(up) -> tuple[list[tuple[int, int]], list[int]]:
    """(pairs, unpaired): indices into up (n, 3), the commanded verticals, paired in order with the first
    opposite one."""
    pairs, unpaired, free = [], [], list(range(len(up)))
    while free:
        a = free.pop(0)
        b = next((k for k in free if up[a] @ up[k] < OPPOSITE), None)
        if b is None:
            unpaired.append(a)
        else:
            free.remove(b)
            pairs.append((a, b))
    return pairs, unpaired


def _six_poses(segs):
    """The static segments of segs (their indices) where they are six with commanded angles, else None."""
    static = [i for i, s in enumerate(segs) if s.kind == "static"]
    if len(static) != 6 or any(segs[i].middle_deg is None or segs[i].inner_deg is None for i in static):
        return None
    return static


def pose_pairs(segs) -> list[tuple[int, int]] | None:
    """[(plus, minus)] indices into segs of three pairs of static poses with opposite commanded verticals
    spanning space (a Ferraris session), or None where the static poses are not exactly that."""
    static = _six_poses(segs)
    if static is None:
        return None
    up, _ = commanded_up_k([segs[i] for i in static])
    pairs, unpaired = _pairing(up)
    if unpaired or abs(np.linalg.det(up[[p for p, _ in pairs]])) < 0.5:
        return None  # three pairs about one plane: not a Ferraris session
    return [(static[a], static[b]) for a, b in pairs]


def _angles(up) -> str:
    """The commanded middle and inner angles that put the vertical on up."""
    _, middle, inner = angles_for([np.round(up, 9) + 0.0])[0]  # round-off off an axis: on it (along y, inner 0)
    inner = 180.0 if abs(inner) > 179.999 else inner  # -180 and 180 are one angle
    return f"middle_deg {round(middle, 3) + 0:g}, inner_deg {round(inner, 3) + 0:g}"


def refuse_unpaired(ms):
    """Six static poses that pair up but for two (one commanded off its place): refused in one line naming
    the pose and its fix, rather than left to a method that cannot take six poses (the exact fit). The
    accelerometer's gravity directions (uncalibrated, a few degrees off) tell which pose the commands put
    wrong, or that the poses themselves are not opposite."""
    static = _six_poses(ms.segments)
    if static is None:
        return
    segs = [ms.segments[i] for i in static]
    up, _ = commanded_up_k(segs)
    pairs, unpaired = _pairing(up)
    if len(pairs) != 2:
        return
    where = f"{ms.path / 'segments.csv'}: the six static poses are no longer three opposite pairs (the Ferraris method"
    rule = "takes opposite pairs, the exact fit nine or more positions)"
    i, j = unpaired
    cmd = np.degrees(np.arccos(np.clip(up @ up.T, -1, 1)))
    means = [ms.in_units("acc", ms.rows(s.segment)).mean(0) for s in segs] if ms.has_acc else []
    if len(means) == 6 and np.all(np.isfinite(means)) and np.all(np.linalg.norm(means, axis=1) > 0):
        d = np.array(means) / np.linalg.norm(means, axis=1)[:, None]
        meas = np.degrees(np.arccos(np.clip(d @ d.T, -1, 1)))
        off = np.abs(meas - cmd).max(axis=1)  # each pose's worst disagreement with the others
        bad, other = (i, j) if off[i] >= off[j] else (j, i)
        if off[bad] > OFF_DEG:
            raise CalibrationError(
                f"{where} {rule}: segment {segs[bad].segment} is commanded at middle_deg {segs[bad].middle_deg:g}, "
                f"inner_deg {segs[bad].inner_deg:g}, {cmd[bad, other]:.0f} deg from segment {segs[other].segment}, "
                f"but its accelerometer reads gravity {meas[bad, other]:.0f} deg from it: command segment "
                f"{segs[bad].segment} at {_angles(-up[other])} (the opposite of segment {segs[other].segment})")
        said = f" (the accelerometer agrees: {meas[i, j]:.0f} deg)"
    else:
        said = ""
    bad, other = (i, j) if np.abs(up[i]).max() <= np.abs(up[j]).max() else (j, i)  # the one off the body's axes
    raise CalibrationError(
        f"{where} {rule}: segments {segs[i].segment} and {segs[j].segment} are commanded {cmd[i, j]:.0f} deg apart"
        f"{said}: place segment {segs[bad].segment} opposite segment {segs[other].segment} ({_angles(-up[other])}), "
        "or calibrate by the commanded attitudes: --method multiposition")


def acc_matrix_and_bias(y_plus, y_minus, U, passes=4):
    """(M, b) from the pairs' mean outputs y_plus, y_minus (3, 3: row j pair j, g) and their commanded
    verticals U (rows u_j): M from the differences (eq. 21-23), b from the norm equality of each pair, and
    each pair's half difference at its true length (module doc). Each pass's change is the square of the
    last one's (the lengths are second order in the tilt): four reach round-off from any hand placement."""
    H = (y_plus - y_minus) / 2
    lengths = np.ones(3)
    for _ in range(passes):
        M = np.linalg.solve(U * lengths[:, None], H).T  # M u_j |h_j| = h_j for each pair j
        Mi = np.linalg.inv(M)
        A = H @ Mi.T @ Mi  # row j: (M^-1 h_j)^T M^-1, the pair's equation A_j . 2 b = A_j . (y+ + y-)
        b = np.linalg.solve(A, np.einsum("ij,ij->i", A, y_plus + y_minus) / 2)
        mismatch = ((y_plus + y_minus) / 2 - b) @ Mi.T  # (f+ + f-) / 2, across each pair's f+ - f-
        lengths = np.sqrt(1 - np.sum(mismatch ** 2, axis=1))
    return M, b


def acc_fit(y_plus, y_minus, U, sig_plus=None, sig_minus=None) -> AccFit:
    """M, b, their stds and the placement's tilt (module doc). sig_*: each mean's std (3, 3), or None
    where the noise is unknown (then the mismatch's variance is taken as the noise's, isotropic). Also
    tilt2 (rad^2 a pose, per component across its vertical) and pose_var (2, 3, 3: side, pair, axis; g^2),
    the model of the poses' errors behind the stds."""
    M, b = acc_matrix_and_bias(y_plus, y_minus, U)
    Mi = np.linalg.inv(M)
    f_plus, f_minus = (y_plus - b) @ Mi.T, (y_minus - b) @ Mi.T
    mismatch = (f_plus + f_minus) / 2
    across = mismatch - np.einsum("ij,ij->i", mismatch, U)[:, None] * U  # the part a tilt moves
    v_across = float(np.sum(across ** 2) / 6)  # per component, g^2 (6 components)
    P = np.eye(3)[None] - U[:, :, None] * U[:, None, :]  # across each pair's vertical
    if sig_plus is None or sig_minus is None:
        noise = np.full((2, 3, 3), 2 * v_across * 6 / 4)  # a pair's mismatch has half a pose's variance; t's 6/4
        tilt2 = 0.0
    else:
        noise = np.stack([sig_plus, sig_minus]) ** 2
        noise_across = np.einsum("pjk,jkk->", noise, P) / 4 / 6  # the noise's share of v_across
        # x 6/4: an error over a std from 6 components is Student's t with 6 dof, whose variance is 6/4
        tilt2 = max(0.0, 2 * (v_across - noise_across)) * 6 / 4
    cov_y = noise[..., None] * np.eye(3) + tilt2 * np.einsum("ik,jkl,ml->jim", M, P, M)[None]  # (2, 3, 3, 3)
    J = _jacobian(lambda yp, yn: np.r_[tuple(np.ravel(x) for x in acc_matrix_and_bias(yp, yn, U))], y_plus, y_minus)
    cov = sum(J[:, k, j] @ cov_y[k, j] @ J[:, k, j].T for k in range(2) for j in range(3))
    std = np.sqrt(np.diag(cov))
    norm_error = np.r_[np.linalg.norm(f_plus, axis=1), np.linalg.norm(f_minus, axis=1)] - 1
    return {"M": M, "bias": b, "std": {"M": std[:9].reshape(3, 3).tolist(), "bias": std[9:].tolist()},
            "residual_rms": float(np.sqrt(np.mean(norm_error ** 2))), "placement_tilt_deg": float(np.degrees(
                np.sqrt(tilt2 * 4 / 6))), "mismatch_g": mismatch.tolist(), "tilt2": tilt2, "pose_var": noise}


def _jacobian(fun, y_plus, y_minus, step=1e-7):
    """d fun / d y by central differences: (n_out, 2, 3 pairs, 3 components)."""
    base = fun(y_plus, y_minus)
    J = np.zeros((len(base), 2, 3, 3))
    for k in range(2):
        for j in range(3):
            for c in range(3):
                ys = [y_plus.copy(), y_minus.copy()]
                ys[k][j, c] += step
                up = fun(*ys)
                ys[k][j, c] -= 2 * step
                J[:, k, j, c] = (up - fun(*ys)) / (2 * step)
    return J


def rests_beside(ms) -> dict[int, int]:
    """{turn's segment: the static segment just before or after it in time with its commanded vertical}."""
    segs = sorted((s for s in ms.segments if ms.rows(s.segment).size),
                  key=lambda s: ms.samples["t_s"][ms.rows(s.segment)[0]])
    out: dict[int, int] = {}
    for k, s in enumerate(segs):
        if s.kind != "rate" or None in (s.middle_deg, s.inner_deg):
            continue
        for r in (segs[i] for i in (k - 1, k + 1) if 0 <= i < len(segs)):
            if r.kind == "static" and None not in (r.middle_deg, r.inner_deg) and \
                    commanded_up_k([r, s])[0].prod(axis=0).sum() > -OPPOSITE:
                out.setdefault(s.segment, r.segment)
    return out


def acc_turn_test(ms, M, b, obs, segs, beside, stated) -> TurnTest:
    """The accelerometer's model test (module doc): chi2 of |f| - 1 at each turn beside a rest, against the
    noise of the turn's mean (its rows about their harmonics in the turn's angle) and the rest's (the fit
    holds |f| = 1 at the rest, the turn reads the same gravity), one dof a turn. A turn with clipped samples
    is left out (a test's row, never a refusal); {} where none is left or the noise is unknown."""
    at, clipped = {s.segment: k for k, s in enumerate(segs)}, saturated_segments(ms, "acc")
    turns = {s.segment: s for s in ms.segments if s.kind == "rate"}
    pairs = [(turns[t], at[r]) for t, r in beside.items() if r in at and t not in clipped]
    if not pairs or obs.sigma is None:
        return {}
    means = [mean_and_sigma(ms.in_units("acc", ms.rows(t.segment)), stated, varying=True,
                            angle_rad=outer_angle_rad(ms, ms.rows(t.segment), t)) for t, _ in pairs]
    y, sig = np.array([m for m, _ in means]), np.array([sd for _, sd in means])
    var_y = sig ** 2 + obs.sigma[[r for _, r in pairs]] ** 2
    if not np.all(np.isfinite(var_y)):
        return {}
    Mi = np.linalg.inv(M)
    f = (y - b) @ Mi.T
    norm = np.linalg.norm(f, axis=1)
    chi2 = float(np.sum((norm - 1) ** 2 / np.einsum("ij,ij->i", ((f / norm[:, None]) @ Mi) ** 2, var_y)))
    return {"chi2": chi2, "dof": len(pairs), "p_value": chi2_sf(chi2, len(pairs)),
            "test": "|f| - 1 at the turns, each beside its rest", "rows": f"{len(pairs)} turns"}


def missing_turns(turns) -> str | None:
    """Why the turns (rate segments) cannot give the gyro matrix, naming the axis no turn is about; None
    where their commanded axes span space."""
    up, _ = commanded_up_k(turns)
    if len(up) >= 3 and np.linalg.svd(up, compute_uv=False)[2] >= SPAN:
        return None
    about = sorted({"xyz"[int(np.argmax(np.abs(u)))] for u in up})
    missing = [c for k, c in enumerate("xyz") if np.all(np.abs(up[:, k]) < 0.5)]
    add = " and ".join(missing) if missing else str(np.round(np.linalg.svd(up)[2][-1], 3).tolist())
    return (f"the turns are about {' and '.join(about)} only (segments {', '.join(str(s.segment) for s in turns)}): "
            f"the Ferraris gyro matrix needs a turn about each axis; add a turn about {add} (360 deg about the "
            "vertical, from the pose with that axis up)")


def _gyro_rows(ms, poses, gyro_obs, gyro_segs, stated, curve):
    """(means (n, 3), their noise variances (n, 3), NaN where unknown) in deg/h of the poses, then the
    turns: a pose's from its rows' scatter (or --noise's curve), a turn's the poses' white noise per
    sample (a turn's own rows hold the hand's varying rate) over its rows."""
    y, var, white = [], [], []
    for s in poses:
        rows = ms.rows(s.segment)
        x = ms.in_units("gyro", rows)
        m, sd = mean_and_sigma(x, stated)
        y.append(m)
        var.append(np.square(curve(segment_duration_s(ms, rows, s.segment)) if curve is not None else sd))
        if len(x) >= 3:
            white.append(moving_sample_var(x))
    n = np.array([len(ms.rows(s.segment)) for s in gyro_segs])
    turn_var = np.mean(white, axis=0)[None] / n[:, None] if white and n.min() >= 3 and curve is None else \
        gyro_obs.sigma ** 2  # --noise's curve at the turn's length, or one averaged row's
    return np.vstack([y, gyro_obs.N]), np.vstack([var, turn_var])


def gyro_fit(y, var, up, rho, static, w_h, err) -> TurnsFit:
    """y = M w + b (module doc) by weighted least squares: y, var (n, 3) the rows' means and noise variances
    (NaN: unknown, then estimated from the residuals, untested), up (n, 3) each row's measured vertical
    (its input rho (n,) deg/h along it), static (n,) the poses, whose horizontal Earth rate w_h (deg/h)
    has an unknown heading. err: each vertical's error model, (T, J, free, tilt2, pose_var):
    delta_k = sum_q T_kq tau_q + J_kq n_q (+ P_k tau'_k where free_k), tau tilts (variance tilt2 a
    component), n the poses' accelerometer noise (pose_var (6, 3))."""
    T, J, free, tilt2, pose_var = err
    n = len(y)
    X = np.column_stack([rho[:, None] * up, np.ones(n)])
    P = np.eye(3)[None] - up[:, :, None] * up[:, None, :]
    H = (w_h ** 2 / 2) * P * static[:, None, None]  # the horizontal Earth rate's covariance a row
    known = bool(np.all(np.isfinite(var)))
    v0 = var + np.einsum("kii->ki", H) if known else np.ones((n, 3))
    A = [np.linalg.solve(X.T @ (X / v0[:, i:i + 1]), (X / v0[:, i:i + 1]).T) for i in range(3)]  # (4, n) an axis
    theta = np.array([A[i] @ y[:, i] for i in range(3)])  # row i: (m_i, b_i)
    M, b = theta[:, :3], theta[:, 3]
    r = y - X @ theta.T
    if not known:
        var = np.tile(np.sum(r ** 2, axis=0) / max(n - 4, 1), (n, 1))
    idx = [[3 * i, 3 * i + 1, 3 * i + 2, 9 + i] for i in range(3)]  # theta_i in (M.ravel(), b)
    K = np.zeros((n, 12, 3))  # d (M.ravel(), b) / d (a row's input)
    cov = np.zeros((12, 12))
    for i in range(3):
        K[:, idx[i], :] -= A[i].T[:, :, None] * M[i][None, None, :]
        cov[np.ix_(idx[i], idx[i])] += (A[i] * var[:, i]) @ A[i].T
    RK = rho[:, None, None] * K
    # a commanded axis off by a tilt d: across it d, along it the second order -|d|^2 / 2, whose mean square
    # is 2 tilt2^2 (|d|^2 / tilt2 is chi-square with 2 dof): the scale a turn reads, where the first order is
    # only d times M's misalignments (without it M's diagonal read rms error / std 1.5 at 1-3 deg tilts)
    P_free = (tilt2 * P + 2 * tilt2 ** 2 * up[:, :, None] * up[:, None, :]) * free[:, None, None]
    L, N = np.einsum("kab,kqbc->qac", RK, T), np.einsum("kab,kqbc->qac", RK, J)
    cov += (np.einsum("kab,kbc,kdc->ad", K, H, K) + tilt2 * np.einsum("qac,qbc->ab", L, L)
            + np.einsum("qac,qc,qbc->ab", N, pose_var, N)
            + np.einsum("kab,kbc,kdc->ad", RK, P_free, RK))
    C_up = (tilt2 * np.einsum("kqab,kqcb->kac", T, T) + np.einsum("kqab,qb,kqcb->kac", J, pose_var, J)
            + P_free)  # each vertical's own covariance
    v = var + np.einsum("ia,kab,ib->ki", M, H + rho[:, None, None] ** 2 * C_up, M)
    chi2, dof = float(np.sum(r ** 2 / v)), 3 * (n - 4)
    std = np.sqrt(np.diag(cov))
    out: TurnsFit = {"M": M, "bias": b, "std": {"M": std[:9].reshape(3, 3).tolist(), "bias": std[9:].tolist()},
                     "residual_rms": float(np.sqrt(np.mean(r ** 2)))}
    if known and dof > 0:
        out["chi2"], out["dof"], out["p_value"] = chi2, dof, chi2_sf(chi2, dof)
    return out


def _verticals(acc, up_cmd, rest):
    """Each gyro row's vertical and its error model (gyro_fit's err): in the accelerometer's calibrated
    frame the gravity direction of its rest where rest[k] >= 0 (pose q = side * 3 + pair of acc's
    y_plus, y_minus), else the commanded one up_cmd[k], off by a placement's tilt (free)."""
    n = len(rest)
    T, J, up = np.zeros((n, 6, 3, 3)), np.zeros((n, 6, 3, 3)), up_cmd.copy()
    if acc is None:
        return up, (T, J, rest < 0, 0.0, np.zeros((6, 3)))
    fit, y_plus, y_minus, U = acc
    has = np.nonzero(rest >= 0)[0]

    def directions(yp, yn):
        M, b = acc_matrix_and_bias(yp, yn, U)
        f = (np.vstack([yp, yn])[rest[has]] - b) @ np.linalg.inv(M).T
        return np.ravel(f / np.linalg.norm(f, axis=1)[:, None])

    up[has] = directions(y_plus, y_minus).reshape(-1, 3)
    J[has] = _jacobian(directions, y_plus, y_minus).reshape(len(has), 3, 6, 3).transpose(0, 2, 1, 3)
    U6 = np.vstack([U, -U])
    P6 = np.eye(3)[None] - U6[:, :, None] * U6[:, None, :]
    T[has] = np.einsum("kqab,bc,qcd->kqad", J[has], fit["M"], P6)  # a pose's tilt, through M and b
    T[has, rest[has]] -= P6[rest[has]]  # the rest's own tilt is the turn's true axis, no error
    return up, (T, J, rest < 0, fit["tilt2"], fit["pose_var"].reshape(6, 3))


def _gyro_block(ms, acc, poses, gyro_obs, gyro_segs, beside, stated, curve):
    """The gyro's block (module doc): poses in acc's pose order (q) where acc is given."""
    y, var = _gyro_rows(ms, poses, gyro_obs, gyro_segs, stated, curve)
    segs = poses + list(gyro_segs)
    q_of = {s.segment: q for q, s in enumerate(poses)} if acc is not None else {}
    rest = np.array([q_of.get(s.segment if s.kind == "static" else beside.get(s.segment), -1) for s in segs])
    up, err = _verticals(acc, commanded_up_k(segs)[0], rest)
    lat, w_e = np.radians(ms.meta.get("latitude_deg", 0.0)), units.earth_rate_dph(ms.meta)
    rho = w_e * np.sin(lat) + np.array([s.outer_rate_dps * units.DPH_PER_DPS if s.kind == "rate" else 0.0
                                        for s in segs])  # deg/h along the vertical
    r = gyro_fit(y, var, up, rho, np.array([s.kind == "static" for s in segs]), w_e * np.cos(lat), err)
    axes = {s.segment: poses[rest[k]].segment if rest[k] >= 0 else None for k, s in enumerate(segs) if s.kind == "rate"}
    return blocks.affine_block(
        "gyro", r["M"], r["bias"], r["std"], r["residual_rms"],
        "linear y = M w + b over the turns and the poses' Earth rate, each turn about the gravity direction of "
        "the rest beside it (else its commanded axis)", rows=f"{len(poses)} poses and {len(gyro_segs)} turns",
        test="the residuals against the raw samples' noise" if "chi2" in r else "no noise estimate",
        turn_axis_from_rest=[[t, p] for t, p in axes.items()],
        **{k: cast("Mapping[str, float]", r)[k] for k in ("chi2", "dof", "p_value") if k in r})


def calibrate_ferraris(ms, acc_noise_g=None, gyro_noise_dph=None, noise_curves=None) -> calibration.Calibration:
    """The calibration of a Ferraris session (six static poses in opposite pairs, turns as rate runs)."""
    cal, (acc_obs, acc_segs, gyro_obs, gyro_segs) = read_observations(
        ms, "ferraris", {"acc": {"static"}, "gyro": {"rate"}}, acc_noise_g, gyro_noise_dph, noise_curves)
    beside, acc, poses = rests_beside(ms), None, [s for s in ms.segments if s.kind == "static"
                                                  and s.middle_deg is not None and s.inner_deg is not None]
    if acc_obs is not None:
        pairs = pose_pairs(acc_segs)
        if pairs is None:
            refuse_unpaired(ms)
            raise CalibrationError(
                f"{ms.path}: the Ferraris method takes six static poses in three pairs of opposite commanded "
                f"verticals (+x/-x, +y/-y, +z/-z); this set's {len(acc_segs)} usable "
                "static segments are not that: use --method exact (nine or more positions) or --method multiposition")
        plus, minus = [p for p, _ in pairs], [m for _, m in pairs]
        poses = [acc_segs[i] for i in plus + minus]
        U = commanded_up_k(poses[:3])[0]
        sig = acc_obs.sigma
        r = acc_fit(acc_obs.N[plus], acc_obs.N[minus], U, None if sig is None else sig[plus],
                    None if sig is None else sig[minus])
        acc = (r, acc_obs.N[plus], acc_obs.N[minus], U)
        stated = acc_noise_g if acc_noise_g is not None else units.stated_noise(ms.meta, "acc")
        test = acc_turn_test(ms, r["M"], r["bias"], acc_obs, acc_segs, beside, stated) or {"test": (
            "six poses fix the affine model, and no turn rests beside its pose to test it on" if not beside else
            "no noise estimate")}
        cal.acc = blocks.affine_block(
            "acc", r["M"], r["bias"], r["std"], r["residual_rms"],
            "Ferraris: M from the opposite poses' differences, b from their norms' equality (no attitude)",
            residual_unit="g (|f| - 1 at the poses)", placement_tilt_deg=r["placement_tilt_deg"],
            pairs=[[acc_obs.labels[p], acc_obs.labels[m]] for p, m in pairs], **test)
        blocks.inflate_if_failing(cal.acc)
    if gyro_obs is not None:
        why = missing_turns(gyro_segs)
        if why:
            cal.drop_sensor("gyro", why)
        else:
            stated = gyro_noise_dph if gyro_noise_dph is not None else units.stated_noise(ms.meta, "gyro")
            cal.gyro = _gyro_block(ms, acc, poses, gyro_obs, gyro_segs, beside, stated,
                                   (noise_curves or {}).get("gyro"))
            blocks.inflate_if_failing(cal.gyro)
    elif ms.has_gyro:
        cal.drop_sensor("gyro", "no usable turns (rate segments) in segments.csv: the Ferraris gyro matrix needs "
                                "a turn about each axis")
    return cal
