"""`simucal.calibrate`: one measurement set in, one calibration out; or a unit over temperature.

The method comes from the registry (methods.py): the one named, or by default the first that takes the set's
data (a turntable test: dong2018's exact method; a stream: the hand-placed session; a field set: ruan2019).
Every method returns the calibration file's record (io/calibration.py). Over temperature (`calibrate_thermal`):
a unit at several temperature plateaus (fit/thermal_plateaus.py), each by its method, every parameter a
polynomial in temperature; a turntable unit fitted once, every row at its own temperature
(turntable/thermal.py); a still board's warm-up by handheld/warmup.py.
"""
from __future__ import annotations

import os
from dataclasses import replace
from typing import Sequence, Union, cast

import numpy as np

from simucal import io, methods
from simucal.arguments import checked
from simucal.io.calibration import Calibration
from simucal.api.sets import as_set
from simucal.errors import CalibrationError, InputError, SimucalError
from simucal.io import calibration
from simucal.io.calibration_checks import check_layout, scale_notes
from simucal.io.details import THERMAL
from simucal.io.sensor_checks import stuck_channels
from simucal.handheld.static_detect import DetectSettings  # an annotation the door checks
from simucal.io.timestamps import with_timestamps
from simucal.options import AUTO, CalibrateOptions, Method, Timestamps, described, unused

Data = Union[str, os.PathLike[str], io.MeasurementSet]


@checked
def calibrate(data: Data | Sequence[Data], options: CalibrateOptions | None = None, *, method: Method = "auto",
              add: str | Sequence[str] = (), acc_model: str = "acc_baseline", gyro_model: str = "gyro_baseline",
              acc_noise_g: float | None = None, gyro_noise_dph: float | None = None,
              heading_accuracy_deg: float = 5.0, t_ref_c: float | None = None,
              noise: str | os.PathLike[str] | None = None, detect: DetectSettings | None = None,
              timestamps: Timestamps = "auto", thermal: bool = False,
              thermal_degree: int | None = None) -> Calibration:
    """Calibrate a unit from one measurement set (or, with ``thermal=True``, from plateaus).

    Parameters
    ----------
    data : str, os.PathLike or MeasurementSet, or a list of them
        The set; a list (plateaus, or one set whose temperature ramps), or one set with
        ``thermal=True``, is a thermal calibration (`simucal calibrate --thermal`).
    options : CalibrateOptions, optional
        The options below as one object (then none of them as a keyword).
    {options}

    An option the method does not read is refused (CalibrationError), naming the methods that read it; None
    is an option left out (its default).

    Returns
    -------
    Calibration

    Raises
    ------
    simucal.errors.CalibrationError, simucal.io.MeasurementSetError
        One line naming the set and the fix.

    Examples
    --------
    >>> import simucal
    >>> cal = simucal.calibrate("set", add=["acc.quadratic.z"])  # doctest: +SKIP
    >>> cal.acc.effects["acc.quadratic.z"].value  # doctest: +SKIP
    0.000198...
    """
    given = {k: v for k, v in locals().items() if k not in ("data", "options") and v is not None}  # None: left out
    defaults = CalibrateOptions()
    also = sorted(k for k in given if getattr(CalibrateOptions(**{k: given[k]}), k) != getattr(defaults, k))
    if options is not None and also:
        raise InputError(f"calibrate: options=CalibrateOptions(...) and {'=, '.join(also)}=: give the options as "
                         "one object or as keywords, not both")
    options = options or CalibrateOptions(**given)
    if isinstance(data, (list, tuple)):
        return calibrate_thermal([as_set(d) for d in data], options)
    one = cast(Data, data)  # not a list: one set
    if options.thermal:
        return calibrate_thermal([as_set(one)], options)
    return calibrate_set(as_set(one), options)


calibrate.__doc__ = (calibrate.__doc__ or "").replace("{options}", described().replace("\n", "\n    "))


def calibrate_set(folder: Data, options: CalibrateOptions = CalibrateOptions()) -> calibration.Calibration:
    """Calibrate a measurement set by its method (options.method, "auto": the default for the set's data).
    options.add: effect ids and model files (augmented.resolve_add), and "auto": the library effects a failing
    model needs, chosen one at a time (each sensor's block lists them under `auto`); options.noise: a noise.json
    of `simucal noise`, whose Allan curve gives each segment's noise at its length; options.timestamps: a stream's
    time stamps as recorded, evenly spaced at their mean step (nominal: the sensor's clock behind a logger's
    arrival times), or auto (io/timestamps.py). An option the method does not read is refused
    (Method.refuse_unused)."""
    ms = io.read_set(folder) if not isinstance(folder, io.MeasurementSet) else folder
    try:
        ms, stamps = with_timestamps(ms, options.timestamps)
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    if options.t_ref_c is not None and "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: --t-ref-c {options.t_ref_c:g}, but there is no temp_c "
                               "column for temperature terms to take it from: leave --t-ref-c out")
    ms = ms.copy(temperature_ref_c=options.t_ref_c)  # the caller's set keeps its own T_ref
    curves = None
    if options.noise is not None:  # the file checked before any work, its refusal naming it alone
        from simucal.fit.noise import load_curves
        curves = load_curves(options.noise)
    try:
        m = methods.choose(options.method, ms)
        m.refuse_unused(options)
        stuck_channels(ms)
        for sensor, stated, flag in (("acc", options.acc_noise_g, "--acc-noise-g"),
                                     ("gyro", options.gyro_noise_dph, "--gyro-noise-dph")):
            if stated is not None and curves and curves.get(sensor) is not None:
                raise CalibrationError(f"--noise {options.noise} gives the {sensor} noise of every segment, and "
                                       f"{flag} {stated:g} one row's: give one of them")
        if "add" in m.reads:  # models and effects: imported only by the methods that fit them
            from simucal.fit.augmented import resolve_add
            acc_model, gyro_model, ids = resolve_add(options.effect_ids, options.acc_model, options.gyro_model)
            options = replace(options, acc_model=acc_model, gyro_model=gyro_model,
                              add=ids + (AUTO,) * options.auto)
        options = replace(options, noise_curves=curves)
        from threadpoolctl import threadpool_limits
        with threadpool_limits(1, "blas"):  # the fits' QRs and pseudo-inverses (up to 522 x 357) are small: on two
            result = m.run(ms, options)     # OpenBLAS threads each ran 1.1-60x slower here (raw41, both ways measured)
        result.warnings += scale_notes(result, ms.meta)
        result.warnings += [f"{options.noise}: holds no {s} curve, so the {s} noise is the data's own (--noise "
                            f"covers the {' and '.join(curves)} only)" for s, _ in result.blocks()
                            if curves and s not in curves]
        if stamps:
            result.details["timestamps"] = stamps
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    return result


def calibrate_to_file(folder: Data, output: str | os.PathLike[str],
                      options: CalibrateOptions) -> tuple[calibration.Calibration | None, str | None]:
    """calibrate_set() one set and write its file; (result, None), or (None, the refusal's message).
    One task of a batch (`simucal calibrate DIR1 DIR2 ... --scheduler`): a refusal loses no other set."""
    try:
        result = calibrate_set(folder, options)
        calibration.save(output, result)
        return result, None
    except SimucalError as e:  # a refusal of this set; anything else is a bug, which stops the batch
        return None, str(e)


# What a still warm-up reads (handheld/warmup.py): its degree, noise and rows come from the data, its method is its own
WARMUP_READS = frozenset({"thermal", "t_ref_c", "add", "add auto", "rank", "noise_curves"})


def _still_warmup(folders: Sequence[Data], options: CalibrateOptions) -> io.MeasurementSet | None:
    """The set, where --thermal is given one stream that never moves (a board warming up, handheld/warmup.py);
    else None. Options a warm-up cannot use are refused by the one rule (options.unused)."""
    if len(folders) != 1:
        return None
    from simucal.handheld.static_detect import still_throughout
    from simucal.handheld.warmup import refuse_a_board_that_moved
    ms = folders[0] if isinstance(folders[0], io.MeasurementSet) else io.read_set(folders[0])
    if methods.data_kind(ms) != methods.STREAM or not ms.has_acc or len(ms.samples["t_s"]) < 20:
        return None
    if not still_throughout(ms.acc_g(), ms.samples["t_s"]):
        refuse_a_board_that_moved(ms)
        return None
    left = unused(options, WARMUP_READS, own=())
    if left:
        raise CalibrationError(f"{left[0][1]}: a still warm-up's bias takes its degree from the data (0 to 3), its "
                               "noise from the data, its rows as they are (no poses to find, no moves to time) and no "
                               "other method; leave it out")
    return ms


def calibrate_thermal(folders: Sequence[Data],
                      options: CalibrateOptions = CalibrateOptions()) -> calibration.Calibration:
    """One unit at two or more temperature plateaus (one set each), or one set whose temperature
    ramps. A turntable unit (method exact) is fitted once, every row at its own temp_c, with every
    parameter of the model a polynomial in (T - T_ref) inside the model, each parameter's degree
    chosen by the model test and by the groups (plateaus, bands of a ramp) left out
    (fit/thermal_select.py); each plateau is also calibrated alone as evidence. Other methods fit
    each plateau alone and then each parameter's polynomial over the plateaus (fit/thermal.py).
    T_ref: options.t_ref_c, else the mean of the plateaus' temperatures. The file holds the unit at T_ref
    and, per sensor, `thermal` (the polynomials) that apply evaluates at each row's temp_c."""
    from simucal.fit.thermal_plateaus import refuse_thermal_options
    if not folders:
        raise CalibrationError("--thermal needs a set whose temperature ramps, or two or more plateaus")
    refuse_thermal_options(folders, options.thermal_degree, options.add)
    from threadpoolctl import threadpool_limits
    # one BLAS thread: the QRs and solves here are small, and OpenBLAS's threads spinning against each other
    # (or against another process) made one run 0.66-7.7 s
    with threadpool_limits(1, "blas"):
        return _calibrate_thermal(folders, options)


def _calibrate_thermal(folders: Sequence[Data], options: CalibrateOptions) -> calibration.Calibration:
    from simucal.fit.thermal_plateaus import plateau, plateaus_block, reference_temperature, refuse_repeated
    warmup = _still_warmup(folders, options)
    if warmup is not None:
        from simucal.handheld.warmup import calibrate_warmup
        return calibrate_warmup(warmup, options.t_ref_c, options.add)
    sets = [plateau(f) for f in folders]
    refuse_repeated([ms for ms, _ in sets])
    t_ref = reference_temperature(sets, options.t_ref_c)
    T_k = [t for _, t in sets]
    near = int(np.argmin(np.abs(np.asarray(T_k) - t_ref)))
    # the plateau nearest T_ref by its method: the gyro frame (C_b^d), the checks, the model's shape
    cal = calibrate_set(sets[near][0], replace(options, t_ref_c=T_k[near], rank=False))
    for ms, _ in sets:
        check_layout(cal, ms, f"the plateau nearest T_ref ({sets[near][0].path})")
    plateaus = [str(ms.path) for ms, _ in sets]
    T_all = np.concatenate([ms.samples["temp_c"] for ms, _ in sets])
    result = calibration.Calibration(f"{THERMAL}{cal.method}, every row at its own temperature)", plateaus,
                                     [ms.sha256 for ms, _ in sets], cal.layout, t_ref_c=t_ref,
                                     temperature_range_c=[float(T_all.min()), float(T_all.max())],
                                     unification=cal.unification, not_calibrated=cal.not_calibrated,
                                     details=cal.details.copy(),  # that plateau's checks (consistency, ...)
                                     samples_sha256=[d for ms, _ in sets for d in ms.sample_digests()])
    if cal.method == "exact":
        from simucal.turntable.thermal import joint_blocks
        joint_blocks(result, sets, cal, options.thermal_degree, t_ref, options.noise, options.acc_noise_g,
                     options.gyro_noise_dph)
    else:
        if len(sets) < 2:
            raise CalibrationError(f"--thermal on one set needs a turntable set (method exact, whose rows are fitted "
                                   f"at their own temperature); method {cal.method} fits each plateau alone: give "
                                   "two or more plateaus")
        cals = [cal if k == near else calibrate_set(ms, replace(options, t_ref_c=t)) for k, (ms, t) in enumerate(sets)]
        for s in cal.sensors:
            setattr(result, s, plateaus_block([getattr(c, s) for c in cals], T_k, t_ref, options.thermal_degree, s,
                                              plateaus))
        result.warnings += [w for c in cals for w in c.warnings]
        return result
    result.warnings += cal.warnings
    return result
