"""Units of the spec and their conversion to the calibration's units.

Calibrations work in g (accelerometers) and deg/h (gyros). Pulse and count
outputs are divided by the nominal scale factors of meta.json. Note
1 arcsec/s = 1 deg/h, so gyro pulse/s / (pulses per arcsec) is deg/h.
"""
import numpy as np

ACC_UNITS = ("g", "m/s^2", "pulse/s", "counts")
GYRO_UNITS = ("deg/h", "deg/s", "rad/s", "pulse/s", "counts")
DEFAULT_GRAVITY = 9.80665
DEFAULT_EARTH_RATE_DPH = 15.04107
SCALE_KEY = {("acc", "pulse/s"): "acc_pulses_per_g", ("acc", "counts"): "acc_counts_per_g",
             ("gyro", "pulse/s"): "gyro_pulses_per_arcsec", ("gyro", "counts"): "gyro_counts_per_dps"}


def check_meta(meta, path, error):
    for sensor, allowed in (("acc", ACC_UNITS), ("gyro", GYRO_UNITS)):
        key = f"{sensor}_unit"
        if key not in meta:
            raise error(path, None, f'"{key}" is required, one of {allowed}')
        if meta[key] not in allowed:
            raise error(path, None, f'"{key}" {meta[key]!r} is not a known unit; use one of {allowed}')
        skey = SCALE_KEY.get((sensor, meta[key]))
        if skey:
            v = meta.get(skey)
            if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) and x > 0 for x in v)):
                raise error(path, None, f'{key} is {meta[key]!r}, so "{skey}" must be three positive numbers')
    lat = meta.get("latitude_deg")
    if lat is not None and not (isinstance(lat, (int, float)) and -90 <= lat <= 90):
        raise error(path, None, f'"latitude_deg" must be a number in -90..90, got {lat!r}')


def gravity(meta):
    return float(meta.get("gravity_mps2", DEFAULT_GRAVITY))


def earth_rate_dph(meta):
    return float(meta.get("earth_rate_dph", DEFAULT_EARTH_RATE_DPH))


def acc_to_g(raw, meta):
    u = meta["acc_unit"]
    if u == "g":
        return raw
    if u == "m/s^2":
        return raw / gravity(meta)
    return raw / np.asarray(meta[SCALE_KEY[("acc", u)]], float)


def gyro_to_dph(raw, meta):
    u = meta["gyro_unit"]
    if u == "deg/h":
        return raw
    if u == "deg/s":
        return raw * 3600.0
    if u == "rad/s":
        return np.degrees(raw) * 3600.0
    if u == "pulse/s":
        return raw / np.asarray(meta["gyro_pulses_per_arcsec"], float)
    return raw / np.asarray(meta["gyro_counts_per_dps"], float) * 3600.0


def g_to_acc(f_g, meta):
    """Inverse of acc_to_g, for the simulator."""
    u = meta["acc_unit"]
    if u == "g":
        return f_g
    if u == "m/s^2":
        return f_g * gravity(meta)
    return f_g * np.asarray(meta[SCALE_KEY[("acc", u)]], float)


def dph_to_gyro(w_dph, meta):
    u = meta["gyro_unit"]
    if u == "deg/h":
        return w_dph
    if u == "deg/s":
        return w_dph / 3600.0
    if u == "rad/s":
        return np.radians(w_dph / 3600.0)
    if u == "pulse/s":
        return w_dph * np.asarray(meta["gyro_pulses_per_arcsec"], float)
    return w_dph / 3600.0 * np.asarray(meta["gyro_counts_per_dps"], float)
