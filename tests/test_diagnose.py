"""Diagnosis on simulated sets whose truth holds an effect the model lacks."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from simucal.cli import main
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.turntable.simulate import Scenario, write

RATES = (5.0, 10.0, -10.0, 20.0)
# (effect id, size, scenario settings rich enough to see it). Every case uses seed 11 except where
# noted: "p > 0.01 after adding" fails 1 % of the time under the null by construction, and seed 11's
# noise is such a draw for the size-effect plan (its clean set gives p = 0.008; 12 other clean seeds
# give p from 0.04 to 0.94).
SEEDS = {"acc.size_effect.yx": 13}
HIDDEN = [
    ("acc.quadratic.z", 5e-5, dict(plan="fibonacci48")),
    ("acc.cross_coupling.xy", 6e-5, dict(plan="fibonacci48")),
    ("acc.scale_asymmetry.x", 1.5e-4, dict(plan="fibonacci48")),
    ("acc.bias_drift_time.y", 3e-7, dict(plan="fibonacci48", shuffle=True)),
    ("gyro.quadratic.x", 2e-4, dict(plan="fibonacci24", outer_rate_dps=RATES)),
    ("gyro.scale_asymmetry.y", 2e-6, dict(plan="fibonacci24", outer_rate_dps=RATES)),
    ("gyro.bias_temperature.z", 3e-3, dict(plan="fibonacci24", outer_rate_dps=RATES, temp_c=(15.0, 45.0))),
    ("gyro.bias_drift_time.x", 2e-5, dict(plan="fibonacci24", outer_rate_dps=RATES, shuffle=True)),
    ("gyro.g_sensitivity.xz", 0.05, dict(plan="fibonacci24", outer_rate_dps=RATES)),
    ("acc.size_effect.yx", 0.005, dict(plan="fibonacci24", outer_rate_dps=(20.0, -20.0, 40.0))),
]


def base_errors(block, truth, sensor):
    t = truth[sensor]["params"]
    return np.array([abs(v["after"] - t[k]) / v["std_after"] for k, v in block["added"]["params"].items()
                     if k in t and "." not in k]), \
        np.array([abs(v["before"] - t[k]) / v["std_before"] for k, v in block["added"]["params"].items()
                  if k in t and "." not in k])


@pytest.mark.slow
@pytest.mark.parametrize("eid,size,settings", HIDDEN, ids=[h[0] for h in HIDDEN])
def test_hidden_effect_found_added_and_explained(tmp_path, eid, size, settings):
    sensor = eid.split(".")[0]
    sc = Scenario(**settings, **{f"{sensor}_effects": {eid: size}})
    truth = write(tmp_path / "set", sc, seed=SEEDS.get(eid, 11))
    d = diagnose(tmp_path / "set")
    block = d[sensor]
    assert block["baseline"]["p_value"] < 0.01, "the baseline should fail on this set"
    first = block["candidates"][0]
    # the right effect first, or a twin the report itself says this plan cannot tell from it
    assert first["significant"] and (first["id"] == eid or eid in (first.get("note") or "")), \
        [c["id"] for c in block["candidates"][:3]]
    assert d["candidates"][0]["id"] == first["id"]
    assert abs(first["estimate"] - size) < 4 * first["std"]
    after = diagnose(tmp_path / "set", add=[first["id"]])[sensor]
    assert after["baseline"]["p_value"] > 0.01
    assert after["baseline"]["residual_rms"] < 1.2 * after["baseline"]["noise_floor"]
    err_after, err_before = base_errors(after, truth, sensor)
    assert np.sqrt(np.mean(err_after ** 2)) < np.sqrt(np.mean(err_before ** 2))  # the other parameters improve


@pytest.mark.parametrize("eid,seed", [("gyro.g_sensitivity.xz", 1), ("gyro.g_sensitivity.xz", 3),
                                      ("gyro.g_sensitivity.zx", 2)])
def test_the_static_rows_choose_between_twins_of_the_rate_runs(tmp_path, eid, seed):
    """G_sensitivity.xz and .zx read alike in fibonacci24's rate runs (likelihood ratios
    within 0.1 of each other); by those alone the wrong one led at these seeds, and with it added the
    gyro failed at rest. The static rows choose: diagnose advises, and --add auto adds, the planted one,
    the model then passes, and both say which rows decided."""
    import simucal
    twin = {"gyro.g_sensitivity.xz": "gyro.g_sensitivity.zx", "gyro.g_sensitivity.zx": "gyro.g_sensitivity.xz"}[eid]
    write(tmp_path / "s", Scenario(plan="fibonacci24", outer_rate_dps=RATES, gyro_effects={eid: 0.05}), seed=seed)
    d = diagnose(tmp_path / "s")
    first = d["gyro"]["candidates"][0]
    rates = {c["id"]: c.get("statistic") for c in d["gyro"]["candidates"]}
    assert first["id"] == eid and twin in first["twins"] and abs(rates[eid] - rates[twin]) < 1.0
    assert first["at_rest"][eid]["chi2"] < first["at_rest"][twin]["chi2"]
    assert f"{eid}, not its twin {twin}" in d["gyro"]["verdict"] and "static positions chose it" in d["gyro"]["verdict"]
    cal = simucal.calibrate(tmp_path / "s", add=["auto"])
    step, = cal.gyro.details["auto"]
    assert step["id"] == eid and "static positions chose it" in step["twin_choice"]
    assert cal.gyro.p_value > 0.01 and cal.gyro.details["static_rows"]["p_value"] > 0.01
    assert cal.gyro.details["advice"] is None
    plain = simucal.calibrate(tmp_path / "s")  # calibrate's own advice, with nothing added
    assert plain.gyro.details["advice"] == eid


def test_g_sensitivity_collinear_with_one_rate_sign(tmp_path):
    write(tmp_path / "s", Scenario(gyro_effects={"gyro.g_sensitivity.xz": 0.05}), seed=4)
    d = diagnose(tmp_path / "s")
    c = next(c for c in d["gyro"]["candidates"] if c["id"] == "gyro.g_sensitivity.xz")
    assert not c["separable"] and "both signs" in c["note"]


@pytest.mark.slow
def test_clean_sets_declare_nothing_beyond_nominal_rate(tmp_path):
    declared = 0
    seeds = 30
    for seed in range(seeds):
        write(tmp_path / f"c{seed}", Scenario(), seed=100 + seed)
        d = diagnose(tmp_path / f"c{seed}")
        declared += any(c.get("significant") for c in d["candidates"])
    # nominal rate 1 %: four or more of 30 has probability below 3e-4 if the test holds its level
    assert declared <= 3, declared


@pytest.mark.slow
def test_cli_diagnose_writes_json_and_html(tmp_path):
    write(tmp_path / "s", Scenario(plan="fibonacci48", acc_effects={"acc.quadratic.z": 5e-5}), seed=2)
    res = CliRunner().invoke(main, ["diagnose", str(tmp_path / "s"), "-o", str(tmp_path / "d.json"),
                                    "--html", str(tmp_path / "r.html"), "--add", "acc.quadratic.z"])
    assert res.exit_code == 0, res.output
    d = json.loads((tmp_path / "d.json").read_text())
    for key in ("baseline", "candidates", "verdict"):
        assert key in d
    for key in ("residual_rms", "noise_floor", "p_value"):
        assert key in d["baseline"]
    c = d["candidates"][0]
    for key in ("effect", "axis", "estimate", "std", "statistic", "p_value", "residual_rms_after"):
        assert key in c
    html = (tmp_path / "r.html").read_text()
    assert html.count("data:image/png;base64,") >= 5 and "http" not in html.split("<body>")[1]
    bad = CliRunner().invoke(main, ["diagnose", str(tmp_path / "s"), "--add", "acc.nonsense.z"])
    assert bad.exit_code != 0 and "unknown effect" in bad.output


def test_table_tilt_where_the_data_can_show_it(tmp_path):
    from simucal.turntable.simulate import ARCSEC
    tilt = 60 * ARCSEC
    write(tmp_path / "t", Scenario(plan="fibonacci48", tilt_rad=(tilt, 0.0), position_error_rad=2 * ARCSEC), seed=3)
    d = diagnose(tmp_path / "t")
    table = [c for c in d["acc"]["candidates"] if c["id"].startswith("table.")]
    first = table[0]
    assert first["id"] == "table.tilt.x" and first["significant"]
    assert abs(first["estimate"] - tilt) < 4 * first["std"]
    assert any(not c["separable"] and "collinear with the mounting" in c["note"] for c in table)
    # the paper's 5" tilt under 1' position errors: the data cannot show it, and nothing is declared
    write(tmp_path / "p", Scenario(), seed=3)
    d = diagnose(tmp_path / "p")
    assert not any(c.get("significant") for c in d["acc"]["candidates"] if c["id"].startswith("table."))


def test_twins_are_judged_by_the_fit_not_by_a_cosine():
    """fit/twins.py: two unit columns at a cosine of 0.995 are twins where the residual holds little of
    either (neither adds chi2 10.83, the test level, to the other), and told apart where it holds enough that the
    better one fits by more; orthogonal columns that both explain the misfit are never twins."""
    from simucal.fit.twins import CANNOT_TELL, told_apart, twins
    rng = np.random.default_rng(0)
    a = rng.normal(size=200)
    a /= np.linalg.norm(a)
    e = rng.normal(size=200)
    e -= (e @ a) * a
    e /= np.linalg.norm(e)
    b = 0.995 * a + np.sqrt(1 - 0.995 ** 2) * e
    assert abs(CANNOT_TELL - 10.828) < 1e-3
    assert not told_apart(a, b, 5.0 * a) and twins("a", {"a": a, "b": b}, 5.0 * a) == ["b"]
    assert told_apart(a, b, 300.0 * a)  # (1 - 0.995^2) * 300^2 = 898 between their fits
    assert twins("a", {"a": a, "b": b}, 1.0 * a) == []  # a explains nothing beyond the noise
    assert told_apart(a, e, 6.0 * a + 6.0 * e)  # both needed: each adds 36 to the other


@pytest.mark.parametrize("plan,seed", [("table1", 15), ("table1", 17), ("fibonacci48", 3), ("fibonacci48", 6)])
def test_the_wrong_twin_never_wins_silently(tmp_path, plan, seed):
    """acc.quadratic.z = 3e-4 and its twin acc.scale_asymmetry.z (`plan --score table1 --separate`: power
    0.01): on Table 1 the twin ranked first at seeds 15 and 17 (LR gaps 3.9 and 4.7) with no note while the
    twin rule stood at chi2 3.84; at the test level (10.83) the winner names its twin. On fibonacci48,
    which separates them (gaps 60-90), quadratic.z wins with no note (20 seeds each in the fix27 report)."""
    write(tmp_path / "s", Scenario(plan=plan, acc_effects={"acc.quadratic.z": 3e-4}), seed=seed)
    first = diagnose(tmp_path / "s")["acc"]["candidates"][0]
    pair = {"acc.quadratic.z", "acc.scale_asymmetry.z"}
    assert first["id"] in pair and first["significant"]
    if plan == "table1":
        assert (pair - {first["id"]}) <= set(first.get("twins", ())) and "cannot tell it from" in first["note"]
        out = CliRunner().invoke(main,
                                 ["calibrate", str(tmp_path / "s"), "--add", "auto", "-o", str(tmp_path / "c.json")])
        assert f"--add auto chose {first['id']}, not its twin" in out.output  # never silently
    else:
        assert first["id"] == "acc.quadratic.z" and not first.get("twins")


@pytest.mark.parametrize("size,ramp,twin", [(2e-6, True, True), (2e-5, True, False), (2e-6, False, False)])
def test_temperature_and_time_twins_only_where_the_data_cannot_tell(tmp_path, size, ramp, twin):
    """On one temperature ramp a y bias following temperature and one drifting with
    time are twins while their likelihood ratios are within 10.83 (LR 82.5 and 84.0 at 2e-6 g/degC), and
    the note says the plan that would separate them (a temperature that goes up and down); ten times
    larger the ramp tells them apart (8450 against 8102), and a temperature that does not follow time
    tells them apart at the small size (bias_temperature first)."""
    settings = dict(temp_c=(15.0, 45.0)) if ramp else dict(columns={"temp_c": (15.0, 45.0)})
    write(tmp_path / "s", Scenario(plan="fibonacci48", acc_effects={"acc.bias_temperature.y": size}, **settings), 11)
    cands = {c["id"]: c for c in diagnose(tmp_path / "s")["acc"]["candidates"]}
    t, d = cands["acc.bias_temperature.y"], cands["acc.bias_drift_time.y"]
    assert t["significant"] and (d["statistic"] > 3.84) == ramp  # without the ramp time explains nothing
    assert ("acc.bias_drift_time.y" in t.get("twins", [])) == twin == (abs(t["statistic"] - d["statistic"]) < 10.83)
    if twin:
        assert "goes up and down" in t["note"] and "acc.bias_temperature.y" in d["twins"]
    elif not ramp:
        assert t is next(iter(cands.values()))


@pytest.mark.parametrize("at_rest,chosen", [((34.3, 32.2), None), ((40.0, 20.0), "gyro.g_sensitivity.zx")])
def test_the_static_rows_choose_a_twin_only_beyond_the_twins_level(at_rest, chosen):
    """Two twins of the rate runs whose static-row chi-squares differ by 2.1: no twin is claimed, the ranking
    stands and the record says these data cannot tell them apart and which plan would; 20 apart: the static
    rows choose."""
    from simucal.turntable.model_test import choose_twin
    a, b = "gyro.g_sensitivity.xz", "gyro.g_sensitivity.zx"
    cands = [{"id": a, "significant": True, "twins": [b], "statistic": 245.9, "estimate": 1.0},
             {"id": b, "significant": True, "twins": [a], "statistic": 245.7, "estimate": 1.0}]

    class Judge:
        def with_effect(self, eid):
            return {"chi2": dict(zip((a, b), at_rest))[eid], "dof": 26, "p_value": 0.5, "positions": 26}
    choose_twin(cands, lambda: Judge())
    if chosen is None:
        assert cands[0]["id"] == a and "cannot tell" in cands[0]["twin_choice"]
        assert f"plan --score PLAN --separate {a},{b}" in cands[0]["twin_choice"]
    else:
        assert cands[0]["id"] == chosen and "static positions chose it" in cands[0]["twin_choice"]
