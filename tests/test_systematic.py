"""Systematic calibration. A rotation sequence simulated (simulate --sequence), the filter's
model held against its SymPy derivation, every parameter within 3 std of the truth, the stds against
the scatter over seeds, the innovations' test failing where an effect is planted and passing once it
is added, and bad input refused in one line."""
import json

import numpy as np
import pytest
import sympy as sp

import simucal
from simucal import io
from simucal.errors import CalibrationError
from simucal.generated import table
from simucal.turntable.sequence import AXES, psins19, read_sequence
from simucal.turntable.simulate import lever_arms_and_delay
from tests.cli_helpers import refused, run

REST_S = 30.0  # the tests' psins19: shorter rests than the built-in 100 s, every parameter still seen


def _sequence_file(path, steps):
    path.write_text("axis,angle_deg,rate_dps,rest_s\n" + "".join(
        f"{s.axis},{s.angle_deg!r},{s.rate_dps!r},{s.rest_s!r}\n" for s in steps))
    return path


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    return _sequence_file(tmp_path_factory.mktemp("seq") / "psins19_30s.csv", psins19(rest_s=REST_S))


def _truth_vector(truth, cal):
    return {s: np.array([truth[s]["params"][k] for k in cal[s]]) for s in ("acc", "gyro")}


def _z(cal, truth):
    """(estimate - truth) / std of every parameter of both blocks."""
    out = []
    for s in ("acc", "gyro"):
        block = getattr(cal, s)
        out += [(block.params[k] - truth[s]["params"][k]) / block.std[k] for k in block.params]
    return np.array(out)


def test_sequence_set_marks_rests_and_moves(tmp_path, short):
    r = run("simulate", "--sequence", short, "--seed", 1, "-o", tmp_path / "s")
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "s")
    kinds = [s.kind for s in ms.segments]
    assert kinds == ["static", "move"] * 18 + ["static"]
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    assert truth["gyro"]["params"] == simucal.simulate(sequence=short, seed=2).truth["gyro"]["params"]
    steps = read_sequence(short)
    for k, s in enumerate(ms.segments):
        rows = ms.rows(s.segment)
        # gravity in b where the commanded angles put it (within the table's and mounting errors)
        if s.kind == "static":
            C = table.C_k_n(*np.radians([s.outer_deg, s.middle_deg, s.inner_deg]), np.zeros(7))
            f = ms.acc_g()[rows].mean(0)
            assert np.degrees(np.arccos(f @ C[2] / np.linalg.norm(f))) < 0.5
        else:  # the gyro's integral over a move: the step's angle (its scale factors and mounting aside)
            turned = (ms.gyro_dph()[rows].sum(0) / 100.0 / 3600.0)
            assert abs(np.linalg.norm(turned) - abs(steps[k // 2].angle_deg)) < 0.5
    assert np.allclose(np.diff(ms.samples["t_s"]), 0.01)


@pytest.mark.parametrize("row, words", [
    ("inner,90,5000,10", ["line 2", "rate_dps 5000"]),
    ("sideways,90,10,10", ["line 2", "outer, middle, inner"]),
    ("inner,90,10,-1", ["line 2", "rest_s"]),
    ("inner,90,10,0.001", ["line 2", "rest_s 0.001", "shorter than one sample at 100 Hz"]),
])
def test_impossible_sequence_files_refused(tmp_path, row, words):
    path = tmp_path / "bad.csv"
    path.write_text("axis,angle_deg,rate_dps,rest_s\n" + row + "\n")
    refused(run("simulate", "--sequence", path, "-o", tmp_path / "out"), str(path), *words)


def test_a_rate_the_sample_rate_cannot_hold_refused(tmp_path):
    path = _sequence_file(tmp_path / "fast.csv", psins19(rest_s=REST_S, rate_dps=400.0))
    refused(run("simulate", "--sequence", path, "--rate-hz", "2", "-o", tmp_path / "out"), str(path), "line 2",
            "200 deg per sample", "--rate-hz above 4.44444")


def test_rests_too_short_for_the_noise_refused(tmp_path):
    """Rests of 5 samples: the filter cannot take the white noise from them; refused in one line."""
    path = _sequence_file(tmp_path / "brief.csv", psins19(rest_s=0.5))
    run("simulate", "--sequence", path, "--rate-hz", "10", "-o", tmp_path / "s")
    r = run("calibrate", tmp_path / "s", "--method", "systematic", "-o", tmp_path / "c.json")
    refused(r, "segments.csv", "no rest holds more than 10 samples")


@pytest.mark.slow
def test_filter_model_equals_its_derivation():
    """F assembled at run time (generated navigation blocks, the models' generated Jacobians) equals
    derive/systematic.error_state_model's F at random values, for the baseline and extended models."""
    from simucal.derive import systematic as d
    from simucal.derive.registry import BUILTIN
    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.aux_inputs import AuxInputs
    from simucal.systematic.filter import DV, Sensors, nav_blocks
    rng = np.random.default_rng(4)
    for acc, gyro in (BUILTIN[:2], BUILTIN[2:]):
        F_sym, _, H, states = d.error_state_model(acc, gyro)
        C = table.mounting(rng.normal(0, 1, 3))
        f_b, w_b, w_ie = rng.normal(0, 1, 3), rng.normal(0, 50, 3), rng.normal(0, 7e-5, 3)
        p_a, p_g, eta = (rng.normal(0, 1e-2, len(acc.params)), rng.normal(0, 1e-2, len(gyro.params)),
                         rng.normal(0, 1e-2, 3))
        t_s, temp_c = 12.5, 30.0
        sensors = Sensors(AugmentedModel(acc.name), AugmentedModel(gyro.name), p_a, p_g, eta)
        aux = AuxInputs({"t_s": np.array([t_s]), "temp_c": np.array([temp_c]), "t_ref_c": 25.0})
        D_a, D_g = sensors.sensitivities(f_b[None], w_b[None], aux, aux)
        F_nn, F_np = nav_blocks(C[None], f_b[None], D_a, D_g, w_ie, 9.8)
        F = np.block([[F_nn[0], F_np[0]], [np.zeros((len(states) - 6, len(states)))]])  # the constants' rows: 0
        f_d = table.mounting(eta) @ f_b
        values = {**dict(zip(d.C, C.ravel())), **dict(zip(d.f_b, f_b)), **dict(zip(d.w_b, w_b)),
                  **dict(zip(d.w_ie, w_ie)), d.g0: 9.8, **dict(zip(d.sensor_params(acc), p_a)),
                  **dict(zip(d.sensor_params(gyro), p_g)),
                  **dict(zip(d.eta, eta)), **{sp.Symbol(n, real=True): v for n, v in (
                      ("t_s", t_s), ("temp_c", temp_c), ("dtemp_c", temp_c - 25.0), ("w2", 0.0),
                      ("f_x", f_d[0]), ("f_y", f_d[1]), ("f_z", f_d[2]))}}
        F_ref = sp.lambdify([list(values)], F_sym, "numpy")(list(values.values()))
        assert F.shape == F_ref.shape == (len(states), len(states))
        assert np.allclose(F, F_ref, rtol=1e-9, atol=1e-15), np.abs(F - F_ref).max()
        assert np.abs(F[:6, 6:]).max() > 0  # the sensors' states reach the navigation errors
        assert np.array_equal(np.asarray(H, float), np.eye(len(states))[DV])  # the update's slice is H


def test_calibration_within_3_std_with_white_innovations(tmp_path, short):
    ms = simucal.simulate(sequence=short, seed=5)
    cal = simucal.calibrate(ms, method="systematic")
    z = _z(cal, ms.truth)
    assert len(z) == 18 and np.abs(z).max() < 3, z
    C_true = np.array(ms.truth["gyro"]["C_b_d"])
    eta_std = max(cal.gyro.details["eta_rad"]["std"])
    assert np.abs(cal.gyro.C_b_model - C_true).max() < 3 * eta_std
    assert np.allclose(cal.gyro.M, np.array(ms.truth["gyro"]["M"]), atol=3 * max(cal.gyro.std.values()))
    test = cal.details["systematic"]["test"]
    assert cal.acc.verdict == cal.gyro.verdict == "passes" and test["p_value"] > 1e-3
    assert np.abs(test["lag1_z"]).max() < 4  # white: lag-1 autocorrelation within 4 / sqrt(m)


def test_smoother_carries_the_constants_back(short):
    """The RTS smoother's parameters at the start equal the filter's at the end, and so do their
    covariances (constants), and its level at the start is known far better than the prior."""
    from simucal.systematic.calibrate import run_filter
    from simucal.systematic.filter import smooth
    r = run_filter(simucal.simulate(sequence=short, seed=6), max_passes=1)
    x_s, P_s = smooth(r.epochs)
    p = slice(6, len(r.prior_var))  # the constants (zero-position updates' clones after them are set on the way)
    sd = np.sqrt(np.diag(r.epochs[-1].P))[p]
    # equal in exact arithmetic (0.002 std apart here): P_k+1|k propagated sample by sample apart from
    # Phi_k+1's product (their round-off amplified by P_k+1|k^-1) had put them 0.55 std apart (acc
    # b_x, seed 6), and the velocity's reset left in x_k+1|N - x_k+1|k 0.009 std
    assert np.all(np.abs(x_s[0][p] - r.epochs[-1].x[p]) < 0.01 * sd)
    assert np.allclose(np.sqrt(np.diag(P_s[0]))[p], sd, rtol=1e-3)
    assert np.all(np.sqrt(np.diag(P_s[0]))[:2] < 0.1 * np.sqrt(r.prior_var[:2]))  # the level seen from the start
    assert np.array_equal(smooth(r.epochs, covariance=False)[0], x_s)


@pytest.mark.slow
def test_planted_effect_fails_the_test_and_passes_once_added(short):
    ms = simucal.simulate(sequence=short, seed=7, effects={"acc.quadratic.z": 2e-4})
    plain = simucal.calibrate(ms, method="systematic")
    assert plain.acc.verdict == "fails", plain.details["systematic"]["test"]
    added = simucal.calibrate(ms, method="systematic", add=["acc.quadratic.z"])
    effect = added.acc.effects["acc.quadratic.z"]
    assert added.acc.verdict == "passes" and abs(effect.value - 2e-4) < 3 * effect.std


def test_a_sequence_that_hides_parameters_is_refused(tmp_path):
    outer_only = _sequence_file(tmp_path / "outer.csv", [s for s in psins19(rest_s=REST_S) if s.axis == AXES[0]])
    run("simulate", "--sequence", outer_only, "-o", tmp_path / "s")
    r = run("calibrate", tmp_path / "s", "--method", "systematic", "-o", tmp_path / "c.json")
    refused(r, "unobserved", "dK_z")
    with pytest.raises(CalibrationError, match="method systematic takes a rotation sequence"):
        simucal.calibrate(simucal.simulate(seed=1, rate_hz=20), method="systematic")


def test_missing_latitude_refused(tmp_path, short):
    run("simulate", "--sequence", short, "-o", tmp_path / "s")
    meta = json.loads((tmp_path / "s" / "meta.json").read_text())
    del meta["latitude_deg"]
    (tmp_path / "s" / "meta.json").write_text(json.dumps(meta))
    refused(run("calibrate", tmp_path / "s", "--method", "systematic", "-o", tmp_path / "c.json"), "latitude")


SEEDS = 6  # 108 errors over std; benchmarks/bench_systematic.py runs 50 (docs/systematic.md)


@pytest.mark.slow
def test_stds_agree_with_the_scatter_over_seeds(short):
    """The filter's stds against the errors over seeds: rms(error / std) within 0.8-1.25."""
    from simucal.systematic.calibrate import run_filter
    z = []
    for seed in range(100, 100 + SEEDS):
        ms = simucal.simulate(sequence=short, seed=seed)
        r = run_filter(ms)
        truth = np.r_[[ms.truth["acc"]["params"][k] for k in r.sensors.acc.params],
                      [ms.truth["gyro"]["params"][k] for k in r.sensors.gyro.params]]
        z.append((r.sensors.vector()[:-3] - truth) / np.sqrt(np.diag(r.cov))[:-3])
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.8 <= rms <= 1.25, rms
    assert np.abs(z).max() < 4.5, np.abs(z).max()  # no parameter off by more than 108 normal draws allow


def test_a_move_segment_with_angles_or_a_rate_is_refused(tmp_path, short):
    run("simulate", "--sequence", short, "-o", tmp_path / "s")
    seg = tmp_path / "s" / "segments.csv"
    seg.write_text(seg.read_text().replace("\n2,move,,,,\n", "\n2,move,,,,10\n"))
    with pytest.raises(io.MeasurementSetError, match="line 3: a move segment has no commanded angles or rate"):
        io.read_set(tmp_path / "s")


def test_a_table_rate_error_reaches_the_norm_method_alone():
    """The comparison's poor table (benchmarks/bench_systematic.py): the rate runs' rate off by 1e-4
    puts exact's gyro M off by about as much, while systematic never reads the table's rates."""
    from pathlib import Path
    from simucal.turntable.simulate import Scenario
    from simucal.turntable.simulate import simulate as simulate_table
    errors = []
    for rate_error in (0.0, 1e-4):
        meta, samples, segments, truth = simulate_table(Scenario(rate_error=rate_error), 0)
        ms = io.MeasurementSet(Path("table1"), meta, samples, segments)
        assert truth["table"]["rate_error"] == rate_error
        errors.append(np.abs(simucal.calibrate(ms, method="exact").gyro.M - np.array(truth["gyro"]["M"])).max())
    assert errors[0] < 2e-5 and 0.7e-4 < errors[1] < 1.3e-4, errors




@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lever_arms_and_a_delay_are_estimated_within_3_std_and_without_them_the_model_fails(short, seed):
    """The accelerometers' lever arms and their delay behind the gyros, read from the body
    rate and its change the gyros give (fit/aux_inputs.motion); the simulator writes them by its own
    physics (turntable/forward.py). Without the states the model fails and names one of them (20 seeds
    of psins19 in docs/systematic.md)."""
    planted = lever_arms_and_delay(seed)
    ms = simucal.simulate(sequence=short, seed=seed, effects=planted)
    plain = simucal.calibrate(ms, method="systematic")
    assert plain.acc.verdict == "fails" and plain.acc.details["targeted"]["strongest"] in planted
    added = simucal.calibrate(ms, method="systematic", add=list(planted))
    assert added.acc.verdict == "passes", added.details["systematic"]["test"]
    z = {e: (added.acc.effects[e].value - v) / added.acc.effects[e].std for e, v in planted.items()}
    assert max(map(abs, z.values())) < 3.0, z


def test_the_body_rate_s_change_adds_up_to_each_move_s_change_of_rate():
    """aux_inputs.motion: a move's samples and the rest blocks on either side share the central differences so
    that sum(dw dt) over the steps is the move's whole change of rate (a rest block gets what spills into
    its first and last samples); a change taken over the blocks' centres instead loses part of it."""
    from simucal.fit.aux_inputs import motion
    dt = np.r_[1.0, np.full(40, 0.01), 1.0]               # a rest block, a move of 40 samples, a rest block
    w = np.r_[0.0, np.linspace(5.0, 200.0, 40), 0.0][:, None] * np.ones(3) * 3600.0  # deg/h
    m = motion(w, dt)
    total = sum(m[f"dwb_{a}"] * dt for a in "x")
    assert abs(total[1:-1].sum() + total[0] + total[-1]) < 1e-12  # the move returns to rest: no change in all
    ramp_up = (m["dwb_x"] * dt)[:21].sum()
    assert abs(ramp_up - np.radians(w[20, 0] / 3600.0 + w[21, 0] / 3600.0) / 2) < 1e-12
    blocks_centres = np.gradient(w[:, 0] * np.pi / 180 / 3600, np.cumsum(dt) - dt / 2)
    assert abs((blocks_centres * dt).sum()) > 1e-3  # what smoothing or the centres lost


def test_zero_position_updates_sharpen_the_heading_s_parameters_and_blunt_none():
    """Where the table returns to a position it held (psins19's inner and outer axes go
    round) and meta.json states its accuracy, each return is an attitude update against the first visit
    (systematic/zero_position.py): every std no worse, the z gyro's scale (seen through the heading, which
    zero-velocity updates see only through the Earth rate) 10 % better at a 4.5 arcsec table; none where
    the accuracy is not stated."""
    from simucal.systematic import calibrate as sc
    ms = simucal.simulate(seed=0, sequence="psins19", position_error_arcmin=0.02)
    on, off = sc.run_filter(ms), sc.run_filter(ms, zero_position=False)
    assert on.returns is not None and len(on.returns.update_at) >= 4 and off.returns is None
    ratio = np.sqrt(np.diag(on.cov) / np.diag(off.cov))
    assert ratio.max() < 1 + 1e-6, ratio
    assert ratio[len(on.sensors.p_acc) + list(on.sensors.gyro.params).index("dK_z")] < 0.9
    cal = simucal.calibrate(ms, method="systematic")
    assert "zero-position updates" in cal.details["systematic"]["zero_position"]["text"]
    unstated = io.MeasurementSet(ms.path, {k: v for k, v in ms.meta.items() if k != "table_accuracy_arcsec"},
                                 ms.samples, ms.segments)
    assert sc.run_filter(unstated, max_passes=1).returns is None


def test_the_returns_enter_the_model_test_and_a_table_claiming_too_much_fails_it():
    """The zero-position returns' innovations join the NIS (3 dof each): at the table's stated accuracy the model
    passes; a table that states 0.05 arcsec while it returns to within arcseconds fails it, which the
    zero-velocity innovations alone would not see."""
    from simucal.systematic import calibrate as sc
    from simucal.systematic.innovations import innovation_test
    ms = simucal.simulate(seed=2, sequence="psins19", position_error_arcmin=0.02)
    honest = innovation_test(sc.run_filter(ms).epochs)
    assert honest["returns"] >= 4 and honest["dof"] == 3 * (honest["updates"] + honest["returns"])
    assert honest["p_value"] > 1e-3 and "zero-position returns" in honest["test"]
    boast = io.MeasurementSet(ms.path, {**ms.meta, "table_accuracy_arcsec": 0.05}, ms.samples, ms.segments)
    claimed = innovation_test(sc.run_filter(boast).epochs)
    assert claimed["p_value"] < 1e-6 and claimed["nis_returns"] > 10 * 3 * claimed["returns"], claimed["nis_returns"]
    zero_velocity_only = claimed["nis"] - claimed["nis_returns"]
    assert zero_velocity_only < 3 * claimed["updates"] + 5 * np.sqrt(6 * claimed["updates"])
    cal = simucal.calibrate(boast, method="systematic")  # the advice names the cause, not a library effect
    assert cal.acc.verdict == "fails" and "disagree with meta.json's table_accuracy_arcsec" in cal.acc.details["advice"]


def test_the_signatures_composition_equals_the_filter_s():
    """innovations._navigation_pass composes each interval's steps by its E_k (the transition to the update) and
    sums E_k B_k: the same A, B and Q as the filter's tree (filter.compose), rests' one-step intervals and moves'
    long ones alike."""
    from simucal.systematic.filter import compose
    from simucal.systematic.innovations import _summed, _to_update
    rng = np.random.default_rng(3)
    m, ends = 40, np.array([0, 1, 9, 10, 25, 26, 39])
    A = np.eye(6) + 0.1 * rng.normal(size=(m, 6, 6))
    B, G = rng.normal(size=(m, 6, 5)), rng.normal(size=(m, 6, 6))
    Q = G @ np.swapaxes(G, 1, 2)
    A_u, B_u, Q_u = compose(A, B, Q, ends)
    E, starts = _to_update(A, ends), np.r_[0, ends[:-1] + 1]
    assert np.allclose(E[starts] @ A[starts], A_u, rtol=0, atol=1e-12)
    assert np.allclose(_summed(E, B, starts, ends), B_u, rtol=0, atol=1e-12)
    assert np.allclose(np.add.reduceat(E @ Q @ np.swapaxes(E, 1, 2), starts, axis=0), Q_u, rtol=0, atol=1e-11)


def test_the_factored_sensitivities_equal_the_filter_s():
    """innovations._factored: M J of each sensor is the filter's D (Sensors.sensitivities), candidates included."""
    from simucal.fit.augmented import AugmentedModel
    from simucal.fit.aux_inputs import AuxInputs
    from simucal.systematic.filter import Sensors
    from simucal.systematic.innovations import _factored
    rng = np.random.default_rng(4)
    acc = AugmentedModel("acc_baseline", ("acc.quadratic.z",))
    gyro = AugmentedModel("gyro_baseline", ("gyro.g_sensitivity.xz", "gyro.quadratic.x"))
    s = Sensors(acc, gyro, 1e-3 * rng.normal(size=len(acc.params)), 1e-2 * rng.normal(size=len(gyro.params)),
                1e-3 * rng.normal(size=3))
    f_b, w_b, aux = rng.normal(size=(50, 3)), 3e5 * rng.normal(size=(50, 3)), AuxInputs({"t_s": np.arange(50.0)})
    D_a, D_g = s.sensitivities(f_b, w_b, aux, aux)
    M_a, J_a, M_g, J_g = _factored(s, f_b, w_b, aux, aux)
    for D, MJ in ((D_a, M_a @ J_a), (D_g, M_g @ J_g)):
        assert D.shape == MJ.shape and np.allclose(MJ, D, rtol=1e-10, atol=1e-12 * np.abs(D).max())
