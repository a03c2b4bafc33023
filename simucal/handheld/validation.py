"""`simucal validate`'s checks on a stream (a hand-placed session): |f| = 1 g at each static pose,
and each move's gravity direction after the move predicted by the integrated gyro against the one
the calibrated accelerometers measure (Tedaldi's cost; handheld/moves.py), as an angle in deg. At
nominal the gyro's bias is taken from the initial rest, as any user would; both use the calibrated
accelerometers' directions, so the check is the gyro's alone. The same residual at the rests' noise
is not known a priori, so moves have no floor (the shared pieces: fit/validation.py)."""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.validation import FLOOR, norm_block, rms, segment_means, with_calibration
from simucal.handheld.moves import build_moves, move_residuals
from simucal.handheld.static_detect import detect_static
from simucal.io import units
from simucal.io.sensor_checks import saturated_rows


def stream_checks(ms, f_before, f_after, w_before, w_after, cal) -> dict:
    """{sensor: [check]} of a calibration cal on the stream ms (as turntable/validation.table_checks)."""
    if f_after is None:
        raise CalibrationError(f"{ms.path}: a stream without accelerometers has no reference to validate against")
    t = ms.samples["t_s"]
    det = detect_static(f_after, t)
    rest = slice(det.starts[0] + det.window // 2, det.ends[0] - det.window // 2)
    groups = [slice(a, b) for a, b in zip(det.starts, det.ends)]
    (mb, _), (ma, fl) = segment_means(f_before, groups, None), segment_means(f_after, groups, None)
    whole, with_cal = with_calibration(fl, cal, "acc", ma, [np.arange(a, b) for a, b in zip(det.starts, det.ends)], ms)
    out = {"acc": [norm_block("g", np.linalg.norm(mb, axis=1) - 1, np.linalg.norm(ma, axis=1) - 1, whole,
                              f"|f| - 1 g at each of the {len(groups)} static poses" + FLOOR[with_cal],
                              [f"pose at {t[a]:.1f} s" for a in det.starts])]}
    if w_after is not None:
        bad = saturated_rows(ms, "gyro")[0]
        angles = []
        g_dirs = ma / np.linalg.norm(ma, axis=1, keepdims=True)  # the calibrated accelerometers: the gyro's reference
        for w, nominal in ((w_before, True), (w_after, False)):
            w_dps = w / units.DPH_PER_DPS
            bias = w_dps[rest].mean(0) if nominal else np.zeros(3)  # nominal: the rest's bias, as a user would
            mv, _ = build_moves(w_dps, t, det, bias, bad)
            angles.append(np.degrees(np.linalg.norm(move_residuals(np.eye(3), mv, g_dirs, jac=False)[0], axis=1)))
        out["gyro"] = [{"what": "gravity direction after each move: the integrated gyro against the calibrated "
                                "accelerometers (at nominal, the gyro bias from the initial rest)", "unit": "deg",
                        "n": int(len(angles[1])), "before_rms": rms(angles[0]), "after_rms": rms(angles[1]),
                        "floor_rms": None}]
    return out


