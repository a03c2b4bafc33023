"""The command line is the API plus printing, so both write the same files
(simulate, validate, diagnose, noise; calibrate in test_api.py); the rest of the API (simulate,
diagnose, noise, tables) as a notebook user meets it, with only the documented names."""
import inspect
import re
import sys

import numpy as np
import pytest
from click.testing import CliRunner

import simucal
from simucal.cli import main
from simucal.options import CalibrateOptions


def _cli(*args):
    res = CliRunner().invoke(main, [str(a) for a in args])
    assert res.exit_code == 0, res.output
    return res


_NUMBER = re.compile(rb"-?\d+\.?\d*(?:[eE][-+]?\d+)?")


def _same_files(a, b):
    """Every file under folder a has its twin under b: the same text, and the same numbers to 1e-9
    relative. Not byte for byte: numpy's SIMD sums and LAPACK depend on how an array happens to
    be aligned in memory, so one computation run twice in one process can differ in the 14th
    digit (seen once in CI: a lack-of-fit F of 17.156036047262326 against ...263054)."""
    names = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert names and names == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for n in names:
        _same_file(a / n, b / n)


def _same_file(a, b):
    x, y = a.read_bytes(), b.read_bytes()
    if x == y:
        return
    assert _NUMBER.split(x) == _NUMBER.split(y), a  # the words, the layout and the number of numbers
    u = np.array([float(t) for t in _NUMBER.findall(x)])
    v = np.array([float(t) for t in _NUMBER.findall(y)])
    assert np.allclose(u, v, rtol=1e-9, atol=0.0), (a, u[~np.isclose(u, v, rtol=1e-9, atol=0.0)])


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    """The same simulations by the command and by the API: a turntable test with a planted effect, a
    raw recording of the same unit (20 Hz: noise pools its static rows), a field set, a hand-placed one."""
    root = tmp_path_factory.mktemp("api_cli")
    runs = {"effect": (["--seed", "1", "--effect", "acc.quadratic.z=2e-4"],
                       dict(seed=1, effects={"acc.quadratic.z": 2e-4})),
            "raw": (["--seed", "2", "--rate-hz", "20"], dict(seed=2, rate_hz=20.0)),
            "field": (["--scenario", "field", "--seed", "3"], dict(scenario="field", seed=3)),
            "hand": (["--scenario", "handheld", "--seed", "4", "--effect", "acc.quadratic.z=1e-3"],
                     dict(scenario="handheld", seed=4, effects=["acc.quadratic.z=1e-3"]))}
    for name, (args, kwargs) in runs.items():
        _cli("simulate", "-o", root / "cli" / name, *args)
        simucal.simulate(**kwargs).write(root / "api" / name)
    return root


def test_simulate_writes_the_same_sets(sets):
    _same_files(sets / "cli", sets / "api")
    hand = simucal.read_set(sets / "api" / "hand")
    assert hand.segments is None and hand.meta["acc_unit"] == "counts"  # a stream: a hand-placed session
    assert simucal.read_set(sets / "api" / "field").segments is not None


@pytest.mark.slow
def test_validate_diagnose_noise_write_the_same_files(sets, tmp_path):
    data = sets / "cli"
    cal = tmp_path / "cal.json"
    _cli("calibrate", data / "effect", "-o", cal, "--add", "acc.quadratic.z")
    for how in ("cli", "api"):
        (tmp_path / how).mkdir()
    out_cli, out_api = tmp_path / "cli", tmp_path / "api"
    _cli("validate", cal, data / "raw", "-o", out_cli / "v.json", "--html", out_cli / "v.html")
    _cli("diagnose", data / "effect", "-o", out_cli / "d.json", "--html", out_cli / "d.html")
    _cli("noise", data / "raw", "-o", out_cli / "n.json", "--html", out_cli / "n.html")
    results = {"v": simucal.validate(str(cal), str(data / "raw")), "d": simucal.diagnose(str(data / "effect")),
               "n": simucal.noise(str(data / "raw"))}
    for name, result in results.items():
        for ext in ("json", "html"):
            simucal.save(out_api / f"{name}.{ext}", result)
    _same_files(out_cli, out_api)


def test_diagnosis_and_noise_as_tables(sets):
    d = simucal.diagnose(sets / "api" / "effect")
    top = d.candidates.iloc[0]  # pandas installed: a DataFrame, strongest candidate first
    assert top["id"] == "acc.quadratic.z" and top["significant"] and abs(top["estimate"] - 2e-4) < 5 * top["std"]
    assert "--add acc.quadratic.z" in d.next_command and "add" in d.verdict["acc"].lower()
    assert "passes" in d.verdict["gyro"] or "explains" in d.verdict["gyro"]
    n = simucal.noise(sets / "api" / "raw")
    white = n.terms[(n.terms.sensor == "acc") & (n.terms.term == "N")]
    assert len(white) == 3 and (white.status == "seen").all()
    # the simulator's row noise (1e-5 g at 20 Hz) as a density: 1e-5 g / sqrt(20 Hz) = 2.24 ug/sqrt(Hz)
    assert np.allclose(white.value, 1e-5 / np.sqrt(20.0) * 1e6, rtol=0.2), white.value
    unseen = n.terms[n.terms.status == "not seen"]
    assert unseen.value.isna().all() and (unseen.bound_95 > 0).all()  # absent: no value, a bound


def test_tables_are_rows_without_pandas(sets, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # pandas cannot be imported
    d = simucal.diagnose(sets / "api" / "effect")
    assert isinstance(d.candidates, list) and d.candidates[0].id == "acc.quadratic.z"
    rows = simucal.table_rows(simucal.noise(sets / "api" / "raw").terms)
    assert all(isinstance(r, simucal.Term) for r in rows) and {r.sensor for r in rows} == {"acc", "gyro"}


def test_simulate_refuses_what_a_scenario_does_not_use():
    with pytest.raises(ValueError, match=r"plan \(--plan\), effects \(--effect\): a turntable test's"):
        simucal.simulate("field", plan="table1", effects={"acc.quadratic.z": 1e-4})
    with pytest.raises(ValueError, match=r"temperature_c \(--temperature-c\).*handheld scenario takes"):
        simucal.simulate("handheld", temperature_c=30.0)
    with pytest.raises(ValueError, match="heading_accuracy_deg"):
        simucal.simulate(heading_accuracy_deg=3.0)
    with pytest.raises(ValueError, match="scenario 'bench'"):
        simucal.simulate("bench")


def test_command_line_constants_are_the_api_s():
    """The command line writes a few names and defaults itself so that it starts without numpy: they are
    the library's."""
    from simucal.api import simulation
    from simucal.cli import main
    from simucal.cli import sets as cli_sets
    from simucal.field.simulate import FieldScenario
    from simucal.handheld.static_detect import DetectSettings
    from simucal.io import units
    from simucal.turntable.simulate import ARCMIN, Scenario, at_temperature
    shown = {(c, p.name): getattr(p, "show_default", None) for c, cmd in main.commands.items() for p in cmd.params}
    detect = DetectSettings()
    for name, value in (("threshold_factor", detect.threshold_factor), ("window_s", detect.window_s),
                        ("min_static_s", detect.min_static_s),
                        ("heading_accuracy_deg", CalibrateOptions().heading_accuracy_deg)):
        assert float(shown[("calibrate", name)]) == value, name
    assert float(shown[("simulate", "heading_error_deg")]) == FieldScenario().heading_error_deg
    table, temperature = Scenario(), inspect.signature(at_temperature).parameters
    assert (shown[("simulate", "plan")], shown[("simulate", "acc_model")], shown[("simulate", "gyro_model")]) == (
        table.plan, table.acc_model, table.gyro_model)
    assert float(shown[("simulate", "position_error_arcmin")]) * ARCMIN == pytest.approx(table.position_error_rad)
    assert float(shown[("simulate", "t_ref_c")]) == temperature["t_ref_c"].default
    assert float(shown[("simulate", "temperature_wander_c")]) == temperature["wander_c"].default
    assert cli_sets.SCENARIOS == simulation.SCENARIOS
    assert (cli_sets.ACC_UNITS, cli_sets.GYRO_UNITS) == (units.ACC_UNITS, units.GYRO_UNITS)
    assert cli_sets.DEFAULT_GRAVITY == units.DEFAULT_GRAVITY
    from simucal.api import imports
    from simucal.cli import common as cli_common
    assert cli_common.MAX_TRIALS == simulation.MAX_TRIALS
    from simucal.api import planning
    from simucal.cli import tools as cli_tools
    assert cli_tools.PAPER_RATE_DPS == planning.PAPER_RATE_DPS
    assert (cli_sets.FORMATS, cli_sets.FERRARIS_HZ, cli_sets.ANNOTATED_HZ, cli_sets.ANNOTATED_ACC,
            cli_sets.ANNOTATED_GYRO) \
        == (imports.FORMATS, imports.FERRARIS_HZ, imports.ANNOTATED_HZ, imports.ANNOTATED_ACC, imports.ANNOTATED_GYRO)


# what each command calls (beside its options' own use of them)
API_OF = {"calibrate": ("calibrate", "calibrate_each"), "diagnose": ("diagnose",), "validate": ("validate",),
          "noise": ("noise",), "simulate": ("simulate",), "montecarlo": ("montecarlo",), "lot": ("lot",),
          "plan": ("plan", "sequence_observability", "design_sequence"), "import": ("import_recording",),
          "convert": ("convert",), "certificate": ("certificate",)}
# the options that say what the command line does with a result, which Python does by itself
CLI_ONLY = {"output", "out_dir", "html", "units", "kalibr", "px4", "ardupilot", "store", "force",
            "design",     # plan --design: design_sequence is a function of its own
            "scenario"}   # montecarlo --scenario: the paper's only


def test_every_option_is_the_api_keyword_of_the_same_name():
    """`--thermal-degree` is `thermal_degree=`, `--threshold-factor` DetectSettings' `threshold_factor`: a
    repeated option is the keyword's plural, `--no-X` is X=False; every other name is one in both."""
    import dataclasses

    kwargs = {f.name for f in dataclasses.fields(simucal.DetectSettings)}  # calibrate's keywords hold the rest
    unmatched = {}
    for command, functions in API_OF.items():
        keywords = set().union(*(inspect.signature(getattr(simucal, f)).parameters for f in functions))
        keywords |= kwargs if command == "calibrate" else set()
        for option in main.commands[command].params:
            if option.param_type_name != "option" or option.hidden:
                continue
            names = {o[2:].replace("-", "_") for o in option.opts if o.startswith("--")}
            names |= {n + "s" for n in names if option.multiple} | {n[3:] for n in names if n.startswith("no_")}
            if not names & (keywords | CLI_ONLY):
                unmatched.setdefault(command, []).append(max(option.opts, key=len))
    assert not unmatched, unmatched


@pytest.mark.slow
def test_deprecated_names_warn_and_do_the_same(sets, tmp_path):
    new = _cli("plan", "--score", "table1", "--model", "gyro_baseline", "--rates-dps", "20")
    old = _cli("plan", "--score", "table1", "--model", "gyro_baseline", "--rate-dps", "20")
    assert old.stdout == new.stdout and "CRLB" in new.stdout and "rate runs at 20 deg/s" in new.stdout
    assert "--rate-dps is deprecated" in old.stderr and not new.stderr
    r = _cli("field-drift", sets / "cli" / "field", "-o", tmp_path / "d.json", "--plot", tmp_path / "f.png",
             "--html", tmp_path / "f.html")
    assert "--plot is deprecated" in r.stderr and (tmp_path / "f.png").stat().st_size > 1000
    page = (tmp_path / "f.html").read_text()
    assert page.count("data:image/png") == 1 and "north drift estimate (Fig. 4)" in page
    # the page is simucal.save's of the API's field calibration
    simucal.save(tmp_path / "api.html", simucal.calibrate(str(sets / "cli" / "field"), method="field"),
                 calibration_path=tmp_path / "d.json")
    _same_file(tmp_path / "f.html", tmp_path / "api.html")


def test_thermal_calibration_and_its_page_the_same(tmp_path):
    """calibrate --thermal -o --html is simucal.calibrate([plateaus]) and save (.json, .html)."""
    plateaus = []
    for t in (0, 25, 50):
        plateaus.append(tmp_path / f"p{t}")
        simucal.simulate(seed=t, temperature_c=float(t), temperature_wander_c=0.3).write(plateaus[-1])
    _cli("calibrate", *plateaus, "--thermal", "-o", tmp_path / "cli.json", "--html", tmp_path / "cli.html")
    cal = simucal.calibrate([str(p) for p in plateaus])
    simucal.save(tmp_path / "api.json", cal)
    simucal.save(tmp_path / "api.html", cal, calibration_path=tmp_path / "cli.json")
    for ext in ("json", "html"):
        _same_file(tmp_path / f"cli.{ext}", tmp_path / f"api.{ext}")
    with pytest.raises(ValueError, match="a thermal or field calibration's"):
        simucal.save(tmp_path / "one.html", simucal.calibrate(str(plateaus[0])))


def test_docstring_examples_run(tmp_path, monkeypatch):
    """The API's examples that need no files run as written (the others are marked to skip)."""
    import doctest
    import importlib
    monkeypatch.chdir(tmp_path)
    for name in ("simucal.api", "simucal.io.measurement_set", "simucal.io.calibration", "simucal.api.applying",
                 "simucal.api.simulation",
                 "simucal.api.analyses", "simucal.api.calibrating", "simucal.api.validating", "simucal.api.diagnosing",
                 "simucal.api.lot_reporting", "simucal.api.tables", "simucal.api.vocabulary"):
        result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
        assert result.failed == 0, name
    assert result.attempted > 0
