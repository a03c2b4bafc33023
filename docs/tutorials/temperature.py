"""One unit over temperature: three plateaus calibrated as one fit, validated at a fourth temperature.

Run in an empty folder: ``python3 temperature.py`` (about ten seconds). Each ``assert`` is a claim
of the page.
"""
import simucal

# The unit's temperature effects (each in its term's unit, acting from T_ref = 25 degC).
EFFECTS = {"acc.bias_temperature.x": 1e-5, "acc.bias_temperature2.x": 1e-7, "acc.scale_temperature.z": 1e-5,
           "gyro.bias_temperature.z": 0.01, "gyro.scale_temperature.x": 2e-6}


def simulate(folder, temperature_c, plan, seed):
    """A turntable test at one chamber temperature that wanders +-0.3 degC (temp_c in samples.csv), as
    `simucal simulate -o FOLDER --temperature-c T --t-ref-c 25 --temperature-wander-c 0.3 --effect ...` writes it."""
    simucal.simulate(plan=plan, seed=seed, temperature_c=temperature_c, t_ref_c=25.0, temperature_wander_c=0.3,
                     effects=EFFECTS).write(folder)
    return folder


# 1. Plateaus at 0, 25 and 50 degC, and a check recording at 35 degC on another plan.
plateaus = [simulate(f"plateau_{t}", t, "fibonacci48", k) for k, t in enumerate((0, 25, 50))]
check = simulate("at_35", 35, "table1", 7)

# 2. A list of sets is a thermal calibration (`simucal calibrate ... --thermal`): one fit, every row
#    at its own temperature; each parameter gets the polynomial in temperature the data ask for.
thermal = simucal.calibrate(plateaus, t_ref_c=25.0)
following = sorted(f"{s}.{name}" for s in ("acc", "gyro")
                   for name, fit in getattr(thermal, s).thermal["parameters"].items() if fit["degree"])
print(f"thermal: acc p = {thermal.acc.p_value:.2g}, gyro p = {thermal.gyro.p_value:.2g}; "
      f"following temperature: {', '.join(following)}")
planted = sorted(f"{e.split('.')[0]}.{'b' if 'bias' in e else 'dK'}_{e[-1]}" for e in EFFECTS)  # b_x, dK_z, ...
assert thermal.acc.p_value > 0.01 and thermal.gyro.p_value > 0.01 and following == sorted(set(planted))
single = simucal.calibrate("plateau_25")  # what one plateau alone gives

# 3. Both on the 35 degC recording: the thermal calibration reaches the floor, the 25 degC one does not.
def norm_error(cal, sensor):
    return next(c for c in simucal.validate(cal, check).check_rows if c.sensor == sensor)


for sensor in ("acc", "gyro"):
    a, b = norm_error(thermal, sensor), norm_error(single, sensor)
    print(f"{a.what[:24]}: thermal {a.calibrated_rms:.2g}, 25 degC only {b.calibrated_rms:.2g}, "
          f"floor {a.floor_rms:.2g} {a.unit}")
    assert a.calibrated_rms < 2 * a.floor_rms < b.calibrated_rms
