"""A unit's trend and due date (simucal/store/trend.py): the weighted line and its crossing of the spec, checked
against the line's own algebra; and from the store, a drifting unit's due date on the command line and its page."""
import json

import numpy as np
import pytest

import simucal
from cli_helpers import run
from simucal.errors import SimucalError
from simucal.store.records import parameter_rows
from simucal.store.trend import HORIZON_YEARS, K, due, line
from store_helpers import DRIFT_ENTRY, DRIFT_PARAM, base_calibration, unit_files


def test_the_line_is_the_weighted_least_squares_one():
    t, v, s = np.array([0.0, 0.5, 1.0, 2.0]), np.array([1.0, 1.4, 2.1, 2.9]), np.array([0.1, 0.2, 0.1, 0.3])
    ab, cov, chi2 = line(t, v, s)
    X = np.column_stack([np.ones(4), t])
    ref, *_ = np.linalg.lstsq(X / s[:, None], v / s, rcond=None)
    assert np.allclose(ab, ref) and np.allclose(cov, np.linalg.inv((X / s[:, None]).T @ (X / s[:, None])))
    assert np.isclose(chi2, np.sum(((v - X @ ab) / s) ** 2))


def test_the_due_dates_are_where_the_line_and_its_band_reach_the_spec():
    ab, cov = np.array([0.0, 1.0]), np.array([[0.01, 0.0], [0.0, 0.04]])
    expected, earliest = due(ab, cov, {"max": 3.0}, 1.0)
    assert np.isclose(expected, 3.0)
    band = K * np.sqrt(np.array([1, earliest]) @ cov @ np.array([1, earliest]))
    assert 1.0 < earliest < expected and np.isclose(earliest + band, 3.0)
    assert due(ab, cov, {"min": 0.5}, 1.0) == (None, None)  # moving away from its only limit
    assert due(ab, cov, {"max": 0.5}, 1.0) == (1.0, 1.0)  # outside already: due at its last calibration
    far = due(np.array([0.0, 1e-3]), cov * 1e-6, {"max": 1.0}, 0.0)
    assert far == (None, None) and HORIZON_YEARS < 1.0 / 1e-3


def test_a_drifting_units_due_date_on_the_command_line_and_its_page(tmp_path):
    base = base_calibration(tmp_path)
    store = tmp_path / "lab.db"
    for month, path in enumerate(unit_files(base, tmp_path / "cals", 1, 3, drifting={0}, seed=2)["SN-0000"]):
        assert run("store", "add", path, "--store", store, "--time", f"2026-{1 + 4 * month:02d}-01").exit_code == 0
    sensor, name = DRIFT_PARAM.split(".")
    block = getattr(simucal.load(base), sensor)
    value, std, unit = block.params[name], block.std[name], block.param_units[name]
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"format": "simucal.limits/1", "limits": {DRIFT_PARAM: {
        "min": value - 100 * std, "max": value + 100 * std, "unit": unit}}}))
    r = run("history", "SN-0000", "--store", store, "--spec", spec, "-o", tmp_path / "h.json",
            "--html", tmp_path / "h.html")
    assert r.exit_code == 0, r.output
    trend = json.loads((tmp_path / "h.json").read_text())["trend"]
    p = next(p for p in trend["parameters"] if p["name"] == DRIFT_ENTRY)  # the spec named it by its own name
    years = (100 - (p["intercept"] - value) / std) * std / p["slope_per_year"]  # the line at value + 100 std
    assert p["own_name"] == name and trend["due_parameter"] == DRIFT_ENTRY
    assert np.isclose(p["expected_years"], years, rtol=1e-6)
    assert p["earliest_years"] < p["expected_years"] and f"{DRIFT_ENTRY} is expected to leave its spec" in r.output
    assert trend["due_utc"] == p["earliest_utc"] and p["earliest_utc"][:10] in (tmp_path / "h.html").read_text()
    last = p["values"][-1]  # measured outside already: due at the last calibration, whatever the line says
    spec.write_text(json.dumps({"format": "simucal.limits/1",
                                "limits": {DRIFT_PARAM: {"max": last - std, "unit": unit}}}))
    out = next(q for q in simucal.Store(store).history("SN-0000", spec=spec)["trend"]["parameters"]
               if q["name"] == p["name"])
    assert out["expected_years"] == out["earliest_years"] == p["t_years"][-1]
    r = run("history", "SN-0000", "--store", store, "-o", store)  # the store is an input: never written over
    assert r.exit_code != 0 and "input" in r.output and len(simucal.Store(store).records()) == 3
    spec.write_text(json.dumps({"format": "simucal.limits/1", "limits": {DRIFT_PARAM: {"max": 1.0, "unit": "g"}}}))
    with pytest.raises(SimucalError, match="spec.json: limits.gyro.b_z: unit 'g'"):
        simucal.Store(store).history("SN-0000", spec=spec)
    # an own parameter that is no entry (M_xx is 1 + dK_x, not dK_x): refused, naming the entries there are
    spec.write_text(json.dumps({"format": "simucal.limits/1", "limits": {"gyro.dK_x": {"max": 1.0, "unit": "1"}}}))
    with pytest.raises(SimucalError, match=r"limits.gyro.dK_x: unit SN-0000's trend .* it has .*gyro.M_xx"):
        simucal.Store(store).history("SN-0000", spec=spec)


def test_a_std_of_zero_is_said_to_leave_no_trend_and_a_value_outside_is_still_due(tmp_path):
    """A record whose std of a parameter is 0 (held fixed, or a file edited) cannot weigh a line: the trend says
    so by name, and the verdict, rather than the parameter silently dropping out of the due dates."""
    base = base_calibration(tmp_path)
    files = unit_files(base, tmp_path / "cals", 1, 3, drifting={0}, seed=2)["SN-0000"]
    sensor, name = DRIFT_PARAM.split(".")
    raw = json.loads(files[1].read_text())
    raw[sensor]["std"][name] = 0.0
    files[1].write_text(json.dumps(raw))
    store = tmp_path / "lab.db"
    for month, path in enumerate(files):
        assert run("store", "add", path, "--store", store, "--time", f"2026-{1 + 4 * month:02d}-01").exit_code == 0
    last = simucal.load(files[-1])
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"format": "simucal.limits/1", "limits": {DRIFT_PARAM: {
        "max": getattr(last, sensor).params[name] - 1e-9, "unit": getattr(last, sensor).param_units[name]}}}))
    trend = simucal.Store(store).history("SN-0000", spec=spec)["trend"]
    p = next(p for p in trend["parameters"] if p["name"] == DRIFT_ENTRY)  # the spec named it by its own name
    assert p["slope_per_year"] is None and "a std of 0 or none in record 2" in p["no_trend"]
    assert p["expected_years"] == p["t_years"][-1] and trend["due_parameter"] == DRIFT_ENTRY  # outside: due now
    assert f"NO TREND for 1 parameter(s), no date from a line for them: {DRIFT_ENTRY}: a std of 0" in trend["verdict"]


def test_a_spec_bounding_another_lines_parameter_is_refused_not_ignored(tmp_path):
    """The trend follows the unit's last method and model: a spec entry naming a parameter only an earlier line
    has (the multi-position method's M_xy, where the unit is now calibrated by the exact method) would bound
    nothing, so it is refused, naming the line."""
    base = base_calibration(tmp_path)
    older = tmp_path / "older.json"
    simucal.save(older, simucal.calibrate(simucal.simulate(seed=1), method="multiposition"))
    store = tmp_path / "lab.db"
    assert run("store", "add", older, "--store", store, "--serial", "SN-0000", "--time", "2025-06-01").exit_code == 0
    for month, path in enumerate(unit_files(base, tmp_path / "cals", 1, 2, seed=2)["SN-0000"]):
        assert run("store", "add", path, "--store", store, "--time", f"2026-{1 + 4 * month:02d}-01").exit_code == 0
    names = {r["name"]: r["unit"] for r in parameter_rows(simucal.load(older)) if r["sensor"] == "acc"}
    name = next(n for n in names if n not in {r["name"] for r in parameter_rows(simucal.load(base))
                                              if r["sensor"] == "acc"})  # M_xy: the exact method's is lower triangular
    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps({"format": "simucal.limits/1", "limits": {f"acc.{name}": {
        "max": 1.0, "unit": names[name]}}}))
    with pytest.raises(SimucalError, match=f"limits.acc.{name}: unit SN-0000's trend \\(its calibrations by exact"):
        simucal.Store(store).history("SN-0000", spec=spec)
