"""calibrate's options as one frozen object (simucal/options.py): the API's keywords are its fields, help() lists
each with its type, default and unit, and an option a method does not read is refused by one rule, for every
method of the registry."""
import dataclasses
import inspect
import pydoc
import re

import pytest
from cli_helpers import run

import simucal
from simucal import methods, options
from simucal.errors import ArgumentError, CalibrationError, InputError
from simucal.handheld.static_detect import DetectSettings
from simucal.options import CalibrateOptions

# a value away from its default for every option a caller gives (add's effects and its "auto" apart)
SAMPLES = {"add": ("acc.quadratic.z",), "add auto": ("auto",), "acc_model": "acc_extended",
           "gyro_model": "gyro_extended", "acc_noise_g": 1e-5, "gyro_noise_dph": 0.01, "heading_accuracy_deg": 1.0,
           "noise": None, "detect": DetectSettings(window_s=2.0)}  # noise: the fixture's file
SCENARIO = {methods.TURNTABLE: "paper", methods.STREAM: "handheld", methods.FIELD: "field",
            methods.SEQUENCE: "sequence"}


def _options(name, value):
    return CalibrateOptions(**{"add" if name == "add auto" else name: value})


def test_every_option_a_caller_gives_has_a_sample_and_only_those_are_refusable():
    refusable = {n for n in options.keywords() if n not in options.EVERY_METHOD} - {"add"} | {"add", "add auto"}
    assert refusable == set(SAMPLES)
    for m in methods.METHODS.values():  # a method reads only what exists
        assert m.reads <= set(SAMPLES), m.name


def test_calibrate_s_keywords_are_the_options_fields_with_their_defaults():
    params = inspect.signature(simucal.calibrate).parameters
    keywords = [n for n, p in params.items() if p.kind is p.KEYWORD_ONLY]
    assert keywords == options.keywords()
    defaults = CalibrateOptions()
    for n in keywords:
        assert params[n].default == getattr(defaults, n), n


def test_help_lists_every_option_with_its_type_default_and_unit():
    text = pydoc.render_doc(simucal.calibrate, renderer=pydoc.plaintext)
    for f in dataclasses.fields(CalibrateOptions):
        if f.metadata["flag"] is None:
            assert not re.search(rf"^\s+{f.name} :", text, re.M), f.name  # simucal's own: not a keyword
            continue
        line = re.search(rf"^\s+{f.name} : (.+), default (.+)$", text, re.M)
        assert line, f.name
        assert line.group(2) == repr(f.default), f.name
        after = text[line.end():].split(" : ", 1)[0]
        assert f.metadata["flag"].split(",")[0] in after, f.name
        if f.metadata["unit"]:
            assert f"In {f.metadata['unit']}." in after, f.name
    units = {f.name: f.metadata["unit"] for f in dataclasses.fields(CalibrateOptions)}
    assert (units["acc_noise_g"], units["gyro_noise_dph"], units["heading_accuracy_deg"], units["t_ref_c"]) == (
        "g", "deg/h", "deg", "degC")  # the unit a name carries is the one its help says


def test_every_flag_is_the_command_s():
    help_text = run("calibrate", "--help").output
    for f in dataclasses.fields(CalibrateOptions):
        for flag in re.findall(r"--[a-z-]+", f.metadata["flag"] or ""):
            assert flag in help_text, flag


@pytest.mark.parametrize("method", list(methods.METHODS))
def test_the_rule_refuses_exactly_what_a_method_does_not_read(method):
    m = methods.METHODS[method]
    for name, value in SAMPLES.items():
        o = _options(name, value if name != "noise" else "noise.json")
        if name in m.reads:
            m.refuse_unused(o)  # read: no refusal
            continue
        with pytest.raises(CalibrationError) as e:
            m.refuse_unused(o)
        flag = "--add auto" if name == "add auto" else dict(
            (f.name, f.metadata["flag"]) for f in dataclasses.fields(CalibrateOptions))[name]
        takes = [x.name for x in methods.METHODS.values() if name in x.reads]
        assert str(e.value).startswith(f"{flag} does not apply to method {method} ")
        assert f"it applies to method {' or '.join(takes)} " in str(e.value)


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    root = tmp_path_factory.mktemp("options")
    made = {kind: simucal.simulate(s, seed=1) for kind, s in SCENARIO.items()}
    still = simucal.simulate("still", seed=1)
    still.write(root / "still")
    assert run("noise", root / "still", "-o", root / "noise.json").exit_code == 0
    return made, root / "noise.json"


@pytest.mark.parametrize("method", list(methods.METHODS))
def test_calibrate_refuses_an_option_its_method_does_not_read(sets, method):
    """End to end, through simucal.calibrate on data of the method's kind: every option it does not read is
    refused before any work (the caller's set is left as it was)."""
    made, noise_file = sets
    m = methods.METHODS[method]
    ms = made[m.data]
    for name in sorted(set(SAMPLES) - m.reads):
        value = noise_file if name == "noise" else SAMPLES[name]
        with pytest.raises(CalibrationError, match=f"does not apply to method {method} "):
            simucal.calibrate(ms, method=method, **{"add" if name == "add auto" else name: value})


def test_a_misspelt_option_and_options_given_twice_are_refused(sets):
    made, _ = sets
    with pytest.raises(ArgumentError, match="did you mean method="):
        simucal.calibrate(made[methods.TURNTABLE], methd="exact")
    with pytest.raises(ArgumentError, match="acc_noise_g='1e-5' is a str, a number"):
        simucal.calibrate(made[methods.TURNTABLE], acc_noise_g="1e-5")
    with pytest.raises(InputError, match=r"and add=: give the options as one object or as keywords, not both"):
        simucal.calibrate(made[methods.TURNTABLE], CalibrateOptions(method="exact"), add="acc.quadratic.z")


def test_a_thermal_option_is_never_dropped(sets, tmp_path):
    """thermal_degree makes a calibration over temperature (as --thermal-degree does), refused for one plateau,
    never a plain calibration; calibrate_each, which calibrates each set on its own, refuses a thermal one."""
    made, _ = sets
    with pytest.raises(CalibrationError, match="shows no temperature dependence|temp_c"):
        simucal.calibrate(made[methods.TURNTABLE], thermal_degree=1)
    made[methods.TURNTABLE].write(tmp_path / "set")
    with pytest.raises(InputError, match="calibrate_each: options with thermal"):
        simucal.calibrate_each([tmp_path / "set"], tmp_path / "cals", options=CalibrateOptions(thermal_degree=1))
    assert not (tmp_path / "cals").exists()


def test_the_options_object_is_frozen_and_takes_one_id_as_a_string():
    o = CalibrateOptions(add="acc.quadratic.z")
    assert o.add == ("acc.quadratic.z",) and CalibrateOptions(add=["auto", "x"]).effect_ids == ("x",)
    assert CalibrateOptions(add=["auto"]).auto and not o.auto
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.method = "linear"  # type: ignore[misc]
