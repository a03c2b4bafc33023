"""A command's outputs: two outputs on one path, or one inside the other, are refused
before any work; every output's place is checked writable before the work; a command writes all
its outputs or none."""
import hashlib
import shutil
from pathlib import Path

import pytest
from cli_helpers import refused as _refused
from cli_helpers import run as _run
from simucal.handheld.simulate import write_still
from simucal.io import outputs
from simucal.turntable.simulate import Scenario, write



def _tree(folder):
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else None
            for p in sorted(Path(folder).rglob("*"))}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("together")
    write(root / "set", Scenario(), 1)
    write_still(root / "still", seconds=60.0)
    assert _run("calibrate", root / "set", "-o", root / "cal.json").exit_code == 0
    return root


@pytest.fixture
def work(made, tmp_path):
    for name in ("set", "still"):
        shutil.copytree(made / name, tmp_path / name)
    shutil.copy(made / "cal.json", tmp_path / "cal.json")
    return tmp_path



@pytest.mark.parametrize("args,words", [
    (["noise", "{d}/still", "-o", "{d}/n.json", "--kalibr", "{d}/n.json"], ["-o and --kalibr", "the same file"]),
    (["noise", "{d}/still", "-o", "{d}/n.json", "--html", "{d}/n.json"], ["-o and --html", "the same file"]),
    (["noise", "{d}/still", "-o", "{d}/n", "--html", "{d}/n/n.html"], ["inside"]),
    (["noise", "{d}/still", "-o", "{d}/n.json", "--html", "{d}/./n.json"], ["the same file"]),
    (["validate", "{d}/cal.json", "{d}/set", "-o", "{d}/v.json", "--html", "{d}/v.json"], ["the same file"]),
    (["diagnose", "{d}/set", "-o", "{d}/d.json", "--html", "{d}/d.json"], ["the same file"]),
    (["diagnose", "{d}/set", "-o", "{d}/d.json", "--html", "{d}/d_acc_model.py"], ["acc model file"]),
    (["calibrate", "{d}/set", "{d}/set", "--thermal", "-o", "{d}/th.json", "--html", "{d}/th.json"],
     ["the same file"]),
    (["plan", "--positions", "12", "-o", "{d}/plan.json"], ["JSON sidecar", "the same file"]),
    (["field-drift", "{d}/set", "-o", "{d}/f.png", "--plot", "{d}/f.png"], ["the same file"]),
])
def test_two_outputs_on_one_path_are_refused_before_any_work(work, args, words):
    before = _tree(work)
    _refused(_run(*[a.format(d=work) for a in args]), *words, "give each output its own name")
    assert _tree(work) == before


@pytest.mark.parametrize("args", [
    ["validate", "{d}/cal.json", "{d}/set", "-o", "{d}/v.json"], ["diagnose", "{d}/set", "-o", "{d}/d.json"],
    ["noise", "{d}/still", "-o", "{d}/n.json"], ["lot", "{d}/cals", "-o", "{d}/l.json"],
    ["field-drift", "{d}/set", "-o", "{d}/f.json"], ["calibrate", "{d}/set", "--thermal", "-o", "{d}/th.json"]])
def test_every_page_path_ends_in_html(work, args):
    """--html v.png wrote HTML into a .png: every --html refuses a name not ending in .html or .htm."""
    (work / "cals").mkdir()
    shutil.copy(work / "cal.json", work / "cals" / "a.json")
    before = _tree(work)
    _refused(_run(*[a.format(d=work) for a in args], "--html", work / "v.png"), "a page is HTML", "v.html")
    assert _tree(work) == before


def test_a_set_beside_files_in_a_folder_made_for_them_is_allowed():
    outputs.check(files={"-o": "out/a.json"}, folders=["out"])  # batch calibrate: one <set>.json each
    outputs.check(sets=["out", "out/loop"])  # the demo: its sets inside its folder
    with pytest.raises(outputs.OutputError, match="inside"):
        outputs.check(files={"-o": "out/a.json"}, sets=["out"])  # a file in a set's folder


@pytest.mark.parametrize("args", [
    ["noise", "{d}/still", "-o", "/proc/n.json"],
    ["apply", "{d}/cal.json", "{d}/set", "-o", "/proc/calibrated"],
    ["validate", "{d}/cal.json", "{d}/set", "-o", "{d}/v.json", "--html", "/proc/v.html"],
])
def test_an_output_where_nothing_can_be_written_is_refused_before_the_work(work, args):
    before = _tree(work)
    _refused(_run(*[a.format(d=work) for a in args]), "cannot write in /proc")
    assert _tree(work) == before


def test_a_read_only_folder_is_refused_before_the_work(work, monkeypatch):
    real = outputs.tempfile.mkstemp

    def denied(*a, dir=None, **k):  # root may write anywhere: the folder's answer stands in for chmod 555
        if Path(dir).resolve() == (work / "ro").resolve():
            raise PermissionError(13, "Permission denied")
        return real(*a, dir=dir, **k)
    (work / "ro").mkdir()
    monkeypatch.setattr(outputs.tempfile, "mkstemp", denied)
    _refused(_run("noise", work / "still", "-o", work / "n.json", "--kalibr", work / "ro" / "imu.yaml"),
             "ro/imu.yaml", "Permission denied")
    assert not (work / "n.json").exists()


def test_a_command_that_fails_after_writing_leaves_none_of_its_outputs(work, monkeypatch):
    from simucal.report import kalibr

    def broken(report):
        raise RuntimeError("the last writer failed")
    monkeypatch.setattr(kalibr, "kalibr_yaml", broken)  # after noise.json and the page were written
    before = _tree(work)
    r = _run("noise", work / "still", "-o", work / "n.json", "--html", work / "n.html", "--kalibr", work / "imu.yaml")
    assert r.exit_code == 3, r.output
    assert _tree(work) == before  # neither file, nor a temporary


def test_a_set_whose_writing_fails_leaves_no_folder_behind(work, monkeypatch):
    from simucal.io import set_writer
    real = set_writer.write_set

    def fails_after(folder, *a, **k):  # every file written, then a failure before the command ends
        real(folder, *a, **k)
        raise OSError(28, "No space left on device")
    monkeypatch.setattr(set_writer, "write_set", fails_after)
    before = _tree(work)
    r = _run("apply", work / "cal.json", work / "set", "-o", work / "applied")
    assert r.exit_code == 3 and _tree(work) == before, r.output


def test_outputs_are_renamed_together_when_the_command_ends(tmp_path):
    with outputs.all_or_nothing():
        outputs.hold([tmp_path / "a.json"], [tmp_path / "set"])
        outputs.write_text(tmp_path / "a.json", "a")
        (tmp_path / "set").mkdir()
        outputs.write_text(tmp_path / "set" / "meta.json", "{}")
        outputs.write_text(tmp_path / "elsewhere.txt", "not held")  # a cache's file: at once
        assert not (tmp_path / "a.json").exists() and not (tmp_path / "set" / "meta.json").exists()
        assert (tmp_path / "elsewhere.txt").read_text() == "not held"
    assert (tmp_path / "a.json").read_text() == "a" and (tmp_path / "set" / "meta.json").read_text() == "{}"
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.json", "elsewhere.txt", "meta.json", "set"]
