"""Kalibr's imu.yaml from a `simucal noise` report (fit/allan_fit's terms): each sensor's white-noise density
and random walk in SI, continuous time, the largest over the three axes."""
from __future__ import annotations

import numpy as np

from simucal.errors import CalibrationError
from simucal.io import units

G0 = units.DEFAULT_GRAVITY  # m/s^2 per g: Kalibr's SI, not the site's gravity
RAD_PER_DEG = np.pi / 180.0

KALIBR = (("acc", "accelerometer", G0), ("gyro", "gyroscope", RAD_PER_DEG / units.DPH_PER_DPS))


def _random_walk_or_bound(axis) -> float | None:
    """K where seen, else its 95 % bound (Kalibr needs a random walk above zero); None where the
    record is too short to say."""
    k = axis["sheet"]["K"]
    return axis["terms"]["K"] if k["status"] == "seen" else axis["bounds"].get("K")


def kalibr_missing(report) -> list[str]:
    """What Kalibr's imu.yaml would lack (it requires both sensors' densities and random walks)."""
    missing = []
    for sensor, key, _ in KALIBR:
        if sensor not in report:
            missing.append(f"{key}_noise_density and {key}_random_walk (the recording has no {sensor} columns)")
            continue
        for a, ax in report[sensor]["axes"].items():
            if "stuck" in ax:
                missing.append(f"{key}_* ({sensor} {a} is {ax['stuck'].split(':')[0]})")
            elif ax["sheet"]["N"]["status"] != "seen":
                missing.append(f"{key}_noise_density ({sensor} {a} shows no white noise)")
            elif _random_walk_or_bound(ax) is None:
                missing.append(f"{key}_random_walk ({sensor} {a}: the record is too short to bound it, it needs "
                               f"{ax['sheet']['K']['needs_s']:.3g} s)")
    return missing


def kalibr_yaml(report) -> str:
    """Kalibr's imu.yaml (continuous-time densities in SI, the largest over the three axes); refused
    where incomplete (kalibr_missing)."""
    missing = kalibr_missing(report)
    if missing:
        raise CalibrationError(f"{report['data']}: Kalibr's imu.yaml would lack " + "; ".join(missing)
                               + ": record both sensors, still, long enough")
    out = ["# written by simucal noise from " + report["data"],
           "# white noise N and random walk K of the Allan fit; a random walk the record does not show",
           "# is given as its 95 % upper bound"]
    if report.get("temperature", {}).get("warning"):
        out.append("# WARNING: " + report["temperature"]["warning"])
    for sensor, key, to_si in KALIBR:
        ax = report[sensor]["axes"].values()
        out.append(f"{key}_noise_density: {max(a['terms']['N'] for a in ax) * to_si:.6e}")
        walks = [w for w in map(_random_walk_or_bound, ax) if w is not None]  # kalibr_missing refused a None
        out.append(f"{key}_random_walk: {max(walks) * to_si:.6e}")
    out.append(f"rostopic: /imu0\nupdate_rate: {report['gyro']['rate_hz']:.6g}")
    return "\n".join(out) + "\n"
