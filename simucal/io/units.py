"""Units of the spec and their conversion to the calibration's units.

Calibrations work in g (accelerometers) and deg/h (gyros). Pulse and count
outputs are divided by the nominal scale factors of meta.json. Note
1 arcsec/s = 1 deg/h, so gyro pulse/s / (pulses per arcsec) is deg/h.

What a person reads may be asked in SI (si_unit, in_units): m/s^2 for g, rad/s for deg/h, and rad for an angle
that is a sensor's error (a quantisation, a misalignment, a table's angle error: given in arcsec); an angle a
person sets or reads as a place or a pose (a latitude, an attitude, a heading: given in deg) stays in deg.
"""
import math
import re
from typing import Any, Callable, Mapping

import numpy as np
from numpy.typing import ArrayLike

ACC_UNITS = ("g", "m/s^2", "pulse/s", "counts")
GYRO_UNITS = ("deg/h", "deg/s", "rad/s", "pulse/s", "counts")
DEFAULT_GRAVITY = 9.80665
DEFAULT_EARTH_RATE_DPH = 15.04107
DPH_PER_DPS = 3600.0  # deg/h per deg/s (1 arcsec/s = 1 deg/h)
ARCSEC_RAD = math.radians(1 / 3600)  # rad per arcsec
RAD_S_PER_DPH = math.pi / 180 / DPH_PER_DPS  # rad/s per deg/h
# meta.json's stated noise of one row's output, per sensor: its key, unit and largest plausible value
# a column named as a temperature in another unit than the spec's temp_c (degC): temp_f, TempF, temp_degF,
# temperature (K), temp_kelvin, ... Its name is the only sound cue: below 125 degF (51.7 degC) degF values
# lie inside an IMU's rated degC range, and a unit's thermal slopes are its own (no scale for the factor 1.8)
# (searched: a meta.json key may say what it measures first, chamber_temp_f)
_TEMP_NAMED = re.compile(r"(tmp|temp|temperature)[ _.\-(\[]*(deg|°)?[ _]?(?P<unit>f|k|fahrenheit|kelvin)[)\]]?$", re.I)


def temperature_unit_in_name(name: str, anywhere=False) -> str | None:
    """'degF' or 'kelvin' where a column's name says its temperature is in that unit, else None;
    anywhere: the name may begin with other words (a meta.json key)."""
    m = (_TEMP_NAMED.search if anywhere else _TEMP_NAMED.match)(name.strip())
    return None if m is None else "kelvin" if m["unit"].lower() in ("k", "kelvin") else "degF"


_TEMP_UNIT_KEY = re.compile(r"^(tmp|temp|temperature)[ _.\-]*(c[ _.\-]*)?units?$", re.I)  # temp_unit, temp_c_unit
TO_C = {"degF": (lambda v: (v - 32.0) / 1.8, "C = (F - 32) / 1.8"), "kelvin": (lambda v: v - 273.15, "C = K - 273.15")}


def _unit_word(text) -> str | None:
    """'degF', 'kelvin' or 'degC' for a unit's spelling (F, degF, °F, fahrenheit, K, kelvin, C, ...)."""
    w = re.sub(r"[\s_°]|deg(rees?)?", "", str(text).lower())
    return {"f": "degF", "fahrenheit": "degF", "k": "kelvin", "kelvin": "kelvin", "c": "degC",
            "celsius": "degC"}.get(w)


def temperature_unit_evidence(meta: Mapping[str, Any], samples: dict) -> str | None:
    """Where a recording itself says that its temp_c is not in degC, the evidence in words, else None:
    a meta.json key stating the temperature's unit (temp_unit, temperature_units, temp_c_unit) as degF or
    kelvin, or a meta.json number or samples.csv column named as a temperature in degF or kelvin
    (chamber_temp_f, setpoint_temp_K, temp_degF) whose values are temp_c's own rather than their
    conversion to degC. Nothing else in a recording tells degF between 32 and 125 from degC (README)."""
    T = np.asarray(samples["temp_c"], float)
    for key, v in meta.items():
        unit = _unit_word(v) if _TEMP_UNIT_KEY.match(key) else None
        if unit in TO_C:
            return f"meta.json states {key} = {v!r} ({unit})"
    named = [(f"meta.json's {k}", temperature_unit_in_name(k, True), np.asarray(v, float)) for k, v in meta.items()
             if isinstance(v, (int, float)) and not isinstance(v, bool)]
    named += [(f"samples.csv's column {c}", temperature_unit_in_name(c, True), np.asarray(v, float))
              for c, v in samples.items() if c != "temp_c"]

    def near(x):  # a column row by row; a number (a setpoint) to the nearest row
        return float(np.median(np.abs(x - T))) if x.ndim else float(np.min(np.abs(x - T)))
    for where, unit, v in named:
        if unit and near(v) < min(near(TO_C[unit][0](v)), 2.0):  # its own values, within a plateau's wander
            return f"{where} (named as {unit}) holds temp_c's own values, not their conversion to degC"
    return None


def refuse_temperature_unit(meta: Mapping[str, Any], samples: dict, path, error) -> None:
    """Raise error naming the evidence where the recording says its temp_c is in degF or kelvin."""
    said = temperature_unit_evidence(meta, samples) if "temp_c" in samples else None
    if said:
        unit = "kelvin" if "kelvin" in said else "degF"
        raise error(f"{path}: {said}: temp_c seems to be in {unit}, but temp_c is degC: convert it "
                    f"({TO_C[unit][1]}), or correct meta.json")


NOISE_KEY = {"acc": "acc_noise_g", "gyro": "gyro_noise_dph"}
NOISE_UNIT = {"acc": ("g", 1.0), "gyro": ("deg/h", 1e6)}
SCALE_KEY = {("acc", "pulse/s"): "acc_pulses_per_g", ("acc", "counts"): "acc_counts_per_g",
             ("gyro", "pulse/s"): "gyro_pulses_per_arcsec", ("gyro", "counts"): "gyro_counts_per_dps"}


def check_meta(meta: Mapping[str, Any], path: Any, error: Callable[[Any, Any, str], Exception]) -> None:
    for sensor, allowed in (("acc", ACC_UNITS), ("gyro", GYRO_UNITS)):
        key = f"{sensor}_unit"
        if key not in meta:
            raise error(path, None, f'"{key}" is required, one of {allowed}')
        if meta[key] not in allowed:
            raise error(path, None, f'"{key}" {meta[key]!r} is not a known unit; use one of {allowed}')
        skey = SCALE_KEY.get((sensor, meta[key]))
        if skey:
            v = meta.get(skey)
            if not (isinstance(v, list) and len(v) == 3
                    and all(isinstance(x, (int, float)) and 0 < x < math.inf for x in v)):
                raise error(path, None, f'{key} is {meta[key]!r}, so "{skey}" must be three positive numbers')
    for sensor, key in NOISE_KEY.items():
        unit, hi = NOISE_UNIT[sensor]
        v = meta.get(key)
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v <= hi):
            raise error(path, None, f'"{key}" is {v!r}, but it is the std of one row\'s output ({unit}): a number '
                                    f'> 0 and <= {hi:g}; leave the key out where the noise is not known (it is then '
                                    'estimated from the data)')
    v = meta.get("average_s")
    if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < math.inf):
        raise error(path, None, f"average_s is {v!r}; it must be a number > 0 (the seconds each averaged row "
                                "averages)")
    for key, what in (("table_accuracy_arcsec", "the std of each commanded angle's position error"),
                      ("table_tilt_arcsec", "the std of the outer axis's tilt about each horizontal axis")):
        v = meta.get(key)
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0):
            raise error(path, None, f"{key} is {v!r}; it must be a number >= 0 ({what}, arcsec)")
    lat = meta.get("latitude_deg")
    if lat is not None and not (isinstance(lat, (int, float)) and not isinstance(lat, bool) and -90 <= lat <= 90):
        raise error(path, None, f'"latitude_deg" must be a number in -90..90, got {lat!r}')
    fs = meta.get("full_scale")
    if fs is not None:
        ok = isinstance(fs, dict) and all(
            k in ("acc", "gyro") and isinstance(v, list) and len(v) == 2 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v) and v[0] < v[1]
            for k, v in fs.items())
        if not ok:
            raise error(path, None, f'"full_scale" is {fs!r}; write {{"acc": [lo, hi], "gyro": [lo, hi]}} with lo < hi '
                                    'in the units of acc_unit and gyro_unit (either key may be left out)')
    for key, what, lo, hi, default in (("gravity_mps2", "local gravity's magnitude, m/s^2", 9.0, 10.5, DEFAULT_GRAVITY),
                                       ("earth_rate_dph", "the Earth's rotation rate, deg/h", 14.5, 15.5,
                                        DEFAULT_EARTH_RATE_DPH)):
        v = meta.get(key)
        if v is not None and not (isinstance(v, (int, float)) and not isinstance(v, bool) and lo <= v <= hi):
            raise error(path, None, f'"{key}" is {v!r}, but it is {what} ({default} by default, {lo}..{hi} '
                                    'anywhere on the Earth): fix the value, or leave the key out for the default')


def stated_noise(meta, sensor):
    """meta.json's noise of one row of `sensor` (g or deg/h), or None where it is not stated."""
    return meta.get(NOISE_KEY[sensor])


def gravity(meta: Mapping[str, Any]) -> float:
    return float(meta.get("gravity_mps2", DEFAULT_GRAVITY))


def earth_rate_dph(meta: Mapping[str, Any]) -> float:
    return float(meta.get("earth_rate_dph", DEFAULT_EARTH_RATE_DPH))


def acc_to_g(raw: np.ndarray, meta: Mapping[str, Any]) -> np.ndarray:
    u = meta["acc_unit"]
    if u == "g":
        return raw
    if u == "m/s^2":
        return raw / gravity(meta)
    return raw / np.asarray(meta[SCALE_KEY[("acc", u)]], float)


def gyro_to_dph(raw: np.ndarray, meta: Mapping[str, Any]) -> np.ndarray:
    u = meta["gyro_unit"]
    if u == "deg/h":
        return raw
    if u == "deg/s":
        return raw * DPH_PER_DPS
    if u == "rad/s":
        return np.degrees(raw) * DPH_PER_DPS
    if u == "pulse/s":
        return raw / np.asarray(meta["gyro_pulses_per_arcsec"], float)
    return raw / np.asarray(meta["gyro_counts_per_dps"], float) * DPH_PER_DPS


def g_to_acc(f_g: np.ndarray, meta: Mapping[str, Any]) -> np.ndarray:
    """Inverse of acc_to_g, for the simulator."""
    u = meta["acc_unit"]
    if u == "g":
        return f_g
    if u == "m/s^2":
        return f_g * gravity(meta)
    return f_g * np.asarray(meta[SCALE_KEY[("acc", u)]], float)


def dph_to_gyro(w_dph: np.ndarray, meta: Mapping[str, Any]) -> np.ndarray:
    u = meta["gyro_unit"]
    if u == "deg/h":
        return w_dph
    if u == "deg/s":
        return w_dph / DPH_PER_DPS
    if u == "rad/s":
        return np.radians(w_dph / DPH_PER_DPS)
    if u == "pulse/s":
        return w_dph * np.asarray(meta["gyro_pulses_per_arcsec"], float)
    return w_dph / DPH_PER_DPS * np.asarray(meta["gyro_counts_per_dps"], float)


# Ratios between the units a recording may really use and the one its meta.json names.
UNIT_MIXUPS = {"acc": {"m/s^2 labelled g": DEFAULT_GRAVITY, "g labelled m/s^2": 1 / DEFAULT_GRAVITY,
                   "mg labelled g": 1000.0},
           "gyro": {"deg/s labelled deg/h": 1 / DPH_PER_DPS, "deg/h labelled deg/s": DPH_PER_DPS,
                    "rad/s labelled deg/s": np.pi / 180, "deg/s labelled rad/s": 180 / np.pi,
                    "rad/s labelled deg/h": np.pi / 180 / DPH_PER_DPS,
                    "deg/h labelled rad/s": DPH_PER_DPS * 180 / np.pi}}


def check_magnitude(sensor: str, measured_norm: ArrayLike, expected_norm: ArrayLike, where: object,
                    meta: Mapping[str, Any] | None = None) -> None:
    """Refuse outputs whose size is far from the known input's: almost always a unit
    mix-up, which a calibration would otherwise absorb into absurd scale factors.
    Raw counts carry an offset by design (the bias absorbs it): for them see check_scale."""
    if meta is not None and meta.get(f"{sensor}_unit") == "counts":
        return
    r = float(np.median(np.asarray(measured_norm) / np.asarray(expected_norm)))
    _refuse_ratio(sensor, r, where)


def check_scale(sensor, M, where):
    """After a fit: scale factors (diagonal of M) far from 1 mean a wrong unit or nominal scale."""
    d = np.abs(np.diag(np.asarray(M, float)))
    r = float(np.median(d))
    _refuse_ratio(sensor, r, where, "fitted scale factors")


def _refuse_ratio(sensor, r, where, what="outputs"):
    if 0.5 < r < 2.0:
        return
    guess = min(UNIT_MIXUPS[sensor].items(), key=lambda kv: abs(np.log(r / kv[1])))
    likely = f"; the ratio matches {guess[0]}" if abs(np.log(r / guess[1])) < 0.2 else ""
    from simucal.errors import CalibrationError
    known = "1 g at rest" if sensor == "acc" else "the commanded rate, or the Earth rate at rest"
    raise CalibrationError(f"{where}: the {sensor} {what} are {r:.4g} times the known input ({known}): check "
                           f"{sensor}_unit and the nominal scale factors in meta.json{likely}")


# The units a person may ask numbers in: the spec's (g, deg/h and the noise terms' data-sheet units) or SI
# (m/s^2, rad/s, rad/sqrt(s), ...). The files keep the spec's; these convert what is printed, tabled or written
# for a person, label and value together (the angles: the module's doc).
UNIT_SYSTEMS = ("spec", "si")
# each spec atom of a unit label as (its SI atom, SI per spec atom, times gravity: the set's or standard)
_SI_ATOMS: dict[str, tuple[str, float, bool]] = {
    "g": ("m/s^2", 1.0, True), "mg": ("m/s^2", 1e-3, True), "ug": ("m/s^2", 1e-6, True),
    "deg": ("rad", math.pi / 180, False), "arcsec": ("rad", ARCSEC_RAD, False), "h": ("s", 3600.0, False)}
_SI_POWERS = {"m/s^2": {"m": 1, "s": -2}}  # a compound SI atom's base atoms, for cancelling (ug*s -> m/s)
_KEPT_ATOMS = {"s", "Hz", "rad", "degC", "m", "1", "ppm", "K"}  # SI already, or dimensionless
_TIMES = {"h", "s", "Hz"}
_SENSOR_ANGLES = {"arcsec"}  # an angle alone converted to rad: only a sensor's error is given in arcsec
_UNIT_TOKEN = re.compile(r"\s*(sqrt\(|[A-Za-z]+|\d+|[()/*^])")


def check_unit_system(system: str, where: str = "units") -> None:
    """Refuse a unit system simucal does not print in, naming the choices."""
    if system not in UNIT_SYSTEMS:
        from simucal.errors import InputError
        raise InputError(f"{where}={system!r}: not a unit system simucal prints in; one of {', '.join(UNIT_SYSTEMS)}")


def si_unit(label: str, gravity_mps2: float = DEFAULT_GRAVITY) -> tuple[float, str] | None:
    """(SI per unit of label, the SI label) for a unit label of the spec's atoms (g, ug, deg/h, deg/sqrt(h),
    (deg/h)/g, g/degC^2, ug*s, arcsec, ...), None where label is no unit made of them; the SI label with its
    like factors cancelled (g/g^2 -> 1/(m/s^2), ug*s -> m/s). An angle in deg and a time alone stay as they are
    (factor 1): accelerations, rates, the noise terms and a sensor's angle errors (arcsec) convert."""
    tokens, at = [], 0
    while at < len(label):
        m = _UNIT_TOKEN.match(label, at)
        if m is None:
            return None
        tokens.append(m.group(1))
        at = m.end()
    try:
        factor, terms, atoms, end = _unit_expr(tokens, 0, gravity_mps2)
    except (IndexError, ValueError):
        return None
    if end != len(tokens):
        return None
    converts = atoms & {"g", "mg", "ug"} or (atoms & {"deg", "arcsec"} and atoms & _TIMES) or atoms == _SENSOR_ANGLES
    return (factor, _render(_simplified(terms))) if converts else (1.0, label)


# A label's SI form as terms [group, exponent]; a group: (its base atoms' powers, its text, compound (several
# atoms: parenthesised where raised or dividing), plain (one atom to an integer power: may cancel into a compound))
def _unit_expr(tokens, i, g):
    """tokens[i:] as factor ((/|*) factor)*: (SI per unit, its SI terms, the atoms met, the index after it)."""
    factor, group, power, atoms, i = _unit_factor(tokens, i, g)
    terms = [[group, power]]
    while i < len(tokens) and tokens[i] in "/*":
        op = tokens[i]
        f, group, power, a, i = _unit_factor(tokens, i + 1, g)
        factor, atoms = factor / f if op == "/" else factor * f, atoms | a
        terms.append([group, -power if op == "/" else power])
    return factor, terms, atoms, i


def _unit_factor(tokens, i, g):
    """One atom, (expr) or sqrt(expr), with an integer power: (SI per unit, group, power, atoms, next index)."""
    t = tokens[i]
    if t in ("(", "sqrt("):
        factor, terms, atoms, i = _unit_expr(tokens, i + 1, g)
        if tokens[i] != ")":
            raise ValueError(t)
        terms, i = _simplified(terms), i + 1
        powers = _powers(terms)
        if t == "sqrt(":
            factor, group = math.sqrt(factor), ({a: p / 2 for a, p in powers.items()}, f"sqrt({_render(terms)})",
                                                False, False)
        else:
            group = (powers, f"({_render(terms)})" if len(powers) > 1 else _render(terms), len(powers) > 1, False)
    elif t in _SI_ATOMS:
        text, per, by_gravity = _SI_ATOMS[t]
        factor, atoms, i = per * (g if by_gravity else 1.0), {t}, i + 1
        group = (_SI_POWERS.get(text, {text: 1}), text, text in _SI_POWERS, text not in _SI_POWERS)
    elif t in _KEPT_ATOMS:
        factor, atoms, i = 1.0, {t} & _TIMES, i + 1
        group = ({} if t == "1" else {t: 1}, t, False, True)
    else:
        raise ValueError(t)
    power = 1
    if i < len(tokens) and tokens[i] == "^":
        power, i = int(tokens[i + 1]), i + 2
        factor **= power
    return factor, group, power, atoms, i


def _powers(terms) -> dict:
    out: dict = {}
    for (powers, *_), e in terms:
        for a, p in powers.items():
            out[a] = out.get(a, 0) + p * e
    return {a: p for a, p in out.items() if p}


def _simplified(terms):
    """Like groups summed (g/g^2 -> 1/g), then a plain atom cancelled into a compound that holds it with the
    opposite sign (m/s^2*s -> m/s); dimensionless and cancelled terms dropped."""
    out: list = []
    for group, e in terms:
        same = next((t for t in out if t[0][0] == group[0]), None)
        if same is not None:
            same[1] += e
        elif group[0]:
            out.append([group, e])
    for plain in [t for t in out if t[0][3] and t[1]]:
        (atom, p), = plain[0][0].items()
        into = next((t for t in out if t[0][2] and t[1] == 1 and t[0][0].get(atom, 0) * plain[1] < 0), None)
        if into is not None:
            powers = _powers([into, plain])
            into[0] = (powers, _render([[({a: 1}, a, False, True), q] for a, q in powers.items()]), len(powers) > 1,
                       False)
            plain[1] = 0
    return [t for t in out if t[1]]


def _render(terms) -> str:
    """The label of SI terms: the numerator's groups by *, then each denominator's by / (a compound in
    parentheses where raised or dividing; the first one alone as it is)."""
    def text(group, e, first):
        paren = group[2] and not group[1].startswith("(") and (e != 1 or not first)
        return (f"({group[1]})" if paren else group[1]) + (f"^{e:g}" if e != 1 else "")
    num = [text(g, e, k == 0) for k, (g, e) in enumerate(t for t in terms if t[1] > 0)]
    return ("*".join(num) or "1") + "".join(f"/{text(g, -e, False)}" for g, e in terms if e < 0)


def in_units(value, label: str, system: str = "spec", gravity_mps2: float = DEFAULT_GRAVITY):
    """(value, label) in the unit system asked: the spec's as given, or SI (si_unit's factor and label; a
    dimensionless or unknown label unchanged). value: a number, an array or None."""
    si = si_unit(label, gravity_mps2) if system == "si" else None
    if si is None or value is None:
        return value, label if si is None else si[1]
    return (value * si[0] if not isinstance(value, list) else [None if v is None else v * si[0] for v in value]), si[1]


_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"
_QUANTITY = re.compile(rf"(?<![\w.^/*-])(?P<a>{_NUMBER})(?:(?P<op> \+- | to | -> )(?P<b>{_NUMBER}))? "
                       rf"(?P<unit>(?:1/)?[A-Za-z(][\w()/*^.]*)(?: against (?P<c>{_NUMBER}))?")


def text_in_units(text: str, system: str = "spec", gravity_mps2: float = DEFAULT_GRAVITY) -> str:
    """A printed line with each quantity (a number, a value +- its std, a range from ... to ... or a change from
    ... -> ..., then its unit; "... against N" for a comparison in the same unit) in the unit system asked, each
    number to its digits."""
    if system != "si":
        return text
    return _QUANTITY.sub(lambda m: _quantity_in_si(m, gravity_mps2), text)


def _quantity_in_si(m: re.Match, gravity_mps2: float) -> str:
    label = m["unit"]
    while label and (label[-1] in ".," or label.count(")") > label.count("(")):  # the sentence's, not the unit's
        label = label[:-1]
    si = si_unit(label, gravity_mps2) if label else None
    if si is None or si[1] == label:
        return m[0]
    rest = m[0][m.start("unit") - m.start() + len(label):]
    if m["c"] is not None:
        rest = rest.replace(m["c"], _number_in(m["c"], si[0]))
    return (_number_in(m["a"], si[0]) + (f"{m['op']}{_number_in(m['b'], si[0])}" if m["b"] else "")
            + f" {si[1]}{rest}")


def _number_in(text: str, factor: float) -> str:
    """text's number times factor, to as many significant digits as text shows (at least 3: %g drops zeros)."""
    digits = len(re.sub(r"^[-+]?0*\.?0*", "", text.split("e")[0]).replace(".", "")) or 1
    v = float(text) * factor
    return ("+" if text.startswith("+") and v >= 0 else "") + f"{v:.{max(digits, 3)}g}"
