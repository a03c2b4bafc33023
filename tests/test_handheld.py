"""Hand-placed sessions: simulated with known truth, refusals, and the real recordings."""
from pathlib import Path

import numpy as np
import pytest

from simucal.api.calibrating import calibrate
from simucal.errors import CalibrationError
from simucal.handheld import moves_selection
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.io.importers import import_imu_tk

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


@pytest.mark.parametrize("seed", [1, 2])
def test_simulated_session_within_3_sigma(tmp_path, seed):
    truth = write_handheld(tmp_path / "h", HandheldScenario(clip_moves=2), seed)
    r = calibrate(tmp_path / "h").to_json()
    assert r["static_detection"]["count"] == 31
    acc_b_err = np.array(r["acc"]["bias"]) - truth["acc"]["bias"]
    std_b = np.array([r["acc"]["std"][k] for k in ("b_x", "b_y", "b_z")])
    assert np.all(np.abs(acc_b_err) < 3 * std_b)
    M = np.array(r["acc"]["M"])
    for (i, j), name in {(0, 0): "dK_x", (1, 1): "dK_y", (2, 2): "dK_z", (1, 0): "theta_yx", (2, 0): "theta_zx",
                         (2, 1): "theta_zy"}.items():
        assert abs(M[i, j] - truth["acc"]["M"][i][j]) < 3 * r["acc"]["std"][name], name
    T_err = np.array(r["gyro"]["T"]) - truth["gyro"]["T"]
    # 9 entries a seed: at 3 std one of 18 draws lands beyond it in 5 % of runs; 3.5 std keeps that under 1 %
    # (seed 1's T_zy is at 3.1 since the detector keeps turns out of the poses; tests/test_mems.py has the rms)
    assert np.all(np.abs(T_err) < 3.5 * np.array(r["gyro"]["std"]["T"]))
    bias_err = np.array(r["gyro"]["bias"]) / 3600 - truth["gyro"]["bias_dps"]
    assert np.all(np.abs(bias_err) < 3 * np.array(r["gyro"]["std"]["bias"]) / 3600)
    assert len(r["gyro"]["moves_skipped"]) == 2 and r["gyro"]["saturation"]  # clipped moves named, left out


@pytest.mark.slow
def test_clean_sessions_moves_chi2_per_dof_is_one(tmp_path):
    """The moves' noise floor is right: over 20 clean simulated sessions chi2/dof averages
    1.00 +- 0.05 (each session's std is about sqrt(2 / 51) = 0.2, so the mean's is 0.045)."""
    ratios = []
    for seed in range(20):
        write_handheld(tmp_path / str(seed), HandheldScenario(), seed)
        g = calibrate(tmp_path / str(seed)).to_json()["gyro"]
        ratios.append(g["chi2"] / g["dof"])
    assert abs(np.mean(ratios) - 1.0) < 0.05, (np.mean(ratios), ratios)


def test_the_scale_model_is_fitted_over_its_own_entries(tmp_path, monkeypatch):
    """The scale-only gyro model (T diagonal) converges in a few steps, its off-diagonal entries exactly
    nominal and not estimated. Held at nominal by a prior of std 1e-9 instead, its system had a
    condition number of 2e11 and it never converged (30 steps, the fit marked unconverged), so that
    model_choice could never take it."""
    from simucal.handheld import moves
    fits, fit = [], moves.fit_gyro_moves

    def recorded(mv, *args, **kwargs):
        fits.append((fit(mv, *args, **kwargs), tuple(kwargs.get("fixed", ()))))
        return fits[-1][0]
    monkeypatch.setattr(moves, "fit_gyro_moves", recorded)
    write_handheld(tmp_path / "h", HandheldScenario(gyro_effects={"gyro.g_sensitivity.zx": 500.0}), 3)
    choice = calibrate(tmp_path / "h", add=("auto",)).to_json()["gyro"]["model_choice"]
    scale = [f for f, fixed in fits if fixed == moves.GYRO_MODELS["scale"]]
    assert len(scale) == 3 and all(f.converged and f.iterations <= 5 for f in scale), [f.iterations for f in scale]
    off = list(moves.GYRO_MODELS["scale"])
    assert np.array_equal(scale[-1].T.ravel()[off], np.zeros(6)) and not scale[-1].cov[off].any()
    assert np.all(np.diag(scale[-1].cov)[[0, 4, 8]] > 0)
    assert (choice["full"]["held_out_rms_deg"] < choice["scale"]["held_out_rms_deg"]
            < choice["nominal"]["held_out_rms_deg"])


@pytest.mark.parametrize("model,planted,seed", [("scale", {}, 3), ("nominal", {"gyro.g_sensitivity.yz": 3000.0}, 1)])
def test_candidates_under_a_simpler_gyro_model_are_credited_with_their_own_share_alone(tmp_path, monkeypatch, model,
                                                                                       planted, seed):
    """Where a simpler gyro model is chosen (forced here) and fails, the candidates are ranked with the entries
    of T it leaves at nominal held so, as in the model. Scale, on a clean unit whose T has misalignments of up
    to 9e-3: with them freed in each trial fit, 18 of 33 candidates were significant at a statistic of ~360
    (the misalignments' share) and the calibration advised gyro.g_sensitivity.yx, which the unit does not
    have. Nominal, with a g-sensitivity planted: the bias stays free under the rest's prior (fixed at the
    rest's, it pinned the effect, which gravity moves there too, and gyro.scale_asymmetry.y was advised)."""
    from simucal.handheld import calibrate as handheld, moves
    ranked, choose = [], handheld.choose_gyro_model
    monkeypatch.setattr(handheld, "rank_move_candidates", lambda *a, **k: ranked.append(
        moves_selection.rank_move_candidates(*a, **k)) or ranked[-1])

    def forced(mv, g_dirs, bias_std, f_full, held=()):
        table = choose(mv, g_dirs, bias_std, f_full, held)[2]
        if model == "nominal":
            r = moves.move_residuals(np.eye(3), mv, g_dirs, jac=False, db=np.zeros(3), p=f_full.p * 0)[0]
            return (model, moves.GyroFit(np.eye(3), np.zeros(3), f_full.p * 0, r, np.zeros_like(f_full.cov), 0, True),
                    table)
        x0 = np.r_[f_full.T.ravel(), f_full.db, f_full.p]
        return model, moves.fit_gyro(mv, g_dirs, bias_std, x0, fixed=moves.GYRO_MODELS["scale"]), table
    monkeypatch.setattr(handheld, "choose_gyro_model", forced)
    write_handheld(tmp_path / "h", HandheldScenario(gyro_effects=planted), seed)
    gyro = calibrate(tmp_path / "h").to_json()["gyro"]
    assert gyro["p_value"] < 1e-6 and gyro["gyro_model"].startswith(model) and len(ranked) == 1, gyro["p_value"]
    if not planted:
        assert not any(c.get("significant") for c in ranked[0]), ranked
        assert max(c.get("statistic", 0.0) for c in ranked[0]) < 20 and gyro["advice"] is None
    else:
        (eid, value), = planted.items()
        top = ranked[0][0]
        assert gyro["advice"] == top["id"] == eid and abs(top["estimate"] - value) < 3 * top["std"], top


@pytest.mark.parametrize("settings,message", [
    (dict(poses=6), "positions for 9 parameters"),
    (dict(clip_moves=14, poses=14), "every move between poses holds saturated"),
    (dict(coplanar_poses=True), "unobservable"),
    (dict(dead_gyro_axis=1), r"gyro output y .* a dead or unconnected channel"),
    (dict(flip_gyro=True), "rotation sense contradicts the accelerometers"),
])
def test_refusals(tmp_path, settings, message):
    write_handheld(tmp_path / "h", HandheldScenario(**settings), 0)
    with pytest.raises(CalibrationError, match=message):
        calibrate(tmp_path / "h")


@pytest.mark.slow
def test_imu_tk_xsens_unattended(tmp_path):
    import_imu_tk(DATA / "imu_tk-xsens" / "xsens_acc.mat", DATA / "imu_tk-xsens" / "xsens_gyro.mat", tmp_path / "x",
                  4096.0, 6258 * np.pi / 180, 45.4, 9.81744)
    r = calibrate(tmp_path / "x").to_json()
    assert 36 <= r["static_detection"]["count"] <= 40  # about 38 intervals, found unattended
    assert r["gyro"]["moves_used"] >= 35
    # the nominal 1/6258 (rad/s)/count is 24 % off; the fit finds imu_tk's scale to 0.1 %
    scale = np.radians(np.diag(np.array(r["gyro"]["T"]))) / (6258 * np.pi / 180)
    assert np.allclose(scale, [2.09295e-4, 2.09899e-4, 2.09483e-4], rtol=2e-3)


@pytest.mark.slow
def test_diagnose_real_stream_says_honestly_what_it_finds(tmp_path):
    from simucal.api.diagnosing import diagnosis_report as diagnose
    import_imu_tk(DATA / "imu_tk-xsens" / "xsens_acc.mat", DATA / "imu_tk-xsens" / "xsens_gyro.mat", tmp_path / "x",
                  4096.0, 6258 * np.pi / 180, 45.4, 9.81744)
    d = diagnose(tmp_path / "x")
    assert d["acc"]["baseline"]["p_value"] < 1e-6  # real poses: more than noise
    assert len(d["acc"]["residuals"]) == d["acc"]["baseline"]["dof"] + 9
    if not any(c.get("significant") for c in d["candidates"]):
        assert "not in the library" in d["verdict"]
    g = d["gyro"]  # the moves: far above the white-noise floor of the rests, and it says so
    assert g["baseline"]["p_value"] < 1e-6 and g["baseline"]["residual_rms"] > 3 * g["baseline"]["noise_floor"]
    assert len(g["residuals"]) == 37 and g["candidates"][0]["separable"]
    assert "more is missing" in g["verdict"] or "not in the library" in g["verdict"]
    # the effects chosen one by one by --add auto's one rule (fit/selection.py: the gate, then the moves
    # left out predicted better) explain more than half the misfit; the rest is not the library's, and
    # it says why it stopped; calibrate carries them
    s = g["misfit_shares"]
    assert s["steps"] and all(x["id"].startswith("gyro.") and x["p_held_out_better"] < 0.05 for x in s["steps"])
    assert s["unexplained"] < 0.05 and s["steps"][-1]["residual_rms_after"] > 1.5 * g["baseline"]["noise_floor"]
    assert "the model still fails" in s["stopped"] and s["stopped"] in g["verdict"]
    assert " ".join(f"--add {e}" for e in s["effects"]) in g["verdict"]
    # a chosen effect with a twin says what would tell them apart in a hand session (moves to make), not
    # a turntable's `simucal plan` (the twin sentence of the norm fit, which the moves' selection shares)
    twins = [x["twin_choice"] for x in s["steps"] if x.get("twin_choice")]
    assert twins and all("moves that would" in t and "simucal plan" not in t for t in twins)
    r = calibrate(tmp_path / "x", add=tuple(s["effects"])).to_json()
    assert r["gyro"]["chi2"] == pytest.approx(s["steps"][-1]["chi2_after"], rel=1e-6)
    assert r["gyro"]["chi2"] < 0.5 * g["baseline"]["chi2"]


@pytest.mark.slow
def test_diagnose_moves_clean_and_with_a_planted_g_sensitivity(tmp_path):
    """A clean simulated session passes the moves' chi-square test with nothing declared missing; a
    planted y-gyro g-sensitivity (1000 (deg/h)/g along z) is found first, and adding it recovers its
    value and brings the residual down to the noise floor. With --add, the block's model test and
    candidates are those of the model with it, as on a turntable set (they were the model's without it:
    the added effect ranked first again, the test failing)."""
    from simucal.api.diagnosing import diagnosis_report as diagnose
    write_handheld(tmp_path / "clean", HandheldScenario(), 1)
    g = diagnose(tmp_path / "clean")["gyro"]
    assert g["baseline"]["p_value"] > 0.01 and not any(c.get("significant") for c in g["candidates"])
    write_handheld(tmp_path / "g", HandheldScenario(gyro_effects={"gyro.g_sensitivity.yz": 1000.0}), 1)
    top = diagnose(tmp_path / "g")["gyro"]["candidates"][0]
    assert top["id"] == "gyro.g_sensitivity.yz" and top["significant"]
    d = diagnose(tmp_path / "g", add=("gyro.g_sensitivity.yz",))
    a, test = d["gyro"]["added"], d["gyro"]["model_test"]
    assert test["p_value"] == a["p_value_after"] > 0.01 > a["p_value_before"] and "g_sensitivity.yz" in test["model"]
    assert "gyro.g_sensitivity.yz" not in [c["id"] for c in d["gyro"]["candidates"]]
    assert not any(c.get("significant") for c in d["gyro"]["candidates"])
    assert abs(a["params"]["G_yz"]["error_after"]) < 3 * a["params"]["G_yz"]["std_after"]
    assert a["residual_rms_after"] < 1.5 * d["gyro"]["baseline"]["noise_floor"] < a["residual_rms_before"] / 10
    assert abs(a["params"]["T_xx"]["error_after"]) < abs(a["params"]["T_xx"]["error_before"])


@pytest.mark.parametrize("eid,value", [("gyro.quadratic.x", 0.05), ("gyro.scale_asymmetry.y", 2e-3),
                                       ("gyro.g_sensitivity.zx", 500.0)])
def test_stream_effect_found_first_and_carried_by_calibrate(tmp_path, eid, value):
    """A rate-dependent scale (the fast turns of a hand session), a scale asymmetry and a
    g-sensitivity planted in a simulated session: diagnose ranks it first, calibrate --add
    recovers it within 3 sigma."""
    from simucal.api.diagnosing import diagnosis_report as diagnose
    write_handheld(tmp_path / "s", HandheldScenario(gyro_effects={eid: value}), 3)
    top = diagnose(tmp_path / "s")["gyro"]["candidates"][0]
    assert top["id"] == eid and top["significant"]
    e = calibrate(tmp_path / "s", add=(eid,)).gyro.effects[eid]
    assert abs(e.value - value) < 3 * e.std


def test_ferraris_sessions(tmp_path):
    from simucal.io.importers import import_ferraris_sections, import_imucal_annotated
    d = DATA / "imucal-ferraris"
    import_ferraris_sections(d / "example_ferraris_session.csv", d / "example_ferraris_session_list.json",
                             tmp_path / "ex", 102.4, 49.6)
    r = calibrate(tmp_path / "ex", method="multiposition")
    assert np.allclose(np.diag(r.gyro.M), 1, atol=0.05) and np.allclose(np.diag(r.acc.M), 1, atol=0.05)
    # imucal's annotated session turns +360 deg where imucal assumes -360: caught, not fitted into -I
    import_imucal_annotated(d / "annotated_session.csv", tmp_path / "an", 204.8, 2048.0, 16.4, 49.6)
    with pytest.raises(CalibrationError, match="turns opposite to the commanded rate in 3 of 3"):
        calibrate(tmp_path / "an", method="multiposition")
    import_imucal_annotated(d / "annotated_session.csv", tmp_path / "an2", 204.8, 2048.0, 16.4, 49.6, turn_deg=360.0)
    assert np.all(np.diag(calibrate(tmp_path / "an2", method="multiposition").gyro.M) > 0.9)


def test_stream_without_initial_rest_takes_its_threshold_from_the_quietest_stretch(tmp_path):
    write_handheld(tmp_path / "h", HandheldScenario(rest_s=0.5), 1)
    r = calibrate(tmp_path / "h")
    det = r.details["static_detection"]
    assert "quietest 3 s" in det["threshold_from"] and det["count"] >= 28


def test_too_few_turns_about_one_axis_calibrates_what_the_moves_determine(tmp_path):
    """Moves that never turn about z: the accelerometer and the rest of T within 3 sigma, T's z column
    held at nominal by the stated prior and named undetermined (with the move that would determine it)."""
    truth = write_handheld(tmp_path / "h", HandheldScenario(weak_axis=2), 3)
    r = calibrate(tmp_path / "h").to_json()
    und = r["gyro"]["undetermined"]
    assert sorted(und) == ["T_xz", "T_yz", "T_zz"]
    assert all(not v["determined"] and v["std_moves_alone"] > 0.05 and "about the z axis" in v["to_determine"]
               for v in und.values())
    T, sd = np.array(r["gyro"]["T"]), np.array(r["gyro"]["std"]["T"])
    assert np.all(np.abs(T - np.array(truth["gyro"]["T"])) < 3 * sd)
    assert np.all(sd[:, :2] < 0.01)  # the determined entries are determined
    M, b = np.array(r["acc"]["M"]), np.array(r["acc"]["bias"])
    std_b = np.array([r["acc"]["std"][k] for k in ("b_x", "b_y", "b_z")])
    assert np.all(np.abs(b - truth["acc"]["bias"]) < 3 * std_b)
    assert abs(M[0, 0] - truth["acc"]["M"][0][0]) < 3 * r["acc"]["std"]["dK_x"]


def test_ferraris_stream_without_its_section_list_gives_what_it_can(tmp_path):
    """imucal's example stream: six axis poses, no initial rest, no section list. The accelerometer's
    scales and biases come out, its misalignments are named undetermined (held at 0)."""
    from simucal.io.importers import import_ferraris
    import_ferraris(DATA / "imucal-ferraris" / "example_ferraris_session.csv", tmp_path / "f", 102.4, 49.6)
    r = calibrate(tmp_path / "f")
    assert sorted(r.acc.details["undetermined"]) == ["theta_yx", "theta_zx", "theta_zy"]
    assert np.allclose(np.diag(r.acc.M), 1, atol=0.05)  # as the section-list calibration finds
    assert all(r.acc.std[k] < 1e-2 for k in ("dK_x", "dK_y", "dK_z", "b_x", "b_y", "b_z"))


def test_gyro_fit_that_does_not_converge_is_refused(tmp_path, monkeypatch):
    from simucal.handheld import moves as handheld
    write_handheld(tmp_path / "h", HandheldScenario(), 0)
    real = handheld.fit_gyro_moves
    monkeypatch.setattr(handheld, "fit_gyro_moves", lambda *a, **k: real(*a, **{**k, "max_iter": 1, "step_tol": 1e-12}))
    with pytest.raises(CalibrationError, match="did not converge in 1 Gauss-Newton steps"):
        calibrate(tmp_path / "h")


def test_stream_with_no_long_enough_static_interval_is_refused(tmp_path):
    from simucal import io
    from simucal.handheld.static_detect import DetectSettings, detect_static
    write_handheld(tmp_path / "h", HandheldScenario(poses=8, rest_s=5.0), 0)
    ms = io.read_set(tmp_path / "h")
    with pytest.raises(CalibrationError, match="no static interval of at least 15 s found"):
        detect_static(ms.acc_g(), ms.samples["t_s"], DetectSettings(min_static_s=15.0))


def _direction_error_rad(tmp_path, acc_effects, add):
    """rms angle between the poses' gravity directions the moves are judged against and the truth,
    and the gyro block (a session with acc_effects planted, calibrated with add)."""
    from simucal import io
    from simucal.fit.augmented import AugmentedModel
    from simucal.handheld.gyro_moves import pose_directions
    from simucal.handheld.poses import acc_from_poses
    folder = tmp_path / str(len(acc_effects))
    truth = write_handheld(folder, HandheldScenario(acc_effects=acc_effects), 1)
    ms = io.read_set(folder)
    obs, _, am, fa, _, _ = acc_from_poses(ms, AugmentedModel("acc_baseline", add))
    u = pose_directions(am, obs, fa)[0]
    true = np.array(truth["pose_directions_b"])
    assert len(u) == len(true)
    err = np.arccos(np.clip(np.sum(u * true, axis=1), -1, 1))
    return float(np.sqrt(np.mean(err ** 2))), calibrate(folder, add=add).gyro


def test_moves_judged_against_the_whole_accelerometer_model(tmp_path):
    """An accelerometer effect added (acc.quadratic.z, planted) must enter the poses'
    gravity directions the gyro's moves are judged against (the exact fit's directions, not
    M^-1 (N - b)): with the affine inverse they were 1.1e-3 rad off (clean 1.4e-4) and the moves'
    chi2 470 on 51 dof; now both are at the clean session's level and the gyro passes."""
    clean, g0 = _direction_error_rad(tmp_path, {}, ())
    added, g1 = _direction_error_rad(tmp_path, {"acc.quadratic.z": 5e-3}, ("acc.quadratic.z",))
    assert added < 1.5 * clean < 5e-4, (added, clean)
    assert g1.p_value > 0.01 and g1.chi2 < 1.2 * g0.chi2, (g1.chi2, g0.chi2)


def test_stream_calibrate_names_what_diagnose_would_add(tmp_path):
    """On a stream a failing model's block carries `advice` (the effect diagnose would add), as on a
    turntable: the poses' from the one model test's ranking, the moves' from their forward selection."""
    write_handheld(tmp_path / "q", HandheldScenario(acc_effects={"acc.quadratic.z": 5e-3}), 1)
    assert calibrate(tmp_path / "q").acc.details["advice"] == "acc.quadratic.z"
    write_handheld(tmp_path / "g", HandheldScenario(gyro_effects={"gyro.g_sensitivity.yz": 1000.0}), 1)
    cal = calibrate(tmp_path / "g")
    assert cal.gyro.p_value < 1e-3 and cal.gyro.details["advice"] == "gyro.g_sensitivity.yz"
    assert cal.acc.details.get("advice") is None  # the accelerometer passes: nothing to add


@pytest.mark.slow
def test_xsens_moves_take_the_g_sensitivities_one_at_a_time(tmp_path):
    """docs/real-recordings.md: on imu_tk's Xsens session `--add auto` takes two g-sensitivities, then yz,
    whose moves left out are predicted better at p between 0.01 (the held-out level before the family test, where
    the selection stopped) and 0.05 (now), then yx; the four together lower the held-out rms by a third."""
    from simucal import io
    from simucal.fit.cross_validation import paired_improvement
    from simucal.fit.selection import HELD_OUT_ALPHA
    from simucal.handheld.gyro_moves import gyro_noise_dps, pose_directions, prepare_moves, regressor_inputs
    from simucal.handheld.moves import fit_gyro
    from simucal.handheld.moves_selection import MovesStep
    from simucal.handheld.poses import acc_from_poses
    import_imu_tk(DATA / "imu_tk-xsens" / "xsens_acc.mat", DATA / "imu_tk-xsens" / "xsens_gyro.mat", tmp_path / "x",
                  4096.0, 6258 * np.pi / 180, 45.4, 9.81744)
    ms = io.read_set(tmp_path / "x")
    p = acc_from_poses(ms)
    gm = prepare_moves(ms, p.det, *pose_directions(p.model, p.obs, p.fit))
    f = fit_gyro(gm.mv, gm.g_dirs, gm.bias_std)
    step = MovesStep(gm, regressor_inputs(ms, gm, f, (p.model, p.fit.vector(p.model.params))),
                     gyro_noise_dps(ms, gm), f)
    two = step.add("gyro.g_sensitivity.xz").add("gyro.g_sensitivity.zy")
    rms = lambda s: float(np.sqrt(np.mean(np.square(s.held_out()))))
    three = two.add("gyro.g_sensitivity.yz")
    p_yz = paired_improvement(two.held_out(), three.held_out())
    assert 0.01 < p_yz < HELD_OUT_ALPHA, p_yz
    four = three.add("gyro.g_sensitivity.yx")
    assert paired_improvement(three.held_out(), four.held_out()) < HELD_OUT_ALPHA
    assert rms(four) < 0.7 * rms(two)


def test_a_fit_that_converged_to_a_reversed_column_is_turned_upright():
    """The norm cannot tell M from M with a column reversed; a clean hand-placed session (seed 29) converged
    to ay reversed and was refused as a wiring fault. The fit turns such a column back (norm_fit._upright):
    the calibration goes through with every scale factor near its nominal sign and value."""
    from simucal import api
    cal = api.calibrate(api.simulate("handheld", seed=29))
    M = cal.acc.M
    assert np.all(np.abs(np.diag(M) - 1) < 0.05), M


def test_a_turn_about_the_vertical_is_no_pose(tmp_path):
    """A turn about the vertical leaves the accelerometers still: the accelerometer-only detector (Tedaldi's)
    took a 42 deg/s turn of a clean simulated session (seed 29) for part of two poses, and the moves, integrated
    between poses, failed their test (chi2 1511 on 51 dof; 9 of 200 clean sessions failed so). The gyro now
    vetoes a pose that turns (static_detect.gyro_limit: on a simulated session, whose poses are still, its limit is
    the rest's noise level)."""
    from simucal import api
    cal = api.calibrate(api.simulate("handheld", seed=29))
    det = cal.details["static_detection"]
    assert det["gyro_threshold_dps"] == det["gyro_limit"]["noise_dps"] < 1.0, det["gyro_limit"]
    assert det["gyro_limit"]["sway_dps"] < det["gyro_limit"]["noise_dps"] / 4
    assert cal.gyro.verdict == "passes" and cal.gyro.chi2 < 2 * cal.gyro.dof, (cal.gyro.chi2, cal.gyro.dof)
    # a bias drifting 3 deg/s over the session is no turn (each interval against its own median): every pose
    # is kept, and the drift is what the moves' test names
    from simucal.handheld.simulate import HandheldScenario, simulate_handheld
    from simucal.io import write_set
    meta, samples, _ = simulate_handheld(HandheldScenario(gyro_effects={"gyro.bias_drift_time.x": 36.0}), 5)
    write_set(tmp_path / "drift", meta, samples)
    cal = api.calibrate(tmp_path / "drift")
    assert cal.details["static_detection"]["count"] == 31 and cal.gyro.details["advice"] == "gyro.bias_drift_time.x"


def test_a_slow_move_is_no_part_of_a_pose():
    """A 3.9 deg move peaking at 2.4 deg/s (seed 927): at a fixed gyro limit of 1 deg/s (the limit is now the session's
    own) the poses on either side took 0.35 deg of it each, and the moves failed their test at chi2 186 on 51 dof (p =
    6e-17) on a clean session."""
    from simucal import api
    cal = api.calibrate(api.simulate("handheld", seed=927))
    assert cal.gyro.verdict == "passes" and cal.gyro.chi2 < 1.5 * cal.gyro.dof, (cal.gyro.chi2, cal.gyro.dof)


def test_a_calibration_keeps_no_moves_problem_alive():
    """The moves' candidate columns are kept per problem, not in a cache on the class (functools.cache on a
    method held every problem, its moves and columns, for the life of the process: 8 GB after 1,200 hand
    sessions in one benchmark)."""
    import gc

    from simucal import api
    from simucal.handheld.moves_selection import MovesProblem
    api.calibrate(api.simulate("handheld", seed=3))
    gc.collect()
    assert not [o for o in gc.get_objects() if isinstance(o, MovesProblem)]


@pytest.mark.parametrize("turn_s", [3.0, 8.0])
def test_a_long_turn_about_the_vertical_is_no_pose_either(turn_s):
    """A 30 deg/s turn about the vertical filling most of an accelerometer-still interval was
    taken for the interval's bias (its median) and kept as the pose. Every interval the detector keeps is still."""
    from simucal.handheld.static_detect import detect_static
    rng, fs, g, acc, gyro = np.random.default_rng(0), 100.0, np.array([0, 0, 1.0]), [], []
    for kind, dur, rate in (("still", 5, 0), ("tilt", 1, 0), ("still", 2, 0), ("yaw", turn_s, 30), ("still", 2, 0),
                            ("tilt", 1, 0), ("still", 5, 0)):
        n = int(dur * fs)
        if kind == "tilt":
            a = (np.linspace(0, 1, n)[:, None] * np.array([0.5, 0, 0]) + g
                 + 0.05 * np.sin(np.linspace(0, np.pi, n))[:, None])
            w, g = np.tile([20.0, 0, 0], (n, 1)), a[-1] / np.linalg.norm(a[-1])
        else:
            a, w = np.tile(g, (n, 1)), np.tile([0, 0, float(rate)], (n, 1))
        acc.append(a)
        gyro.append(w)
    acc = np.vstack(acc) + rng.normal(0, 1e-3, (sum(map(len, acc)), 3))
    gyro = np.vstack(gyro) + rng.normal(0, 0.05, acc.shape)
    d = detect_static(acc, np.arange(len(acc)) / fs, gyro_dps=gyro)
    assert len(d.starts) >= 4 and all(np.abs(gyro[a:b, 2]).mean() < 1.0 for a, b in zip(d.starts, d.ends))


def test_a_trial_s_decimation_from_its_base_is_the_whole_s():
    """moves.decimate with base (the moves' decimation less their last regressor, as each trial of a ranking adds
    one): the same numbers as decimating the whole, bit for bit."""
    from simucal.handheld.moves import Moves, decimate
    rng = np.random.default_rng(5)
    dt = np.where(np.arange(23) < [[23], [17], [9]], 0.01, 0.0)  # three moves, zero-padded
    y, phi = rng.normal(size=(3, 3, 23)) * (dt > 0), rng.normal(size=(2, 3, 23)) * (dt > 0)
    for before in (None, phi[:1]):
        mv = Moves(y, dt, np.arange(3), np.arange(1, 4), phi=phi if before is not None else phi[-1:],
                   phi_axes=(0, 2) if before is not None else (2,), phi_rest=np.zeros(2 if before is not None else 1))
        less = Moves(y, dt, mv.before, mv.after, phi=before, phi_axes=(0,) if before is not None else ())
        whole, trial = decimate(mv, 4), decimate(mv, 4, decimate(less, 4))
        for a, b in ((whole.y, trial.y), (whole.dt, trial.dt), (whole.phi, trial.phi)):
            assert np.array_equal(a, b)
        assert trial.phi_axes == mv.phi_axes
