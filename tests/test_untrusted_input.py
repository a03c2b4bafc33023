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


def _meta(folder, **kw):
    m = json.loads((folder / "meta.json").read_text())
    (folder / "meta.json").write_text(json.dumps({**m, **kw}))


def test_validate_knows_its_own_rows_by_their_samples(raw, tmp_path):
    """Issue 39: adding average_s to meta.json (which calibrate --noise asks for) hid that the rows were
    the calibration's own. The calibration records a digest of each segment's samples: an edit of
    meta.json, segments.csv or the number format does not hide them, a few of its segments copied into
    another set show, and a file without the digests (an older one) still compares the files."""
    import shutil

    from simucal.io import read_set
    cal = tmp_path / "cal.json"
    assert _run("calibrate", raw / "raw", "-o", cal).exit_code == 0
    own = "these are the data the calibration was made from"
    edited = tmp_path / "edited"
    shutil.copytree(raw / "raw", edited)
    _meta(edited, average_s=10.0, notes="edited")
    lines = (edited / "samples.csv").read_text().splitlines()
    (edited / "samples.csv").write_text("\r\n".join(lines) + "\r\n")  # another line ending: the same numbers
    r = _run("validate", cal, edited, "-o", tmp_path / "v.json")
    assert r.exit_code == 0 and own in r.output, r.output
    assert json.loads((tmp_path / "v.json").read_text())["independent"] is False
    # another recording of the same unit is independent; with three of the calibration's segments in it, not
    write(tmp_path / "other", Scenario(plan="table1", rate_hz=20.0), 4)
    r = _run("validate", cal, tmp_path / "other", "-o", tmp_path / "v2.json")
    assert r.exit_code == 0 and "NOTE" not in r.output, r.output
    mixed, ours = tmp_path / "mixed", read_set(raw / "raw")
    shutil.copytree(tmp_path / "other", mixed)
    header, *body = (mixed / "samples.csv").read_text().splitlines()
    col = header.split(",").index("segment")
    keep = {s.segment for s in ours.segments[:3]}
    mine = [ln for ln in (raw / "raw" / "samples.csv").read_text().splitlines()[1:] if int(ln.split(",")[col]) in keep]
    (mixed / "samples.csv").write_text("\n".join([header] + mine + [ln for ln in body if int(ln.split(",")[col])
                                                                      not in keep]) + "\n")
    r = _run("validate", cal, mixed, "-o", tmp_path / "v3.json")
    assert r.exit_code == 0 and f"3 of the {len(ours.segments)} segments" in r.output, r.output
    # an older file, without the digests: the files' hash still finds the unedited set, and only it
    old = json.loads(cal.read_text())
    del old["samples_sha256"]
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert own in _run("validate", tmp_path / "old.json", raw / "raw", "-o", tmp_path / "v4.json").output
    assert own not in _run("validate", tmp_path / "old.json", tmp_path / "other", "-o", tmp_path / "v5.json").output


@pytest.mark.parametrize("entry, value", [("std", -1e-6), ("std", "1e-6"), ("std_raw", float("nan")),
                                          ("samples_sha256", 7)])
def test_a_calibration_with_a_std_that_is_none_is_refused(raw, tmp_path, entry, value):
    cal = tmp_path / "cal.json"
    assert _run("calibrate", raw / "raw", "-o", cal).exit_code == 0
    d = json.loads(cal.read_text())
    if entry == "samples_sha256":
        d[entry], name = value, "samples_sha256"
    else:
        block = d["acc"].setdefault(entry, dict(d["acc"]["std"]))
        block[next(iter(block))] = value
        name = f"acc.{entry}.{next(iter(block))}"
    (tmp_path / "bad.json").write_text(json.dumps(d))
    for cmd in (["validate", tmp_path / "bad.json", raw / "raw"], ["apply", tmp_path / "bad.json", raw / "raw"]):
        refused(_run(*cmd, "-o", tmp_path / "out"), "bad.json", name, "calibrate again")
    assert not (tmp_path / "out").exists()
