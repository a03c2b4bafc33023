"""A turntable set's segments as observations of the norm fit: each segment's mean and the std of
that mean (from its rows' scatter, the stated noise or the Allan curve of `calibrate --noise`),
its input's norm and auxiliary inputs, with the checks of the rows behind them (clipped
samples, glitches, a dead accelerometer axis, gyro rates in the wrong unit)."""
from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from numpy.typing import NDArray

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit import aux_inputs
from simucal.fit.augmented import AugmentedModel
from simucal.fit.aux_inputs import AuxInputs, column_means
from simucal.fit.noise import axis_rows, mean_and_sigma, white_noise_var
from simucal.fit.norm_fit import Observations
from simucal.generated import table
from simucal.io import calibration, records, run_or_rows, units
from simucal.io.sensor_checks import saturated_rows


def outer_angle_rad(ms, rows, segment):
    """A rate run's outer angle at each row (rad, from its first row's), from t_s and outer_rate_dps;
    None for a static segment."""
    if segment.kind != "rate" or not segment.outer_rate_dps:
        return None
    t = ms.samples["t_s"][run_or_rows(rows)]
    return np.radians(segment.outer_rate_dps * (t - t[0]))


def segment_duration_s(ms, rows, where) -> float:
    """The seconds a segment's mean covers: its rows' span and one step; an averaged row's meta
    average_s (the spec's optional key), which the Allan curve needs."""
    t = ms.samples["t_s"][rows]
    if len(t) >= 2:
        return float(t[-1] - t[0] + np.median(np.diff(t)))
    if "average_s" not in ms.meta:
        raise CalibrationError(f"{ms.path / 'meta.json'}: --noise takes each row's noise from the Allan curve at the "
                               f"seconds it averages, but segment {where} is one averaged row and meta.json states no "
                               "average_s: add \"average_s\": SECONDS (or leave --noise out)")
    return float(ms.meta["average_s"])


def segment_observations(ms: io.MeasurementSet, sensor: str, kinds=None, stated=None, curve=None):
    """(Observations, segments) for 'acc' (by default the static segments; with kinds
    {"static", "rate"} the rate runs too, whose centripetal scale w2 lets lever arms show)
    or 'gyro' (rate segments). stated: the noise of one row (g or deg/h) where the data
    cannot give it; default meta's acc_noise_g / gyro_noise_dph. curve: the std of a mean
    over tau seconds (fit/noise.load_curves, `calibrate --noise`), which then gives every
    segment's noise at its length: with bias instability a long mean is noisier than its
    rows' scatter over sqrt(n) says. The segments one after the other: on two threads a segment's
    many short numpy calls wait on each other for the GIL (the 400 Hz set's 9,140-row segments took
    0.24 s of wall and 0.2 s more CPU than in one thread, 20 Hz plateaus twice the time)."""
    if ms.segments is None:
        raise CalibrationError(f"{ms.path}: no segments.csv: this is a continuous stream (use calibrate, "
                               "which detects its static poses)")
    kinds = kinds or ({"static"} if sensor == "acc" else {"rate"})
    segs = [s for s in ms.segments if s.kind in kinds]
    if stated is None:
        stated = units.stated_noise(ms.meta, sensor)
    lat = np.radians(ms.meta.get("latitude_deg", 0.0))
    w_e = units.earth_rate_dph(ms.meta)
    N, sig, rho, keep, longest = [], [], [], [], 0.0
    raw = ms.raw(sensor)
    clipped = saturated_segments(ms, sensor)
    averaged = functools.partial(_averaged, ms, sensor, raw, stated, clipped)
    for s, done in zip(segs, map(averaged, segs)):
        if done is None:
            continue
        rows, (m, sd) = done
        if curve is not None:
            tau = segment_duration_s(ms, rows, s.segment)
            sd, longest = curve(tau), max(longest, tau)
        N.append(m)
        sig.append(sd)
        rho.append(1.0 if sensor == "acc" else abs(s.outer_rate_dps * units.DPH_PER_DPS + w_e * np.sin(lat)))  # |input|
        keep.append(s)
    if curve is not None:
        still = [ms.rows(s.segment) for s in ms.segments if s.kind == "static"]  # as simucal noise pools them
        check_curve_scale(ms, sensor, still if any(len(r) >= 3 for r in still) else
                          [ms.rows(s.segment) for s in keep], curve)
    dropped = [s.segment for s in segs if s.segment in clipped]
    need = len(AugmentedModel(f"{sensor}_baseline").params)
    if dropped and len(keep) < need and (keep or sensor == "acc"):  # no gyro at all: not calibrated, said so
        raise CalibrationError(
            f"{ms.path / 'samples.csv'}: {len(dropped)} of {len(segs)} {sensor} segments hold clipped samples (at or "
            f"beyond full_scale, or repeating the rail: segments {dropped[:8]}{' ...' if len(dropped) > 8 else ''}) "
            f"and are left out, leaving {len(keep)}, too few for the {need} parameters of {sensor}_baseline; record "
            "them within the sensor's range, or correct full_scale in meta.json if the rails are wrong")
    aux = column_means(ms.samples, [ms.rows(s.segment) for s in keep], t_ref_c=ms.t_ref_c)
    aux.update(specific_force(ms, keep) if sensor == "gyro" else {"w2": centripetal_scale(ms, keep)})
    obs = Observations(np.array(N).reshape(-1, 3), np.array(rho), np.array(sig).reshape(-1, 3), AuxInputs(aux),
                       [s.segment for s in keep])
    obs.sigma_stated = curve is not None or (stated is not None and any(len(ms.rows(s.segment)) < 3 for s in keep))
    if curve is not None:
        obs.noise_file = curve.source  # _exact_sensor refuses it where the residuals show it far too large
        obs.sigma_source = "the Allan curve of --noise at each segment's length" + (
            f" (it was measured to {curve.tau_max_s:.3g} s; the segments average up to {longest:.3g} s, so beyond "
            "it their noise is its white part: record a still stretch 9 times a segment's length to measure "
            "it)" if longest > curve.tau_max_s else "")
    if sensor == "acc":
        check_axes_follow_gravity(ms, obs, keep)
    if keep:
        try:
            units.check_magnitude(sensor, np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
        except CalibrationError as e:
            raise CalibrationError(f"{e}{_rates_not_units(ms) if sensor == 'gyro' else ''}") from None
    return obs, keep


def _averaged(ms, sensor, raw, stated, clipped, s):
    """(rows, (mean, its std)) of segment s, its rows checked first; None where it holds clipped
    samples (left out). Its rows in g or deg/h alone, not the whole set's (ms.in_units)."""
    rows = ms.rows(s.segment)
    if not rows.size:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: segment {s.segment} has no samples")
    if s.segment in clipped:  # before the glitch test: a clipped sample is no glitch
        return None
    refuse_outliers(ms, raw, rows, sensor, s.segment)
    return rows, mean_and_sigma(ms.in_units(sensor, run_or_rows(rows)), stated,
                                varying=(s.kind == "rate"), angle_rad=outer_angle_rad(ms, rows, s))  # the inputs turn


CURVE_FACTOR = 10.0  # a noise file's row noise this many times the data's own (or a tenth): another unit or unit


def check_curve_scale(ms, sensor, rows, curve):
    """Refuse a noise file (`calibrate --noise`) whose noise of one row is not the data's own: per axis
    the Allan curve at a row's length against the rows' own white noise (first differences, the median
    over the segments of 3 rows or more: the static ones where there are, as simucal noise pools), and for one-row
    segments against meta.json's stated noise where it is given. A file CURVE_FACTOR times too large makes every model
    pass (a silent wrong answer); one too small fails every model, blaming it."""
    noises, tau = [], []
    for r in (r for r in rows if len(r) >= 3):
        noises.append(np.sqrt(white_noise_var(ms.in_units(sensor, r))))
        tau.append(float(np.median(np.diff(ms.samples["t_s"][r]))))
    stated = units.stated_noise(ms.meta, sensor)
    if noises:
        own, at = np.median(noises, axis=0), float(np.median(tau))
        what = f"the rows' own noise (first differences of {len(tau)} segments' rows, {at:.3g} s each)"
    elif stated is not None and "average_s" in ms.meta:
        own, at = np.full(3, float(stated)), float(ms.meta["average_s"])
        what = f"meta.json's stated noise of one row ({at:.3g} s averaged)"
    else:
        return  # one averaged row per segment and no stated noise: nothing of the data's own to compare with
    if not (np.isfinite(at) and at > 0):
        return
    file = np.atleast_1d(curve(at))
    unit = units.NOISE_UNIT[sensor][0]
    for k in range(3):
        if own[k] > 0 and not 1 / CURVE_FACTOR <= file[k] / own[k] <= CURVE_FACTOR:
            if not tau:  # the stated noise of averaged rows: their average_s may be the slip
                refuse_average_s(ms, sensor, curve, own, at)
            raise CalibrationError(
                f"{curve.source}: its {sensor} {'xyz'[k]} noise over {at:.3g} s is {file[k]:.3g} {unit}, "
                f"{file[k] / own[k]:.3g} times {what}, {own[k]:.3g} {unit}: the report is of another unit, "
                f"another output unit or another rate; measure this unit's still recording with simucal noise "
                "(or leave --noise out)")


def refuse_average_s(ms, sensor, curve, stated, average_s):
    """Refuse meta.json's average_s where the noise file's curve gives the stated noise of one row at other
    averages only (the range where every axis is within CURVE_FACTOR of it, computed on a grid 0.05 decade
    apart): the averaging is the likelier slip than the report (the report is blamed where no average would do)."""
    taus = average_s * np.logspace(-12, 12, 481)
    ratio = np.atleast_2d(curve(taus)).reshape(len(taus), -1) / np.asarray(stated, float)
    fits = taus[np.all((ratio >= 1 / CURVE_FACTOR) & (ratio <= CURVE_FACTOR), axis=1)]
    if len(fits) and not fits[0] <= average_s <= fits[-1]:
        raise CalibrationError(
            f"{ms.path / 'meta.json'}: average_s is {average_s:.4g} s, but {curve.source}'s Allan curve gives the "
            f"stated {sensor} noise of one row ({units.NOISE_KEY[sensor]} {stated[0]:.3g}) at averages of "
            f"{fits[0]:.3g} to {fits[-1]:.3g} s only: average_s must lie in that range (the seconds each averaged "
            f"row averages); correct average_s, or the stated noise, or leave --noise out")


def check_axes_follow_gravity(ms, obs, segs, live_g=0.5, dead_ratio=0.05, spread=0.2):
    """Refuse an accelerometer axis whose static means do not follow gravity while the others
    do (they span live_g or more): a dead channel, or a column holding another signal. Only
    where the commanded angles turn gravity out of every plane (its directions in the table
    frame spread by `spread` or more across their flattest direction), so that every axis of the
    unit, however mounted, must see it change."""
    rows = [i for i, s in enumerate(segs) if s.kind == "static" and s.middle_deg is not None
            and s.inner_deg is not None]
    if len(rows) < 4:
        return
    up_k, _ = commanded_up_k([segs[i] for i in rows])
    if np.sqrt(max(np.linalg.eigvalsh(np.cov(up_k.T))[0], 0.0)) < spread:
        return
    span = np.ptp(obs.N[rows], axis=0)
    for j in range(3):
        others = np.delete(span, j)
        if others.min() > live_g and span[j] < dead_ratio * others.min():
            raise CalibrationError(
                f"{ms.path / 'samples.csv'}: column a{'xyz'[j]} does not follow gravity: its static means span "
                f"{span[j]:.2g} g over the {len(rows)} positions, where the other axes' span {others.min():.2g} g "
                "or more: a dead or unconnected channel, or the column holds another signal; check the wiring and "
                "the column order")


def _rates_not_units(ms) -> str:
    """Where the static segments read the Earth rate in gyro_unit (a gyro that resolves it), the
    unit is right and the commanded rates are what is off: say so."""
    if "Ferraris" in ms.meta.get("description", ""):
        return ("; this set was imported from a Ferraris session, whose commanded rate is the turn angle over the "
                "turn's duration: check the import's --rate-hz (the sample rate) and --turn-deg")
    static = np.isin(ms.samples["segment"], [s.segment for s in ms.segments if s.kind == "static"])
    if not static.any():
        return ""
    w = float(np.median(np.linalg.norm(ms.gyro_dph()[static], axis=1)))
    w_e = units.earth_rate_dph(ms.meta)
    if not 0.5 * w_e < w < 2 * w_e:
        return ""
    return (f"; but the static segments read the Earth rate ({w:.3g} deg/h against {w_e:.4g}) in that unit, so it "
            "is outer_rate_dps in segments.csv that is off: it is deg/s (not rad/s, not deg/h)")


def saturated_segments(ms, sensor) -> dict[int, int]:
    """{segment: number of its samples clipped} of one sensor (io/sensor_checks.saturated_rows)."""
    bad = saturated_rows(ms, sensor)[0]
    seg, n = np.unique(ms.samples["segment"][bad], return_counts=True)
    return dict(zip(seg.tolist(), n.tolist()))


def refuse_outliers(ms, raw, rows, sensor, segment, k=100.0):
    """Refuse a gross glitch: an isolated sample k robust spreads (1.4826 MAD, floored at 1e-9 of
    the median) from its segment's median, whose neighbours are normal, would carry the segment's
    mean with it. A smooth excursion (a table settling) spans its neighbours and is not a glitch."""
    if len(rows) < 10:
        return
    x = np.ascontiguousarray(raw[run_or_rows(rows)].T)  # (3, n): a median along contiguous rows is twice as fast
    med = median_rows(x)
    dev = np.abs(x - med[:, None])
    spread = np.maximum(1.4826 * median_rows(dev), 1e-9 * np.maximum(np.abs(med), 1.0))
    dev /= spread[:, None]
    bad = dev > k
    if not bad.any():
        return  # no sample that far out: the usual segment, its neighbours not looked at
    calm = dev < k / 10
    bad[:, 1:] &= calm[:, :-1]  # its neighbours are normal
    bad[:, :-1] &= calm[:, 1:]
    if bad.any():
        i = int(bad.any(axis=0).argmax())
        j = int(bad[:, i].argmax())
        line = 2 + int(rows[i])
        col = ("ax", "ay", "az", "gx", "gy", "gz")[j + (0 if sensor == "acc" else 3)]
        raise CalibrationError(f"{ms.path / 'samples.csv'}, line {line}: {col} = {x[j, i]:g} is a glitch in segment "
                               f"{segment} (its median {med[j]:g}, spread {spread[j]:.3g}): remove or repair that row")


def median_rows(x, overwrite=False) -> np.ndarray:
    """np.median(x, axis=1) of finite x (k, n), the same numbers by one partition: numpy's median of
    an even count partitions at the two middle places at once, 6x slower (205 against 36 us at
    3 x 9,040); the lower middle value is the largest of the lower half. overwrite: x partitioned in
    place (no copy)."""
    h = x.shape[1] // 2
    part = x if overwrite else np.partition(x, h, axis=1)
    if overwrite:
        part.partition(h, axis=1)
    return part[:, h] if x.shape[1] % 2 else (part[:, :h].max(axis=1) + part[:, h]) / 2


def centripetal_scale(ms, segs):
    """w2 = w_T^2 / g (1/m) of each segment: 0 at rest, the outer-axis rate's under rotation."""
    return np.array([np.radians(s.outer_rate_dps) ** 2 / units.gravity(ms.meta) for s in segs])


def specific_force(ms, segs) -> dict[str, NDArray[np.float64]]:
    """The specific force (g) each segment's gyro saw, for g-sensitivity terms (f_x, f_y, f_z):
    the accelerometer mean where there is one, else the commanded vertical, else none."""
    if not segs:
        return {}
    if ms.has_acc:
        return aux_inputs.specific_force([axis_rows(ms.in_units("acc", run_or_rows(r))).sum(1) / len(r)
                                          for r in map(ms.rows, (s.segment for s in segs))])
    if all(s.middle_deg is not None and s.inner_deg is not None for s in segs):
        return aux_inputs.specific_force(commanded_up_k(segs)[0])
    return {}


def table_accuracy_rad(ms):
    """meta.json's table_accuracy_arcsec (the std of each commanded angle's position error) in rad,
    or None where not stated (the unification then estimates it from the static pairs)."""
    v = ms.meta.get("table_accuracy_arcsec")  # checked when the set is read (units.check_meta)
    return None if v is None else float(v * units.ARCSEC_RAD)


def commanded_up_k(segs):
    """Unit vertical (outer axis) in k at each segment's commanded middle/inner angles."""
    if any(s.middle_deg is None or s.inner_deg is None for s in segs):
        raise CalibrationError("this method needs commanded middle and inner angles in segments.csv")
    C = table.C_k_n(0.0, np.radians([s.middle_deg for s in segs]), np.radians([s.inner_deg for s in segs]),
                    np.zeros(7))
    return C[:, 2, :], C


def read_observations(ms, method, rows, acc_noise_g=None, gyro_noise_dph=None, noise_curves=None):
    """A turntable method's start: the calibration's header (io/calibration.py) naming the segments
    left out for clipped samples, and (acc_obs, acc_segs, gyro_obs, gyro_segs) of the segment
    kinds rows[sensor] (None for a sensor the set lacks, or a gyro without usable rate runs);
    the gyro's rate runs checked to turn the commanded way."""
    curves = noise_curves or {}
    stated = {"acc": acc_noise_g, "gyro": gyro_noise_dph}
    sensors = [s for s, present in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if present]
    if ms.segments:
        ms.rows(ms.segments[0].segment)  # formed before the digests' thread shares them
    with ThreadPoolExecutor(1) as pool:  # hashlib frees the GIL for its whole pass
        pool.submit(ms.sample_digests)  # the calibration's header asks below
        found = {s: segment_observations(ms, s, rows[s], stated[s], curves.get(s)) for s in sensors}
    acc_obs, acc_segs = found.get("acc", (None, None))
    gyro_obs, gyro_segs = found.get("gyro", (None, None))
    if not gyro_segs:
        gyro_obs = None
    check_rate_sense(ms, gyro_obs, gyro_segs)
    cal = calibration.header(method, ms)
    kind = {s.segment: s.kind for s in ms.segments}
    excluded = [records.ExcludedSegment(sensor=sensor, segment=k, samples=n, reason="saturated samples")
                for sensor, present in (("acc", ms.has_acc), ("gyro", ms.has_gyro)) if present
                for k, n in saturated_segments(ms, sensor).items() if kind.get(k) in rows[sensor]]
    if excluded:
        cal.details["excluded_segments"] = excluded
    return cal, (acc_obs, acc_segs, gyro_obs, gyro_segs)


def check_rate_sense(ms, gyro_obs, gyro_segs):
    """Refuse rate runs whose gyro output turns opposite to the commanded rate.

    The mean output along the commanded axis, less the static outputs' mean,
    must have the sign of outer_rate_dps; a reversed turn (or a gyro of the
    opposite sign convention) would otherwise be fitted into a matrix near -I.
    """
    if gyro_obs is None or not gyro_segs:
        return
    keep = [i for i, s in enumerate(gyro_segs) if s.middle_deg is not None and s.inner_deg is not None]
    if not keep:
        return  # no commanded axis to compare with
    gyro_segs = [gyro_segs[i] for i in keep]
    gyro_obs = Observations(gyro_obs.N[keep], gyro_obs.rho[keep])
    up, _ = commanded_up_k(gyro_segs)
    static = np.concatenate([ms.rows(s.segment) for s in ms.segments if s.kind == "static"] + [np.zeros(0, int)])
    raw = ms.raw("gyro")  # the static rows' median a column at a time, partitioned where gathered: no (n, 3) copies,
    rest = units.gyro_to_dph(np.array([median_rows(raw[static, j][None], overwrite=True)[0] for j in range(3)]),
                             ms.meta) if static.size else np.zeros(3)  # in raw units (a unit's scale keeps the order)
    rate = np.array([s.outer_rate_dps for s in gyro_segs])
    along = np.einsum("ni,ni->n", gyro_obs.N - rest, up) / units.DPH_PER_DPS
    wrong = np.sign(along) != np.sign(rate)
    if not wrong.any():
        return
    for k in range(3):  # some runs reversed, some not: one axis of the triad reversed?
        D = np.diag([-1.0 if j == k else 1.0 for j in range(3)])
        if wrong.sum() < len(rate) and np.all(np.sign(np.einsum("ni,ni->n", (gyro_obs.N - rest) @ D, up))
                                              == np.sign(rate)):
            raise CalibrationError(
                f"{ms.path}: the gyro {'xyz'[k]} output has the wrong sign: {int(wrong.sum())} of {len(rate)} "
                f"rate runs turn opposite to the commanded rate, and all agree once gyro {'xyz'[k]} is reversed "
                "(a left-handed triad, the axis wired or declared with its sign reversed); "
                f"fix the sign of g{'xyz'[k]} in samples.csv (or the wiring) and calibrate again")
    detail = ", ".join([f"segment {s.segment}: commanded {r:+.1f} deg/s, measured {a:+.1f} deg/s"
                        for s, r, a, w in zip(gyro_segs, rate, along, wrong) if w][:4])
    raise CalibrationError(
        f"the gyro turns opposite to the commanded rate in {int(wrong.sum())} of {len(rate)} rate segments "
        f"({detail}{', ...' if wrong.sum() > 4 else ''}): the rotation was made the other way (or the gyro's sign "
        "convention or axes differ); not fitted, since it would give a gyro matrix near -I. Check the protocol's "
        "rotation sense (for imucal's Ferraris: import with --turn-deg 360 if the turns were counter-clockwise)")
