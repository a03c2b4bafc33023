"""Static intervals in a continuous stream (Tedaldi et al. 2014, as in imu_tk).

The norm of the per-axis accelerometer variance over a centred window is
compared with `factor` times the same norm over the initial rest; runs below
it, at least `min_s` long, are static poses. Where the gyro is given, a pose must
also not turn: the gyro's mean over the window, less the still interval's own
reference, within GYRO_STILL_DPS or 20 times its noise over the window, whichever is
larger. The reference is the interval's median or its windowed mean nearest the rest's
bias, whichever more of the interval stays near (a bias that drifts between poses is
no turn; a turn filling most of an interval is not taken for its bias: no reference
lies GYRO_DRIFT_DPS from the rest's). A turn
about the vertical leaves the accelerometers still (a clean simulated session took a
42 deg/s turn for a pose, and its moves then failed their test), and any turn during a
pose is lost to the moves, which are integrated between poses: a slow move's ends too (a 3.9 deg
move peaking at 2.4 deg/s gave its poses 0.35 deg of it each at 1 deg/s, and its moves failed at
chi2 186 on 51 dof, 1 clean session in 1000; at 0.3 deg/s, 0.03 deg and chi2 46). The initial rest is found from
the data: it lasts while the moving variance stays within `rest_factor` of
the white-noise level that first differences give over the first window. Everything is reported so a user can
check and override it.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.noise import moving_sample_var, quantization_step, white_noise_var


@dataclass(frozen=True)
class DetectSettings:
    """The static detector's settings (the --init-rest-s, --threshold-factor, --window-s and
    --min-static-s options): window of the moving variance (s), threshold as a multiple of the
    rest's variance, shortest static interval (s), the initial rest's length (None: found)."""
    window_s: float = 1.0
    factor: float = 6.0
    min_s: float = 1.0
    init_rest_s: float | None = None


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


GYRO_STILL_DPS = 0.3  # a pose's windowed mean rate less its reference may reach this (a hand's settling)
GYRO_DRIFT_DPS = 10.0  # no gyro's bias drifts this far from the rest's in a session: an interval turning throughout


def detect_static(acc, t, settings: DetectSettings = DetectSettings(), rest_factor=20.0, gyro_dps=None) -> Detection:
    """The static intervals (module doc) of accelerometer rows acc (n, 3) at times t; gyro_dps (n, 3) the gyro
    in deg/s where the stream has one."""
    if len(t) < 20:
        raise CalibrationError(f"the stream has {len(t)} row{'s' * (len(t) != 1)}: a hand-placed session is one "
                               "continuous recording, an initial rest and then poses joined by moves")
    window_s, factor, min_s, init_rest_s = settings.window_s, settings.factor, settings.min_s, settings.init_rest_s
    dt, length = float(np.median(np.diff(t))), float(t[-1] - t[0])
    if dt >= 0.5:
        raise CalibrationError(f"t_s steps by {dt:g} s (median): {1 / dt:.2g} Hz is too slow to follow a move between "
                               "poses; if t_s is in milliseconds, write it in seconds (the spec's unit)")
    for name, value, part in (("--window-s", window_s, 4), ("--min-static-s", min_s, 4), ("--init-rest-s", init_rest_s, 2)):
        if value is not None and value > length / part:
            raise CalibrationError(f"{name} {value:g}: longer than 1/{part} of the stream ({length:.1f} s), which "
                                   "leaves no room for the poses and moves; give seconds")
    w = max(int(round(window_s / dt)) | 1, 3)
    mv = np.linalg.norm(moving_variance(acc, w), axis=1)
    init_end = int(np.searchsorted(t, t[0] + init_rest_s)) if init_rest_s is not None else first_motion(mv, acc, w,
                                                                                                       rest_factor)
    if init_end >= len(mv) and init_rest_s is None:
        raise CalibrationError(f"no motion: the accelerometers stay still through the whole stream "
                               f"({t[-1] - t[0]:.1f} s); a calibration needs the unit turned into many poses. Still data "
                               "give the bias over temperature where temp_c rises (simucal calibrate SET --thermal: a "
                               "warm-up, as PX4's and ArduPilot's thermal calibrations take it) and the noise terms "
                               "(simucal noise SET)")
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
    gyro_threshold = None
    edges = np.diff(np.r_[0, still.astype(int), 0])
    starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    if gyro_dps is not None:
        still, gyro_threshold = _not_turning(still, starts, ends, np.asarray(gyro_dps, float), rest, w)
        edges = np.diff(np.r_[0, still.astype(int), 0])
        starts, ends = np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]
    min_samples = int(round(min_s / dt))
    keep = (ends - starts) >= min_samples
    if not keep.any():
        raise CalibrationError(f"no static interval of at least {min_s:g} s found (threshold {threshold:.3g}, "
                               f"{factor:g} x the initial rest's variance); lower --min-static-s or raise "
                               "--threshold-factor")
    source = ("the initial rest" if rest.start == 0 else
              f"the quietest 3 s ({t[rest.start]:.1f}-{t[rest.stop - 1]:.1f} s; the stream has no initial rest)")
    return Detection(starts[keep].tolist(), ends[keep].tolist(), threshold, w, min_samples, init_end, factor, source,
                     gyro_threshold)


def _not_turning(still, starts, ends, g, rest, w) -> tuple[np.ndarray, float]:
    """The still rows (mask) of the accelerometers' intervals (starts, ends) where the gyro g (deg/s) does
    not turn either (module doc), and the threshold on its windowed mean (deg/s)."""
    threshold = max(GYRO_STILL_DPS, 20 * float(np.sqrt(np.sum(moving_sample_var(g[rest], g)))) / np.sqrt(w))
    windowed = moving_mean(g, w)
    b_rest, still = g[rest].mean(0), still.copy()
    for a, b in zip(starts, ends):
        # the interval's own reference: its median, or its windowed mean nearest the rest's bias, whichever
        # more of it stays within the threshold of, and none that far from the rest's
        refs = [r for r in (np.median(windowed[a:b], axis=0),
                            windowed[a + int(np.argmin(np.linalg.norm(windowed[a:b] - b_rest, axis=1)))])
                if np.linalg.norm(r - b_rest) < GYRO_DRIFT_DPS]
        within = [np.linalg.norm(windowed[a:b] - r, axis=1) < threshold for r in refs]
        still[a:b] &= max(within, key=np.sum) if within else False
    return still, threshold
