"""Turntable simulation: exact rotations for the truth, any generated model.

Truth: the table of derive/table.py with its errors (tilt, non-perpendicular
axes, zero-position and random angular position errors), the IMU mounted by
C_b^k and C_d^k, accelerometer and gyro error models with true parameters
(any generated model, including terms a calibration model lacks), Earth rate
at the latitude, white noise. Rate runs turn the outer axis through whole
revolutions; their mean outputs are averaged over the exact rotation.
"""
from __future__ import annotations

import math

from dataclasses import dataclass, field
from typing import Callable, cast

import numpy as np

from simucal.errors import InputError
from simucal import io
from simucal.fit.augmented import AugmentedModel
from simucal.fit.aux_inputs import DEFAULT_ZERO, T_REF, AuxInputs, specific_force
from simucal.fit.thermal import PLAUSIBLE_C
from simucal.turntable import forward
from simucal.generated import table
from simucal.io import results, units
from simucal.io.meta import Meta
from simucal.io.calibration_checks import PARAM_LIMIT
from simucal.turntable import kinematics, plans

ARCMIN = np.radians(1 / 60)
ARCSEC = units.ARCSEC_RAD


@dataclass
class Scenario:
    """Settings of one simulated test (defaults: dong2018 section 4)."""
    latitude_deg: float = 45.0
    acc_model: str = "acc_baseline"
    gyro_model: str = "gyro_baseline"
    acc_params: dict = field(default_factory=lambda: dict(
        dK_x=0.002, dK_y=0.008, dK_z=0.006, theta_yx=1e-4, theta_zx=1e-4, theta_zy=1e-4,
        b_x=8e-4, b_y=-1e-3, b_z=-3.2e-3))
    # phi and lambda chosen so that M^g in b (eq. 23) has Table 3's off-diagonals.
    gyro_params: dict = field(default_factory=lambda: dict(
        dK_x=0.002, dK_y=-0.0015, dK_z=-0.0015, phi_yx=3e-4, phi_zx=-5e-4, phi_zy=6e-4,
        b_x=-0.34, b_y=0.17, b_z=-0.02))
    theta4_rad: tuple = (12 * ARCMIN, 2 * ARCMIN, -5 * ARCMIN)
    lambda4_rad: tuple = (12 * ARCMIN + 1e-4, 2 * ARCMIN - 1e-4, -5 * ARCMIN + 1e-4)
    tilt_rad: tuple = (5 * ARCSEC, 5 * ARCSEC)
    nonperp_rad: tuple = (5 * ARCSEC, 5 * ARCSEC)        # outer/middle, middle/inner
    zero_rad: tuple = (0.0, 5 * ARCSEC, 5 * ARCSEC)       # outer, middle, inner
    position_error_rad: float = 1 * ARCMIN               # uniform +- this, each axis, each position
    rate_error: float = 0.0           # the rate runs' true rate off the commanded by this fraction (the table's
                                      # rate accuracy)
    outer_rate_dps: tuple = (10.0,)
    acc_noise_g: float = 1e-5         # std of one row (one position mean when rate_hz is None)
    gyro_noise_dph: float = 0.01
    rate_hz: float | None = None      # None: one averaged row per position
    static_s: float = 10.0
    plan: str = "table1"
    unify_positions: bool = True      # add the Table 2 positions and rate runs
    acc_unit: str = "pulse/s"
    gyro_unit: str = "pulse/s"
    acc_pulses_per_g: tuple = (10800.0, 10400.0, 10600.0)
    gyro_pulses_per_arcsec: tuple = (1.1866, 1.1866, 1.1866)
    # Effects in the truth that a calibration model may lack: {effect id: value}.
    acc_effects: dict = field(default_factory=dict)
    gyro_effects: dict = field(default_factory=dict)
    # a gyro bias fixed in the local frame n (ENU, deg/h; e.g. one following the magnetic field): it turns
    # with the unit, so it is no library effect; rate-run means see only its vertical part
    gyro_bias_local_dph: tuple = (0.0, 0.0, 0.0)
    temp_c: tuple[float, float] | None = None  # (first, last): a linear sweep over the segments; None: no temp_c column
    t_ref_c: float | None = None      # T_ref of the unit's temperature terms; None: the data's mean temp_c
    temp_wander_c: float = 0.0        # each segment's temp_c off the sweep by a uniform draw within +- this
    columns: dict = field(default_factory=dict)  # auxiliary columns {name: (low, high)}: uniform, one value per segment
    shuffle: bool = False             # visit the positions in random order (separates time from direction)
    state_noise: bool = True          # write acc_noise_g / gyro_noise_dph into meta.json
    # meta.json states the table simulated, as a lab's would: table_tilt_arcsec, the levelling's std
    # per axis (default the tilt's rms), and table_accuracy_arcsec, each angle's error std (default the position
    # error's, position_error_rad / sqrt(3) for its uniform draw, with the axes' fixed zero offsets and
    # non-perpendicularity, which turn the commanded attitude as much); state_table False: neither
    state_table: bool = True
    tilt_stated_arcsec: float | None = None
    accuracy_stated_arcsec: float | None = None

    def table_errors_rad(self) -> np.ndarray:
        """(tilt_x, tilt_y, nonperp_om, nonperp_mi), rad: the same at every position."""
        return np.r_[self.tilt_rad, self.nonperp_rad]

    def angle_errors_rad(self, rng, shape, position_error=True) -> np.ndarray:
        """(d_gamma, d_alpha, d_beta) per position (*shape, 3), rad: the zero-position error plus,
        where position_error, a uniform angular position error drawn from rng."""
        e = np.broadcast_to(np.array(self.zero_rad, float), tuple(shape) + (3,))
        if position_error:
            e = e + rng.uniform(-1, 1, tuple(shape) + (3,)) * self.position_error_rad
        return e


def _pairs(items, what):
    """NAME=VALUE strings -> {name: float}, refusing malformed ones."""
    out: dict[str, float] = {}
    for item in items:
        name, eq, val = item.partition("=")
        example = "acc.quadratic.z=6e-5" if what == "--effect" else "K3_x=1e-3"
        if name.strip() in out:
            raise InputError(f"{what} {name.strip()} is given twice ({out[name.strip()]:g} and {val.strip()}): "
                             "give each once")
        try:
            if not eq or not name.strip():
                raise InputError
            out[name.strip()] = float(val)
        except ValueError:
            raise InputError(f"{what} {item!r}: write NAME=VALUE with a number, e.g. {example}") from None
        if not abs(out[name.strip()]) <= PARAM_LIMIT:  # NaN fails this too
            raise InputError(f"{what} {item!r}: the value must be finite and at most {PARAM_LIMIT:g} in size (in "
                             "the unit its term declares), as a calibration file's parameters")
    return out


def at_temperature(sc: Scenario, text, t_ref_c=25.0, wander_c=0.0, columns=()):
    """`simulate --temperature-c T` (a plateau) or `T0:T1` (a ramp over the segments), with the unit's
    T_ref (--t-ref-c: its parameters are the truth's there) and a wander (--temperature-wander-c),
    into the scenario; refused in one line where the text is not one or two temperatures."""
    if text is None:
        if wander_c:
            raise InputError("--temperature-wander-c needs --temperature-c (the plateau or ramp it wanders about)")
        return
    if any(c.partition("=")[0].strip() == "temp_c" for c in columns):
        raise InputError("--temperature-c and --column temp_c=...: give one")
    try:
        ends = [float(x) for x in str(text).split(":")]
        if len(ends) not in (1, 2) or not all(PLAUSIBLE_C[0] <= x <= PLAUSIBLE_C[1] for x in ends):
            raise InputError
    except ValueError:
        raise InputError(f"--temperature-c {text!r}: one temperature (a plateau, e.g. 40) or two (a ramp, e.g. 5:45), "
                         f"degC, within {PLAUSIBLE_C[0]:g}..{PLAUSIBLE_C[1]:g} (an IMU's rated range)") from None
    sc.temp_c, sc.t_ref_c, sc.temp_wander_c = (ends[0], ends[-1]), float(t_ref_c), float(wander_c)


def plant(sc: Scenario, effects=(), effect_file=None, sets=(), columns=(), writes_columns=True):
    """Put effects into the truth: candidate ids (--effect ID=VALUE) and a model file's terms
    (--effect-file FILE --set NAME=VALUE), with the auxiliary columns they read
    (--column NAME=LOW:HIGH). Unknown ids or names are refused, and, where a set is written
    (writes_columns), a model file's column with no values."""
    for item in columns:
        name, eq, ends = item.partition("=")
        try:
            low, high = (float(x) for x in ends.split(":"))
            if not eq or not name.strip().isidentifier() or name.strip() in io.SAMPLE_COLS + ("segment", "t_s"):
                raise InputError
        except ValueError:
            raise InputError(f"--column {item!r}: write NAME=LOW:HIGH with a new column name and two numbers, "
                             "e.g. supply_v=4.8:5.2") from None
        if not (math.isfinite(low) and math.isfinite(high) and low <= high):
            raise InputError(f"--column {item!r}: LOW:HIGH must be finite numbers with LOW <= HIGH, e.g. "
                             f"{name.strip()}=4.8:5.2")
        sc.columns[name.strip()] = (low, high)
    from simucal.fit.augmented import check_effect
    from simucal.generated.effects import EFFECTS
    for eid, val in _pairs(effects, "--effect").items():
        check_effect(eid)
        if "dtemp_c" in EFFECTS[eid].reads and not sc.temp_c and "temp_c" not in sc.columns:
            raise InputError(f"--effect {eid}: without a temperature temp_c stays at T_ref, so the effect is zero and "
                             "the samples are those without it; give one: --temperature-c T (a plateau) or T0:T1 (a "
                             "ramp), degC (a turntable set)")
        (sc.acc_effects if EFFECTS[eid].sensor == "acc" else sc.gyro_effects)[eid] = val
    values = _pairs(sets, "--set")
    if values and not effect_file:
        raise InputError("--set needs --effect-file: the model file that defines those parameters")
    if effect_file:
        from simucal.fit.catalog import derive_model_file, load
        for name in derive_model_file(effect_file)[0]:
            model = load(name)
            setattr(sc, f"{model.sensor}_model", name)
            getattr(sc, f"{model.sensor}_params").update({k: v for k, v in values.items() if k in model.params})
        known = set(load(sc.acc_model).params) | set(load(sc.gyro_model).params)
        unknown = sorted(set(values) - known)
        if unknown:
            raise InputError(f"--set {unknown}: not parameters of {effect_file}; its parameters are {sorted(known)}")
        reads = (set(load(sc.acc_model).aux) | set(load(sc.gyro_model).aux)) - DEFAULT_ZERO - set(sc.columns)
        if reads and writes_columns:
            raise InputError(f"{effect_file} reads the column(s) {sorted(reads)}: give their values with "
                             f"--column {sorted(reads)[0]}=LOW:HIGH")


SCENARIOS = {"paper": Scenario}


def unit_from_calibration(path=None, acc_noise_g=None, gyro_noise_dph=None, rate_hz=100.0) -> tuple[Scenario, str]:
    """(a unit to simulate at rate_hz, its description; a sequence is designed for it): the default unit,
    or the baseline parameters of a calibration file (the others the default unit's) with its white
    noise per sample (a systematic calibration's, at rate_hz from the rate it states). acc_noise_g,
    gyro_noise_dph: the noise per sample at rate_hz, over the file's; a file that states none needs both."""
    from simucal.io import calibration
    sc = Scenario()
    if path is None:
        said = "the default unit"
    else:
        cal = calibration.load(path)
        for sensor, block, params in (("acc", cal.acc, sc.acc_params), ("gyro", cal.gyro, sc.gyro_params)):
            taken = {k: v for k, v in (block.params if block else {}).items() if k in params}
            if block is not None and not taken:
                raise InputError(f"--calibration {path}: its {sensor} model {block.model} holds none of the "
                                 f"baseline's parameters ({', '.join(params)}), which the design's filter estimates")
            params.update(taken)
        sc.acc_unit, sc.gyro_unit = "g", "deg/h"
        noise = cal.details.get("systematic", {}).get("white_noise_per_sample", {})
        if (acc_noise_g is None or gyro_noise_dph is None) and "rate_hz" not in noise:
            raise InputError(f"--calibration {path}: states no white noise per sample with its rate (a systematic "
                             "calibration of this version does): give --acc-noise-g and --gyro-noise-dph, the "
                             f"unit's noise per sample at {rate_hz:g} Hz")
        if "rate_hz" in noise:  # white noise: its std per sample goes as the square root of the rate
            k = np.sqrt(rate_hz / noise["rate_hz"])
            sc.acc_noise_g = float(k * np.sqrt(np.mean(np.square(noise["acc_g"]))))
            sc.gyro_noise_dph = float(k * np.sqrt(np.mean(np.square(noise["gyro_dph"]))))
        said = f"the unit of {path}"
    sc.acc_noise_g = acc_noise_g or sc.acc_noise_g
    sc.gyro_noise_dph = gyro_noise_dph or sc.gyro_noise_dph
    sc.rate_hz = rate_hz
    return sc, said


def lever_arms_and_delay(seed: int) -> dict[str, float]:
    """Library effects drawn at seed: the y and z accelerometers' lever arms from the x
    accelerometer, 1-5 cm either way (acc.lever_arm.*, m), and one 1-5 ms delay of the accelerometers
    behind the gyros (acc.time_delay.*, s)."""
    rng = np.random.default_rng(500 + seed)
    planted = {f"acc.lever_arm.{a}{c}": float(rng.choice([-1, 1]) * rng.uniform(0.01, 0.05))
               for a in "yz" for c in "xyz"}
    tau = float(rng.uniform(1e-3, 5e-3))
    return planted | {f"acc.time_delay.{a}": tau for a in "xyz"}


def drawn_unit(rng, shape_std: float, acc_bias_g: float, gyro_bias_dph: float, acc_noise_g: float,
               gyro_noise_dph: float) -> Scenario:
    """A unit of one grade drawn from rng: scale factors and misalignments of std shape_std, the biases' stds,
    the noise per sample; outputs in g and deg/h."""
    sc = Scenario()
    sc.acc_unit, sc.gyro_unit = "g", "deg/h"
    shape = ("dK_x", "dK_y", "dK_z")
    sc.acc_params = {**{k: rng.normal(0, shape_std) for k in shape + ("theta_yx", "theta_zx", "theta_zy")},
                     **{k: rng.normal(0, acc_bias_g) for k in ("b_x", "b_y", "b_z")}}
    sc.gyro_params = {**{k: rng.normal(0, shape_std) for k in shape + ("phi_yx", "phi_zx", "phi_zy")},
                      **{k: rng.normal(0, gyro_bias_dph) for k in ("b_x", "b_y", "b_z")}}
    sc.acc_noise_g, sc.gyro_noise_dph = acc_noise_g, gyro_noise_dph
    return sc


def mems_unit(seed: int) -> Scenario:
    """A MEMS unit drawn at seed: gyro biases near 0.5 deg/s (1800 deg/h std), accelerometer biases near 50 mg,
    scale factors and misalignments near 2e-2, noise 2e-4 g and 30 deg/h per sample."""
    return drawn_unit(np.random.default_rng(1000 + seed), 2e-2, 0.05, 1800.0, 2e-4, 30.0)


def tactical_unit(seed: int) -> Scenario:
    """A tactical-grade unit drawn at seed (HG1700's class, uncompensated): gyro biases near 3 deg/h,
    accelerometer biases near 1 mg, scale factors and misalignments near 1e-3, noise 75 deg/h and 1.1e-3 g per
    sample at 100 Hz (0.125 deg/sqrt(h), 0.065 m/s/sqrt(h))."""
    return drawn_unit(np.random.default_rng(3000 + seed), 1e-3, 1e-3, 3.0, 1.1e-3, 75.0)

AVERAGE_POINTS = 720  # an averaged rate run: the mean of its inputs at this many outer angles over the revolution


def _segments(sc: Scenario, rng):
    """The plan's segments and, per segment, (inputs, duration): inputs(t) the true (f_b, w_d, f_d)
    at the times t (s, (n,)) from the segment's start: static positions at the table's errors, rate
    runs about the outer axis turning continuously (the outer angle at t is rate * t)."""
    C_b_k = table.mounting(np.array(sc.theta4_rad))
    C_d_k = table.mounting(np.array(sc.lambda4_rad))
    w_ie_n = table.earth_rate_n(units.DEFAULT_EARTH_RATE_DPH, np.radians(sc.latitude_deg)) + np.array(
        sc.gyro_bias_local_dph, float)  # what the gyro reads at rest
    plan = plans.PLANS[sc.plan]() if sc.plan in plans.PLANS else plans.read_csv(sc.plan)
    static: list[tuple[float, float, float]] = list(plan) + (plans.TABLE2 if sc.unify_positions else [])
    rates = [(0.0, a, b, r) for r in sc.outer_rate_dps for (_, a, b) in plan]
    if sc.unify_positions:
        rates += [(0.0, a, 0.0, r) for r in sc.outer_rate_dps for a in (0.0, 90.0)]
    if sc.shuffle:
        static = [static[i] for i in rng.permutation(len(static))]
        rates = [rates[i] for i in rng.permutation(len(rates))]
    segments: list[io.Segment] = []
    rows: list[tuple[Callable, float]] = []  # per segment: (inputs(t), duration)

    def table_errors(n):
        return kinematics.errors(sc.table_errors_rad(), sc.angle_errors_rad(rng, (n,)))

    def sensed(C, w_n):  # the inputs (f_b, w_d, f_d) at table attitudes C (n, 3, 3) under the rate w_n
        return (np.einsum("ji,nkj,k->ni", C_b_k, C, up), np.einsum("ji,nkj,k->ni", C_d_k, C, w_n),
                np.einsum("ji,nkj,k->ni", C_d_k, C, up))

    up = np.array([0, 0, 1.0])
    for ang, err in zip(static, table_errors(len(static))):
        at_rest = sensed(table.C_k_n(*np.radians(ang), err)[None], w_ie_n)
        segments.append(io.Segment(len(segments) + 1, "static", *ang, 0.0))
        rows.append((lambda t, v=at_rest: tuple(np.repeat(x, len(t), 0) for x in v), sc.static_s))
    tilt_n = table.C_k_n(0.0, 0.0, 0.0, np.r_[sc.tilt_rad, np.zeros(5)])[:, 2]
    for (g0, a, b, rate), err in zip(rates, table_errors(len(rates))):
        def turning(t, g0=g0, a=a, b=b, rate=rate * (1 + sc.rate_error), err=err):  # segments.csv: the commanded
            C = table.C_k_n(np.radians(g0 + rate * np.asarray(t)), *np.radians([a, b]), err)
            return sensed(C, w_ie_n + rate * units.DPH_PER_DPS * tilt_n)
        segments.append(io.Segment(len(segments) + 1, "rate", None, a, b, rate))
        rows.append((turning, 360.0 / abs(rate)))
    return segments, rows


def meta_of(sc: Scenario, seed) -> Meta:
    """meta.json of a simulated test."""
    meta = {"latitude_deg": sc.latitude_deg, "gravity_mps2": units.DEFAULT_GRAVITY,
            "earth_rate_dph": units.DEFAULT_EARTH_RATE_DPH, "acc_unit": sc.acc_unit, "gyro_unit": sc.gyro_unit,
            "description": f"simucal simulate, seed {seed}"}
    if sc.state_noise:  # a noise-free set states none (the spec's noise is a std > 0)
        meta.update({units.NOISE_KEY[s]: v for s, v in (("acc", sc.acc_noise_g), ("gyro", sc.gyro_noise_dph)) if v > 0})
    if sc.state_table:
        tilt = sc.tilt_stated_arcsec if sc.tilt_stated_arcsec is not None else \
            float(np.sqrt(np.mean(np.square(sc.tilt_rad)))) / ARCSEC
        accuracy = sc.accuracy_stated_arcsec if sc.accuracy_stated_arcsec is not None else float(np.sqrt(
            sc.position_error_rad ** 2 / 3 + np.mean(np.square(np.r_[sc.zero_rad, sc.nonperp_rad])))) / ARCSEC
        meta.update(table_tilt_arcsec=tilt, table_accuracy_arcsec=accuracy)
    if sc.acc_unit == "pulse/s":
        meta["acc_pulses_per_g"] = list(sc.acc_pulses_per_g)
    if sc.gyro_unit == "pulse/s":
        meta["gyro_pulses_per_arcsec"] = list(sc.gyro_pulses_per_arcsec)
    return cast(Meta, meta)


def _samples(sc: Scenario, rng, segments, rows, acc, p_acc, gyro, p_gyro, meta):
    """samples.csv's columns (raw rows at sc.rate_hz, else one averaged row per segment) of the
    models' outputs with noise, and T_ref of temperature terms (None without temp_c)."""
    seg_ids, times, acc_out, gyro_out = [], [], [], []
    values = {name: rng.uniform(*ends, len(segments)) for name, ends in sc.columns.items()}
    if sc.temp_c:
        values["temp_c"] = np.linspace(*sc.temp_c, len(segments))
        if sc.temp_wander_c:  # a chamber's or a self-heating unit's wander (drawn only then: other seeds unchanged)
            values["temp_c"] = values["temp_c"] + rng.uniform(-sc.temp_wander_c, sc.temp_wander_c, len(segments))
    columns: dict[str, list[np.ndarray]] = {name: [] for name in values}  # auxiliary columns written
    rows_per = [1 if sc.rate_hz is None else int(round(dur * sc.rate_hz)) for _, dur in rows]
    t_ref_c = None if "temp_c" not in values else sc.t_ref_c if sc.t_ref_c is not None else \
        float(np.average(values["temp_c"], weights=rows_per))  # as MeasurementSet.t_ref_c
    t0 = 0.0
    for k, (seg, (inputs, dur)) in enumerate(zip(segments, rows)):
        if sc.rate_hz is None:  # the mean over one revolution: exact for the inputs' harmonics below AVERAGE_POINTS
            f, w, fd = (x.mean(0, keepdims=True) for x in inputs(np.arange(AVERAGE_POINTS) * dur / AVERAGE_POINTS))
            t = np.array([t0 + dur / 2])
        else:
            n = rows_per[k]
            if n < 3:  # raw rows are for a segment's scatter; fewer is an averaged row, written as such
                raise InputError(f"--rate-hz {sc.rate_hz:g}: a {dur:g} s segment would get {n} rows; use at least "
                                 f"{3 / dur:.3g} Hz, or leave --rate-hz out for one averaged row per segment")
            f, w, fd = inputs(np.arange(n) / sc.rate_hz)  # each row at its own instant (a point sample)
            t = t0 + np.arange(n) / sc.rate_hz
        col = {name: np.full(len(t), v[k]) for name, v in values.items()}
        aux = AuxInputs({"t_s": t, **col, **({} if t_ref_c is None else {T_REF: t_ref_c})})
        w2 = np.radians(seg.outer_rate_dps) ** 2 / units.DEFAULT_GRAVITY  # centripetal scale, 1/m
        acc_out.append(forward.output(acc, p_acc, f, aux.with_values(w2=w2)) + rng.normal(0, sc.acc_noise_g, f.shape))
        gyro_out.append(forward.output(gyro, p_gyro, w, aux.with_values(**specific_force(fd)))
                        + rng.normal(0, sc.gyro_noise_dph, w.shape))
        seg_ids.append(np.full(len(t), seg.segment))
        times.append(t)
        for name in columns:
            columns[name].append(col[name])
        t0 += dur + 5.0
    N_a = units.g_to_acc(np.concatenate(acc_out), meta)
    N_g = units.dph_to_gyro(np.concatenate(gyro_out), meta)
    samples = {"segment": np.concatenate(seg_ids), "t_s": np.concatenate(times)}
    samples.update({name: np.concatenate(v) for name, v in columns.items()})
    for j, c in enumerate("xyz"):
        samples["a" + c] = N_a[:, j]
        samples["g" + c] = N_g[:, j]
    return samples, t_ref_c


def models(sc: Scenario):
    """(acc, p_acc, gyro, p_gyro): the unit's models, its baseline terms and planted effects, and their
    true parameters."""
    acc = AugmentedModel(sc.acc_model, tuple(sc.acc_effects))
    gyro = AugmentedModel(sc.gyro_model, tuple(sc.gyro_effects))
    p_acc = np.array([{**sc.acc_params, **sc.acc_effects}.get(k, 0.0) for k in acc.params])
    p_gyro = np.array([{**sc.gyro_params, **sc.gyro_effects}.get(k, 0.0) for k in gyro.params])
    return acc, p_acc, gyro, p_gyro


def truth_of(sc: Scenario, acc, p_acc, gyro, p_gyro, seed) -> results.Truth:
    """truth.json: every parameter of the unit and the table."""
    M_a, b_a = acc.matrix_and_bias(p_acc)
    M_g_d, b_g = gyro.matrix_and_bias(p_gyro)
    C_b_d = table.mounting(np.array(sc.lambda4_rad)).T @ table.mounting(np.array(sc.theta4_rad))
    return {
        "acc": {"model": acc.name, "params": dict(zip(acc.params, p_acc.tolist())), "effects": dict(sc.acc_effects),
                "M": M_a.tolist(), "bias": b_a.tolist(), "bias_unit": "g"},
        "gyro": {"model": gyro.name, "params": dict(zip(gyro.params, p_gyro.tolist())),
                 "effects": dict(sc.gyro_effects),
                 "M": (M_g_d @ C_b_d).tolist(), "bias": b_g.tolist(), "bias_unit": "deg/h",
                 "M_in_d": M_g_d.tolist(), "C_b_d": C_b_d.tolist()},
        "mounting": {"theta4_rad": list(sc.theta4_rad), "lambda4_rad": list(sc.lambda4_rad)},
        "table": {"tilt_rad": list(sc.tilt_rad), "nonperp_rad": list(sc.nonperp_rad),
                  "zero_rad": list(sc.zero_rad), "position_error_rad": sc.position_error_rad,
                  "rate_error": sc.rate_error},
        "seed": seed,
    }


def simulate(sc: Scenario, seed: int = 0):
    """Return (meta, samples, segments, truth) of one simulated test."""
    if sc.rate_hz is not None and not sc.rate_hz > 0:
        raise InputError(f"--rate-hz {sc.rate_hz}: the sample rate must be positive")
    rng = np.random.default_rng(seed)
    acc, p_acc, gyro, p_gyro = models(sc)
    segments, rows = _segments(sc, rng)
    meta = meta_of(sc, seed)
    samples, t_ref_c = _samples(sc, rng, segments, rows, acc, p_acc, gyro, p_gyro, meta)
    truth = truth_of(sc, acc, p_acc, gyro, p_gyro, seed)
    if t_ref_c is not None:
        truth["t_ref_c"] = t_ref_c  # the bias and M above are at this temperature
    return meta, samples, segments, truth


def write(folder, sc: Scenario, seed: int = 0):
    meta, samples, segments, truth = simulate(sc, seed)
    io.write_set(folder, meta, samples, segments, {"truth.json": truth})
    return truth
