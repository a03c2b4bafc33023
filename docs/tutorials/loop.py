"""The loop on a turntable set: plant an effect, calibrate, diagnose, add it, validate.

Run in an empty folder: ``python3 loop.py`` (about ten seconds), on the Python API alone; each
command line step is named beside its call (``simucal simulate``, ``simucal diagnose``, ...). Each
``assert`` is a claim of the tutorial's page, checked by the test suite.
"""
import simucal

# 1. A unit with a hidden z accelerometer nonlinearity (2e-4 g/g^2), tested on 48 table positions,
#    and a second recording of the same unit on another plan (truth.json says what was planted).
simucal.simulate(plan="fibonacci48", effects={"acc.quadratic.z": 2e-4}).write("set")  # simucal simulate -o set ...
simucal.simulate(plan="table1", rate_hz=20.0, seed=2, effects={"acc.quadratic.z": 2e-4}).write("other")

# 2. The baseline model (scale factors, misalignments, biases) fails its chi-square test.
base = simucal.calibrate("set")
print(f"baseline: acc p = {base.acc.p_value:.2g}")
assert base.acc.p_value < 1e-3

# 3. diagnose ranks the library's effects by how much of the misfit each explains; what it suggests is data:
#    each effect with its estimate, std and statistic, and whether it can be added (no undecided twin).
diagnosis = simucal.diagnose("set")  # simucal diagnose set -o diagnosis.json
simucal.save("diagnosis.json", diagnosis)
suggestion = diagnosis.suggested[0]
print(f"diagnose: {suggestion.id} = {suggestion.estimate:.3g} +- {suggestion.std:.2g} {suggestion.unit} "
      f"(chi2 {suggestion.statistic:.0f}, twins: {', '.join(suggestion.twins) or 'none'})")
assert suggestion.id == "acc.quadratic.z" and suggestion.add

# 4. The next step is data too: the API's function and its keywords (diagnosis.next.command is the same step as
#    a command line). Run it: the model passes, and the effect is found within 3 std of the truth.
step = diagnosis.next
print(f"next: {step.call}   (command: {step.command})")
cal = getattr(simucal, step.function)("set", **step.options)
effect = cal.acc.effects["acc.quadratic.z"]
print(f"with the effect: acc p = {cal.acc.p_value:.2g}; acc.quadratic.z = {effect.value:.3g} +- {effect.std:.2g}")
assert cal.acc.p_value > 0.01 and abs(effect.value - 2e-4) < 3 * effect.std
simucal.save("calibration.json", cal)  # the file `simucal calibrate set --add ... -o` writes

# 5. Both calibrations on the other recording, which neither fit saw: |f| - 1 g at every static segment.
def norm_error_g(c):
    check = next(k for k in simucal.validate(c, "other").check_rows if k.sensor == "acc" and k.unit == "g")
    return check.nominal_rms, check.calibrated_rms, check.floor_rms


nominal, before, _ = norm_error_g(base)
_, after, floor = norm_error_g(cal)  # the floor: the noise and this calibration's own uncertainty
print(f"|f| - 1 g rms: nominal {nominal:.2g} g, baseline {before:.2g} g, with the effect {after:.2g} g "
      f"(noise floor {floor:.2g} g)")
assert after < before / 3 < nominal and after < 2 * floor

# 6. The parameter table (a pandas DataFrame where pandas is installed, else a list of rows; table_rows
#    gives rows either way): M and bias in one vocabulary for every method, the method's own names beside them.
for p in simucal.table_rows(simucal.parameters(cal))[:10]:
    own = p.own_name if isinstance(p.own_name, str) else "none: fixed by the model"  # a missing cell: NaN or None
    print(f"  {p.sensor:4} {p.name:16} {p.value:+.4g} +- {p.std:.2g} {p.unit} (the method's {own})")
