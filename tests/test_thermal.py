"""Thermal calibration over plateaus and temperature in the library (issue 26, items 1 and 2):
one unit simulated at three temperature plateaus with known polynomials, calibrated with
--thermal, recovered within 3 std, applied at an intermediate temperature on another plan
(at the noise floor, where one plateau's calibration is measurably worse), and the bad inputs
refused or warned in one line."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from simucal.calibrate import calibrate_thermal
from simucal.cli import main
from simucal.fit.thermal import fit_polynomial
from simucal.turntable.simulate import Scenario, plant, write

T_REF = 25.0
PLANTED = {"acc.bias_temperature.x": 2e-6, "acc.bias_temperature2.x": 5e-8, "acc.scale_temperature.z": 3e-6,
           "gyro.bias_temperature.z": 2e-3, "gyro.scale_temperature.x": 2e-6}


def _set(folder, T, seed, plan="fibonacci48", rate_hz=None):
    sc = Scenario(plan=plan, temp_c=(T, T), t_ref_c=T_REF, rate_hz=rate_hz)
    plant(sc, [f"{k}={v}" for k, v in PLANTED.items()])
    write(folder, sc, seed)
    return folder


@pytest.fixture(scope="module")
def plateaus(tmp_path_factory):
    root = tmp_path_factory.mktemp("thermal")
    sets = [_set(root / f"p{T}", T, seed, rate_hz=20) for T, seed in ((0.0, 1), (25.0, 2), (50.0, 3))]
    code, out = _run("calibrate", *sets, "--thermal", "--t-ref-c", T_REF, "-o", root / "cal.json", "--html",
                     root / "t.html")
    assert code == 0, out
    return root, sets, out


def _run(*args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    return r.exit_code, r.output


def test_polynomials_recovered_within_three_std(plateaus):
    root, sets, out = plateaus
    assert "b_x = " in out and "degree 2 chosen by the data" in out
    page = (root / "t.html").read_text()
    assert page.count("<img") >= 4  # b_x, dK_z, gyro b_z and dK_x against temperature
    assert "T_ref 25 degC" in page
    cal = json.loads((root / "cal.json").read_text())
    assert cal["t_ref_c"] == T_REF and cal["temperature_range_c"] == [0.0, 50.0]
    truth = json.loads((sets[1] / "truth.json").read_text())  # the unit at 25 degC = T_REF
    expect = {("acc", "b_x", 1): 2e-6, ("acc", "b_x", 2): 5e-8, ("acc", "dK_z", 1): 3e-6,
              ("gyro", "b_z", 1): 2e-3, ("gyro", "dK_x", 1): 2e-6}
    for (s, name, k), value in expect.items():
        f = cal[s]["thermal"]["parameters"][name]
        assert f["degree"] >= k and abs(f["coefficients"][k] - value) < 3 * f["std"][k], (s, name, f)
    for s in ("acc", "gyro"):  # c_0: the unit at T_ref
        for name, f in cal[s]["thermal"]["parameters"].items():
            assert abs(f["coefficients"][0] - truth[s]["params"][name]) < 4 * f["std"][0] + 1e-12, (s, name)
    unplanted = [n for s in ("acc", "gyro") for n, f in cal[s]["thermal"]["parameters"].items()
                 if (s, n) not in {(a, b) for a, b, _ in expect} and f["degree"] > 0]
    assert len(unplanted) <= 2  # 14 constant parameters tested at 1 %: a chance pick or two at most


def test_applied_between_plateaus_on_another_plan_reaches_the_noise_floor(plateaus):
    root, sets, _ = plateaus
    assert _run("calibrate", sets[1], "-o", root / "one.json")[0] == 0
    other = _set(root / "p35", 35.0, 7, plan="table1", rate_hz=20)
    for name in ("cal", "one"):
        code, out = _run("validate", root / f"{name}.json", other, "-o", root / f"v_{name}.json")
        assert code == 0, out
    v_th = json.loads((root / "v_cal.json").read_text())
    v_one = json.loads((root / "v_one.json").read_text())

    for s in ("acc", "gyro"):  # the first check: the norm, |f| - 1 g at rest, |w| - |w_T + w_e sin L| in rate runs
        th, one = v_th["checks"][s][0], v_one["checks"][s][0]
        assert th["verdict"] == "at the noise floor" and th["after_rms"] < 1.5 * th["floor_rms"], (s, th)
        assert one["after_rms"] > 5 * th["after_rms"], (s, one, th)  # one plateau: measurably worse


def test_apply_warns_outside_the_range_and_refuses_without_temp_c(plateaus, tmp_path):
    root, sets, _ = plateaus
    hot = _set(tmp_path / "hot", 70.0, 9)
    code, out = _run("apply", root / "cal.json", hot, "-o", tmp_path / "out")
    assert code == 0 and "WARNING" in out and "outside the calibrated 0 to 50 degC" in out
    meta = json.loads((tmp_path / "out" / "meta.json").read_text())
    assert "extrapolated" in meta["warnings"][0]
    cold = tmp_path / "notemp"
    write(cold, Scenario(plan="fibonacci48"), 5)
    code, out = _run("apply", root / "cal.json", cold, "-o", tmp_path / "out2")
    assert code == 2 and "no temp_c column" in out and not (tmp_path / "out2").exists()


def test_bad_plateaus_refused_in_one_line(plateaus, tmp_path):
    root, sets, _ = plateaus
    code, out = _run("calibrate", sets[0], "--thermal", "-o", tmp_path / "c.json")
    assert code == 2 and "two or more plateaus" in out
    write(tmp_path / "notemp", Scenario(plan="fibonacci48"), 5)
    code, out = _run("calibrate", sets[0], tmp_path / "notemp", "--thermal", "-o", tmp_path / "c.json")
    assert code == 2 and "no temp_c column" in out
    _set(tmp_path / "kelvin", 298.0, 6)
    code, out = _run("calibrate", sets[0], tmp_path / "kelvin", "--thermal", "-o", tmp_path / "c.json")
    assert code == 2 and "kelvin" in out
    _set(tmp_path / "same", 0.5, 6)
    code, out = _run("calibrate", sets[0], tmp_path / "same", "--thermal", "-o", tmp_path / "c.json")
    assert code == 2 and "too little" in out
    code, out = _run("calibrate", *sets[:2], "--thermal-degree", 2, "-o", tmp_path / "c.json")
    assert code == 2 and "degree 1" in out
    assert not (tmp_path / "c.json").exists()
    assert out.count("\n") == 1


def test_degree_chosen_by_the_chi2_drop():
    T = np.array([-20.0, 0.0, 20.0, 40.0, 60.0])
    std = np.full(5, 1e-3)
    lin = fit_polynomial(T, 0.5 + 0.01 * (T - 20), std, 20.0)
    assert lin["degree"] == 1 and abs(lin["coefficients"][1] - 0.01) < 1e-9
    flat = fit_polynomial(T, 0.5 + np.array([1, -1, 0.5, 0, -0.5]) * 1e-3, std, 20.0)
    assert flat["degree"] == 0
    forced = fit_polynomial(T, 0.5 + 1e-5 * (T - 20) ** 3, std, 20.0, degree=3)
    assert forced["degree"] == 3 and abs(forced["coefficients"][3] - 1e-5) < 1e-9


def test_one_model_at_every_plateau(plateaus, monkeypatch):
    """A plateau whose model differs (another effect added there) is refused, naming it."""
    import simucal.calibrate as c
    real, adds = c.calibrate, iter([(), ("acc.quadratic.z",), ()])
    monkeypatch.setattr(c, "calibrate", lambda ms, **kw: real(ms, **{**kw, "add": next(adds)}))
    with pytest.raises(c.CalibrationError, match="one model at every plateau"):
        calibrate_thermal(plateaus[1][:2])


def test_diagnose_names_a_scale_factor_following_temperature(tmp_path):
    """The issue's case: a z gyro scale factor linear in temperature, which the generic basis could
    not describe. Now the library has it and diagnose names it; the generic basis's input x
    temperature term is the same regressor (so a model file from it would be the library term)."""
    sc = Scenario(plan="fibonacci48", temp_c=(20.0, 40.0))
    plant(sc, ["gyro.scale_temperature.z=3e-6"])
    write(tmp_path / "s", sc, 2)
    code, out = _run("diagnose", tmp_path / "s", "-o", tmp_path / "d.json")
    assert code == 0, out
    d = json.loads((tmp_path / "d.json").read_text())
    best = d["gyro"]["candidates"][0]
    assert best["id"] == "gyro.scale_temperature.z" and best["significant"]
    assert abs(best["estimate"] - 3e-6) < 4 * best["std"]
    assert "gyro.scale_temperature.z" in d["gyro"]["verdict"]


def test_generic_input_times_temperature_is_the_library_term():
    from simucal.fit.aux_inputs import AuxInputs
    from simucal.fit.lack_of_fit import catalog_id, generic_terms
    from simucal.fit.norm_fit import Observations
    rng = np.random.default_rng(1)
    obs = Observations(rng.normal(size=(8, 3)), np.ones(8), None,
                       AuxInputs({"temp_c": rng.uniform(10, 40, 8), "t_ref_c": 25.0}))
    for sensor in ("acc", "gyro"):
        scale = [t for t in generic_terms(sensor, obs) if t.is_scale]
        assert [catalog_id(t) for t in scale] == [f"{sensor}.scale_temperature.{a}" for a in "xyz"]
        assert scale[0].unit() == "1/degC" and "dtemp_c" in scale[0].sympy()


def test_readme_gyro_model_file_example(tmp_path, monkeypatch):
    """The README's gyro model file (temperature terms from T_ref) plants, calibrates and is found."""
    from pathlib import Path
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    text = readme.split("# my_gyro.py\n", 1)[1].split("```", 1)[0]
    (tmp_path / "my_gyro.py").write_text(text)
    code, out = _run("simulate", tmp_path / "s", "--plan", "fibonacci48", "--column", "temp_c=10:40", "--effect-file",
                     tmp_path / "my_gyro.py", "--set", "kT3_z=1e-9", "--set", "Gt_xz=0.01")
    assert code == 0, out
    code, out = _run("calibrate", tmp_path / "s", "--add", tmp_path / "my_gyro.py", "-o", tmp_path / "c.json")
    assert code == 0, out
    g = json.loads((tmp_path / "c.json").read_text())["gyro"]
    for name, value in (("kT3_z", 1e-9), ("Gt_xz", 0.01)):
        assert abs(g["effects"][name]["value"] - value) < 4 * g["effects"][name]["std"]


def test_a_g_sensitivity_drifting_with_temperature_is_described_and_written(tmp_path, monkeypatch):
    """Outside the library: a gyro g-sensitivity changing with temperature. diagnose's generic basis
    (specific force times temperature) describes it, names its twin, and its model file passes."""
    from simucal.fit.lack_of_fit import catalog_id, generic_terms
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    (tmp_path / "gt.py").write_text(
        "from simucal.derive.frames import dtemp_c, f_b\nfrom simucal.derive.models import Term\n"
        "from simucal.derive.models.baseline import GYRO_BASELINE\nMODELS = [GYRO_BASELINE.with_terms('gyro_gt', "
        "[Term('Gt_xz', 'x', f_b[2] * dtemp_c, '(deg/h)/g/degC', 'x g-sensitivity drifting')])]\n")
    code, out = _run("simulate", tmp_path / "s", "--plan", "fibonacci48", "--column", "temp_c=10:40", "--effect-file",
                     tmp_path / "gt.py", "--set", "Gt_xz=0.01")
    assert code == 0, out
    code, out = _run("diagnose", tmp_path / "s", "-o", tmp_path / "d.json")
    assert code == 0, out
    shape = json.loads((tmp_path / "d.json").read_text())["gyro"]["shape"]
    found = {f"{shape['regressor']} on {shape['axis']}"} | set(shape["indistinguishable_here"])
    assert "f_z dtemp_c on x" in found and shape["unit"] == "(deg/h)/g/degC" and shape["catalog_id"] is None
    assert abs(abs(shape["estimate"]) - 0.01) < 0.002
    code, out = _run("calibrate", tmp_path / "s", "--add", tmp_path / "d_gyro_model.py", "-o", tmp_path / "c.json")
    assert code == 0, out
    assert json.loads((tmp_path / "c.json").read_text())["gyro"]["p_value"] > 1e-3


def test_review_findings_refused_or_right(plateaus, tmp_path):
    """A temperature effect added within each plateau (it would count the temperature twice), a model file
    that does not exist, --t-ref-c without temp_c and a hand-edited thermal section are refused in one
    line; validate knows a plateau of a thermal calibration as its own data."""
    root, sets, _ = plateaus
    code, out = _run("calibrate", *sets, "--thermal", "--add", "acc.bias_temperature.x", "-o", tmp_path / "c.json")
    assert code == 2 and "count it twice" in out
    code, out = _run("calibrate", *sets, "--thermal", "--add", tmp_path / "none.py", "-o", tmp_path / "c.json")
    assert code == 2 and "internal error" not in out and out.count("\n") == 1
    write(tmp_path / "notemp", Scenario(plan="fibonacci48"), 5)
    code, out = _run("calibrate", tmp_path / "notemp", "--t-ref-c", 20, "-o", tmp_path / "c.json")
    assert code == 2 and "no temp_c column" in out
    cal = json.loads((root / "cal.json").read_text())
    cal["acc"]["thermal"]["parameters"]["b_x"]["coefficients"][0] += 1e-3
    (tmp_path / "edited.json").write_text(json.dumps(cal))
    code, out = _run("apply", tmp_path / "edited.json", sets[0], "-o", tmp_path / "out")
    assert code == 2 and "edited by hand" in out
    code, out = _run("validate", root / "cal.json", sets[0], "-o", tmp_path / "v.json")
    assert code == 0 and not json.loads((tmp_path / "v.json").read_text())["independent"]
