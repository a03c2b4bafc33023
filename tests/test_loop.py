"""The discovery loop: plant, see the misfit, add, calibrate with it, apply."""
import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.cli import main
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.fit.apply import apply
from simucal.io import calibration
from simucal.turntable.simulate import Scenario, write

PLANTED = {"acc.quadratic.z": 2e-4, "acc.cross_coupling.xy": 2e-4, "acc.scale_asymmetry.x": 1e-4,
           "acc.bias_drift_time.y": 1e-7, "acc.size_effect.xx": 0.05, "gyro.quadratic.y": 0.5,
           "gyro.scale_asymmetry.x": 1e-4, "gyro.bias_temperature.z": 0.01, "gyro.bias_drift_time.x": 1e-5,
           "gyro.g_sensitivity.xz": 0.3}


def rich(**kw):
    """A plan that separates every family: 48 directions, rates of both signs and two sizes,
    a temperature sweep, positions in random order."""
    return Scenario(plan="fibonacci48", outer_rate_dps=(10.0, -10.0, 20.0), temp_c=(20.0, 40.0), shuffle=True, **kw)


@pytest.mark.slow
@pytest.mark.parametrize("eid", list(PLANTED))
def test_planted_effect_found_and_carried_by_calibrate(eid, tmp_path):
    sensor = eid.split(".")[0]
    sc = rich()
    getattr(sc, f"{sensor}_effects")[eid] = PLANTED[eid]
    truth = write(tmp_path, sc, 1)
    assert truth[sensor]["effects"] == {eid: PLANTED[eid]}
    base = getattr(calibrate(tmp_path), sensor)
    assert base.p_value < 1e-3 and base.details["std_raw"]  # fails, stds inflated
    diag = diagnose(tmp_path)[sensor]
    # one model test (turntable/model_test.py): calibrate and diagnose fit the same rows, report the
    # same statistic and read their advice from the same ranking
    assert base.details["rows"] == diag["baseline"]["rows"] and base.dof == diag["baseline"]["dof"]
    assert base.p_value == pytest.approx(diag["baseline"]["p_value"], rel=1e-9, abs=1e-300)
    top = [c for c in diag["candidates"] if c.get("significant")][0]
    if top.get("twins_undecided"):  # no rows chose between the twins: calibrate names both and the plan, adds neither
        assert base.details["advice"].startswith(f"{top['id']} or ") and eid in base.details["advice"]
        assert "cannot tell apart" in base.details["advice"] and "--separate" in base.details["advice"]
    else:
        assert base.details["advice"] == top["id"]
    # the planted effect, or a twin this plan cannot tell from it
    assert top["id"] == eid or eid in top.get("note", ""), (top["id"], top.get("note"))
    cal = getattr(calibrate(tmp_path, add=(eid,)), sensor)
    e = cal.effects[eid]
    assert abs(e.value - PLANTED[eid]) < 3 * e.std
    assert cal.p_value > 1e-3 and "std_raw" not in cal.details
    assert e.unit and e.meaning


def _strip_noise(folder):
    meta = json.loads((folder / "meta.json").read_text())
    meta.pop("acc_noise_g"), meta.pop("gyro_noise_dph")
    (folder / "meta.json").write_text(json.dumps(meta))


def test_mixed_raw_and_averaged_rows_are_tested(tmp_path):
    """Raw static segments, one averaged row per rate run, no stated noise: the rate rows get a
    variance component, the test stays on, and a bias drift is declared."""
    sc = Scenario(rate_hz=20.0, static_s=5.0, shuffle=True, acc_effects={"acc.bias_drift_time.y": 1e-7})
    write(tmp_path / "raw", sc, 2)
    ms = io.read_set(tmp_path / "raw")
    kinds = {s.segment: s.kind for s in ms.segments}
    rows = {k: [] for k in ms.samples}
    for seg in np.unique(ms.samples["segment"]):
        m = ms.samples["segment"] == seg
        for k, v in ms.samples.items():
            rows[k].append(v[m].mean(keepdims=True) if kinds[seg] == "rate" else v[m])
    samples = {k: np.concatenate(v) for k, v in rows.items()}
    meta = {k: v for k, v in ms.meta.items() if k not in ("acc_noise_g", "gyro_noise_dph")}
    io.write_set(tmp_path / "mixed", meta, samples, ms.segments)
    d = diagnose(tmp_path / "mixed")
    assert d["acc"]["baseline"]["noise"]["rows_estimated"] > 0
    assert d["acc"]["baseline"]["p_value"] < 1e-3
    assert [c["id"] for c in d["acc"]["candidates"] if c.get("significant")][0] == "acc.bias_drift_time.y"


@pytest.mark.slow
def test_averaged_set_without_noise_declared_failing(tmp_path):
    write(tmp_path / "bad", rich(state_noise=False, acc_effects={"acc.quadratic.z": 3e-4}), 4)
    write(tmp_path / "ok", rich(state_noise=False), 4)
    bad, ok = diagnose(tmp_path / "bad"), diagnose(tmp_path / "ok")
    assert bad["acc"]["baseline"]["chi2"] is None  # no noise anywhere: the lack-of-fit F test decides
    assert bad["acc"]["baseline"]["p_value"] < 1e-3 and "does not explain" in bad["acc"]["verdict"]
    assert ok["acc"]["baseline"]["p_value"] > 1e-3 and "explains the data" in ok["acc"]["verdict"]


CUBIC = """from simucal.derive.frames import f_b
from simucal.derive.models import Term
from simucal.derive.models.baseline import ACC_BASELINE
MODELS = [ACC_BASELINE.with_terms("acc_cubic_truth", [Term("K3_x", "x", f_b[0] ** 3, "g/g^3", "x cubic")])]
"""


@pytest.mark.slow
def test_effect_outside_the_library_described_and_added(tmp_path):
    (tmp_path / "cubic.py").write_text(CUBIC)
    r = CliRunner().invoke(main, ["simulate", str(tmp_path / "set"), "--plan", "fibonacci48",
                                  "--effect-file", str(tmp_path / "cubic.py"), "--set", "K3_x=3e-4"])
    assert r.exit_code == 0, r.output
    out = tmp_path / "d.json"
    r = CliRunner().invoke(main, ["diagnose", str(tmp_path / "set"), "-o", str(out)])
    assert r.exit_code == 0, r.output
    shape = json.loads(out.read_text())["acc"]["shape"]
    assert (shape["axis"], shape["degree"], shape["regressor"]) == ("x", 3, "f_x^3")
    assert "odd in f_x" in shape["parity"] and abs(shape["estimate"] - 3e-4) < 0.2 * 3e-4
    model_file = tmp_path / "d_acc_model.py"
    assert model_file.is_file() and str(model_file) in r.output
    r = CliRunner().invoke(main, ["diagnose", str(tmp_path / "set"), "--add", str(model_file), "-o",
                                  str(tmp_path / "d2.json")])
    assert r.exit_code == 0, r.output
    after = json.loads((tmp_path / "d2.json").read_text())["acc"]
    assert after["baseline"]["p_value"] > 1e-3  # down to the floor
    assert after["added"]["residual_rms_after"] < 0.5 * after["added"]["residual_rms_before"]
    assert "->" in r.output and "g" in r.output  # before and after, with units


def test_apply_brings_rest_to_one_g(tmp_path):
    sc = Scenario(acc_unit="pulse/s", acc_effects={"acc.quadratic.z": 2e-4}, plan="fibonacci48")
    write(tmp_path / "set", sc, 5)
    cal = calibrate(tmp_path / "set", add=("acc.quadratic.z",))
    calibration.save(tmp_path / "cal.json", cal)
    back = calibration.load(tmp_path / "cal.json")
    meta, samples, segments = apply(back, tmp_path / "set")
    io.write_set(tmp_path / "applied", meta, samples, segments)
    ms = io.read_set(tmp_path / "applied")
    static = np.isin(ms.samples["segment"], [s.segment for s in ms.segments if s.kind == "static"])
    err = np.linalg.norm(ms.acc_g()[static], axis=1) - 1.0
    assert ms.meta["acc_unit"] == "g" and ms.meta["gyro_unit"] == "deg/h"
    assert np.sqrt(np.mean(err ** 2)) < 1.5 * sc.acc_noise_g
    # without the effect the rest is off by more than the noise
    _, s0, _ = apply(calibrate(tmp_path / "set"), tmp_path / "set")
    f0 = np.column_stack([s0[c] for c in ("ax", "ay", "az")])[static]
    assert np.sqrt(np.mean((np.linalg.norm(f0, axis=1) - 1) ** 2)) > 2 * sc.acc_noise_g


def test_apply_inverts_the_nonlinear_model_exactly(tmp_path):
    """Noise-free outputs of a model with effects come back as the true inputs."""
    from simucal.fit.augmented import AugmentedModel
    m = AugmentedModel("acc_baseline", ("acc.quadratic.z", "acc.cross_coupling.xy"))
    p = np.r_[np.random.default_rng(0).normal(size=9) * 1e-3, 3e-3, -2e-3]
    u = np.random.default_rng(1).normal(size=(50, 3))
    M, b = m.matrix_and_bias(p)
    from simucal.fit.apply import invert
    from simucal.io.calibration import EffectValue, SensorBlock
    block = SensorBlock("acc_baseline", M, b, "g", {e: EffectValue(v, 0.0, "", "") for e, v in zip(m.effects, p[9:])},
                        params=dict(zip(m.params, p)))
    from simucal.fit.aux_inputs import AuxInputs
    got = invert(block, "acc", m.output(u, p), AuxInputs(), "test")
    assert np.max(np.abs(got - u)) < 1e-12


@pytest.mark.parametrize("args,msg", [
    (["simulate", "{d}/x", "--effect", "quadratic=1"], "unknown effect"),
    (["simulate", "{d}/x", "--effect", "acc.quadratic.z"], "NAME=VALUE"),
    (["simulate", "{d}/x", "--rate-hz", "0"], "--rate-hz 0: must be > 0"),
    (["diagnose", "{set}", "--add", "ACC.QUADRATIC.Z", "-o", "{d}/d.json"], "did you mean acc.quadratic.z"),
    (["calibrate", "{set}", "--add", "quadratic", "-o", "{d}/c.json"], "unknown effect"),
    (["calibrate", "{set}", "-o", "{d}/missing/c.json"], "does not exist"),
    (["diagnose", "{set}", "-o", "{d}/d.json", "--html", "{d}/missing/r.html"], "does not exist"),
])
def test_bad_input_one_line_nothing_written(args, msg, tmp_path, paper_set):
    args = [a.format(d=tmp_path, set=paper_set[0]) for a in args]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2 and msg in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_apply_refuses_another_layout(tmp_path, paper_set):
    r = CliRunner().invoke(main, ["calibrate", str(paper_set[0]), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0 and "chi2" in r.output and "p =" in r.output
    other = tmp_path / "other"
    shutil.copytree(paper_set[0], other)
    meta = json.loads((other / "meta.json").read_text())
    meta["acc_pulses_per_g"] = [1.0, 1.0, 1.0]
    (other / "meta.json").write_text(json.dumps(meta))
    r = CliRunner().invoke(main, ["apply", str(tmp_path / "c.json"), str(other), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and "another sensor or unit" in r.output and not (tmp_path / "out").exists()


def test_stream_calibrate_carries_a_gyro_effect_and_applies(tmp_path):
    """A hand-placed stream: calibrate --add fits a gyro effect over the moves (planted
    G_yz = 1000 (deg/h)/g), reports the moves' chi-square, and apply reads the stream back."""
    from simucal.handheld.simulate import HandheldScenario, write_handheld
    write_handheld(tmp_path / "h", HandheldScenario(gyro_effects={"gyro.g_sensitivity.yz": 1000.0}), 1)
    base = calibrate(tmp_path / "h").to_json()
    cal = calibrate(tmp_path / "h", add=("gyro.g_sensitivity.yz",))
    e = cal.gyro.effects["gyro.g_sensitivity.yz"]
    assert abs(e.value - 1000.0) < 3 * e.std and e.unit == "(deg/h)/g"
    assert base["gyro"]["p_value"] < 1e-3 < cal.gyro.p_value and cal.gyro.dof > 0
    calibration.save(tmp_path / "c.json", cal)
    meta, samples, _ = apply(calibration.load(tmp_path / "c.json"), tmp_path / "h")
    assert meta["gyro_unit"] == "deg/h" and np.all(np.isfinite(samples["gx"]))


@pytest.mark.slow
def test_add_auto_chooses_the_planted_effects_and_nothing_on_clean_data(tmp_path):
    """calibrate --add auto: the library effects a failing model needs, one at a time; none where
    the model already passes."""
    sc = rich()
    sc.acc_effects["acc.quadratic.z"] = 2e-4
    sc.gyro_effects["gyro.bias_temperature.z"] = 0.02
    write(tmp_path / "s", sc, 2)
    r = calibrate(tmp_path / "s", add=("auto",)).to_json()
    for sensor, eid, value in (("acc", "acc.quadratic.z", 2e-4), ("gyro", "gyro.bias_temperature.z", 0.02)):
        assert [x["id"] for x in r[sensor]["auto"]] == [eid]
        e = r[sensor]["effects"][eid]
        assert abs(e["value"] - value) < 3 * e["std"] and r[sensor]["p_value"] > 1e-3
    write(tmp_path / "clean", rich(), 2)
    r = calibrate(tmp_path / "clean", add=("auto",)).to_json()
    assert r["acc"]["auto"] == [] and r["gyro"]["auto"] == [] and not r["acc"]["effects"]
