"""An option a run will not use is refused in one line naming what it applies to, before any work
(simulate --scenario field dropped --effect, --plan, ...; plan --score dropped --rates-dps;
--plot with a name that is not an image failed after the work)."""
import json
import pytest
from cli_helpers import refused as _refused
from cli_helpers import run as _run
from simucal.handheld.simulate import write_still
from simucal.turntable.simulate import Scenario, write



@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("unused")
    write(root / "set", Scenario(), 1)
    write_still(root / "still", seconds=60.0)
    assert _run("noise", root / "still", "-o", root / "noise.json").exit_code == 0
    assert _run("simulate", "-o", root / "field", "--scenario", "field").exit_code == 0
    (root / "m.py").write_text("MODELS = []\n")
    return root



@pytest.mark.parametrize("args,words", [
    (["simulate", "-o", "{o}", "--scenario", "field", "--effect", "acc.quadratic.z=1e-4"], ["--effect", "paper"]),
    (["simulate", "-o", "{o}", "--scenario", "field", "--plan", "table1"], ["--plan", "paper"]),
    (["simulate", "-o", "{o}", "--scenario", "field", "--column", "temp_c=20:40"], ["--column"]),
    (["simulate", "-o", "{o}", "--scenario", "field", "--acc-unit", "g", "--gyro-model", "gyro_baseline"],
     ["--acc-unit", "--gyro-model"]),
    (["simulate", "-o", "{o}", "--scenario", "field", "--effect-file", "{d}/m.py"], ["--effect-file"]),
    (["simulate", "-o", "{o}", "--heading-accuracy-deg", "3"], ["--heading-accuracy-deg", "--scenario field"]),
    (["calibrate", "{d}/set", "-o", "{o}.json", "--heading-accuracy-deg", "3"], ["--heading-accuracy-deg", "field"]),
    (["calibrate", "{d}/set", "-o", "{o}.json", "--window-s", "2"], ["--window-s", "handheld"]),
    (["calibrate", "{d}/set", "-o", "{o}.json", "--scheduler", "processes"], ["--scheduler", "several sets"]),
    (["calibrate", "{d}/set", "-o", "{o}.json", "--noise", "{d}/noise.json", "--acc-noise-g", "1e-5"],
     ["--noise", "--acc-noise-g", "give one of them"]),
    (["plan", "--score", "table1", "--model", "gyro_baseline", "--rates-dps", "5,10", "-o", "{o}.json"],
     ["--rates-dps", "a design"]),
    (["plan", "--score", "table1", "--criterion", "A", "-o", "{o}.json"], ["--criterion", "a design"]),
    (["plan", "--score", "table1", "--sizes", "1e-4,1e-4", "-o", "{o}.json"], ["--sizes", "--separate"]),
    (["plan", "--score", "table1", "--rate-dps", "20", "-o", "{o}.json"], ["--rate-dps", "gyro models"]),
    (["plan", "--positions", "12", "--model", "gyro_baseline", "--rates-dps", "5,10", "--rate-dps", "20",
      "-o", "{o}.csv"], ["--rate-dps"]),
    (["field-drift", "{d}/field", "-o", "{o}.json", "--plot", "{o}.json.fig"], ["--plot", "not an image", ".png"]),
])
def test_an_option_the_run_would_not_use_is_refused(made, tmp_path, args, words):
    out = tmp_path / "out"
    _refused(_run(*[a.format(d=made, o=out) for a in args]), *words)
    assert list(tmp_path.iterdir()) == []  # refused before any work: nothing written


@pytest.mark.slow
def test_the_options_a_run_uses_still_take_their_defaults(made, tmp_path):
    """The field set's heading accuracy, now refused elsewhere, is 5 deg where not given."""
    cals = []
    for extra in ([], ["--heading-accuracy-deg", "5"], ["--heading-accuracy-deg", "1"]):
        r = _run("calibrate", made / "field", "-o", tmp_path / f"c{len(cals)}.json", *extra)
        assert r.exit_code == 0, r.output
        cals.append(json.loads((tmp_path / f"c{len(cals)}.json").read_text())["gyro"]["std"])
    assert cals[0] == cals[1] != cals[2]
    r = _run("plan", "--positions", "12", "--model", "gyro_baseline", "--rates-dps", "5,10", "-o", tmp_path / "p.csv")
    assert r.exit_code == 0, r.output  # the design's rates: chosen from --rates-dps, not --rate-dps's 10 alone
    assert set(json.loads((tmp_path / "p.json").read_text())["rows"][0][3:]) <= {5.0, 10.0}
