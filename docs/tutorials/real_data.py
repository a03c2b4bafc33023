"""Real recordings from other tools: imu_tk's Xsens session and imucal's Ferraris session.

Run from anywhere: ``python3 real_data.py [DATA]`` (a few seconds), where DATA holds
``imu_tk-xsens/`` and ``imucal-ferraris/`` (default: the ``shared/data`` folder beside the
repository; each has a README saying where the files come from). Each ``assert`` is a claim of the page.
"""
import sys
from pathlib import Path

import numpy as np

import simucal

DATA = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[3] / "shared" / "data"


# 1. imu_tk's Xsens session (Tedaldi et al. 2014): raw 16-bit counts, moved by hand, no turntable.
#    import writes a measurement set; the nominal scale factors are the sensor's (4096 counts/g) and
#    imu_tk's starting guess for the gyro (1/6258 (rad/s)/count = 109.2 counts per deg/s).
xsens = DATA / "imu_tk-xsens"
gyro_counts_per_dps = 6258 * np.pi / 180
simucal.import_recording("imu_tk", [xsens / "xsens_acc.mat", xsens / "xsens_gyro.mat"], "xsens",
                         acc_counts_per_g=4096, gyro_counts_per_dps=gyro_counts_per_dps, latitude_deg=45.4,
                         gravity_mps2=9.81744)  # simucal import imu_tk ... -o xsens
cal = simucal.calibrate("xsens")
poses = cal.details["static_detection"]["count"]
print(f"xsens: {poses} still stretches found unattended (the data's README counts 38)")
assert 36 <= poses <= 40

# 2. The gyro's scale in (rad/s)/count beside imu_tk's own calibration of the same session: within
#    0.2 % (the nominal 1/6258 is 24 % off).
ours = np.radians(np.diag(np.array(cal.to_json()["gyro"]["T"]))) / gyro_counts_per_dps
imu_tk = np.array([2.09295e-4, 2.09899e-4, 2.09483e-4])
print(f"gyro scale, (rad/s)/count: simucal {np.round(ours * 1e4, 5)} e-4, imu_tk {imu_tk * 1e4} e-4")
assert np.allclose(ours, imu_tk, rtol=2e-3)

# 3. Real moves hold more than T and a bias: the moves' chi-square is far above its dof. The
#    gyro's sensitivity to specific force (the six off-diagonal terms diagnose adds one by one,
#    `python3 benchmarks/bench_imu_tk.py`) brings it down by more than 30 times.
terms = [f"gyro.g_sensitivity.{a}" for a in ("xz", "zy", "yz", "yx", "zx", "xy")]
richer = simucal.calibrate("xsens", add=terms)
chi2 = [c.to_json()["gyro"]["chi2"] for c in (cal, richer)]
print(f"gyro moves: chi2 {chi2[0]:.0f} with T and bias, {chi2[1]:.0f} with the g-sensitivity")
assert chi2[1] < chi2[0] / 30

# 4. imucal's Ferraris session with its section list: six axis poses and three turns, the
#    Ferraris method (simucal's multi-position method on the imported poses and turns).
ferraris = DATA / "imucal-ferraris"
simucal.import_recording("imucal-ferraris", [ferraris / "example_ferraris_session.csv",
                                            ferraris / "example_ferraris_session_list.json"], "ferraris",
                         latitude_deg=49.6)  # simucal import imucal-ferraris ... -o ferraris
fer = simucal.calibrate("ferraris", method="multiposition")
print(f"ferraris: acc M diagonal {np.round(np.diag(fer.acc.M), 4)}, gyro M diagonal {np.round(np.diag(fer.gyro.M), 4)}")
assert np.allclose(np.diag(fer.acc.M), 1, atol=0.05) and np.allclose(np.diag(fer.gyro.M), 1, atol=0.05)
simucal.save("ferraris.json", fer)  # the file `simucal calibrate ferraris --method multiposition -o` writes
