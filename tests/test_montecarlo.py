"""simucal montecarlo: batched simulation and compiled fits, std against the CRLB."""
import json

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from simucal.cli import main
from simucal.turntable.montecarlo import run, simulate_batch
from simucal.turntable.simulate import Scenario


def test_std_matches_the_cramer_rao_bound(tmp_path):
    r = CliRunner().invoke(main, ["montecarlo", "--trials", "3000", "--seed", "2", "-o", str(tmp_path / "mc.json")])
    assert r.exit_code == 0, r.output
    out = json.loads((tmp_path / "mc.json").read_text())
    assert out["trials"] == 3000 and out["failed"] == 0 and out["trials_per_s"] > 0
    assert len(out["parameters"]) == 18
    for name, v in out["parameters"].items():  # 3000 trials: the ratio's spread is about 1.3 %
        assert 0.94 < v["std_over_crlb"] < 1.06, (name, v)
        assert abs(v["mean"] - v["truth"]) < 4 * v["std"] / np.sqrt(3000), (name, v)
    assert max(out["unification"]["C_b_d_error_rms_rad"]) < 3e-5
    from simucal.fit.catalog import load
    for name, v in out["parameters"].items():  # each row's unit, on the console as in the file
        sensor, p = name.split(".", 1)
        m = load(f"{sensor}_baseline")
        assert v["unit"] == m.param_units[m.params.index(p)]
        assert any(x.split()[:2] == [name, v["unit"]] for x in r.output.splitlines()), name


def test_batched_simulation_matches_the_simulator(tmp_path):
    """Noise-free, no position errors: the batch's mean outputs are simulate()'s (720 samples per revolution)."""
    from simucal import io
    from simucal.turntable.simulate import write
    sc = Scenario(position_error_rad=0.0, acc_effects={"acc.quadratic.z": 2e-4},
                  gyro_effects={"gyro.g_sensitivity.xz": 0.3})
    sc.acc_noise_g = sc.gyro_noise_dph = 0.0
    write(tmp_path, sc, 0)
    ms = io.read_set(tmp_path)
    b = simulate_batch(sc, 1, np.random.default_rng(0), noise=False)
    acc, gyro = ms.acc_g(), ms.gyro_dph()
    static = [s.segment for s in ms.segments if s.kind == "static"]
    rate = [s.segment for s in ms.segments if s.kind == "rate"]
    mean = lambda x, segs: np.array([x[ms.samples["segment"] == s].mean(0) for s in segs])
    assert np.allclose(mean(acc, static), b["acc"][0], atol=1e-12)
    assert np.allclose(mean(gyro, rate), b["gyro"][0], atol=1e-9)
    assert np.allclose(mean(acc, rate), b["acc_rate"][0], atol=1e-12)


def test_failed_trials_are_counted_not_dropped():
    """A trial the fit cannot solve is counted and listed (gyro noise 1e5 deg/h, above the 36000 deg/h rate)."""
    sc = Scenario()
    sc.gyro_noise_dph = 1e5
    out = run(sc, 50, 1)
    assert 0 < out["failed"] == len(out["failed_trials"]) <= 50
    assert all(0 <= t < 50 for t in out["failed_trials"]) and len(set(out["failed_trials"])) == out["failed"]


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_numbers(dask_cluster):
    """The same seeds on a LocalCluster of 2 workers: the same estimates, bit for bit."""
    here = run(Scenario(), 600, 5, chunk=200)
    there = run(Scenario(), 600, 5, chunk=200, scheduler=dask_cluster)
    assert there["scheduler"] == dask_cluster
    for k, v in here["parameters"].items():
        assert there["parameters"][k]["mean"] == v["mean"] and there["parameters"][k]["std"] == v["std"], k


def test_batch_calibration_keeps_the_good_sets(tmp_path, dask_cluster):
    from simucal.turntable.simulate import write
    for i in (1, 2):
        write(tmp_path / f"u{i}", Scenario(), i)
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "meta.json").write_text("{")
    for name, scheduler in (("local", "local"), ("dask", dask_cluster)):
        out = tmp_path / f"cal-{name}"
        r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "u1"), str(tmp_path / "bad"), str(tmp_path / "u2"),
                                      "-o", str(out), "--scheduler", scheduler])
        assert r.exit_code == 2 and "bad/meta.json" in r.stderr and "2 of 3 sets" in r.output, r.output
        assert sorted(p.name for p in out.iterdir()) == ["u1.json", "u2.json"]
    a = json.loads((tmp_path / "cal-local" / "u1.json").read_text())
    b = json.loads((tmp_path / "cal-dask" / "u1.json").read_text())
    assert a["acc"]["params"] == b["acc"]["params"]


@pytest.mark.slow
@pytest.mark.parametrize("effects", [{}, {"acc.quadratic.z": 1e-4}])
def test_compiled_and_numpy_paths_give_the_same_trials(monkeypatch, effects):
    """The compiled route (table kinematics, the fits' linear start and LM in C; with an effect, the
    augmented model derived into the cache, augmented.compiled_form) and the numpy one
    (SIMUCAL_NO_COMPILE) simulate from the same draws and reach the same estimates."""
    from simucal.fit import augmented, catalog
    from simucal.turntable import kinematics
    from simucal.turntable.montecarlo import chunk_of_trials
    sc = Scenario(acc_effects=effects)
    if effects:
        derived = augmented.compiled_form(augmented.AugmentedModel("acc_baseline", tuple(effects)))
        assert derived is not None and derived.backend == "casadi-c" and len(derived.params) == 10
    compiled = chunk_of_trials(sc, 300, 3, 0)
    monkeypatch.setenv("SIMUCAL_NO_COMPILE", "1")
    for cached in (catalog.load, kinematics.compiled):
        cached.cache_clear()
    try:
        assert kinematics.compiled() is None
        plain = chunk_of_trials(sc, 300, 3, 0)
    finally:
        monkeypatch.delenv("SIMUCAL_NO_COMPILE")
        for cached in (catalog.load, kinematics.compiled):
            cached.cache_clear()
    assert compiled["failed"] == plain["failed"] == []
    for key in ("acc", "gyro", "phi"):  # both stop within 1e-6 std of the optimum
        spread = np.std(plain[key], axis=0)
        assert np.all(np.abs(compiled[key] - plain[key]) < 1e-5 * spread), key


def test_table_kinematics_compiled_equals_the_numpy_module():
    """generated/table.c (its cos/sin of the table errors taken once per batch) against generated/table.py."""
    from simucal.generated import table

    from simucal.turntable import kinematics
    if kinematics.compiled() is None:  # SIMUCAL_NO_COMPILE: the numpy module is the only route
        return
    rng = np.random.default_rng(4)
    g, a, b = rng.uniform(-np.pi, np.pi, (3, 200))
    table_err, angle_err = rng.normal(0, 0.01, 4), rng.normal(0, 0.01, (200, 3))
    e = kinematics.errors(table_err, angle_err)
    assert np.allclose(kinematics.specific_force_k(g, a, b, table_err, angle_err),
                       table.specific_force_k(g, a, b, e), rtol=0, atol=1e-14)
    assert np.allclose(kinematics.outer_axis_k(a, b, table_err, angle_err), table.outer_axis_k(a, b, e),
                       rtol=0, atol=1e-14)


@settings(max_examples=30, deadline=None)
@given(st.integers(1, 24), st.integers(0, 2 ** 31))
def test_the_turning_vertical_equals_the_kinematics_at_every_outer_angle(k_rev, seed):
    """specific_force_turning_k (one evaluation turned about the outer axis by Rodrigues' formula)
    against the table's kinematics evaluated at each of the k_rev outer angles, with table errors."""
    from simucal.turntable import kinematics
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-np.pi, np.pi, (2, 5))
    table_err, angle_err = rng.normal(0, 0.01, 4), rng.normal(0, 0.01, (3, 5, 3))
    turned = kinematics.specific_force_turning_k(k_rev, a, b, table_err, angle_err,
                                                 kinematics.outer_axis_k(a, b, table_err, angle_err))
    gam = np.arange(k_rev) * 2 * np.pi / k_rev
    each = kinematics.specific_force_k(gam[:, None, None], a, b, table_err,
                                       np.broadcast_to(angle_err, (k_rev, 3, 5, 3)))
    assert turned.shape == each.shape == (k_rev, 3, 5, 3)
    assert np.abs(turned - each).max() < 1e-14


def test_a_revolution_is_sampled_at_the_fewest_outer_angles_that_average_it_exactly():
    """A quadratic term averages exactly over 3 outer angles; a gyro's sign-dependent scale on an axis
    whose input changes sign as the table turns (x in the paper's plan) over none of few: it gets 12.
    The chosen count's rate-run means equal 24's."""
    from simucal.turntable.montecarlo import revolution_samples
    from simucal.turntable.simulate import plant
    quadratic, asymmetric = Scenario(), Scenario()
    plant(quadratic, ["acc.quadratic.z=1e-3"])
    plant(asymmetric, ["gyro.scale_asymmetry.x=1e-3"])
    assert revolution_samples(quadratic) == 3 and revolution_samples(asymmetric) == 12
    few, many = (simulate_batch(quadratic, 4, np.random.default_rng(1), k_rev=k) for k in (3, 24))
    assert np.abs(few["acc_rate"] - many["acc_rate"]).max() < 1e-14
    kinked = [simulate_batch(asymmetric, 8, np.random.default_rng(0), k_rev=k)["gyro"] for k in (4, 24)]
    assert np.abs(kinked[0] - kinked[1]).max() > 1e-9 * np.abs(kinked[1]).max()  # 4 angles miss the kink


@pytest.mark.slow
def test_an_effect_the_plan_cannot_see_is_refused_before_any_trial():
    """G_xz on the paper's plan (one rate): the noise-free trial's fit fails, so the run says what the
    plan lacks instead of counting thousands of failed trials with a CRLB of nan."""
    sc = Scenario(gyro_effects={"gyro.g_sensitivity.xz": 0.3})
    with pytest.raises(ValueError, match="unobservable.*rate runs of both signs"):
        run(sc, 100, 0)


def test_an_effect_runs_in_numpy_where_the_cache_cannot_take_its_compiled_form(monkeypatch):
    """A read-only cache (or a failed derivation): said once, and the same Monte Carlo in numpy."""
    from simucal.fit import augmented

    def read_only(*args):
        raise OSError(30, "Read-only file system")
    augmented._derived.cache_clear()
    monkeypatch.setattr(augmented, "_derive", read_only)
    try:
        with pytest.warns(UserWarning, match="could not be derived into the cache"):
            r = run(Scenario(acc_effects={"acc.quadratic.z": 1e-4}), 300, 0)
    finally:
        augmented._derived.cache_clear()
    assert "numpy" in r["backend"]["acc"] and r["failed"] == 0


MODEL_FILE = """from simucal.derive.frames import column_input, f_b
from simucal.derive.models import Term
from simucal.derive.models.baseline import ACC_BASELINE
MODELS = [ACC_BASELINE.with_terms("acc_{name}_mc", [Term("{param}", "x", {term}, "{unit}", "a term of the test's")])]
"""


@pytest.mark.slow
def test_a_users_model_file_runs_compiled_with_std_at_the_bound(tmp_path):
    """--effect-file: the user's model is the truth and the fitted model, through the compiled fit
    (any library effect or user model file); its term's std meets its CRLB and its mean the
    truth. A term reading a column the averaged positions never vary is refused, naming the column."""
    (tmp_path / "cubic.py").write_text(MODEL_FILE.format(name="cubic", param="K3_x", term="f_b[0] ** 3",
                                                          unit="g/g^3"))
    out = tmp_path / "mc.json"
    r = CliRunner().invoke(main, ["montecarlo", "--effect-file", str(tmp_path / "cubic.py"), "--set", "K3_x=1e-3",
                                  "--trials", "4000", "--seed", "3", "-o", str(out)])
    assert r.exit_code == 0, r.output
    res = json.loads(out.read_text())
    assert res["backend"]["acc"] == "compiled acc_cubic_mc (one call per batch)" and res["failed"] == 0
    k3 = res["parameters"]["acc.K3_x"]
    assert k3["truth"] == 1e-3 and abs(k3["mean"] - k3["truth"]) < 4 * k3["std"] / np.sqrt(4000)
    assert 0.93 < k3["std_over_crlb"] < 1.07, k3
    (tmp_path / "supply.py").write_text(MODEL_FILE.format(name="supply", param="bV_x", unit="g/V",
                                                           term='column_input("supply_v", "V", "supply")'))
    r = CliRunner().invoke(main, ["montecarlo", "--effect-file", str(tmp_path / "supply.py"), "--set", "bV_x=1e-4",
                                  "--trials", "100", "-o", str(tmp_path / "mc2.json")])
    assert r.exit_code == 2 and "reads supply_v" in r.output and "--column supply_v" in r.output, r.output
    assert not (tmp_path / "mc2.json").exists()


@pytest.mark.slow
def test_a_model_file_is_refused_only_for_inputs_the_averaged_positions_never_vary(tmp_path):
    """A term in temperature times time is refused naming both inputs (a product, which moving one
    input from zero would miss) and the simulate command that gives them; a gyro term in the specific
    force, which the Monte Carlo supplies, runs, seen by rate runs of both signs (--rates-dps)."""
    header = ("from simucal.derive.frames import dtemp_c, f_b, t_s\nfrom simucal.derive.models import Term\n"
              "from simucal.derive.models.baseline import ACC_BASELINE, GYRO_BASELINE\n")
    (tmp_path / "drift.py").write_text(header + 'MODELS = [ACC_BASELINE.with_terms("acc_drift_mc", [Term("c_x", "x", '
                                       'dtemp_c * t_s, "g/(degC s)", "a drift growing with temperature")])]\n')
    r = CliRunner().invoke(main, ["montecarlo", "--effect-file", str(tmp_path / "drift.py"), "--set", "c_x=1e-6",
                                  "--trials", "100", "-o", str(tmp_path / "a.json")])
    assert r.exit_code == 2 and "reads dtemp_c, t_s" in r.output, r.output
    assert "--column temp_c=LOW:HIGH" in r.output and "--column t_s" not in r.output
    (tmp_path / "gsens.py").write_text(header + 'MODELS = [GYRO_BASELINE.with_terms("gyro_gsens_mc", [Term("G_xz", '
                                       '"x", f_b[2], "(deg/h)/g", "x rate from the z specific force")])]\n')
    r = CliRunner().invoke(main, ["montecarlo", "--effect-file", str(tmp_path / "gsens.py"), "--set", "G_xz=0.3",
                                  "--rates-dps", "10,-10", "--trials", "3000", "-o", str(tmp_path / "g.json")])
    assert r.exit_code == 0, r.output
    g = json.loads((tmp_path / "g.json").read_text())["parameters"]["gyro.G_xz"]
    assert g["truth"] == 0.3 and 0.9 < g["std_over_crlb"] < 1.1, g


@pytest.mark.slow
def test_an_effect_is_reported_under_its_own_id(tmp_path):
    """The effect's estimate is keyed acc.quadratic.z, the id the user typed (not acc.acc.quadratic.z)."""
    out = tmp_path / "mc.json"
    r = CliRunner().invoke(main, ["montecarlo", "--effect", "acc.quadratic.z=1e-4", "--trials", "200", "-o", str(out)])
    assert r.exit_code == 0, r.output
    keys = json.loads(out.read_text())["parameters"]
    assert "acc.quadratic.z" in keys and not any(k.startswith(("acc.acc.", "gyro.gyro.")) for k in keys)
    assert "acc.quadratic.z " in r.output
