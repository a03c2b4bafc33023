"""The linter and the type checker, run by the suite: ruff's pyflakes and
pycodestyle errors over the repository, mypy over the whole package (simucal/), both as configured
in pyproject.toml. A finding fails the test with the tool's own lines."""
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(*args):
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, capture_output=True, text=True)


@pytest.mark.slow
def test_ruff_finds_nothing():
    r = _run("ruff", "check", "--no-cache", "--output-format", "concise", ".")
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow
def test_mypy_finds_nothing_in_the_package():
    r = _run("mypy")
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow
def test_the_api_passes_mypy_strict():
    """The API's own modules type-check strictly: every function annotated, every generic given its parameters,
    no call into an unannotated function."""
    r = _run("mypy", "--strict", "simucal/api")
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow
def test_the_api_tutorial_passes_mypy_strict():
    """A notebook's code on the API alone type-checks strictly, with no ignores."""
    tutorial = ROOT / "docs" / "tutorials" / "three_methods.py"
    assert "type: ignore" not in tutorial.read_text()
    r = _run("mypy", "--strict", str(tutorial))
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow
def test_a_misspelt_option_or_a_record_read_wrongly_is_a_type_error(tmp_path):
    """Calibrate's options are typed (its keywords, simucal/options.py) and a calibration's records too (io/records.py):
    a checker finds a misspelt option, an unknown method, a wrong type, a record's key read as the wrong type, and
    a method that became a function (cal.apply), in a notebook's code."""
    user = tmp_path / "user.py"
    user.write_text('import simucal\n\n'
                    'cal = simucal.calibrate("set", methd="exact")\n'
                    'cal = simucal.calibrate("set", method="exakt")\n'
                    'cal = simucal.calibrate("set", acc_noise_g="1e-5")\n'
                    'strongest: int = simucal.calibrate("set").sensor("acc").details["targeted"]["strongest"]\n'
                    'ok = simucal.calibrate("set", method="exact", add=["acc.quadratic.z"], acc_noise_g=1e-5)\n'
                    'old = ok.apply([[0.0] * 6])\n'  # a method that became simucal.apply(cal, x)
                    'new = simucal.apply(ok, [[0.0] * 6])\n')
    r = _run("mypy", "--strict", "--cache-dir", str(tmp_path / "cache"), str(user))
    lines = [x for x in r.stdout.splitlines() if ": error:" in x]
    assert [int(x.split(":")[1]) for x in lines] == [3, 4, 5, 6, 8], r.stdout
    assert '"methd"' in lines[0] and "exakt" in lines[1] and "acc_noise_g" in lines[2], r.stdout
    assert 'has no attribute "apply"' in lines[4], r.stdout


@pytest.mark.slow
def test_the_lint_catches_what_it_claims_to(tmp_path):
    """The rules bite: an unused import and a wrong type in a typed result are found (the configuration
    is read, not skipped)."""
    bad = tmp_path / "bad.py"
    bad.write_text("import os\n\n\ndef f(x: int) -> str:\n    return x\n")
    r = _run("ruff", "check", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(bad))
    assert r.returncode == 1 and "F401" in r.stdout, r.stdout + r.stderr
    r = _run("mypy", "--cache-dir", str(tmp_path / "cache"), "--config-file", str(ROOT / "pyproject.toml"), str(bad))
    assert r.returncode == 1 and "Incompatible return value" in r.stdout, r.stdout + r.stderr


@pytest.mark.slow
def test_a_users_script_type_checks_against_the_installed_package_under_strict(tmp_path):
    """Installed as a user installs it (a wheel, not this checkout's editable hook, which mypy cannot follow), the
    package is found through its py.typed: the verbs return their classes, and a misspelt keyword is an error."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", str(venv)], check=True)
    python = venv / "bin" / "python"
    import shutil
    source = tmp_path / "source"  # a copy: setuptools builds in the tree it installs from (build/), not in ours
    shutil.copytree(ROOT, source, symlinks=True,
                    ignore=shutil.ignore_patterns(".git", ".venv*", "build", "*.egg-info", "__pycache__", "_build",
                                                                 ".mypy_cache", ".ruff_cache", ".pytest_cache"))
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--no-deps", str(source)], check=True,
                   capture_output=True, cwd=tmp_path)
    script = tmp_path / "user.py"
    script.write_text('import simucal\n\nms = simucal.simulate("paper", seed=1)\ncal = simucal.calibrate(ms)\n'
                      "reveal_type(cal)\nreveal_type(simucal.validate(cal, ms))\n")
    r = subprocess.run([str(python), "-m", "mypy", "--strict", "--no-incremental", str(script)], capture_output=True,
                       text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "Calibration" in r.stdout and "Validation" in r.stdout, r.stdout
    script.write_text('import simucal\n\nsimucal.calibrate("set", methd="exact")\n')
    r = subprocess.run([str(python), "-m", "mypy", "--strict", "--no-incremental", str(script)], capture_output=True,
                       text=True, cwd=tmp_path)
    assert r.returncode == 1 and 'did you mean "method"' in r.stdout, r.stdout
