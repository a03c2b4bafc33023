"""The noise of a still recording: Allan deviation and its IEEE 952 terms.

Run in an empty folder: ``python3 noise.py`` (a few seconds). The recording is written by hand
as a measurement set (meta.json and samples.csv, the data format's two required files), so this
is also how to bring a logger's file to simucal; each ``assert`` is a claim of the page.
"""
import json
from pathlib import Path

import numpy as np

import simucal

# 1. Ten minutes at 100 Hz of a unit at rest, level: white noise of a known density on every
#    channel (gyro: an angle random walk of 0.1 deg/sqrt(h); accelerometer: 50 ug/sqrt(Hz)).
rate_hz, seconds = 100.0, 600.0
arw_deg_sqrt_h, vrw_ug_sqrt_hz = 0.1, 50.0
rng = np.random.default_rng(1)
n = int(seconds * rate_hz)
gyro_dph = arw_deg_sqrt_h * 60 * np.sqrt(rate_hz) * rng.standard_normal((n, 3)) + [1.0, 2.0, 3.0]
acc_g = vrw_ug_sqrt_hz * 1e-6 * np.sqrt(rate_hz) * rng.standard_normal((n, 3)) + [0.0, 0.0, 1.0]

still = Path("still")
still.mkdir()
meta = {"format": "simucal.measurements/1", "latitude_deg": 45.0, "acc_unit": "g", "gyro_unit": "deg/h",
        "description": "a still unit, white noise only"}
(still / "meta.json").write_text(json.dumps(meta, indent=1))
table = np.column_stack([np.arange(n) / rate_hz, acc_g, gyro_dph])
np.savetxt(still / "samples.csv", table, delimiter=",", fmt="%.10g", comments="",
           header="t_s,ax,ay,az,gx,gy,gz")  # no segment column and no segments.csv: one stream

# 2. simucal noise: the overlapping Allan deviation of every channel and the IEEE 952 terms
#    fitted to it (generalised least squares with the Allan variance's own covariance).
noise = simucal.noise("still")  # simucal noise still -o noise.json --html noise.html
simucal.save("noise.json", noise)
simucal.save("noise.html", noise)
report = noise.report

# 3. The white noise comes back within 3 std of what was planted, on every axis; the terms not
#    planted are "not seen", each with the 95 % bound the record allows.
for sensor, planted in (("gyro", arw_deg_sqrt_h), ("acc", vrw_ug_sqrt_hz)):
    for axis, fit in report[sensor]["axes"].items():
        term = fit["sheet"]["N"]
        print(f"{sensor} {axis}: {term['value']:.4g} +- {term['std']:.2g} {term['unit']} (planted {planted})")
        assert abs(term["value"] - planted) < 3 * term["std"], (sensor, axis, term)
        others = {k: t for k, t in fit["sheet"].items() if k != "N"}
        assert all(t["status"] == "not seen" and t["bound_95"] > 0 for t in others.values()), others
print("not seen:", "; ".join(f"{t['name']} < {t['bound_95']:.2g} {t['unit']}"
                             for k, t in report["gyro"]["axes"]["x"]["sheet"].items() if k != "N"))
