"""Twins decided only by evidence (turntable/model_test.choose_twin): the rows the rate-run fit does not use,
the static rows and the unification pairs, choose between twins the rate runs cannot tell apart, and only
beyond the twins' level; closer, no twin is claimed: diagnose and calibrate's advice name both with the
plan command that would tell them, and `--add auto` adds neither. A MEMS unit's x gyro following f_z (15
of its stds) on Table 1 at +-12 and +-30 deg/s: the rate runs and the static rows read the twin z gyro
following f_x alike, the pairs do not (chi2 near their dof with the truth, near 2000 on 109 with the twin);
at +-1500 deg/s the pairs' directions turn by G f / w_T, under their noise, and nothing tells them."""
import shlex

import pytest
from click.testing import CliRunner

from simucal.api.calibrating import calibrate
from simucal.cli import main
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.report.console import next_command
from simucal.turntable.model_test import choose_twin, pairs_evidence
from simucal.turntable.simulate import mems_unit, write

XZ, ZX = "gyro.g_sensitivity.xz", "gyro.g_sensitivity.zx"


def _set(folder, rates, size, seed=0):
    sc = mems_unit(seed)
    sc.outer_rate_dps, sc.gyro_effects = rates, {XZ: size}
    write(folder, sc, seed)
    return folder


def _judged(static, pairs):
    """Two twins and a judge whose rows give these chi-squares (None: no pairs)."""
    cands = [{"id": XZ, "significant": True, "twins": [ZX], "statistic": 220.0, "estimate": 250.0},
             {"id": ZX, "significant": True, "twins": [XZ], "statistic": 222.0, "estimate": 250.0}]

    class Judge:
        def with_effect(self, eid):
            k = (ZX, XZ).index(eid)
            st = {"chi2": static[k], "dof": 16, "p_value": 0.5, "positions": 16}
            return st if pairs is None else {**st, "pairs": {"pairs": 56, "chi2": pairs[k], "dof": 109, "p_value": 0.5}}
    choose_twin(cands, lambda: Judge())
    return cands


@pytest.mark.parametrize("static,pairs,lead,decided", [  # chi-squares of (ZX, XZ)
    ((9.3, 10.7), (1954.0, 111.2), XZ, True),    # the pairs choose where the static rows cannot
    ((9.3, 10.7), (111.2, 1954.0), ZX, True),    # ... either way: the chosen one leads
    ((9.3, 10.7), None, XZ, False),              # the static rows alone, 1.4 apart: neither; the ranking stands
    ((30.0, 10.0), (100.0, 105.0), XZ, True),    # the sum decides: 130 against 115
    ((12.0, 10.0), (111.0, 115.0), XZ, False)])  # 123 against 125: under the level
def test_the_rows_that_judge_choose_by_their_summed_chi2_beyond_the_level(static, pairs, lead, decided):
    first = _judged(static, pairs)[0]
    assert first["id"] == lead and bool(first.get("twins_undecided")) is not decided
    if decided:
        assert ("unification pairs" in first["twin_choice"]) is (pairs is not None)
        assert "static positions chose it" in first["twin_choice"]
    else:
        assert first["twin_choice"].startswith("cannot tell") and "--separate" in first["twin_choice"]


def test_pairs_whose_noise_comes_from_their_own_scatter_are_no_evidence():
    info = {"method": "rate_run_means", "pairs": 56, "chi2": 109.0, "dof": 109, "noise": {}}
    assert pairs_evidence(info)["p_value"] == pytest.approx(0.48, abs=0.01)
    assert pairs_evidence({**info, "noise": {"acc_rate_run_means": {"std_g": 1e-4}}}) is None
    assert pairs_evidence({**info, "method": "static_pairs", "noise": {"table_angles": {"dof": 40.0}}}) is None


def test_the_pairs_choose_the_planted_twin_and_auto_adds_it(tmp_path):
    folder = _set(tmp_path / "s", (12.0, -12.0, 30.0, -30.0), 254.0)
    first = diagnose(folder)["gyro"]["candidates"][0]
    assert first["id"] == XZ and not first.get("twins_undecided"), first.get("twin_choice")
    assert "with the 56 unification pairs" in first["twin_choice"]
    assert first["at_rest"][ZX]["pairs"]["chi2"] - first["at_rest"][XZ]["pairs"]["chi2"] > 100
    step, = calibrate(folder, add=["auto"]).gyro.details["auto"]
    assert step["id"] == XZ


def test_where_no_rows_tell_the_twins_apart_none_is_claimed_and_the_plan_is_named(tmp_path):
    folder = _set(tmp_path / "s", (1500.0, -1500.0), 359.0)
    d = diagnose(folder)
    g = d["gyro"]
    first = next(c for c in g["candidates"] if c.get("significant"))
    assert first.get("twins_undecided") and first["twin_choice"].startswith("cannot tell")
    assert "Add it" not in g["verdict"] and "Add neither" in g["verdict"]
    command, notes = next_command(d)
    assert "--add" not in command
    plan = next(n for n in notes if "simucal plan" in n).split("simucal plan ", 1)[1]
    assert f"--separate {first['id']}," in plan and "--model gyro_baseline" in plan
    ran = CliRunner().invoke(main, ["plan", *shlex.split(plan.replace("PLAN", "table1"))])
    assert ran.exit_code == 0 and "separate gyro.g_sensitivity" in ran.output, ran.output
    cal = calibrate(folder, add=["auto"])
    assert cal.gyro.details["auto"] == [] and "--add auto adds neither" in cal.gyro.details["auto_stopped"]
    advice = calibrate(folder).gyro.details["advice"]
    assert f"{XZ} or {ZX}" in advice or f"{ZX} or {XZ}" in advice
