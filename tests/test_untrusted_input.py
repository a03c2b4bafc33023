"""Input that looks valid and is not (issue 39): a noise.json, a calibration, a measurement set or a
model file that a user edited or a tool damaged is refused in one line naming the file, the entry
and the fix, never an internal error or a silent wrong answer."""
import copy
import json
import re

import pytest
from click.testing import CliRunner

from simucal.cli import main
from simucal.turntable.simulate import Scenario, write


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def refused(r, *expect):
    """Exit 2, one line on stderr holding each of expect, no internal error."""
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), (r.exit_code, r.output, r.exception)
    assert len(lines) == 1 and "internal error" not in lines[0], r.stderr
    for e in expect:
        assert e in lines[0], (e, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    """A raw turntable set (20 Hz) and the noise.json of its own static segments."""
    root = tmp_path_factory.mktemp("raw")
    write(root / "raw", Scenario(plan="table1", rate_hz=20.0), 3)
    assert _run("noise", root / "raw", "-o", root / "n.json").exit_code == 0
    return root


def _edit(d, sensor, axis, term, value):
    d[sensor]["axes"][axis]["terms"][term] = value


EDITS = {  # what a hand edit or a damaged copy does to a noise.json, and the entry the refusal names
    "a term as a string": (lambda d: _edit(d, "acc", "x", "N", "2e-6"), "acc.axes.x.terms.N"),
    "an axis missing": (lambda d: d["gyro"]["axes"].pop("y"), "gyro.axes.y is missing"),
    "a negative term": (lambda d: _edit(d, "gyro", "z", "N", -0.01), "gyro.axes.z.terms.N is -0.01"),
    "NaN": (lambda d: _edit(d, "acc", "y", "B", float("nan")), "acc.axes.y.terms.B is nan"),
    "infinity": (lambda d: _edit(d, "acc", "y", "Q", float("inf")), "acc.axes.y.terms.Q is inf"),
    "a boolean": (lambda d: _edit(d, "acc", "y", "Q", True), "acc.axes.y.terms.Q is True"),
    "all zeros": (lambda d: d["acc"]["axes"]["z"].update(terms=dict.fromkeys("QNBKR", 0.0)), "are all zero"),
    "a term missing": (lambda d: d["acc"]["axes"]["z"]["terms"].pop("K"), "acc.axes.z.terms must hold"),
    "another unit": (lambda d: d["acc"].update(unit="m/s^2"), "acc.unit is 'm/s^2'"),
    "no taus": (lambda d: d["gyro"].update(tau_s=[]), "gyro.tau_s"),
    "a sensor as a list": (lambda d: d.update(acc=[1, 2]), "acc is a list"),
    "a damaged sheet": (lambda d: d["acc"]["axes"]["x"].update(sheet={"B": "x"}), None),
}


@pytest.mark.parametrize("case", sorted(EDITS))
def test_a_noise_file_is_checked_entry_by_entry(raw, tmp_path, case):
    edit, entry = EDITS[case]
    d = json.loads((raw / "n.json").read_text())
    edit(d)
    (tmp_path / "bad.json").write_text(json.dumps(d))
    r = _run("calibrate", raw / "raw", "--noise", tmp_path / "bad.json", "-o", tmp_path / "c.json")
    if entry is None:  # the sheet is a report's summary: damaged, it measures no long term, and the terms stand
        assert r.exit_code == 0, r.output
        return
    line = refused(r, "bad.json", entry, "simucal noise")
    assert not (tmp_path / "c.json").exists(), line


@pytest.mark.parametrize("factor", [1e6, 30.0, 1 / 30])
def test_a_noise_file_not_the_datas_own_size_is_refused(raw, tmp_path, factor):
    """Terms 30 (1e6) times the rows' own noise would make every model pass (the stds 1e6 times too
    large); a thirtieth would fail every model and blame it: both refused, naming the factor."""
    d = json.loads((raw / "n.json").read_text())
    scaled = copy.deepcopy(d)
    for ax in scaled["gyro"]["axes"].values():
        ax["terms"] = {k: v * factor for k, v in ax["terms"].items()}
    (tmp_path / "big.json").write_text(json.dumps(scaled))
    r = _run("calibrate", raw / "raw", "--noise", tmp_path / "big.json", "-o", tmp_path / "c.json")
    line = refused(r, "big.json", "gyro x noise", "times the rows' own noise")
    measured = float(re.search(r", ([0-9.e+-]+) times the rows' own noise", line).group(1))
    assert factor / 2 < measured < factor * 2, line  # the factor measured, ~the one applied
    r = _run("calibrate", raw / "raw", "--noise", raw / "n.json", "-o", tmp_path / "c.json")
    assert r.exit_code == 0, r.output  # the set's own report is its own size


def test_a_noise_file_that_is_a_folder_or_not_json_is_named(raw, tmp_path):
    (tmp_path / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    for path, what in ((tmp_path / "deep.json", "not a readable noise report"),):
        refused(_run("calibrate", raw / "raw", "--noise", path, "-o", tmp_path / "c.json"), str(path), what)
