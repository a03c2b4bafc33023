"""Static intervals in a continuous stream (Tedaldi et al. 2014, as in imu_tk).

The norm of the per-axis accelerometer variance over a centred window is
compared with `factor` times the same norm over the initial rest; runs below
it, at least `min_static_s` long, are static poses. Where the gyro is given, a pose must
also not turn: the gyro's mean over the window, less the still interval's own
reference, within the gyro limit (gyro_limit). The reference is the interval's median or its windowed mean nearest
the rest's bias, whichever more of the interval stays near (a bias that drifts between poses is
no turn; a turn filling most of an interval is not taken for its bias: no reference
lies GYRO_DRIFT_DPS from the rest's). A turn
about the vertical leaves the accelerometers still (a clean simulated session took a
42 deg/s turn for a pose, and its moves then failed their test), and any turn during a
pose is lost to the moves, which are integrated between poses: a slow move's ends too (a 3.9 deg
move peaking at 2.4 deg/s gave its poses 0.35 deg of it each at 1 deg/s, and its moves failed at
chi2 186 on 51 dof, 1 clean session in 1000; at 0.3 deg/s, 0.03 deg and chi2 46).

The limit is the session's own, the larger of two levels the data give (gyro_limit):
- the gyro's noise: GYRO_NOISE_FACTOR times the std of the windowed mean (norm over the axes) from the
  initial rest's white noise, at least the quantisation's q^2/12 per sample (0.35 deg/s for a 0.1 deg/s
  gyro at 100 Hz and a 1 s window; a still unit's windowed mean never reaches it);
- the hand's: GYRO_SWAY_FACTOR times the poses' sway, the median over the poses of each pose's median
  windowed rate less its median. A hand does not hold a pose still: on a real MPU-6050 session a pose's
  windowed rate wanders 0.1-0.3 deg/s (median) about its own level and settles from 1-4 deg/s over
  the first 0.2-0.5 s after its move; the pose's gravity direction is as uncertain as that sway
  makes it, and a move's tail below it cannot be told from the hand. Medians over and within poses: a
  pose's settling and a turn in one pose move it little. A simulated pose is still, and its sway is
  the noise's (4 x it, at most 0.06 deg/s, is below the noise level, which then sets the limit).
A fixed floor tuned on simulated sessions (0.3 deg/s) dropped three of that session's nine poses and split a
fourth (8 positions for 9 parameters: refused); from its sway (0.17 deg/s) the limit is 0.66 deg/s and keeps
all nine, each trimmed of its settling. On 40 clean simulated sessions the detection is what the fixed floor
gave (4 x their sway is at most 0.18 of the noise level); on imu_tk's Xsens session the noise level (0.82
deg/s) sets it, as before; on imucal's Ferraris session read as a stream the noise level, 0.14 deg/s (the floor
gave 0.3), keeps the same 13 poses.
`DetectSettings.gyro_limit_dps` (--gyro-limit-dps) states it instead.

Every accelerometer-still interval a rule drops is reported with the rule and its numbers
(Detection.dropped: the gyro limit, the gyro far from the rest's bias throughout, or shorter than
`min_static_s`), and every one the gyro shortens (Detection.trimmed). The initial rest is found from
the data: it lasts while the moving variance stays within `rest_factor` of
the white-noise level that first differences give over the first window. Everything is reported so a user can
check and override it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.noise import moving_sample_var, quantization_step, white_noise_var
from simucal.io.stream_records import DroppedInterval, GyroLimit


@dataclass(frozen=True)
class DetectSettings:
    """The static detector's settings (the --init-rest-s, --threshold-factor, --window-s,
    --min-static-s and --gyro-limit-dps options): window of the moving variance (s), threshold as a
    multiple of the rest's variance, shortest static interval (s), the initial rest's length (None:
    found), the gyro's limit on a pose's windowed rate less its reference (deg/s; None: from the
    data, gyro_limit)."""
    window_s: float = 1.0
    threshold_factor: float = 6.0
    min_static_s: float = 1.0
    init_rest_s: float | None = None
    gyro_limit_dps: float | None = None


@dataclass
class Detection:
    starts: list          # first row of each interval
    ends: list            # one past the last row
    threshold: float      # on the moving-variance norm, (output unit)^2
    window: int           # samples
    min_samples: int
    init_rest_end: int    # rows [0, init_rest_end) are the initial rest
    factor: float
    threshold_from: str = "the initial rest"  # or the quietest 3 s of a stream without one
    gyro_threshold_dps: float | None = None  # on the gyro's windowed mean rate less the interval's (None: no gyro)
    gyro_limit: GyroLimit | None = None  # how that limit was set (gyro_limit): noise_dps, sway_dps, set_by
    # still intervals no pose was kept from: t_s, rule, text
    dropped: list[DroppedInterval] = field(default_factory=list)
    trimmed: list[DroppedInterval] = field(default_factory=list)  # those the gyro shortened: t_s, kept_s, text

    def as_dict(self, t):
        d = asdict(self)
        d["intervals_s"] = [[float(t[a]), float(t[b - 1])] for a, b in zip(self.starts, self.ends)]
        d["count"] = len(self.starts)
        return d


def moving_mean(x, w):
    """Per-axis mean over a centred window of w samples (edges: shrunk window)."""
    n = len(x)
    c = np.vstack([np.zeros((1, x.shape[1])), np.cumsum(x, 0)])
    lo, hi = np.clip(np.arange(n) - w // 2, 0, n), np.clip(np.arange(n) + w // 2 + 1, 0, n)
    return (c[hi] - c[lo]) / (hi - lo)[:, None]


def moving_variance(x, w):
    """Per-axis variance over a centred window of w samples (edges: shrunk window)."""
    return np.maximum(moving_mean(x * x, w) - moving_mean(x, w) ** 2, 0.0)


def first_motion(mv, acc, w, rest_factor=20.0) -> int:
    """The first row whose moving variance (norm, mv) exceeds rest_factor times the white-noise level that first
    differences give over the first window (blind to slow motion and drift, so a stream that starts moving shows
    a moving variance far above it); len(mv) where none does: still throughout."""
    seed = float(np.linalg.norm(white_noise_var(acc[:w])))
    above = np.nonzero(mv > rest_factor * max(seed, 1e-300))[0]
    return int(above[0]) if above.size else len(mv)


def still_throughout(acc, t, window_s=1.0, rest_factor=20.0) -> bool:
    """Whether a stream never moves (first_motion finds no row), as detect_static judges its initial rest."""
    dt = float(np.median(np.diff(t)))
    w = max(int(round(window_s / dt)) | 1, 3)
    return first_motion(np.linalg.norm(moving_variance(acc, w), axis=1), acc, w, rest_factor) >= len(t)


GYRO_NOISE_FACTOR = 20.0  # the gyro limit's noise level: this many stds of the rest's windowed mean (norm)
GYRO_SWAY_FACTOR = 4.0  # the gyro limit's hand level: this many times the poses' median sway
GYRO_DRIFT_DPS = 10.0  # no gyro's bias drifts this far from the rest's in a session: an interval turning throughout


def detect_static(acc, t, settings: DetectSettings = DetectSettings(), rest_factor=20.0, gyro_dps=None) -> Detection:
    """The static intervals (module doc) of accelerometer rows acc (n, 3) at times t; gyro_dps (n, 3) the gyro
    in deg/s where the stream has one."""
    if len(t) < 20:
        raise CalibrationError(f"the stream has {len(t)} row{'s' * (len(t) != 1)}: a hand-placed session is one "
                               "continuous recording, an initial rest and then poses joined by moves")
    window_s, factor, min_s, init_rest_s = (settings.window_s, settings.threshold_factor, settings.min_static_s,
                                            settings.init_rest_s)
    dt, length = float(np.median(np.diff(t))), float(t[-1] - t[0])
    if dt >= 0.5:
        raise CalibrationError(f"t_s steps by {dt:g} s (median): {1 / dt:.2g} Hz is too slow to follow a move between "
                               "poses; if t_s is in milliseconds, write it in seconds (the spec's unit)")
    for name, value, part in (("--window-s", window_s, 4), ("--min-static-s", min_s, 4),
                              ("--init-rest-s", init_rest_s, 2)):
        if value is not None and value > length / part:
            raise CalibrationError(f"{name} {value:g}: longer than 1/{part} of the stream ({length:.1f} s), which "
                                   "leaves no room for the poses and moves; give seconds")
    w = max(int(round(window_s / dt)) | 1, 3)
    mv = np.linalg.norm(moving_variance(acc, w), axis=1)
    init_end = int(np.searchsorted(t, t[0] + init_rest_s)) if init_rest_s is not None else first_motion(mv, acc, w,
                                                                                                       rest_factor)
    if init_end >= len(mv) and init_rest_s is None:
        raise CalibrationError(f"no motion: the accelerometers stay still through the whole stream "
                               f"({t[-1] - t[0]:.1f} s); a calibration needs the unit turned into many poses. "
                               "Still data give the bias over temperature where temp_c rises "
                               "(simucal calibrate SET --thermal: a warm-up, as PX4's and ArduPilot's thermal "
                               "calibrations take it) and the noise terms (simucal noise SET)")
    needed = 3.0 if init_rest_s is None else 0.5  # a stated rest is the user's call
    rest = slice(0, init_end)
    if t[min(init_end, len(t) - 1)] - t[0] < needed:
        if init_rest_s is not None:
            raise CalibrationError(f"--init-rest-s {init_rest_s:g}: shorter than {needed} s of samples")
        # no initial rest (Tedaldi's protocol starts with one): the quietest 3 s anywhere sets the threshold
        k = max(int(round(3.0 / dt)), w)
        if len(mv) < 2 * k:
            raise CalibrationError(f"the stream is {t[-1] - t[0]:.1f} s long, too short to find a still stretch of "
                                   "3 s for the static detector's threshold; record an initial rest of 3 s or more")
        c = np.cumsum(np.r_[0.0, mv])
        j = int(np.argmin(c[k:] - c[:-k]))
        rest = slice(j, j + k)
    # a rest quieter than one LSB reads constant: its variance is floored at q^2/12 (noise.quantization_step)
    q2 = np.maximum(np.var(acc[rest], axis=0), quantization_step(acc[rest], acc) ** 2 / 12)
    threshold = factor * float(np.linalg.norm(q2))
    still = mv < threshold
    acc_starts, acc_ends = _runs(still)
    min_samples = int(round(min_s / dt))
    gyro_threshold, limit_info, dev = None, None, None
    starts, ends = acc_starts, acc_ends
    if gyro_dps is not None:
        g = np.asarray(gyro_dps, float)
        gyro_threshold, limit_info = gyro_limit(g, rest, w, acc_starts, acc_ends, min_samples,
                                                settings.gyro_limit_dps)
        still, dev = _not_turning(still, acc_starts, acc_ends, g, rest, w, gyro_threshold)
        starts, ends = _runs(still)
    keep = (ends - starts) >= min_samples
    starts, ends = starts[keep], ends[keep]
    dropped, trimmed = _dropped(acc_starts, acc_ends, starts, ends, dev, gyro_threshold, min_samples, min_s, t, dt)
    if not len(starts):
        raise CalibrationError(f"no static interval of at least {min_s:g} s found (threshold {threshold:.3g}, "
                               f"{factor:g} x the initial rest's variance); lower --min-static-s or raise "
                               "--threshold-factor" + "".join(f"; {x['text']}" for x in dropped))
    source = ("the initial rest" if rest.start == 0 else
              f"the quietest 3 s ({t[rest.start]:.1f}-{t[rest.stop - 1]:.1f} s; the stream has no initial rest)")
    return Detection(starts.tolist(), ends.tolist(), threshold, w, min_samples, init_end, factor, source,
                     gyro_threshold, limit_info, dropped, trimmed)


def _runs(mask) -> tuple[np.ndarray, np.ndarray]:
    """(first rows, one past the last rows) of the runs of True in mask."""
    edges = np.diff(np.r_[0, mask.astype(int), 0])
    return np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]


def _reference(windowed, a, b, b_rest, limit):
    """An accelerometer-still interval's gyro reference (deg/s), or None: its median, or its windowed mean
    nearest the rest's bias b_rest, whichever more of it stays within limit of, and none GYRO_DRIFT_DPS
    or more from the rest's (the interval then turns throughout)."""
    refs = [r for r in (np.median(windowed[a:b], axis=0),
                        windowed[a + int(np.argmin(np.linalg.norm(windowed[a:b] - b_rest, axis=1)))])
            if np.linalg.norm(r - b_rest) < GYRO_DRIFT_DPS]
    if not refs:
        return None
    return max(refs, key=lambda r: int(np.sum(np.linalg.norm(windowed[a:b] - r, axis=1) < limit)))


def gyro_limit(g, rest, w, starts, ends, min_samples, stated=None) -> tuple[float, GyroLimit]:
    """The gyro veto's limit on a pose's windowed mean rate less its reference (deg/s), and how it was set:
    the larger of the rest's noise level and the hand's sway level (module doc), or the stated one."""
    noise = GYRO_NOISE_FACTOR * float(np.sqrt(np.sum(moving_sample_var(g[rest], g)))) / np.sqrt(w)
    windowed = moving_mean(g, w)
    b_rest = g[rest].mean(0)
    sways = []
    for a, b in zip(starts, ends):  # the poses: long enough, not the rest, and not turning throughout
        if b - a < min_samples or (a < rest.stop and b > rest.start):
            continue
        med = np.median(windowed[a:b], axis=0)
        if np.linalg.norm(med - b_rest) < GYRO_DRIFT_DPS:
            sways.append(float(np.median(np.linalg.norm(windowed[a:b] - med, axis=1))))
    sway = float(np.median(sways)) if sways else 0.0
    data = max(noise, GYRO_SWAY_FACTOR * sway)
    limit = float(stated) if stated is not None else data
    why = ("--gyro-limit-dps (stated)" if stated is not None else
           f"the poses' sway ({GYRO_SWAY_FACTOR:g} x {sway:.3g} deg/s, the median over {len(sways)} poses)"
           if GYRO_SWAY_FACTOR * sway > noise else
           f"the rest's gyro noise ({GYRO_NOISE_FACTOR:g} x the std of its {w}-sample mean)")
    return limit, {"limit_dps": limit, "set_by": why, "noise_dps": noise, "sway_dps": sway, "poses": len(sways),
                   "noise_factor": GYRO_NOISE_FACTOR, "sway_factor": GYRO_SWAY_FACTOR, "from_data_dps": data,
                   "text": f"gyro limit {limit:.3g} deg/s on a pose's windowed rate less its reference, set by {why}; "
                           f"rest noise level {noise:.3g}, the poses' sway {sway:.3g} deg/s (median of {len(sways)})"}


def _not_turning(still, starts, ends, g, rest, w, limit) -> tuple[np.ndarray, list]:
    """The still rows (mask) of the accelerometers' intervals (starts, ends) where the gyro g (deg/s) does
    not turn either (module doc), and per interval its windowed rate less its reference (deg/s; None where
    no reference lies within GYRO_DRIFT_DPS of the rest's bias, with that distance)."""
    windowed = moving_mean(g, w)
    b_rest, still, dev = g[rest].mean(0), still.copy(), []
    for a, b in zip(starts, ends):
        ref = _reference(windowed, a, b, b_rest, limit)
        if ref is None:
            still[a:b] = False
            dev.append(float(np.linalg.norm(np.median(windowed[a:b], axis=0) - b_rest)))
            continue
        d = np.linalg.norm(windowed[a:b] - ref, axis=1)
        still[a:b] &= d < limit
        dev.append(d)
    return still, dev


def _spans(t, a, b) -> list:
    """[first, last] time of rows a .. b-1."""
    return [float(t[a]), float(t[b - 1])]


def two_digits(x, up) -> float:
    """x to two significant digits: up, the next such value above x (a limit that keeps what reaches x); down,
    the one at or below it (a shortest length that keeps what lasts x)."""
    if x <= 0:
        return 0.0
    e = 10.0 ** (np.floor(np.log10(x)) - 1)
    m = np.floor(x / e + 1e-6) + (1 if up else 0)
    return float(f"{m * e:.3g}")


def _dropped(acc_starts, acc_ends, starts, ends, dev, limit, min_samples, min_s, t,
             dt) -> tuple[list[DroppedInterval], list[DroppedInterval]]:
    """Each accelerometer-still interval no pose was kept from, with the rule that dropped it and its numbers,
    and each one the gyro shortened (module doc)."""
    dropped: list[DroppedInterval] = []
    trimmed: list[DroppedInterval] = []
    for k, (a, b) in enumerate(zip(acc_starts, acc_ends)):
        span, secs = _spans(t, a, b), float((b - a) * dt)
        where = f"interval {span[0]:.2f}-{span[1]:.2f} s"
        if b - a < min_samples:
            dropped.append({"t_s": span, "rule": "min_static_s", "length_s": secs,
                            "text": f"{where} dropped by --min-static-s: {secs:.2f} s still, shorter than "
                                    f"{min_s:g} s (kept from --min-static-s "
                                    f"{max(two_digits(secs, False), dt):g})"})
            continue
        if dev is None:
            continue
        d = dev[k]
        if not isinstance(d, np.ndarray):
            dropped.append({"t_s": span, "rule": "gyro_drift", "from_rest_dps": d,
                            "text": f"{where} dropped by the gyro drift rule: its gyro reads {d:.3g} deg/s from the "
                                    f"rest's bias throughout, {GYRO_DRIFT_DPS:g} or more: a turn (the accelerometers "
                                    "miss one about the vertical)"})
            continue
        kept = [(max(a, s), min(b, e)) for s, e in zip(starts, ends) if s < b and e > a]
        if kept and sum(e - s for s, e in kept) == b - a:
            continue
        over = float(np.mean(d >= limit))
        # the least limit that keeps a stretch of min_samples: the smallest maximum over such a stretch
        need = float(np.min(np.lib.stride_tricks.sliding_window_view(d, max(min_samples, 1)).max(axis=1)))
        numbers = (f"its gyro windowed rate, less its own level, reaches {d.max():.3g} deg/s (median "
                   f"{np.median(d):.3g}), above the limit {limit:.3g} on {100 * over:.0f} % of it")
        if not kept:
            within = _runs(d < limit)
            longest = float(np.max(within[1] - within[0], initial=0)) * dt
            dropped.append({"t_s": span, "rule": "gyro", "max_dps": float(d.max()), "median_dps": float(np.median(d)),
                            "limit_dps": limit, "share_above": over, "longest_within_s": longest,
                            "kept_from_limit_dps": need,
                            "text": f"{where} dropped by the gyro limit: {numbers}; its longest stretch within the "
                                    f"limit, {longest:.2f} s, is shorter than --min-static-s {min_s:g} "
                                    f"(kept from --gyro-limit-dps {two_digits(need, True):g})"})
        else:
            trimmed.append({"t_s": span, "kept_s": [_spans(t, s, e) for s, e in kept], "rule": "gyro",
                            "max_dps": float(d.max()), "limit_dps": limit, "share_above": over,
                            "text": f"{where} kept as " + ", ".join(f"{t[s]:.2f}-{t[e - 1]:.2f}" for s, e in kept)
                                    + f" s: {numbers}"})
    return dropped, trimmed


def dropped_text(dropped, sep="; ", skip_short_s=None) -> str:
    """The dropped intervals in words, joined by sep (for a refusal or the console); skip_short_s: the stretches
    dropped as shorter than --min-static-s that are shorter than this (a pause in a move) only counted."""
    shown = [x for x in dropped if skip_short_s is None or x["rule"] != "min_static_s"
             or x["length_s"] >= skip_short_s]
    left = len(dropped) - len(shown)
    return sep.join([x["text"] for x in shown] + ([f"{left} still stretch{'es' * (left != 1)} under "
                                                    f"{skip_short_s:g} s dropped (--min-static-s)"] if left else []))
