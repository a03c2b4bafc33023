"""simucal plan: the Fisher information of a plan, its scores, D/A-optimal designs."""
import numpy as np
import pytest
from click.testing import CliRunner

from simucal.cli import main
from simucal.fit.augmented import AugmentedModel
from simucal.fit.norm_fit import Observations, fit_exact
from simucal.turntable import plans
from simucal.turntable.plan_design import (
    design,
    directions_k,
    information,
    plan_rows,
    score,
)


def test_information_is_the_exact_solvers_covariance_by_finite_differences():
    """inv(H) equals the covariance of the exact fit propagated by finite differences of its solution
    with respect to every output (noise-free data, sigma per output)."""
    am = AugmentedModel("acc_baseline")
    u = directions_k(plans.TABLE1)
    p = np.array([2e-3, 8e-3, 6e-3, 1e-4, 1e-4, 1e-4, 8e-4, -1e-3, -3.2e-3])
    N0, sigma = am.output(u, p), 1e-5
    sig = np.full_like(N0, sigma)

    def solve(N):
        return fit_exact(am, Observations(N, np.ones(len(N)), sig), p0=p).vector(am.params)
    base, h = solve(N0), 1e-7
    S = np.empty((len(p), N0.size))
    for k in range(N0.size):
        d = np.zeros(N0.size)
        d[k] = h
        S[:, k] = (solve(N0 + d.reshape(N0.shape)) - base) / h
    cov_fd = S @ S.T * sigma ** 2
    H = information(am, u, 1.0, sigma, p)
    assert np.allclose(cov_fd, np.linalg.inv(H), rtol=1e-3, atol=1e-6 * np.abs(cov_fd).max())


@pytest.mark.slow
def test_designs_match_or_beat_table1_per_position():
    am = AugmentedModel("acc_baseline")
    t1 = score(am, directions_k(plans.TABLE1), 1.0, 1e-5)
    for n in (12, 24):
        d = score(am, design(am, n, 1.0, 1e-5, "D")[0], 1.0, 1e-5)
        assert d["D_per_position"] >= t1["D_per_position"] * (1 - 1e-6), (n, d["D_per_position"])
    a = score(am, design(am, 12, 1.0, 1e-5, "A")[0], 1.0, 1e-5)
    assert a["A"] <= t1["A"] * (1 + 1e-9)


def test_designed_plan_monte_carlo_std_matches_its_crlb(tmp_path):
    from simucal.turntable.montecarlo import run
    from simucal.turntable.simulate import Scenario
    am = AugmentedModel("acc_baseline")
    u = design(am, 12, 1.0, 1e-5)[0]
    csv = tmp_path / "p.csv"
    csv.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(",".join(map(str, r)) + "\n" for r in plan_rows(u)))
    predicted = score(am, u, 1.0, 1e-5)["crlb"]
    out = run(Scenario(plan=str(csv), unify_positions=False), 3000, 4)
    for k, crlb in predicted.items():
        assert out["parameters"][f"acc.{k}"]["std"] == pytest.approx(crlb, rel=0.05), k


@pytest.mark.parametrize("args,named", [
    (["--score", "{bad}"], "plan needs columns"),
    (["--score", "table1", "--add", "acc.quad"], "unknown effect"),
    (["--positions", "6"], "at least 9"),
    (["--score", "table1", "--model", "gyro_baseline", "--rate-dps", "0"], "non-zero rate"),
    ([], "--score PLAN"),
    (["--positions", "12", "--separate", "acc.quadratic.z,acc.quadratic.y", "--sizes", "1,1"],
     "--separate needs --score"),
    (["--score", "table1", "--separate", "acc.quadratic.z,gyro.quadratic.y", "--sizes", "1,1"], "not the acc"),
])
def test_bad_input_one_line(tmp_path, args, named):
    bad = tmp_path / "bad.csv"
    bad.write_text("outer_deg,middle_deg\n0,0\n")
    r = CliRunner().invoke(main, ["plan"] + [a.replace("{bad}", str(bad)) for a in args])
    assert r.exit_code == 2 and named in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr


@pytest.mark.slow
def test_designed_plan_file_runs_a_test(tmp_path):
    """A gyro plan choosing among three rates runs as a simulated test (for a quadratic the D-optimum
    takes the fastest: its signature varies with the direction too); a hand-placed design is
    written as gravity directions."""
    from simucal.turntable.simulate import Scenario, write
    r = CliRunner().invoke(main, ["plan", "--positions", "12", "--model", "gyro_baseline", "--add", "gyro.quadratic.x",
                                  "--rates-dps", "5,10,20", "-o", str(tmp_path / "g.csv")])
    assert r.exit_code == 0, r.output
    lines = (tmp_path / "g.csv").read_text().splitlines()
    assert lines[0] == "outer_deg,middle_deg,inner_deg,outer_rate_dps" and len(lines) == 13
    assert {float(line.split(",")[3]) for line in lines[1:]} <= {5.0, 10.0, 20.0} and (tmp_path / "g.json").is_file()
    write(tmp_path / "s", Scenario(plan=str(tmp_path / "g.csv"), unify_positions=False), 1)
    r = CliRunner().invoke(main, ["plan", "--positions", "12", "--table", "hand", "-o", str(tmp_path / "h.csv")])
    lines = (tmp_path / "h.csv").read_text().splitlines()
    assert r.exit_code == 0 and lines[0] == "pose,f_x,f_y,f_z" and len(lines) == 13


@pytest.mark.slow
def test_separation_design_decides_an_inseparable_pair(tmp_path):
    """On Table 1, acc.quadratic.z and acc.scale_asymmetry.z cannot be told apart (noncentrality 0);
    the designed extra positions separate them, and a simulated test on the extended plan finds the
    planted quadratic first, with its twin rejected."""
    from simucal.api.diagnosing import diagnosis_report as diagnose
    from simucal.turntable.plan_design import separate
    from simucal.turntable.simulate import Scenario, write
    u = directions_k(plans.TABLE1)
    sep = separate("acc_baseline", "acc.quadratic.z", "acc.scale_asymmetry.z", u, 1.0, 1e-5, (3e-4, 3e-4),
                   target=0.99)
    assert max(sep["start"]["noncentrality"]) < 1e-12 and sep["reached"] and sep["added"]
    rows = list(plans.TABLE1) + plan_rows(np.array([a["direction_k"] for a in sep["added"]]))
    csv = tmp_path / "p.csv"
    csv.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(",".join(map(str, r[:3])) + "\n" for r in rows))
    write(tmp_path / "s", Scenario(plan=str(csv), unify_positions=False, acc_effects={"acc.quadratic.z": 3e-4}), 2)
    cands = {c["id"]: c for c in diagnose(tmp_path / "s")["acc"]["candidates"]}
    top = max((c for c in cands.values() if c.get("separable", True) and "statistic" in c),
              key=lambda c: c["statistic"])
    assert top["id"] == "acc.quadratic.z" and top.get("significant")
    twin = cands["acc.scale_asymmetry.z"]
    assert twin.get("separable", True) and twin["statistic"] < top["statistic"]


@pytest.mark.slow
def test_separation_power_is_the_rate_observed(tmp_path):
    """The predicted power of telling acc.quadratic.z from acc.scale_asymmetry.z on a designed plan is
    the rate at which simulated tests reject the twin (chi2 of the twin's fit less the true one's
    beyond the 1-dof critical value)."""
    from simucal import io
    from simucal.fit.distributions import chi2_isf
    from simucal.turntable.observations import segment_observations
    from simucal.turntable.plan_design import separate
    from simucal.turntable.simulate import Scenario, write
    u = directions_k(plans.TABLE1)
    sep = separate("acc_baseline", "acc.quadratic.z", "acc.scale_asymmetry.z", u, 1.0, 1e-5, (1e-4, 1e-4), target=0.6)
    predicted = sep["power"][0]
    rows = list(plans.TABLE1) + plan_rows(np.array([a["direction_k"] for a in sep["added"]]))
    csv = tmp_path / "p.csv"
    csv.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(",".join(map(str, r[:3])) + "\n" for r in rows))
    truth, twin = (AugmentedModel("acc_baseline", ("acc.quadratic.z",)),
                   AugmentedModel("acc_baseline", ("acc.scale_asymmetry.z",)))
    crit, rejected, n = chi2_isf(0.01, 1), 0, 40
    for seed in range(n):
        write(tmp_path / str(seed),
              Scenario(plan=str(csv), unify_positions=False, acc_effects={"acc.quadratic.z": 1e-4}), seed)
        obs, _ = segment_observations(io.read_set(tmp_path / str(seed)), "acc")
        rejected += (fit_exact(twin, obs).chi2 - fit_exact(truth, obs).chi2) > crit
    assert (abs(rejected / n - predicted)
            < 3 * np.sqrt(predicted * (1 - predicted) / n) + 0.05), (rejected / n, predicted)
