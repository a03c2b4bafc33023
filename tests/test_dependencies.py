"""Dependencies for a user's environment: ranges in pyproject.toml, the lowest
set CI tests equal to their lower bounds, the locked set inside the ranges, and Dask an extra
that only --scheduler processes or an address needs."""
import sys
import tomllib
from importlib.metadata import version
from pathlib import Path

import pytest
from click.testing import CliRunner
from packaging.requirements import Requirement
from packaging.version import Version

from simucal.cli import main
from simucal.turntable.simulate import Scenario, write

ROOT = Path(__file__).resolve().parent.parent


def _requirements() -> dict[str, Requirement]:
    """Every requirement of simucal[test] (the core, the test extra and the extras it names), by lower-case name."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]
    named = [e for r in map(Requirement, extras["test"]) if r.name == "simucal" for e in sorted(r.extras)]
    reqs = [Requirement(r) for r in project["dependencies"] + extras["test"] + [x for e in named for x in extras[e]]]
    return {r.name.lower(): r for r in reqs if r.name != "simucal"}


def _pins(name: str) -> dict[str, Version]:
    lines = (ROOT / "constraints" / name).read_text().splitlines()
    pins = [Requirement(x) for x in lines if x.strip() and not x.startswith("#")]
    assert all(len(p.specifier) == 1 and next(iter(p.specifier)).operator == "==" for p in pins), name
    return {p.name.lower(): Version(next(iter(p.specifier)).version) for p in pins}


def test_the_lowest_set_is_each_lower_bound_and_the_locked_set_lies_in_the_ranges():
    reqs, lowest, locked = _requirements(), _pins("lowest.txt"), _pins("locked.txt")
    bounds = {n: [Version(s.version) for s in r.specifier if s.operator == ">="] for n, r in reqs.items()}
    assert all(len(b) == 1 for b in bounds.values()), bounds  # every range has its tested floor
    assert lowest == {n: b[0] for n, b in bounds.items()}, (lowest, bounds)
    assert all(not any(s.operator == "==" for s in r.specifier) for r in reqs.values())  # ranges, not pins
    outside = {n: str(locked.get(n)) for n, r in reqs.items() if locked.get(n) not in r.specifier}
    assert not outside, outside


def test_this_environment_lies_in_the_ranges():
    """The suite runs on versions the ranges admit (the lowest or the locked set in CI)."""
    outside = {n: version(n) for n, r in _requirements().items() if version(n) not in r.specifier}
    assert not outside, outside


@pytest.fixture()
def without_dask(monkeypatch):
    """An environment without the dask extra: every import of Dask fails as where it is not installed."""
    for name in ("dask", "dask.config", "dask.distributed", "distributed", "distributed.security"):
        monkeypatch.setitem(sys.modules, name, None)


def test_the_core_runs_without_dask_and_a_dask_scheduler_names_the_extra(tmp_path, without_dask):
    for name, seed in (("a", 1), ("b", 2)):
        write(tmp_path / name, Scenario(), seed)
    sets = [str(tmp_path / "a"), str(tmp_path / "b")]
    r = CliRunner().invoke(main, ["calibrate", *sets, "-o", str(tmp_path / "local")])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "local").iterdir()) == ["a.json", "b.json"]
    r = CliRunner().invoke(main, ["calibrate", *sets, "-o", str(tmp_path / "out"), "--scheduler", "processes"])
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), (r.exit_code, r.stderr)
    assert "pip install 'simucal[dask]'" in lines[0]
    assert not (tmp_path / "out").exists()
