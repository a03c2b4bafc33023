"""`simucal lot`: a simulated lot with a planted outlier, a unit recorded twice with a
planted drift and one without, spec limits, a file that is no calibration and a unit of another method;
the outlier rule's false-alarm rate and power over seeds; bad limits files refused in one line."""
import json
import shutil
import re

import numpy as np
import pytest

from cli_helpers import refused, run
from page_layout import figures_checked, html_problems
import simucal
from simucal.api import lot_reporting
from simucal.report.page import STYLE
from simucal.turntable.lot import SPREAD, write_lot

N = 21  # lot_reporting.MIN_UNITS and one more
OUTLIER = 3     # acc.b_x off by 15 spreads of units
LIMIT_MAX = 0.0025  # acc.b_x's max: the design's 8e-4 + 8.5 spreads, so only the outlier breaks it


@pytest.fixture(scope="module")
def lot(tmp_path_factory):
    root = tmp_path_factory.mktemp("lot")
    sets = write_lot(root / "sets", N, seed=3, planted={OUTLIER: {"acc.b_x": 15 * SPREAD["acc"]["b"]}}, again=2,
                     drift={0: {"gyro.b_z": 0.05}})
    cals = root / "cals"
    r = run("calibrate", *sets, "-o", cals)
    assert r.exit_code == 0, r.output
    assert run("calibrate", sets[-1], "--method", "linear", "-o", cals / "zz_linear.json").exit_code == 0
    assert run("calibrate", sets[-2], "--method", "multiposition", "-o", cals / "zz_mp.json").exit_code == 0
    (cals / "notes.txt").write_text("the operator's notes\n")
    limits = root / "limits.json"
    limits.write_text(json.dumps({"format": "simucal.limits/1",
                                  "limits": {"acc.b_x": {"max": LIMIT_MAX, "unit": "g"}}}))
    with figures_checked() as (problems, figures):  # the command's own page, its figures checked as it saves them
        r = run("lot", cals, "-o", root / "lot.json", "--html", root / "lot.html", "--limits", limits)
    assert r.exit_code == 0, r.output
    return root, json.loads((root / "lot.json").read_text()), r.output, (problems, figures)


@pytest.mark.slow
def test_the_lot_report_finds_what_was_planted(lot):
    root, report, out, _ = lot
    units = {u["file"]: u for u in report["units"]}
    bad = f"unit{OUTLIER:04d}.json"
    assert units[bad]["status"] == "fails" and any("acc.b_x" in w and "above its max" in w for w in units[bad]["why"])
    assert [o["name"] for o in units[bad]["outliers"]] == ["acc.bias_x"]  # the one vocabulary; the limit named b_x
    exact = {p["name"]: p for p in report["groups"][0]["parameters"]}
    assert exact["acc.bias_x"]["own_name"] == "b_x" and exact["acc.M_yx"]["own_name"] == "theta_yx"
    # the other units of the lot: none flagged (the rule's chance 1e-3 each), every model test passes
    others = [u for u in report["units"] if u["file"] not in (bad, "zz_linear.json", "zz_mp.json")]
    assert others and all(not u["outliers"] and not u["outside_limits"] for u in others)
    drift = {d["later"]: d for d in report["drift"]}
    assert set(drift) == {"unit0000_b.json", "unit0001_b.json"}  # the linear one is another group: no drift
    assert drift["unit0000_b.json"]["sensors"]["gyro"]["verdict"] == "drifted"
    z = {r["name"]: r["z"] for r in drift["unit0000_b.json"]["parameters"]}  # the one vocabulary: b_z is bias_z
    assert abs(z["gyro.bias_z"]) > 5 and max(abs(v) for k, v in z.items() if k != "gyro.bias_z") < 4
    assert {r["own_name"] for r in drift["unit0000_b.json"]["parameters"] if r["name"] == "gyro.bias_z"} == {"b_z"}
    # chi^2 on the rank: the exact accelerometer's 9 parameters are its 9 entries (M lower triangular, bias); the
    # gyro's 12 entries in b carry C_b^d's own std beside its 9 parameters (std_M)
    assert {s: v["dof"] for s, v in drift["unit0001_b.json"]["sensors"].items()} == {"acc": 9, "gyro": 12}
    assert all(v["verdict"] == "no drift seen" for v in drift["unit0001_b.json"]["sensors"].values())
    assert units["unit0000_b.json"]["status"] == "flagged" and "unit0000.json" in report["superseded"]
    assert [g["units"] for g in report["groups"]][1:] == [["zz_linear.json"], ["zz_mp.json"]]
    assert report["groups"][1]["outlier_rule"].startswith("not tested: 1 unit, fewer than")
    mp = {p["name"]: p for p in report["groups"][2]["parameters"]}  # an affine block: M's entries and the bias
    assert len(mp) == 24 and mp["acc.M_xx"]["stds"][0] > 0 and mp["gyro.bias_z"]["unit"] == "deg/h"
    assert [o["file"] for o in report["not_calibrations"]] == ["notes.txt"]
    assert out.splitlines()[0] == report["verdict"][0]
    assert re.match(rf"{N} of {N + 2} units pass, 1 fail, 1 flagged \(3 groups", report["verdict"][0])
    assert "notes.txt" in out and f"next: {report['next']}" in out


def test_the_page_opens_with_the_verdict_and_the_next_command(lot):
    root, report, _, (problems, figures) = lot
    page = (root / "lot.html").read_text()
    first = page.index("<h1>")
    assert page.index("<img") > page.index("Next: <code>") > first and report["verdict"][0] in page[first:first + 400]
    assert "class='verdict bad'><b>" + report["verdict"][0] in page  # one unit fails: the lot's line says so
    assert page.count("<img") == 6  # acc and gyro of each group (the exact, linear and multi-position methods)
    assert STYLE in page  # the pages' one stylesheet and font
    assert len(figures) == 6 and not problems + html_problems(page), problems + html_problems(page)


def test_the_python_api_gives_the_report(lot):
    import simucal.api
    root, report, _, _ = lot
    limits = root / "limits.json"
    assert json.loads(json.dumps(simucal.api.lot(report["folder"], limits))) == report


@pytest.mark.slow
@pytest.mark.parametrize("n", [lot_reporting.MIN_UNITS, 60])
def test_the_outlier_rule_false_alarm_rate_and_power_over_seeds(n):
    """Lots of n units without outliers, each parameter's stds 0.05 to 2 times its spread of units (within
    one parameter within 25 %, as one plan gives): a unit is flagged at the rule's chance p (here 0.05,
    for events enough in a test; the report uses OUTLIER_P); a unit 30 combined stds off is always found."""
    rng = np.random.default_rng(n)
    k, p, lots = 18, 0.05, 2000 // n
    tau = np.geomspace(1e-4, 1e-2, k)
    alarms, found = 0, 0
    for seed in range(lots):
        s = tau * rng.uniform(0.05, 2.0, k) * rng.uniform(0.8, 1.25, (n, k))
        x = tau * rng.standard_normal((n, k)) + s * rng.standard_normal((n, k))
        z, _, _, tau_hat = lot_reporting._z(x, s)
        z_max = lot_reporting.threshold(tau_hat[0], s, p=p, units=2000, seed=seed)
        alarms += int((np.abs(z).max(axis=1) > z_max).sum())
        x[0, seed % k] += 30 * np.sqrt(tau[seed % k] ** 2 + s[0, seed % k] ** 2)
        found += abs(lot_reporting._z(x, s)[0][0, seed % k]) > z_max
    units = lots * n
    assert abs(alarms - p * units) < 4 * np.sqrt(p * (1 - p) * units), (alarms, units)
    assert found == lots


@pytest.mark.slow
@pytest.mark.parametrize("text,words", [
    ("{", ["not a readable limits file"]),
    ('{"format": "simucal.limits/1", "limits": {"acc.b_q": {"max": 1, "unit": "g"}}}', ["limits.acc.b_q", "acc.b_x"]),
    ('{"format": "simucal.limits/1", "limits": {"acc.b_x": {"max": 1, "unit": "m/s^2"}}}', ["limits.acc.b_x", "'g'"]),
    ('{"format": "simucal.limits/1", "limits": {"acc.b_x": {"min": 1, "max": 0, "unit": "g"}}}', ["min 1 is above"]),
    ('{"format": "simucal.limits/1", "limits": {"acc.b_x": {"max": "0.1", "unit": "g"}}}', ["limits.acc.b_x.max"]),
    ('{"format": "simucal.limits/1", "limits": {"acc.b_x": {"unit": "g"}}}', ["min, max or both"]),
    ('{"limits": {}}', ["top level", "simucal.limits/1"]),
    ('{"format": "simucal.limits/1", "limits": {}, "limits": {}}', ["not a readable limits file"]),
])
def test_a_bad_limits_file_is_refused_in_one_line(lot, tmp_path, text, words):
    root = lot[0]
    bad = tmp_path / "limits.json"
    bad.write_text(text)
    refused(run("lot", root / "cals", "-o", tmp_path / "l.json", "--limits", bad), str(bad), *words)
    assert not (tmp_path / "l.json").exists()


def test_a_folder_without_calibrations_is_refused(tmp_path):
    (tmp_path / "cals").mkdir()
    (tmp_path / "cals" / "a.json").write_text("{}")
    refused(run("lot", tmp_path / "cals", "-o", tmp_path / "l.json"), "holds no calibration file",
            "simucal calibrate DIR1 DIR2 ... -o FOLDER")


@pytest.mark.slow
def test_a_lot_of_one_unit_says_unit(lot, tmp_path):
    """A count of one is '1 unit' (the review read '1 units'): in the verdict, the outlier rule and the page."""
    root = lot[0]
    (tmp_path / "one").mkdir()
    shutil.copy(root / "cals" / "zz_mp.json", tmp_path / "one" / "a.json")
    r = run("lot", tmp_path / "one", "-o", tmp_path / "l.json", "--html", tmp_path / "l.html")
    assert r.exit_code == 0, r.output
    said = r.output + (tmp_path / "l.html").read_text() + (tmp_path / "l.json").read_text()
    assert "1 unit" in said and "1 units" not in said, r.output


@pytest.mark.slow
def test_a_limit_by_the_one_vocabulary_s_name_or_the_method_s_own_is_the_same_limit(lot, tmp_path):
    """acc.bias_x (the one vocabulary's entry, every method's) and acc.b_x (the exact method's own, as limits files
    written before name it) break the same unit."""
    root, report, _, _ = lot
    limits = tmp_path / "limits.json"
    limits.write_text(json.dumps({"format": "simucal.limits/1",
                                  "limits": {"acc.bias_x": {"max": LIMIT_MAX, "unit": "g"}}}))
    common = simucal.lot(root / "cals", limits=limits)
    assert ([u["file"] for u in common["units"] if u["outside_limits"]]
            == [u["file"] for u in report["units"] if u["outside_limits"]] == [f"unit{OUTLIER:04d}.json"])
