"""A hand-placed session: a MEMS unit turned by hand through poses, no turntable (Tedaldi et al. 2014).

Run in an empty folder: ``python3 handheld.py`` (a few seconds). The session is simulated, so
the truth is known; each ``assert`` is a claim of the page.
"""
import numpy as np

import simucal

# 1. 30 s at rest, then 30 poses held 5 s each and joined by 3 s hand moves, recorded at 100 Hz in
#    raw counts (a 16-bit ADC resting near 32768), with no segments.csv: one continuous stream.
ms = simucal.simulate("handheld", seed=1)
ms.write("session")  # as `simucal simulate --scenario handheld -o session` writes it
truth = ms.truth
print(f"{len(ms.samples['t_s'])} samples, segments: {ms.segments}")
assert ms.segments is None

# 2. calibrate finds the poses itself, fits the accelerometer by the exact norm on each pose and
#    the gyro by matching the gravity directions before and after each move.
cal = simucal.calibrate(ms)
found = cal.details["static_detection"]["count"]
print(f"{cal.method}: {found} still stretches found; acc p = {cal.acc.p_value:.2g}, gyro p = {cal.gyro.p_value:.2g}")
assert found == 31 and cal.acc.p_value > 0.01 and cal.gyro.p_value > 0.01  # the rest and 30 poses; both pass

# 3. The gyro's T (rate = T (output - bias)) against the truth, entry by entry, in units of its std.
g = cal.to_json()["gyro"]
z = (np.array(g["T"]) - np.array(truth["gyro"]["T"])) / np.array(g["std"]["T"])
print(f"gyro model chosen by the moves left out: {g['gyro_model']}; T - truth in std: {np.round(z, 1).tolist()}")
assert np.all(np.abs(z) < 3)

# 4. Apply it to the raw stream: a numpy array of counts in, g and deg/h out (counts have no
#    physical unit). At the initial rest |f| is 1 g to the noise.
raw = ms.to_arrays()
x = np.column_stack([raw[c] for c in ("ax", "ay", "az", "gx", "gy", "gz")])
u = simucal.apply(cal, x)
rest = raw["t_s"] < 25.0
err_g = np.linalg.norm(u[rest, :3].mean(axis=0)) - 1.0
nominal_g = np.linalg.norm((x[rest, :3].mean(axis=0) - 32768.0) / 4096.0) - 1.0
print(f"|f| - 1 g at the rest: {err_g:.2g} g calibrated, {nominal_g:.2g} g at the nominal 4096 counts/g")
assert abs(err_g) < abs(nominal_g) / 10
