"""What a designed sequence promises (`plan --sequence --design`: each parameter's std from one pass of the
linearised filter over it, simulated on the unit) is what the calibration achieves on it: the filter's reported
std and the errors' scatter over seeds, for a tactical and a MEMS unit. The design's pass is linearised about
the unit's truth, where the calibration's passes converge; about the nominal, a MEMS unit's calibrations on its
8-minute design reported 0.79-1.08 of the promise (gyro eta_z, acc dK_z), and a unit with 1e-2 scale errors
3.1 times gyro dK_z's on psins19's moves at 60 deg/s (systematic/observability.py)."""
from pathlib import Path

import numpy as np
import pytest

from simucal import io
from simucal.api.planning import reference_stds, sequence_stds
from simucal.systematic.method import calibrate_systematic
from simucal.systematic.observability import ETA, truth_start
from simucal.turntable import sequence_design
from simucal.turntable.sequence import simulate_sequence
from simucal.turntable.simulate import mems_unit, tactical_unit

MINUTES = 5.0        # the reference, psins19 as written (10 deg/s), needs 4.4 min with 5 s rests
EVALUATIONS = 19     # the built-ins and one round of changes: a design, not the best one
SEEDS = range(1, 6)  # seed 0 is the design's own simulation


def _designed(sc):
    """(the designed steps, each parameter's promised std, the rows naming them)."""
    sc.rate_hz = 100.0
    _, _, rows = reference_stds(sc, "psins19", MINUTES)
    target = np.array([r["std"] for r in rows])
    found = sequence_design.design(lambda steps: np.array([r["std"] for r in sequence_stds(sc, steps)]), MINUTES,
                                   target, 60.0, EVALUATIONS)
    return found.best.steps, found.best.std, rows


def _calibrated(sc, steps, rows, seed):
    """(each parameter's reported std, its error against the truth) of the steps simulated at seed and calibrated."""
    meta, samples, segments, truth = simulate_sequence(sc, list(steps), seed)
    cal = calibrate_systematic(io.MeasurementSet(Path(f"designed_{seed}"), meta, samples, segments))
    eta, eta_true = cal.gyro.details["eta_rad"], truth_start(truth)["eta"]
    std, err = [], []
    for r in rows:
        if r["parameter"] in ETA:
            j = ETA.index(r["parameter"])
            std.append(eta["std"][j])
            err.append(eta["value"][j] - eta_true[j])
        else:
            block = getattr(cal, r["sensor"])
            std.append(block.std[r["parameter"]])
            err.append(block.params[r["parameter"]] - truth[r["sensor"]]["params"][r["parameter"]])
    return np.array(std), np.array(err)


@pytest.mark.parametrize("unit", [tactical_unit, mems_unit], ids=["tactical", "mems"])
def test_the_design_promises_what_the_calibration_achieves(unit):
    sc = unit(0)
    steps, promised, rows = _designed(sc)
    runs = [_calibrated(sc, steps, rows, seed) for seed in SEEDS]
    std, err = np.array([s for s, _ in runs]), np.array([e for _, e in runs])
    ratio = std / promised
    # one computation: the filter's stds on other draws within 2 % (the MEMS design's promise about the nominal:
    # 0.87-1.07 of them, gyro eta_z and dK_x)
    assert np.all((ratio > 0.97) & (ratio < 1.03)), [(r["parameter"], q) for r, q in zip(rows, ratio.T)]
    scatter = float(np.sqrt(np.mean(np.square(err / promised))))  # all parameters and seeds together
    z = float(np.sqrt(np.mean(np.square(err / std))))
    assert 0.8 < scatter < 1.25 and z <= 1.3, (scatter, z)
    assert np.abs(err / std).max() < 4.5
