"""Systematic calibration: simulate a rotation sequence, calibrate, diagnose, add the effect, validate.

Run in an empty folder: ``python3 systematic.py`` (about a minute: the filter runs over the sequence
five times), on the Python API alone; each command line step is named beside its call (``simucal
plan``, ``simucal simulate``, ``simucal diagnose``). Each ``assert`` is a claim of the tutorial's page,
checked by the test suite.
"""
import simucal

# 1. Before recording: what the psins19 sequence lets the filter see (one pass of the linearised filter),
#    beside the norm method's CRLB on dong2018's Table 1 plan.
seen = simucal.sequence_observability("psins19")["observability"]  # simucal plan --sequence psins19
worst = max(seen["parameters"], key=lambda x: x["ratio"])
print(f"plan: every parameter observed; the least, {worst['sensor']} {worst['parameter']}, to "
      f"{worst['ratio']:.2g} of its prior std")
assert seen["unobserved"] == [] and worst["ratio"] < 1e-3

# 2. A unit with a hidden z accelerometer nonlinearity (2e-4 g/g^2) turned through psins19 (19 rests,
#    18 turns of 90 deg, raw samples at 100 Hz), and another recording of it through dong2018's sequence.
simucal.simulate(sequence="psins19", effects={"acc.quadratic.z": 2e-4}).write("seq")  # simucal simulate --sequence ...
simucal.simulate(sequence="dong2018", seed=2, effects={"acc.quadratic.z": 2e-4}).write("other")

# 3. The filter with the baseline models: its innovations fail their test (NIS far above 3 per update).
base = simucal.calibrate("seq", method="systematic")
test = base.details["systematic"]["test"]
print(f"baseline: NIS {test['nis_per_update']:.3g} per update (3 where the model is right), p = {test['p_value']:.2g}")
assert base.acc.verdict == "fails" and test["p_value"] < 1e-3

# 4. diagnose ranks every library effect on the innovations (their sensitivity to its parameter).
diagnosis = simucal.diagnose("seq")  # simucal diagnose seq -o diagnosis.json --html diagnosis.html
simucal.save("diagnosis.json", diagnosis)
simucal.save("diagnosis.html", diagnosis)
best = simucal.table_rows(diagnosis.candidates)[0]
print(f"diagnose: {best.id} = {best.estimate:.4g} +- {best.std:.2g} {best.unit}")
assert best.id == "acc.quadratic.z" and best.significant

# 5. The filter with that effect among its states: the innovations pass, the effect within 3 std of the truth.
cal = simucal.calibrate("seq", add=["acc.quadratic.z"])  # method auto: a sequence's is systematic
effect = cal.acc.effects["acc.quadratic.z"]
test = cal.details["systematic"]["test"]
print(f"with the effect: NIS {test['nis_per_update']:.3g} per update, p = {test['p_value']:.2g}; "
      f"acc.quadratic.z = {effect.value:.4g} +- {effect.std:.2g}")
assert cal.acc.verdict == "passes" and abs(effect.value - 2e-4) < 3 * effect.std


# 6. Both calibrations on the other recording, which neither saw: |f| - 1 g at each of its rests.
def norm_error_g(c):
    check = next(k for k in simucal.validate(c, "other").check_rows if k.sensor == "acc" and k.unit == "g")
    return check.nominal_rms, check.calibrated_rms, check.floor_rms


nominal, before, _ = norm_error_g(base)
_, after, floor = norm_error_g(cal)  # the floor: the noise and this calibration's own uncertainty
print(f"|f| - 1 g rms on dong2018's sequence: nominal {nominal:.2g} g, baseline {before:.2g} g, with the effect "
      f"{after:.2g} g (floor {floor:.2g} g)")
assert after < before / 10 < nominal and after < 2 * floor
