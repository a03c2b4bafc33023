"""The linter and the type checker, run by the suite (issue 40, item 0): ruff's pyflakes and
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
def test_the_api_tutorial_passes_mypy_strict():
    """Issue 54: a notebook's code on the API alone type-checks strictly, with no ignores."""
    tutorial = ROOT / "docs" / "tutorials" / "three_methods.py"
    assert "type: ignore" not in tutorial.read_text()
    r = _run("mypy", "--strict", str(tutorial))
    assert r.returncode == 0, r.stdout + r.stderr


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
