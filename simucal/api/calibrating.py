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
from typing import Any, Mapping, Sequence, Union, cast

import numpy as np

from simucal import io, methods
from simucal.api.arguments import checked
from simucal.api.calibration import Calibration
from simucal.api.options import CalibrateOptions
from simucal.api.sets import as_set, keywords
from simucal.errors import CalibrationError, SimucalError
from simucal.io import calibration
from simucal.io.calibration_checks import check_layout, scale_notes
from simucal.io.sensor_checks import stuck_channels
from simucal.io.stream_records import Timestamps
from simucal.io.timestamps import with_timestamps

Data = Union[str, os.PathLike[str], io.MeasurementSet]
TYPE_CHECKING = False
if TYPE_CHECKING:  # api/options.py says why
    from typing_extensions import Unpack

    from simucal.handheld.static_detect import DetectSettings


@checked
def calibrate(data: Data | Sequence[Data], **options: Unpack[CalibrateOptions]) -> Calibration:
    """Calibrate a unit from one measurement set (or, with ``thermal=True``, from plateaus).

    Parameters
    ----------
    data : str, os.PathLike or MeasurementSet, or a list of them
        The set; a list (plateaus, or one set whose temperature ramps), or one set with
        ``thermal=True``, is a thermal calibration (`simucal calibrate --thermal`).
    method : str
        The method (simucal.api.options.Method, the registry's: auto, exact, linear, multiposition, ferraris,
        handheld, field or systematic; default "auto", the one the data's kind takes).
    add : str or list of str
        Effect ids, model files, or "auto" (a forward selection): one as a string.
    acc_model, gyro_model : str
        A built-in model's name (default the baselines) or a model file.
    acc_noise_g, gyro_noise_dph : float, optional
        The noise of one row (g, deg/h) where the data cannot give it.
    heading_accuracy_deg : float, optional
        A field set's north reference accuracy (deg).
    t_ref_c : float, optional
        T_ref of the temperature terms (degC; default the data's middle).
    noise : str or os.PathLike, optional
        A noise.json of `simucal noise`, the noise of one row at any averaging.
    detect : DetectSettings, optional
        A stream's static detection (its window, threshold factor, gyro limit).
    timestamps : {"auto", "recorded", "nominal"}
        A stream's clock: the recorded time stamps, or the even clock of their median step.
    thermal : bool
        One set whose temperature ramps calibrated over temperature (a list of sets always is).
    thermal_degree : int, optional
        The thermal polynomials' degree, 0-3 (`--thermal-degree`; default chosen by the data).

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
    if isinstance(data, (list, tuple)):
        return calibrate_over_temperature(list(data), **options)
    one = cast(Data, data)  # not a list: one set
    if options.get("thermal"):
        return calibrate_over_temperature([one], **options)
    return Calibration.of(calibrate_set(as_set(one), **keywords(options)))


def calibrate_over_temperature(sets: Sequence[Data], **options: Unpack[CalibrateOptions]) -> Calibration:
    """One unit's thermal calibration (`calibrate(data, thermal=True)`: calibrate_thermal)."""
    return Calibration.of(calibrate_thermal([as_set(d) for d in sets], **keywords(options)))


def calibrate_set(folder: Data, method: str = "auto", acc_model: str = "acc_baseline",
                  gyro_model: str = "gyro_baseline",
                  detect: DetectSettings | None = None, add: Sequence[str] = (), acc_noise_g: float | None = None,
                  gyro_noise_dph: float | None = None, heading_accuracy_deg: float | None = None,
                  t_ref_c: float | None = None, noise: str | os.PathLike[str] | None = None, rank: bool = True,
                  timestamps: str = "auto") -> calibration.Calibration:
    """Calibrate a measurement set. method: a name of methods.METHODS, or "auto" (the default for
    the set's data). add: effect ids and model files (augmented.resolve_add), and "auto": the
    library effects a failing model needs, chosen one at a time (each sensor's block lists them
    under `auto`); acc_noise_g / gyro_noise_dph: the noise of one row where the data cannot give
    it; detect: a stream's static detection settings; heading_accuracy_deg: a field set's north
    reference (None: methods.DEFAULTS' 5 deg); t_ref_c: T_ref of temperature terms (default the mean of temp_c); noise:
    a noise.json of `simucal noise`, whose Allan curve gives each segment's noise at its length; rank: a failing model's
    candidates ranked (turntable; a thermal calibration's plateau needs none); timestamps: a
    stream's time stamps as recorded, evenly spaced at their mean step (nominal: the sensor's clock
    behind a logger's arrival times), or auto (io/timestamps.py). Options a method does not take are
    refused when set."""
    ms = io.read_set(folder) if not isinstance(folder, io.MeasurementSet) else folder
    try:
        ms, stamps = with_timestamps(ms, timestamps)
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    if t_ref_c is not None and "temp_c" not in ms.samples:
        raise CalibrationError(f"{ms.path / 'samples.csv'}: --t-ref-c {t_ref_c:g}, but there is no temp_c column for "
                               "temperature terms to take it from: leave --t-ref-c out")
    ms = ms.copy(temperature_ref_c=t_ref_c)  # the caller's set keeps its own T_ref
    curves = None
    if noise is not None:  # the file checked before any work, its refusal naming it alone
        from simucal.fit.noise import load_curves
        curves = load_curves(noise)
    try:
        m = methods.choose(method, ms)
        stuck_channels(ms)
        ids = tuple(a for a in add if a != "auto")
        if "ids" in m.options:  # models and effects: imported only by the methods that fit them
            from simucal.fit.augmented import resolve_add
            acc_model, gyro_model, ids = resolve_add(ids, acc_model, gyro_model)
        for sensor, stated, flag in (("acc", acc_noise_g, "--acc-noise-g"),
                                     ("gyro", gyro_noise_dph, "--gyro-noise-dph")):
            if stated is not None and curves and curves.get(sensor) is not None:
                raise CalibrationError(f"--noise {noise} gives the {sensor} noise of every segment, and {flag} "
                                       f"{stated:g} one row's: give one of them")
        given = dict(acc_model=acc_model, gyro_model=gyro_model, ids=ids, auto="auto" in add, detect=detect,
                     acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg,
                     noise_curves=curves, rank=rank)
        unused = [k for k in ("ids", "auto", "acc_noise_g", "gyro_noise_dph", "noise_curves", "detect",
                              "heading_accuracy_deg") if given[k] not in (None, False, ()) and k not in m.options]
        if unused:
            flag = {"ids": "--add", "auto": "--add auto", "noise_curves": "--noise",
                    "detect": "--init-rest-s, --threshold-factor, --window-s, --min-static-s and --gyro-limit-dps "
                              "(a stream's)"}.get(
                unused[0], "--" + unused[0].replace("_", "-"))
            takes = [x.name for x in methods.METHODS.values() if unused[0] in x.options]
            raise CalibrationError(f"{flag} does not apply to method {m.name} ({m.summary}); it applies to method "
                                   f"{' or '.join(takes)} "
                                   f"({' or '.join(sorted({methods.DATA[methods.METHODS[t].data] for t in takes}))}).")
        from threadpoolctl import threadpool_limits
        with threadpool_limits(1, "blas"):  # the fits' QRs and pseudo-inverses (up to 522 x 357) are small: on two
            result = m.call(ms, **given)    # OpenBLAS threads each ran 1.1-60x slower here (raw41, both ways measured)
        result.warnings += scale_notes(result, ms.meta)
        result.warnings += [f"{noise}: holds no {s} curve, so the {s} noise is the data's own (--noise covers the "
                            f"{' and '.join(curves)} only)" for s, _ in result.blocks() if curves and s not in curves]
        if stamps:
            result.details["timestamps"] = cast(Timestamps, stamps)  # with_timestamps's block
    except CalibrationError as e:
        raise e.naming(ms.path) from None
    return result


def calibrate_to_file(folder: Data, output: str | os.PathLike[str],
                      kwargs: dict[str, Any]) -> tuple[calibration.Calibration | None, str | None]:
    """calibrate_set() one set and write its file; (result, None), or (None, the refusal's message).
    One task of a batch (`simucal calibrate DIR1 DIR2 ... --scheduler`): a refusal loses no other set."""
    try:
        result = calibrate_set(folder, **kwargs)
        calibration.save(output, result)
        return result, None
    except SimucalError as e:  # a refusal of this set; anything else is a bug, which stops the batch
        return None, str(e)


def _still_warmup(folders: Sequence[Data], degree: int | None, kwargs: Mapping[str, Any]) -> io.MeasurementSet | None:
    """The set, where --thermal is given one stream that never moves (a board warming up, handheld/warmup.py);
    else None. Options a warm-up cannot use are refused by name."""
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
    method = kwargs.get("method")
    given = [o for o, v in (("--thermal-degree", degree),
                            ("--method", method not in (None, "auto") and method),
                            ("--acc-noise-g", kwargs.get("acc_noise_g")),
                            ("--gyro-noise-dph", kwargs.get("gyro_noise_dph")), ("--noise", kwargs.get("noise")),
                            ("--window-s, --threshold-factor, --init-rest-s, --min-static-s, --gyro-limit-dps (a "
                             "hand session's static detection)", kwargs.get("detect")),
                            ("--timestamps", kwargs.get("timestamps") not in (None, "auto"))) if v]
    if given:
        raise CalibrationError(f"{given[0]}: a still warm-up's bias takes its degree from the data (0 to 3), its noise "
                               "from the data, its rows as they are (no poses to find, no moves to time) and no "
                               "other method; leave it out")
    return ms


def calibrate_thermal(folders: Sequence[Data], thermal_degree: int | None = None, t_ref_c: float | None = None,
                      **kwargs: Any) -> calibration.Calibration:
    """One unit at two or more temperature plateaus (one set each), or one set whose temperature
    ramps. A turntable unit (method exact) is fitted once, every row at its own temp_c, with every
    parameter of the model a polynomial in (T - T_ref) inside the model, each parameter's degree
    chosen by the model test and by the groups (plateaus, bands of a ramp) left out
    (fit/thermal_select.py); each plateau is also calibrated alone as evidence. Other methods fit
    each plateau alone and then each parameter's polynomial over the plateaus (fit/thermal.py).
    T_ref: t_ref_c, else the mean of the plateaus' temperatures. The file holds the unit at T_ref
    and, per sensor, `thermal` (the polynomials) that apply evaluates at each row's temp_c."""
    from simucal.fit.thermal_plateaus import refuse_thermal_options
    if not folders:
        raise CalibrationError("--thermal needs a set whose temperature ramps, or two or more plateaus")
    refuse_thermal_options(folders, thermal_degree, kwargs.get("add", ()))
    from threadpoolctl import threadpool_limits
    # one BLAS thread: the QRs and solves here are small, and OpenBLAS's threads spinning against each other
    # (or against another process) made one run 0.66-7.7 s
    with threadpool_limits(1, "blas"):
        return _calibrate_thermal(folders, thermal_degree, t_ref_c, kwargs)


def _calibrate_thermal(folders: Sequence[Data], degree: int | None, t_ref_c: float | None,
                       kwargs: dict[str, Any]) -> calibration.Calibration:
    from simucal.fit.thermal_plateaus import plateau, plateaus_block, reference_temperature, refuse_repeated
    warmup = _still_warmup(folders, degree, kwargs)
    if warmup is not None:
        from simucal.handheld.warmup import calibrate_warmup
        return calibrate_warmup(warmup, t_ref_c, kwargs.get("add") or ())
    sets = [plateau(f) for f in folders]
    refuse_repeated([ms for ms, _ in sets])
    t_ref = reference_temperature(sets, t_ref_c)
    T_k = [t for _, t in sets]
    near = int(np.argmin(np.abs(np.asarray(T_k) - t_ref)))
    # the plateau nearest T_ref by its method: the gyro frame (C_b^d), the checks, the model's shape
    cal = calibrate_set(sets[near][0], t_ref_c=T_k[near], rank=False, **kwargs)
    for ms, _ in sets:
        check_layout(cal, ms, f"the plateau nearest T_ref ({sets[near][0].path})")
    plateaus = [str(ms.path) for ms, _ in sets]
    T_all = np.concatenate([ms.samples["temp_c"] for ms, _ in sets])
    result = calibration.Calibration(f"thermal ({cal.method}, every row at its own temperature)", plateaus,
                                     [ms.sha256 for ms, _ in sets], cal.layout, t_ref_c=t_ref,
                                     temperature_range_c=[float(T_all.min()), float(T_all.max())],
                                     unification=cal.unification, not_calibrated=cal.not_calibrated,
                                     details=cal.details.copy(),  # that plateau's checks (consistency, ...)
                                     samples_sha256=[d for ms, _ in sets for d in ms.sample_digests()])
    if cal.method == "exact":
        from simucal.turntable.thermal import joint_blocks
        joint_blocks(result, sets, cal, degree, t_ref, kwargs.get("noise"), kwargs.get("acc_noise_g"),
                     kwargs.get("gyro_noise_dph"))
    else:
        if len(sets) < 2:
            raise CalibrationError(f"--thermal on one set needs a turntable set (method exact, whose rows are fitted "
                                   f"at their own temperature); method {cal.method} fits each plateau alone: give "
                                   "two or more plateaus")
        cals = [cal if k == near else calibrate_set(ms, t_ref_c=t, **kwargs) for k, (ms, t) in enumerate(sets)]
        for s in cal.sensors:
            setattr(result, s, plateaus_block([getattr(c, s) for c in cals], T_k, t_ref, degree, s, plateaus))
        result.warnings += [w for c in cals for w in c.warnings]
        return result
    result.warnings += cal.warnings
    return result
