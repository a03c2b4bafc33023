"""Refusals that were right but did not say why: each now names its cause in one line (the file or argument, the
rule, the fix), through the command line and the API: a model file that runs itself or never ends, a folder given
to --add, a model that reads a sensor column as an auxiliary input, two sets whose calibration files would be one,
a coplanar plan scored, and an average_s the noise file cannot match."""
import json
import re
from pathlib import Path

import pytest

import simucal
from simucal.errors import SimucalError
from simucal.turntable.simulate import Scenario, write
from tests.cli_helpers import refused, run


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    root = tmp_path_factory.mktemp("unclear")
    write(root / "table", Scenario(), 1)
    return root / "table"


@pytest.fixture
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))


@pytest.mark.slow
def test_a_model_file_that_runs_itself_names_the_loop(tmp_path, own_cache):
    """Each way a file includes itself (exec of its own text, runpy, load_model_file of its own path) was
    'RecursionError: maximum recursion depth exceeded': the line and the loop are named."""
    bodies = {"exec": "exec(open(__file__).read())\n",
              "runpy": "import runpy\nrunpy.run_path(__file__)\n",
              "load": "from simucal.derive.registry import load_model_file\nMODELS = load_model_file(__file__)\n"}
    for name, body in bodies.items():
        f = tmp_path / f"{name}.py"
        f.write_text(body)
        line = body.count("\n")  # the file's last line runs it again
        refused(run("derive", "--model", f), f"{f}, line {line}: the file runs itself", "a loop without end")
    with pytest.raises(SimucalError, match="load.py, line 2: the file runs itself"):
        simucal.derive_model(tmp_path / "load.py")


@pytest.mark.slow
def test_a_model_file_that_never_ends_names_the_line_it_loops_on(tmp_path, own_cache, monkeypatch):
    monkeypatch.setenv("SIMUCAL_DERIVE_TIMEOUT_S", "20")  # past SymPy's import, however loaded the machine
    f = tmp_path / "spin.py"
    f.write_text("x = 1\nwhile x: x += 1  # the loop on one line, wherever the stack is taken\n")
    refused(run("derive", "--model", f), f"{f}, line 2: deriving it took more than 20 s, still at this line",
            "SIMUCAL_DERIVE_TIMEOUT_S")


def test_a_folder_after_add_is_named_a_folder(table, tmp_path):
    """--add some/dir/set was "unknown effect 'some/dir/set'" and every family: a folder, the set's place named."""
    line = refused(run("calibrate", table, "--add", table, "-o", tmp_path / "c.json"),
                   f"--add {table}: a folder (a measurement set?)", "the command's argument, not after --add")
    assert "famil" not in line and not (tmp_path / "c.json").exists()
    refused(run("diagnose", table, "--add", tmp_path / "nothing" / "here"), "a path, and no such file")
    with pytest.raises(SimucalError, match="a folder"):
        simucal.calibrate(str(table), add=[str(table)])
    assert "unknown effect 'acc.quadratc.z'" in refused(run("calibrate", table, "--add", "acc.quadratc.z", "-o",
                                                          tmp_path / "c.json"))  # a typo still an effect's


@pytest.mark.slow
def test_a_sensor_column_as_an_auxiliary_input_is_named(table, tmp_path, own_cache):
    """A model's column_input named ax was reported as data lacking an auxiliary input ax (which they hold)."""
    f = tmp_path / "ax_model.py"
    f.write_text("from simucal.derive.frames import column_input\nfrom simucal.derive.models import Term\n"
                 "from simucal.derive.models.baseline import ACC_BASELINE\n"
                 "ax = column_input('ax', 'g', 'x output')\n"
                 "MODELS = [ACC_BASELINE.with_terms('acc_ax_in', [Term('bA_z', 'z', ax, '1', 'z bias with ax')])]\n")
    refused(run("calibrate", table, "--add", f, "-o", tmp_path / "c.json"), str(f), "reads ax as an auxiliary input",
            "ax is a spec sensor column", "column_input('ax_aux'")
    assert not (tmp_path / "c.json").exists()


def test_two_sets_of_one_folder_name_say_whose_files_collide(table, tmp_path):
    import shutil
    a, b = (Path(shutil.copytree(table, tmp_path / side / "set")) for side in ("a", "b"))
    refused(run("calibrate", a, b, "-o", tmp_path / "out"), f"{a} and {b} would both be calibrated into "
            f"{tmp_path / 'out' / 'set.json'}", "rename one of the folders")
    assert not (tmp_path / "out").exists()
    with pytest.raises(SimucalError, match=f"{a} and {b} would both"):
        simucal.calibrate_each([a, b], tmp_path / "out")


def test_a_coplanar_plan_scored_is_named_coplanar(tmp_path):
    plan = tmp_path / "ring.csv"  # twelve turns of the inner axis: every direction in one plane
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(f"0,0,{30 * i}\n" for i in range(12)))
    for model, sensor in (("acc_baseline", "accelerometer"), ("gyro_baseline", "gyro")):
        line = refused(run("plan", "--score", plan, "--model", model), f"plan {plan}: the 12 {sensor} input directions",
                       "coplanar", "add positions tilted out of that plane")
        normal = json.loads(re.search(r"normal (\[[^]]*\])", line).group(1))
        assert abs(abs(normal[1]) - 1) < 1e-9, line  # the ring's axis
    with pytest.raises(SimucalError, match="coplanar"):
        simucal.plan(str(plan))
    assert simucal.plan("table1")["positions"] > 0  # a plan with spread directions scores


def test_an_average_s_the_noise_file_cannot_match_is_named(tmp_path):
    """average_s 1e6 on averaged rows was blamed on the noise file (its ratio to the stated noise named, not
    average_s): the file, the key, its value and the range where the curve meets the stated noise."""
    write(tmp_path / "raw", Scenario(plan="table1", rate_hz=20.0), 3)
    assert run("noise", tmp_path / "raw", "-o", tmp_path / "n.json").exit_code == 0
    write(tmp_path / "avg", Scenario(plan="table1"), 5)
    meta = json.loads((tmp_path / "avg" / "meta.json").read_text())
    (tmp_path / "avg" / "meta.json").write_text(json.dumps({**meta, "average_s": 1e6}))
    args = ["calibrate", tmp_path / "avg", "--noise", tmp_path / "n.json", "-o", tmp_path / "c.json"]
    line = refused(run(*args), f"{tmp_path / 'avg' / 'meta.json'}: average_s is 1e+06 s", "n.json's Allan curve",
                   "acc_noise_g 1e-05", "average_s must lie in that range")
    lo, hi = map(float, re.search(r"at averages of ([0-9.e+-]+) to ([0-9.e+-]+) s", line).groups())
    assert 0 < lo < hi < 1e6, line
    (tmp_path / "avg" / "meta.json").write_text(json.dumps({**meta, "average_s": (lo * hi) ** 0.5}))
    r = run(*args)
    assert r.exit_code == 0, r.output  # an average_s within the range named is taken
