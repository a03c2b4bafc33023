"""A user's recordings are read-only: no command writes into or over its inputs, a
measurement set is replaced only with --force, and files are written by a temporary name and a
rename, so an interrupted write leaves the old file or the new one, never half."""
import hashlib
import os
import shutil
from pathlib import Path

import pytest
from cli_helpers import refused as _refused
from cli_helpers import run as _run
from simucal.io import outputs
from simucal.turntable.simulate import Scenario, write


def _digest(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(Path(folder).iterdir()) if p.is_file()}



@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("safety")
    write(root / "set", Scenario(), 1)
    assert _run("calibrate", root / "set", "-o", root / "cal.json").exit_code == 0
    return root


@pytest.fixture
def work(made, tmp_path):
    shutil.copytree(made / "set", tmp_path / "set")
    shutil.copy(made / "cal.json", tmp_path / "cal.json")
    return tmp_path



@pytest.mark.parametrize("args,words", [
    (["apply", "{d}/cal.json", "{d}/set", "-o", "{d}/set"], ["over the input"]),
    (["apply", "{d}/cal.json", "{d}/set", "-o", "{d}/set", "--force"], ["over the input"]),
    (["apply", "{d}/cal.json", "{d}/set", "-o", "{d}/set/calibrated"], ["into the input"]),
    (["calibrate", "{d}/set", "-o", "{d}/set/meta.json"], ["into the input"]),
    (["calibrate", "{d}/set", "-o", "{d}/set/cal.json"], ["into the input"]),
    (["diagnose", "{d}/set", "-o", "{d}/d.json", "--html", "{d}/set/samples.csv"], ["into the input"]),
    (["field-drift", "{d}/set", "-o", "{d}/set/drift.json"], ["into the input"]),
    (["simulate", "{d}/set"], ["already holds a measurement set", "--force"]),
    (["import", "csv", "{d}/set/samples.csv", "-o", "{d}/set", "--columns",
      "t_s=t_s,ax=ax,ay=ay,az=az", "--acc-unit", "g", "--gyro-unit", "deg/h", "--latitude-deg", "45"],
     ["over the input"]),
])
def test_no_command_changes_its_inputs(work, args, words):
    before = _digest(work / "set"), _digest(work)
    _refused(_run(*[a.format(d=work) for a in args]), *words)
    assert (_digest(work / "set"), _digest(work)) == before


def test_an_existing_set_is_replaced_only_with_force(work):
    other = work / "other"
    write(other, Scenario(), 2)
    before = _digest(other)
    _refused(_run("apply", work / "cal.json", work / "set", "-o", other), "already holds a measurement set")
    assert _digest(other) == before
    r = _run("apply", work / "cal.json", work / "set", "-o", other, "--force")
    assert r.exit_code == 0, r.output
    assert _digest(other)["samples.csv"] != before["samples.csv"]
    assert not [p for p in other.iterdir() if p.name.startswith(".")]  # no temporary left behind


def test_a_calibration_never_lands_on_another_sets_file(work):
    other = work / "other"
    write(other, Scenario(), 2)
    before = _digest(other)
    _refused(_run("calibrate", work / "set", "-o", other / "meta.json"), "file of the measurement set")
    assert _digest(other) == before


def test_writing_over_a_hard_link_to_an_input_leaves_the_input(work):
    os.link(work / "set" / "samples.csv", work / "linked.json")  # a rename replaces the link, not the data
    before = _digest(work / "set")
    assert _run("calibrate", work / "set", "-o", work / "linked.json").exit_code == 0
    assert _digest(work / "set") == before and (work / "linked.json").read_text().startswith("{")


def test_diagnose_never_writes_its_model_file_over_the_one_it_was_given(work):
    model = work / "d_acc_model.py"
    model.write_text("from simucal.derive.models.baseline import ACC_BASELINE\n"
                     "from simucal.derive.models.effects import acc_quadratic\n"
                     "MODELS = [ACC_BASELINE.with_terms('acc_given_q', [acc_quadratic('y')])]\n")
    text = model.read_text()
    _refused(_run("diagnose", work / "set", "-o", work / "d.json", "--add", model), "over the input")
    assert model.read_text() == text


def test_an_interrupted_write_leaves_the_old_file(tmp_path):
    path = tmp_path / "cal.json"
    path.write_text("old")
    with pytest.raises(RuntimeError):
        with outputs.replacing(path) as tmp:
            tmp.write_text("half")
            raise RuntimeError("interrupted")
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["cal.json"]
    outputs.write_text(path, "new")
    assert path.read_text() == "new" and [p.name for p in tmp_path.iterdir()] == ["cal.json"]


def test_a_stream_written_with_force_over_a_segmented_set_leaves_no_stale_segments(work, made):
    from simucal import io
    from simucal.handheld.simulate import HandheldScenario, write_handheld
    target = work / "target"
    shutil.copytree(made / "set", target)
    write_handheld(target, HandheldScenario(poses=10, rest_s=5.0), 1)
    assert not (target / "segments.csv").exists() and io.read_set(target).segments is None


def test_demo_replaces_only_what_a_demo_wrote(tmp_path):
    write(tmp_path / "out" / "paper", Scenario(), 1)  # a user's set where the demo would write its own
    before = _digest(tmp_path / "out" / "paper")
    _refused(_run("demo", "-o", tmp_path / "out"), "already holds a measurement set")
    assert _digest(tmp_path / "out" / "paper") == before
