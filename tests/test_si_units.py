"""SI units on request: `--units si` on the commands that print numbers for a person, ``units="si"`` in the API.
Each SI number is the spec's times io/units.py's factor to the digits printed; the default output and every file
written are those of a run without the option; an unknown system is refused in one line naming the choices."""
import json
import math
import re

import numpy as np
import pytest

import simucal
from cli_helpers import refused, run
from simucal.handheld.simulate import write_still
from simucal.io import units
from simucal.turntable.simulate import Scenario, write

G, DPH = units.DEFAULT_GRAVITY, units.RAD_S_PER_DPH  # the sets below state no gravity_mps2: the standard
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?"


def _half_ulp(text: str) -> float:
    """Half a unit in the last digit printed of a number."""
    mantissa, _, exponent = text.lstrip("+-").partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (-decimals + int(exponent or 0))


def _agrees(si: str, spec: str, factor: float) -> bool:
    """The SI number printed is the spec's printed times factor, within both numbers' printed digits."""
    return math.isclose(float(si), float(spec) * factor, rel_tol=0,
                        abs_tol=_half_ulp(si) + _half_ulp(spec) * factor + 1e-300)


def _pairs(spec_out: str, si_out: str, spec_unit: str, si_unit: str):
    """(SI number, spec number) of each quantity printed before its unit, line by line in the same place."""
    pattern = lambda u: re.compile(rf"({NUMBER})(?: \+- ({NUMBER}))? {re.escape(u)}(?![\w/^*(])")
    out = []
    for a, b in zip(spec_out.splitlines(), si_out.splitlines(), strict=True):
        xs, ys = pattern(spec_unit).findall(a), pattern(si_unit).findall(b)
        assert len(xs) == len(ys), (a, b)
        out += [(y, x) for pair_x, pair_y in zip(xs, ys) for x, y in zip(pair_x, pair_y) if x]
    return out


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    d = tmp_path_factory.mktemp("si")
    write(d / "set", Scenario(), 1)
    write(d / "other", Scenario(), 2)
    write_still(d / "still", 600.0, 0.01, 0.1, 5 / 60, 50e-6, 0, False)
    return d


def test_calibrate_prints_si_as_the_spec_times_the_factor_and_writes_the_same_file(sets, tmp_path):
    spec = run("calibrate", sets / "set", "-o", tmp_path / "spec.json")
    same = run("calibrate", sets / "set", "-o", tmp_path / "spec2.json", "--units", "spec")
    si = run("calibrate", sets / "set", "-o", tmp_path / "si.json", "--units", "si")
    assert spec.exit_code == same.exit_code == si.exit_code == 0, si.output
    assert spec.output.replace("spec.json", "X") == same.output.replace("spec2.json", "X")
    assert (tmp_path / "spec.json").read_bytes() == (tmp_path / "si.json").read_bytes()  # the file: the spec's
    for spec_unit, si_unit, factor in (("g", "m/s^2", G), ("deg/h", "rad/s", DPH)):
        pairs = _pairs(spec.output, si.output.replace("si.json", "spec.json"), spec_unit, si_unit)
        assert len(pairs) >= 3, (spec_unit, si.output)
        assert all(_agrees(y, x, factor) for y, x in pairs), pairs
    assert "deg/h" not in si.output and not re.search(rf"{NUMBER} g\b", si.output), si.output
    # the held-out error has no label of its own: it follows the in-sample one's unit
    held = [re.search(rf"({NUMBER}) on rows left out", t) for t in (spec.output, si.output)]
    assert held[0] and held[1] and _agrees(held[1][1], held[0][1], G)


def test_parameters_in_si_are_the_spec_ones_converted():
    cal = simucal.calibrate(simucal.simulate("paper", seed=3))
    spec, si = simucal.parameters(cal, "own"), simucal.parameters(cal, "own", units="si")
    factor = {"g": (G, "m/s^2"), "deg/h": (DPH, "rad/s"), "1": (1.0, "1"), "rad": (1.0, "rad")}
    assert set(spec["unit"]) <= set(factor) and {"g", "deg/h", "1"} <= set(spec["unit"])
    f = np.array([factor[u][0] for u in spec["unit"]])
    assert list(si["unit"]) == [factor[u][1] for u in spec["unit"]]
    np.testing.assert_allclose(si["value"], spec["value"] * f, rtol=1e-12)
    np.testing.assert_allclose(si["std"], spec["std"] * f, rtol=1e-12)
    assert list(si["name"]) == list(spec["name"])
    assert simucal.parameters(cal, "own").equals(spec)  # the calibration unchanged
    common, common_si = simucal.parameters(cal), simucal.parameters(cal, units="si")
    f = np.array([factor[u][0] for u in common["unit"]])
    np.testing.assert_allclose(common_si["value"], common["value"] * f, rtol=1e-12)
    np.testing.assert_allclose(common_si["std"], common["std"] * f, rtol=1e-6)


def test_validate_and_its_page_in_si(sets, tmp_path):
    assert run("calibrate", sets / "set", "-o", tmp_path / "cal.json").exit_code == 0
    spec = run("validate", tmp_path / "cal.json", sets / "other", "-o", tmp_path / "v.json", "--html",
               tmp_path / "v.html")
    si = run("validate", tmp_path / "cal.json", sets / "other", "-o", tmp_path / "v_si.json", "--html",
             tmp_path / "v_si.html", "--units", "si")
    assert spec.exit_code == si.exit_code == 0, si.output
    assert json.loads((tmp_path / "v.json").read_text())["checks"] == json.loads((tmp_path / "v_si.json").read_text())[
        "checks"]
    factor = {"g": (G, "m/s^2"), "deg/h": (DPH, "rad/s"), "rad": (1.0, "rad")}
    rows = [(a.split(), b.split()) for a, b in zip(spec.output.splitlines(), si.output.splitlines())
            if a.startswith(("acc ", "gyro "))]
    assert len(rows) >= 4
    for a, b in rows:
        f, label = factor[a[4]]
        assert b[4] == label and all(_agrees(y, x, f) for x, y in zip(a[1:4], b[1:4])), (a, b)
    v, v_si = (simucal.validate(tmp_path / "cal.json", sets / "other", units=u) for u in ("spec", "si"))
    for c, d in zip(v.check_rows, v_si.check_rows, strict=True):
        f, label = factor[c.unit]
        assert d.unit == label and d.calibrated_rms == pytest.approx(c.calibrated_rms * f, rel=1e-12)
    page = (tmp_path / "v_si.html").read_text()
    assert "<td>m/s^2</td>" in page and "<td>rad/s</td>" in page and "<td>deg/h</td>" not in page


def test_noise_terms_in_si(sets, tmp_path):
    spec = run("noise", sets / "still", "-o", tmp_path / "n.json")
    si = run("noise", sets / "still", "-o", tmp_path / "n_si.json", "--units", "si", "--html", tmp_path / "n.html")
    assert spec.exit_code == si.exit_code == 0, si.output
    assert (tmp_path / "n.json").read_bytes() == (tmp_path / "n_si.json").read_bytes()
    spec_out, si_out = spec.output.replace("n.json", "X"), si.output.replace("n_si.json and ", "").replace(
        str(tmp_path / "n.html"), "").replace("n_si.json", "X")
    for spec_unit, si_unit, factor in (("deg/sqrt(h)", "rad/sqrt(s)", math.radians(1) / 60),
                                       ("ug/sqrt(Hz)", "m/s^2/sqrt(Hz)", 1e-6 * G),
                                       ("deg/h/sqrt(h)", "rad/s/sqrt(s)", DPH / 60), ("deg/h", "rad/s", DPH)):
        pairs = _pairs(spec_out, si_out.replace(str(tmp_path), ""), spec_unit, si_unit)
        assert len(pairs) >= 3 and all(_agrees(y, x, factor) for y, x in pairs), (spec_unit, pairs)
    assert "rad/sqrt(s)" in (tmp_path / "n.html").read_text()
    # the quantisation, a sensor's angle error, in rad: the spec's arcsec times the factor
    q = _pairs(spec_out, si_out.replace(str(tmp_path), ""), "arcsec", "rad")
    assert len(q) == 3 and all(_agrees(y, x, units.ARCSEC_RAD) for y, x in q), q
    noise, noise_si = simucal.noise(sets / "still"), simucal.noise(sets / "still", units="si")
    assert noise.lines() == noise.lines(units="spec") != noise.lines(units="si") == noise_si.lines(units="si")
    assert noise_si.report == noise.report  # the file's numbers: the spec's
    factor = {"deg/sqrt(h)": math.radians(1) / 60, "deg/h": DPH, "deg/h/sqrt(h)": DPH / 60, "deg/h/h": DPH / 3600,
              "arcsec": units.ARCSEC_RAD, "ug*s": 1e-6 * G, "ug/sqrt(Hz)": 1e-6 * G, "ug": 1e-6 * G,
              "ug/sqrt(s)": 1e-6 * G, "ug/s": 1e-6 * G}
    for t, u in zip(noise.term_rows, noise_si.term_rows, strict=True):
        for x, y in ((t.value, u.value), (t.std, u.std), (t.bound_95, u.bound_95)):
            assert (x is None) == (y is None) and (x is None or math.isclose(y, x * factor[t.unit], rel_tol=1e-12))
    adev = ({p.sensor: (p.adev, p.unit) for p in noise.curve_rows},
            {p.sensor: (p.adev, p.unit) for p in noise_si.curve_rows})
    assert adev[1]["acc"] == (pytest.approx(adev[0]["acc"][0] * G), "m/s^2") and adev[1]["gyro"][1] == "rad/s"


def test_apply_in_si_writes_the_specs_si_units(sets, tmp_path):
    assert run("calibrate", sets / "set", "-o", tmp_path / "cal.json").exit_code == 0
    spec = run("apply", tmp_path / "cal.json", sets / "other", "-o", tmp_path / "a")
    si = run("apply", tmp_path / "cal.json", sets / "other", "-o", tmp_path / "a_si", "--units", "si")
    assert spec.exit_code == si.exit_code == 0 and "in m/s^2 and rad/s" in si.output, si.output
    a, b = simucal.read_set(tmp_path / "a"), simucal.read_set(tmp_path / "a_si")  # the spec's reader takes it
    assert (a.meta["acc_unit"], a.meta["gyro_unit"], b.meta["acc_unit"], b.meta["gyro_unit"]) == (
        "g", "deg/h", "m/s^2", "rad/s")
    np.testing.assert_allclose(b.raw("acc"), a.raw("acc") * G, rtol=1e-12)
    np.testing.assert_allclose(b.raw("gyro"), a.raw("gyro") * DPH, rtol=1e-12)


@pytest.mark.parametrize("command", ["calibrate", "validate", "noise", "diagnose", "apply"])
def test_an_unknown_unit_system_is_refused_naming_the_choices(sets, tmp_path, command):
    args = {"calibrate": [sets / "set"], "validate": [tmp_path / "c.json", sets / "set"], "noise": [sets / "still"],
            "diagnose": [sets / "set"], "apply": [tmp_path / "c.json", sets / "set"]}[command]
    (tmp_path / "c.json").write_text("{}")
    r = run(command, *args, "-o", tmp_path / "out", "--units", "imperial")
    refused(r, "--units", "'imperial'", "'spec'", "'si'")
    assert not (tmp_path / "out").exists()
    with pytest.raises(simucal.errors.InputError, match="spec, si"):
        units.check_unit_system("imperial")


def test_the_command_lines_choices_are_the_units_modules():
    from simucal.cli.common import UNIT_SYSTEMS
    assert UNIT_SYSTEMS == units.UNIT_SYSTEMS


@pytest.mark.parametrize("label, factor, si", [
    ("g/g^2", 1 / G, "1/(m/s^2)"), ("ug*s", 1e-6 * G, "m/s"), ("(deg/h)/(deg/s)^2", DPH / math.radians(1) ** 2,
                                                              "1/(rad/s)"),
    ("deg/h/h", DPH / 3600, "rad/s^2"), ("(deg/h)/g", DPH / G, "(rad/s)/(m/s^2)"), ("g/degC^2", G, "m/s^2/degC^2"),
    ("ug/sqrt(Hz)", 1e-6 * G, "m/s^2/sqrt(Hz)"), ("deg/h/sqrt(h)", DPH / 60, "rad/s/sqrt(s)"),
    ("arcsec", units.ARCSEC_RAD, "rad"), ("deg", 1.0, "deg"), ("1/degC", 1.0, "1/degC")])
def test_si_labels_cancel_like_factors_and_a_sensors_angle_error_is_in_rad(label, factor, si):
    got = units.si_unit(label)
    assert got is not None and got[1] == si and math.isclose(got[0], factor, rel_tol=1e-12), got


def _number_before(text: str, unit: str) -> list[str]:
    return re.findall(rf"({NUMBER}) {re.escape(unit)}(?![\w/^*(])", text)


def test_diagnose_prints_its_page_and_added_parameters_in_si(sets, tmp_path):
    add = ("--add", "acc.quadratic.z")
    spec = run("diagnose", sets / "set", "-o", tmp_path / "d.json", "--html", tmp_path / "d.html", *add)
    same = run("diagnose", sets / "set", "-o", tmp_path / "d2.json", "--units", "spec", *add)
    si = run("diagnose", sets / "set", "-o", tmp_path / "d3.json", "--html", tmp_path / "d3.html", "--units", "si",
             *add)
    assert spec.exit_code == same.exit_code == si.exit_code == 0, si.output
    out = {k: r.output.split("\nwrote ")[0] for k, r in (("spec", spec), ("same", same), ("si", si))}
    assert out["spec"] == out["same"]
    assert (tmp_path / "d.json").read_bytes() == (tmp_path / "d3.json").read_bytes()
    for spec_unit, si_unit, factor in (("g", "m/s^2", G), ("deg/h", "rad/s", DPH), ("g/g^2", "1/(m/s^2)", 1 / G)):
        pairs = _pairs(out["spec"], out["si"], spec_unit, si_unit)
        assert pairs and all(_agrees(y, x, factor) for y, x in pairs), (spec_unit, pairs)
    assert re.search(rf"^    acc.quadratic.z = {NUMBER} \+- {NUMBER} g/g\^2(, truth {NUMBER} g/g\^2)?$", out["spec"],
                     re.M)
    assert "deg/h" not in out["si"] and not re.search(rf"{NUMBER} g\b", out["si"]), out["si"]
    # one number, one reading: the gyro's residual as calibrate --units si prints it, from the number not its text
    cal = run("calibrate", sets / "set", "-o", tmp_path / "c.json", "--units", "si", *add)
    gyro = [re.search(rf"gyro: .*?residual rms ({NUMBER}) rad/s", t)[1] for t in (cal.output, out["si"])]
    assert gyro[0] == gyro[1], gyro
    pages = [re.sub(r"data:image/png;base64,[^\"]+", "", (tmp_path / f).read_text()) for f in ("d.html", "d3.html")]
    row = [re.search(r"<td>acc.quadratic.z</td><td>([^<]*)</td><td></td><td></td><td><span "
                     r"class='n'>([^<]+)</span></td>", t)
           for t in pages]
    assert row[0][1] == "g/g^2" and row[1][1] == "1/(m/s^2)" and _agrees(row[1][2], row[0][2], 1 / G), row
    assert "residual rms" in pages[1] and "m/s^2" in pages[1] and not re.search(rf"{NUMBER} g\b", pages[1])


def test_the_diagnosis_in_si_converts_the_numbers_and_writes_its_verdicts_from_them(sets):
    from simucal.report.units import diagnosis_in
    from simucal.report.verdicts import sensor_verdict
    report = simucal.diagnose(sets / "set").report
    si, api_si = diagnosis_in(report, "si"), simucal.diagnose(sets / "set", units="si")
    assert diagnosis_in(report, "spec") is report and api_si.report == report  # the file: the spec's
    assert api_si.verdict == {s: si[s]["verdict"] for s in ("acc", "gyro")} != {s: report[s]["verdict"] for s in
                                                                                ("acc", "gyro")}
    by_id = {c["id"]: c for c in report["candidates"]}
    assert [c.unit for c in api_si.candidate_rows] == [units.in_units(1.0, by_id[c.id]["unit"], "si")[1]
                                                       for c in api_si.candidate_rows]
    for s, f in (("acc", G), ("gyro", DPH)):
        assert sensor_verdict(report[s], s) == report[s]["verdict"]  # the verdict is its numbers' sentence
        a, b = report[s]["model_test"], si[s]["model_test"]
        assert b["residual_rms"] == pytest.approx(a["residual_rms"] * f, rel=1e-12) and b["residual_unit"] != a[
            "residual_unit"]
        np.testing.assert_allclose(si[s]["residuals"][0]["residual"],
                                   np.array(report[s]["residuals"][0]["residual"]) * f)
        assert f"{b['residual_rms']:.3g} {b['residual_unit']}" in si[s]["verdict"]
        estimated = [(c, d) for c, d in zip(report[s]["candidates"], si[s]["candidates"], strict=True)
                     if c.get("estimate") is not None]
        assert len(estimated) > 3
        for c, d in estimated:
            per, label = units.si_unit(c["unit"])
            assert d["unit"] == label and d["estimate"] == pytest.approx(c["estimate"] * per, rel=1e-12)


def test_plan_lot_and_montecarlo_print_si(sets, tmp_path):
    plan = [run("plan", "--score", "table1", *x).output for x in ((), ("--units", "spec"), ("--units", "si"))]
    assert plan[0] == plan[1] and len(_pairs(plan[0], plan[2], "g", "m/s^2")) == 4  # the noise and 3 biases
    assert all(_agrees(y, x, G) for y, x in _pairs(plan[0], plan[2], "g", "m/s^2"))
    mc = [run("montecarlo", "--trials", 20, "-o", tmp_path / f"mc{k}.json", *x).output.splitlines()[1:-1]
          for k, x in enumerate(((), ("--units", "spec"), ("--units", "si")))]
    assert mc[0] == mc[1] and len(mc[0]) == len(mc[2]) > 10
    factor = {"1": (1.0, "1"), "rad": (1.0, "rad"), "g": (G, "m/s^2"), "deg/h": (DPH, "rad/s")}
    for a, b in zip(mc[0][1:], mc[2][1:]):
        a, b = a.split(), b.split()
        f, label = factor[a[1]]
        assert b[1] == label and all(_agrees(y, x, f) for x, y in zip(a[2:6], b[2:6])), (a, b)
    assert run("calibrate", sets / "set", sets / "other", "-o", tmp_path / "cals").exit_code == 0
    (tmp_path / "lim.json").write_text(json.dumps({"format": "simucal.limits/1", "limits": {
        "acc.b_x": {"min": -1e-4, "max": 1e-4, "unit": "g"}}}))
    lot = [run("lot", tmp_path / "cals", "-o", tmp_path / f"lot{k}.json", "--limits", tmp_path / "lim.json", *x)
           for k, x in enumerate(((), ("--units", "spec"), ("--units", "si")))]
    assert [r.exit_code for r in lot] == [0, 0, 0], lot[2].output
    assert lot[0].output.replace("lot0", "X") == lot[1].output.replace("lot1", "X")
    assert (tmp_path / "lot0.json").read_bytes() == (tmp_path / "lot2.json").read_bytes()
    pairs = _pairs(lot[0].output, lot[2].output.replace("lot2", "lot0"), "g", "m/s^2")
    assert len(pairs) >= 2 and all(_agrees(y, x, G) for y, x in pairs), pairs
