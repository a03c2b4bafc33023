"""A sequence whose every move turns 360 deg rests the unit at one attitude: the observability check (the
filter's first pass) names what it leaves unobserved and calibrate refuses it there, naming the fix; a filter
that diverges (a state or covariance not finite, or a negative variance) is refused at the pass, update, time
and move where it did, with the check's verdict, never as passes that "did not converge ... by nan"."""
from pathlib import Path

import numpy as np
import pytest

import simucal
from simucal import io
from simucal.errors import CalibrationError
from simucal.systematic.calibrate import divergence, run_filter
from simucal.systematic.method import refusal
from simucal.systematic.observability import INFLATION, observability
from simucal.turntable.sequence import Step, psins19, simulate_sequence
from simucal.turntable.simulate import Scenario
from tests.cli_helpers import refused, run

WHOLE_TURNS = [Step(a, 360.0, 60.0, 10.0) for a in ("inner", "middle", "outer") * 2]


def _set(steps, seed=0):
    sc = Scenario()
    sc.rate_hz = 100.0
    meta, samples, segments, truth = simulate_sequence(sc, steps, seed)
    return io.MeasurementSet(Path("whole_turns"), meta, samples, segments), truth


@pytest.fixture(scope="module")
def whole_turns():
    return _set(WHOLE_TURNS)


def test_whole_turns_are_refused_up_front_naming_the_unobserved_and_the_fix(tmp_path):
    seq = tmp_path / "whole.csv"
    seq.write_text("axis,angle_deg,rate_dps,rest_s\n" + "".join(f"{s.axis},360,60,10\n" for s in WHOLE_TURNS))
    assert run("simulate", "--sequence", seq, "-o", tmp_path / "s").exit_code == 0
    r = run("calibrate", tmp_path / "s", "--method", "systematic", "-o", tmp_path / "c.json")
    refused(r, "the sequence leaves acc ", "unobserved", "times its own", "rests all hold the unit at one attitude",
            "turn 90 or 180 deg")
    assert "nan" not in r.stderr and not (tmp_path / "c.json").exists()
    with pytest.raises(CalibrationError, match="unobserved.*one attitude.*90 or 180 deg"):
        simucal.calibrate(simucal.simulate(sequence=str(seq)), method="systematic")


def test_the_check_sees_the_collinear_states_whatever_the_noise(whole_turns):
    """Every std of the whole turns is under half its prior (the old rule saw none unobserved); the inflation
    names the accelerometers, while psins19 with a MEMS unit's noise (30 deg/h, 2e-4 g per sample) keeps every
    state seen."""
    ms, truth = whole_turns
    obs = observability(ms, truth=truth)
    rows = {f"{x['sensor']} {x['parameter']}": x for x in obs["parameters"]}
    assert all(x["ratio"] < 0.5 for x in rows.values())
    assert {f"acc {k}" for k in ("dK_z", "b_x", "b_y", "b_z")} <= set(obs["unobserved"])
    assert all(rows[k]["inflation"] > INFLATION for k in obs["unobserved"])
    noisy = Scenario()
    noisy.rate_hz, noisy.acc_noise_g, noisy.gyro_noise_dph = 100.0, 2e-4, 30.0
    meta, samples, segments, truth = simulate_sequence(noisy, psins19(rest_s=10.0), 0)
    seen = observability(io.MeasurementSet(Path("noisy"), meta, samples, segments), truth=truth)
    assert seen["unobserved"] == [] and max(x["inflation"] for x in seen["parameters"]) < 10


def test_a_diverged_filter_is_refused_where_it_diverged_with_the_verdict(whole_turns, tmp_path):
    ms, _ = whole_turns
    r = run_filter(ms)  # no stop at the first pass: the passes run until they diverge
    assert r.diverged.startswith(f"pass {r.passes}, the filter at update ") and "t = " in r.diverged
    assert "move" in r.diverged and not r.converged
    why = refusal(r, ms.path).why
    assert why.startswith("whole_turns: the filter diverged") and r.diverged in why
    assert "unobserved" in why and "turn 90 or 180 deg" in why and "nan" not in why
    with pytest.raises(CalibrationError, match="diverged"):
        simucal.diagnose(ms)


def test_divergence_names_the_first_bad_epoch():
    """A NaN planted in one epoch's covariance, or a negative variance, is named at its update and time."""
    ms, _ = _set(psins19(rest_s=5.0, rate_dps=60.0))
    r = run_filter(ms, max_passes=1)
    steps, segments = r.setting[0], [s for s in ms.segments if len(ms.rows(s.segment))]
    rests = sum(s.kind == "static" for s in segments)  # psins19 returns 6 times to earlier positions
    assert r.diverged == "" and rests == 19 and r.positions == rests - len(r.returns.update_at) == 13
    k = 40
    t = steps.t[np.flatnonzero(steps.zupt)[k - 1]]
    r.epochs[k].P[7, 7] = np.nan
    assert divergence(r.epochs, steps, segments, 1).startswith(f"pass 1, the filter at update {k} of "
                                                               f"{len(r.epochs) - 1} (t = {t:.1f} s")
    r.epochs[k].P[7, 7], r.epochs[k + 3].P_pred[9, 9] = 1.0, -1e-12
    assert f"update {k + 3} of" in divergence(r.epochs, steps, segments, 1)
    x_s = np.zeros((len(r.epochs), len(r.epochs[0].x)))
    x_s[: k + 1] = np.nan  # the smoother runs back: the last NaN is where it went wrong
    r.epochs[k + 3].P_pred[9, 9] = 1.0
    assert divergence(r.epochs, steps, segments, 2, x_s).startswith(f"pass 2, the smoother at update {k} of")
