"""The loop on the filter: diagnose on the innovations (the model test, the candidates of
both sensors ranked on them), --add auto through the filter, and plan --sequence's observability."""
import json

import numpy as np
import pytest

import simucal
from simucal.systematic.calibrate import run_filter
from simucal.systematic.innovations import family_test, ranked
from simucal.turntable.sequence import AXES, psins19
from tests.cli_helpers import refused, run
from tests.test_systematic import REST_S, _sequence_file  # psins19 with 30 s rests: every parameter seen


@pytest.fixture(scope="module")
def short(tmp_path_factory):
    return _sequence_file(tmp_path_factory.mktemp("seq") / "psins19_30s.csv", psins19(rest_s=REST_S))


@pytest.fixture(scope="module")
def quadratic(tmp_path_factory, short):
    """A sequence of a unit with acc.quadratic.z = 2e-4 /g planted (written with truth.json)."""
    out = tmp_path_factory.mktemp("quadratic") / "set"
    assert run("simulate", "--sequence", short, "--effect", "acc.quadratic.z=2e-4", "--seed", 7, "-o",
               out).exit_code == 0
    return out


def _ranked(ms):
    test, sig = family_test(run_filter(ms))
    return test, ranked(test, sig)


@pytest.mark.slow
def test_diagnose_names_the_planted_effect_on_the_innovations(quadratic, tmp_path):
    r = run("diagnose", quadratic, "-o", tmp_path / "d.json", "--html", tmp_path / "d.html")
    assert r.exit_code == 0, r.output
    d = json.loads((tmp_path / "d.json").read_text())
    assert d["acc"]["model_test"]["p_value"] < 1e-3 and d["acc"]["model_test"]["test"].startswith("NIS")
    assert d["acc"]["model_test"]["targeted"]["strongest"] == "acc.quadratic.z"
    best = d["candidates"][0]
    assert best["id"] == "acc.quadratic.z" and best["significant"], best
    assert abs(best["estimate"] - 2e-4) < 3 * best["std"], best
    # one test for both sensors, one effect at a time: the gyro's verdict points at the accelerometer's
    assert not [c for c in d["gyro"]["candidates"] if c["significant"]]
    assert d["gyro"]["explained_by"]["id"] == "acc.quadratic.z" and "acc.quadratic.z" in d["gyro"]["verdict"]
    assert f"next: simucal calibrate {quadratic} --add acc.quadratic.z -o calibration.json" in r.output
    rows = d["acc"]["residuals"]
    test = d["acc"]["model_test"]  # one row per zero-velocity update; the returns' 3 dof each beside them
    returns = test["returns"]
    assert len(rows) == test["dof"] // 3 - returns and returns > 0 and {x["kind"] for x in rows} == {"static"}
    assert "acc.quadratic.z" in (tmp_path / "d.html").read_text()


@pytest.mark.slow
def test_diagnose_add_shows_the_fall_against_truth(quadratic, tmp_path):
    r = run("diagnose", quadratic, "--add", "acc.quadratic.z", "-o", tmp_path / "d.json")
    assert r.exit_code == 0, r.output
    added = json.loads((tmp_path / "d.json").read_text())["acc"]["added"]
    assert added["p_value_before"] < 1e-3 < added["p_value_after"]
    assert added["residual_rms_after"] < 0.1 * added["residual_rms_before"]
    q = added["params"]["acc.quadratic.z"]
    assert q["before"] is None and abs(q["error_after"]) < 3 * q["std_after"]
    assert all(abs(v["error_after"]) < 3 * v["std_after"] for v in added["params"].values()), added["params"]


@pytest.mark.slow
def test_add_auto_through_the_filter(quadratic, tmp_path):
    r = run("calibrate", quadratic, "--add", "auto", "-o", tmp_path / "c.json")
    assert r.exit_code == 0, r.output
    cal = simucal.load(tmp_path / "c.json")
    steps = cal.acc.details["auto"]
    assert [s["id"] for s in steps] == ["acc.quadratic.z"] and cal.gyro.details["auto"] == []
    assert steps[0]["p_value_after"] > 1e-3 and steps[0]["p_held_out_better"] < 0.01  # the updates predicted better
    effect = cal.acc.effects["acc.quadratic.z"]
    assert abs(effect.value - 2e-4) < 3 * effect.std
    assert cal.acc.verdict == "passes" and cal.acc.details["auto_stopped"] == "the model passes its test"


@pytest.mark.slow
def test_a_planted_gyro_g_sensitivity_is_found(short):
    ms = simucal.simulate(sequence=short, seed=4, effects={"gyro.g_sensitivity.xz": 0.01})
    test, cands = _ranked(ms)
    assert test["p_value"] < 1e-3
    best = cands[0]
    assert best.id == "gyro.g_sensitivity.xz" and best.significant
    assert abs(best.estimate - 0.01) < 3 * best.std, best


SEEDS = 3


@pytest.mark.slow
def test_clean_sequences_pass_and_the_candidates_stds_hold(short):
    """Where the model is right, no candidate passes the gate, and each candidate's estimate (truth 0)
    over its std scatters as N(0, 1) over the candidates and seeds."""
    z = []
    for seed in range(200, 200 + SEEDS):
        test, cands = _ranked(simucal.simulate(sequence=short, seed=seed))
        assert test["p_value"] > 1e-3 and not [c for c in cands if c.significant]
        z += [c.estimate / c.std for c in cands if c.separable]
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert len(z) > 60 and 0.7 < rms < 1.3, rms


def test_plan_sequence_shows_each_parameter_beside_the_norm_crlb(short, tmp_path):
    r = run("plan", "--sequence", short, "-o", tmp_path / "p.json")
    assert r.exit_code == 0, r.output
    out = json.loads((tmp_path / "p.json").read_text())
    rows = out["observability"]["parameters"]
    assert len(rows) == 21 and out["observability"]["unobserved"] == [] and "every parameter observed" in r.output
    assert all(x["std"] < 1e-3 * x["prior_std"] for x in rows)
    crlb = out["norm"]["acc"]["crlb"]
    assert set(crlb) == {x["parameter"] for x in rows if x["sensor"] == "acc"}
    line = next(x for x in r.output.splitlines() if x.strip().startswith("acc b_z"))
    assert f"{crlb['b_z']:.3g}" in line


def test_plan_sequence_names_what_a_sequence_leaves_unobserved(tmp_path):
    outer_only = _sequence_file(tmp_path / "outer.csv", [s for s in psins19(rest_s=REST_S) if s.axis == AXES[0]])
    r = run("plan", "--sequence", outer_only)
    assert r.exit_code == 0, r.output
    line = next(x for x in r.output.splitlines() if x.startswith("UNOBSERVED"))
    assert "acc dK_z" in line and "acc b_z" in line and "gyro phi_zx" in line  # z always up: its scale and bias one
    refused(run("plan", "--sequence", "psins19", "--positions", 5), "--sequence", "--positions")
    refused(run("plan", "--sequence", tmp_path / "none.csv"), "none.csv")


FXFY = """from simucal.derive.frames import f_b
from simucal.derive.models import Term
from simucal.derive.models.baseline import ACC_BASELINE
MODELS = [ACC_BASELINE.with_terms("acc_fxfy_truth", [Term("K_xy", "z", f_b[0] * f_b[1], "g/g^2", "z reads f_x f_y")])]
"""


@pytest.mark.slow
def test_a_strong_effect_fails_the_model_where_the_omnibus_passes(short):
    """An effect at about 12 of its stds adds ~150 to a NIS of thousands of dof, inside the omnibus's
    tail; its targeted test (fit/family.py) fails the model, and calibrate advises it."""
    ms = simucal.simulate(sequence=short, seed=5, effects={"acc.cross_coupling.xy": 3e-4})
    cal = simucal.calibrate(ms, method="systematic")
    t = cal.acc.details["targeted"]
    assert cal.acc.details["omnibus_p_value"] > 1e-3 and cal.acc.verdict == "fails", t
    assert t["strongest"] == "acc.cross_coupling.xy" and t["p_value"] < t["level"] and "verdict" in t
    assert cal.acc.details["advice"] == cal.gyro.details["advice"] == "acc.cross_coupling.xy"
    auto = simucal.calibrate(ms, method="systematic", add="auto")
    assert list(auto.acc.effects) == ["acc.cross_coupling.xy"] and auto.acc.verdict == "passes"
    e = auto.acc.effects["acc.cross_coupling.xy"]
    assert abs(e.value - 3e-4) < 3 * e.std


@pytest.mark.slow
def test_an_effect_outside_the_library_is_said_so_on_a_sequence(short, tmp_path):
    """Acc z reading f_x f_y (no library effect has it). calibrate and diagnose say that no library
    effect explains the misfit, advise no --add, and --add auto keeps nothing (the parameters as without it)."""
    (tmp_path / "fxfy.py").write_text(FXFY)
    ms = simucal.simulate(sequence=short, seed=3, effect_file=str(tmp_path / "fxfy.py"), sets={"K_xy": 1e-3})
    cal = simucal.calibrate(ms, method="systematic")
    assert cal.acc.verdict == "fails" and cal.acc.details["advice"].startswith("no library effect explains the misfit")
    diag = simucal.diagnose(ms)
    d = diag.report
    assert not d["acc"].get("explained_by") and not d["gyro"].get("explained_by")
    for sensor in ("acc", "gyro"):
        assert "outside the library" in d[sensor]["verdict"] or "not in the library" in d[sensor]["verdict"], d[sensor]
    assert "--add" not in diag.next_command
    auto = simucal.calibrate(ms, method="systematic", add="auto")
    assert not auto.acc.effects and not auto.gyro.effects, auto.acc.details["auto_stopped"]
    for sensor in ("acc", "gyro"):
        assert getattr(auto, sensor).params == getattr(cal, sensor).params


def test_auto_leaves_out_an_effect_whose_filter_does_not_converge(monkeypatch, short):
    """--add auto's step with a candidate whose passes do not converge is refused as that step (said), not
    taken into a model that calibrate would then refuse whole."""
    from simucal.systematic import auto
    step = auto.FilterStep(simucal.simulate(sequence=short, seed=3), "acc_baseline", "gyro_baseline")
    real = auto.run_filter

    def stuck(*args, **kwargs):
        r = real(*args, **kwargs)
        r.step_std = 0.5
        return r
    monkeypatch.setattr(auto, "run_filter", stuck)
    assert "with acc.quadratic.z the filter's passes did not converge" in step.add("acc.quadratic.z")
