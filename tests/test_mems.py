"""MEMS units (issue 50, item 4): gyro biases near 0.5 deg/s, accelerometer biases near 50 mg, scale factors and
misalignments near 2e-2, MEMS noise. Systematic calibration on psins19: the filter starts from the first rest
and scales its priors to the unit (systematic/calibrate.start_from_rest); before, such a unit was refused as
unobserved or calibrated hundreds of thousands of stds off. And the exact method on a turntable plan."""
import numpy as np
import pytest

from simucal import io
from simucal.systematic.method import calibrate_systematic
from simucal.turntable.sequence import simulate_sequence
from simucal.turntable.simulate import Scenario


def mems_unit(seed):
    rng = np.random.default_rng(1000 + seed)
    sc = Scenario()
    sc.acc_unit, sc.gyro_unit = "g", "deg/h"
    shape = ("dK_x", "dK_y", "dK_z")
    sc.acc_params = {**{k: rng.normal(0, 2e-2) for k in shape + ("theta_yx", "theta_zx", "theta_zy")},
                     **{k: rng.normal(0, 0.05) for k in ("b_x", "b_y", "b_z")}}
    sc.gyro_params = {**{k: rng.normal(0, 2e-2) for k in shape + ("phi_yx", "phi_zx", "phi_zy")},
                      **{k: rng.normal(0, 1800.0) for k in ("b_x", "b_y", "b_z")}}
    sc.acc_noise_g, sc.gyro_noise_dph = 2e-4, 30.0
    return sc


@pytest.mark.slow
def test_mems_units_are_calibrated_within_their_stds(tmp_path):
    z = []
    for seed in range(6):
        sc = mems_unit(seed)
        meta, samples, segments, _ = simulate_sequence(sc, "psins19", seed)
        io.write_set(tmp_path / str(seed), meta, samples, segments)
        cal = calibrate_systematic(io.read_set(tmp_path / str(seed)))
        assert cal.acc.p_value > 1e-3 and cal.gyro.p_value > 1e-3
        for sensor, truth in (("acc", sc.acc_params), ("gyro", sc.gyro_params)):
            block = getattr(cal, sensor)
            z += [(block.params[k] - v) / block.std[k] for k, v in truth.items()]
    assert np.sqrt(np.mean(np.square(z))) < 1.3 and np.max(np.abs(z)) < 4.5, np.round(z, 2)


@pytest.mark.slow
def test_mems_units_on_a_table_by_the_exact_method(tmp_path):
    from simucal.calibrate import calibrate
    from simucal.turntable.simulate import write
    z = []
    for seed in range(8):
        sc = mems_unit(seed)
        sc.plan, sc.acc_noise_g, sc.gyro_noise_dph = "fibonacci24", 2e-5, 3.0  # averaged rows: each mean's noise
        write(tmp_path / str(seed), sc, seed)
        cal = calibrate(tmp_path / str(seed))
        for sensor, truth in (("acc", sc.acc_params), ("gyro", sc.gyro_params)):
            block = getattr(cal, sensor)
            assert block.p_value > 1e-3
            z += [(block.params[k] - v) / block.std[k] for k, v in truth.items()]
    assert np.sqrt(np.mean(np.square(z))) < 1.3 and np.max(np.abs(z)) < 4.5, np.round(z, 2)
