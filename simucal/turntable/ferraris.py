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

Gyro: the multi-position regression (multiposition.py) over the turns (rate runs, each at its
protocol's angle over its duration) and the poses' Earth rate, as imucal's bias from the poses and its
matrix from the turns.
"""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.io import calibration
from simucal.turntable.multiposition import multiposition
from simucal.turntable.observations import commanded_up_k, read_observations

OPPOSITE = -1 + 1e-6  # cosine between two commanded verticals that make a pair


def pose_pairs(segs) -> list[tuple[int, int]] | None:
    """[(plus, minus)] indices into segs of three pairs of static poses with opposite commanded verticals
    spanning space (a Ferraris session), or None where the static poses are not exactly that."""
    static = [i for i, s in enumerate(segs) if s.kind == "static"]
    if len(static) != 6 or any(segs[i].middle_deg is None or segs[i].inner_deg is None for i in static):
        return None
    up, _ = commanded_up_k([segs[i] for i in static])
    pairs, free = [], list(range(6))
    while free:
        a = free.pop(0)
        b = next((k for k in free if up[a] @ up[k] < OPPOSITE), None)
        if b is None:
            return None
        free.remove(b)
        pairs.append((static[a], static[b]))
    if abs(np.linalg.det(up[[static.index(p) for p, _ in pairs]])) < 0.5:
        return None  # three pairs about one plane: not a Ferraris session
    return pairs


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


def acc_fit(y_plus, y_minus, U, sig_plus=None, sig_minus=None) -> dict:
    """M, b, their stds and the placement's tilt (module doc). sig_*: each mean's std (3, 3), or None
    where the noise is unknown (then the mismatch's variance is taken as the noise's, isotropic)."""
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
        # rad^2 a pose, per component across its vertical; x 6/4: an error over a std from 6 components is
        # Student's t with 6 dof, whose variance is 6/4
        tilt2 = max(0.0, 2 * (v_across - noise_across)) * 6 / 4
    cov_y = noise[..., None] * np.eye(3) + tilt2 * np.einsum("ik,jkl,ml->jim", M, P, M)[None]  # (2, 3, 3, 3)
    J = _jacobian(lambda yp, yn: np.r_[tuple(np.ravel(x) for x in acc_matrix_and_bias(yp, yn, U))], y_plus, y_minus)
    cov = sum(J[:, k, j] @ cov_y[k, j] @ J[:, k, j].T for k in range(2) for j in range(3))
    std = np.sqrt(np.diag(cov))
    norm_error = np.r_[np.linalg.norm(f_plus, axis=1), np.linalg.norm(f_minus, axis=1)] - 1
    return {"M": M, "bias": b, "std": {"M": std[:9].reshape(3, 3).tolist(), "bias": std[9:].tolist()},
            "residual_rms": float(np.sqrt(np.mean(norm_error ** 2))), "placement_tilt_deg": float(np.degrees(
                np.sqrt(tilt2 * 4 / 6))), "mismatch_g": mismatch.tolist()}


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


def calibrate_ferraris(ms, acc_noise_g=None, gyro_noise_dph=None, noise_curves=None) -> calibration.Calibration:
    """The calibration of a Ferraris session (six static poses in opposite pairs, turns as rate runs)."""
    cal, (acc_obs, acc_segs, gyro_obs, gyro_segs) = read_observations(
        ms, "ferraris", {"acc": {"static"}, "gyro": {"rate"}}, acc_noise_g, gyro_noise_dph, noise_curves)
    if acc_obs is not None:
        pairs = pose_pairs(acc_segs)
        if pairs is None:
            raise CalibrationError(
                f"{ms.path}: the Ferraris method takes six static poses in three pairs of opposite commanded "
                f"verticals (+x/-x, +y/-y, +z/-z); this set's {len(acc_segs)} usable static segments are not that: "
                f"use --method exact (nine or more positions) or --method multiposition")
        plus, minus = [p for p, _ in pairs], [m for _, m in pairs]
        U = commanded_up_k([acc_segs[i] for i in plus])[0]
        sig = acc_obs.sigma
        r = acc_fit(acc_obs.N[plus], acc_obs.N[minus], U, None if sig is None else sig[plus],
                    None if sig is None else sig[minus])
        cal.acc = calibration.affine_block(
            "acc", r["M"], r["bias"], r["std"], r["residual_rms"],
            "Ferraris: M from the opposite poses' differences, b from their norms' equality (no attitude)",
            residual_unit="g (|f| - 1 at the poses)", placement_tilt_deg=r["placement_tilt_deg"],
            pairs=[[acc_obs.labels[p], acc_obs.labels[m]] for p, m in pairs])
    if gyro_obs is not None:
        r = multiposition(ms, None, None, gyro_obs, gyro_segs)["gyro"]
        cal.gyro = calibration.affine_block("gyro", r["M"], r["bias"], r["std"], r["residual_rms"],
                                            "linear y = M f + b over the turns and the poses' Earth rate")
    elif ms.has_gyro:
        cal.drop_sensor("gyro", "no usable turns (rate segments) in segments.csv: the Ferraris gyro matrix needs "
                                "a turn about each axis")
    return cal
