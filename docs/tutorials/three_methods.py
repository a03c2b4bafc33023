"""One unit, three methods, one table: the norm-observation fit (dong2018's exact maximum likelihood), the
paper's linear regression (eq. 8, 12, 25-27 as printed) and the traditional multi-position method, side by
side in one vocabulary.

Run in an empty folder: ``python3 three_methods.py`` (a few seconds), on the Python API alone; it passes
``mypy --strict`` (tests/test_lint.py). Each ``assert`` is a claim of the tutorial's page.
"""
from typing import Literal

import numpy as np

import simucal

# 1. One simulated turntable test of a unit (dong2018's 12 positions and rate runs); truth.json's numbers
#    are in ms.truth, for scoring only.
ms = simucal.simulate(seed=1)

# 2. Calibrate it three ways. Each method fits its own parameters (dK_x, theta_yx, b_x; or M_xx, bias_x).
# method= is checked
methods: tuple[Literal["exact", "linear", "multiposition"], ...] = ("exact", "linear", "multiposition")
cals: dict[str, simucal.Calibration] = {m: simucal.calibrate(ms, method=m) for m in methods}
for m, cal in cals.items():
    acc = cal.sensor("acc")  # never None: a calibration without an accelerometer block says why
    print(f"{m}: acc chi2 {acc.chi2}, p = {acc.p_value}")

# 3. One table: every M entry and bias with its std, a column per method, all in the accelerometers'
#    frame (the multi-position method works in the table's, which the table turns into theirs).
table = simucal.compare(cals)
print(table.round(6).to_string())

# 4. The methods agree where they should: every accelerometer entry of the exact fit lies within 4 of the
#    multi-position method's stds of it, and the exact fit's stds are the smaller (it uses every row's
#    norm, not the commanded attitudes).
acc_rows = table.loc["acc"]
gap = (acc_rows["exact"] - acc_rows["multiposition"]).abs()
assert bool((gap <= 4 * np.hypot(acc_rows["exact std"], acc_rows["multiposition std"]) + 1e-15).all())
scales = acc_rows.loc[["M_xx", "M_yy", "M_zz"]]
assert bool((scales["exact std"] < scales["multiposition std"]).all())

# 5. Against the truth the simulator kept: the exact fit's scale factors within 4 std.
assert ms.truth is not None  # a simulated set's; a recording has none
true_M = np.asarray(ms.truth["acc"]["M"])
for i, name in enumerate(("M_xx", "M_yy", "M_zz")):
    z = (float(acc_rows.loc[name, "exact"]) - float(true_M[i, i])) / float(acc_rows.loc[name, "exact std"])
    print(f"{name}: exact {acc_rows.loc[name, 'exact']:.6f}, truth {true_M[i, i]:.6f}, z = {z:+.2f}")
    assert abs(z) < 4
