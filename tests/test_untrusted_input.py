"""Input that looks valid and is not: a noise.json, a calibration, a measurement set or a
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
    lines = [x for x in r.stderr.splitlines() if x.strip() and not x.startswith("deriving ")]  # said with its limit
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
TWICE = '"terms": {"N": 1.0, '  # json.dumps cannot write a key twice: the test edits the text


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
    (tmp_path / "twice.json").write_text((raw / "n.json").read_text().replace('"terms": {', TWICE, 1))
    for path, what in ((tmp_path / "deep.json", "not a readable noise report"),
                       (tmp_path / "twice.json", "key 'N' appears twice")):
        refused(_run("calibrate", raw / "raw", "--noise", path, "-o", tmp_path / "c.json"), str(path), what)


def _meta(folder, **kw):
    m = json.loads((folder / "meta.json").read_text())
    (folder / "meta.json").write_text(json.dumps({**m, **kw}))


def test_validate_knows_its_own_rows_by_their_samples(raw, tmp_path):
    """Adding average_s to meta.json (which calibrate --noise asks for) hid that the rows were
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


@pytest.fixture(scope="module")
def avg(tmp_path_factory):
    """An averaged turntable set (one row per position) and its calibration."""
    root = tmp_path_factory.mktemp("avg")
    write(root / "set", Scenario(plan="table1"), 5)
    assert _run("calibrate", root / "set", "-o", root / "cal.json").exit_code == 0
    return root


def _csv_edit(folder, name, edit):
    lines = (folder / name).read_text().splitlines()
    (folder / name).write_text(edit(lines))


def _cell(lines, row, col, value):
    cells = lines[row].split(",")
    cells[col] = value
    lines[row] = ",".join(cells)
    return "\n".join(lines) + "\n"


def _deep(path):
    path.write_text('{"a":' * 100_000 + "1" + "}" * 100_000)


def _loop(path):
    path.unlink()
    other = path.with_name("other_" + path.name)
    path.symlink_to(other.name)
    other.symlink_to(path.name)


DAMAGE = {  # what breaks a set that still looks like one, and what the refusal says
    "a static segment turning": (lambda d: _csv_edit(d, "segments.csv", lambda ln: _cell(ln, 1, 5, "5")),
                                 "segments.csv, line 2: a static segment with outer_rate_dps 5"),
    "a column twice in segments.csv": (lambda d: _csv_edit(d, "segments.csv", lambda ln: "\n".join(
        [ln[0] + ",middle_deg"] + [r + ",45" for r in ln[1:]]) + "\n"), "column middle_deg appears 2 times"),
    "a column twice in samples.csv": (lambda d: _csv_edit(d, "samples.csv", lambda ln: "\n".join(
        [ln[0] + ",ax"] + [r + ",1" for r in ln[1:]]) + "\n"), "column ax appears 2 times"),
    "samples.csv cut mid-number": (lambda d: (d / "samples.csv").write_text((d / "samples.csv").read_text()
                                                                             .rstrip()[:-3]), "no line end"),
    "segments.csv cut mid-number": (lambda d: (d / "segments.csv").write_text((d / "segments.csv").read_text()
                                                                               .rstrip()[:-3]), "no line end"),
    "a 10 MB single line": (lambda d: (d / "samples.csv").write_text("1" * 10_000_000 + "\n"), "not readable as CSV"),
    "a 10 MB cell": (lambda d: _csv_edit(d, "samples.csv", lambda ln: _cell(ln, 1, 2, "1" * 10_000_000)),
                     "line 2: not readable as CSV"),
    "meta.json 100,000 deep": (lambda d: _deep(d / "meta.json"), "nested too deep"),
    "meta.json a 5000-digit number": (lambda d: (d / "meta.json").write_text("1" * 5000), "not readable JSON"),
    "meta.json a symlink loop": (lambda d: _loop(d / "meta.json"), "symbolic link that leads nowhere"),
    "meta.json a key twice": (lambda d: (d / "meta.json").write_text((d / "meta.json").read_text().replace(
        "{", '{"latitude_deg": 10, ', 1)), "key 'latitude_deg' appears twice"),
    "samples.csv a folder": (lambda d: ((d / "samples.csv").unlink(), (d / "samples.csv").mkdir()), "is a folder"),
}


@pytest.mark.parametrize("case", sorted(DAMAGE))
def test_data_that_look_valid_and_are_not_are_refused(avg, tmp_path, case):
    import shutil
    damage, expect = DAMAGE[case]
    d = tmp_path / "set"
    shutil.copytree(avg / "set", d)
    damage(d)
    for cmd in (["calibrate", d, "-o", tmp_path / "c.json"],
                ["validate", avg / "cal.json", d, "-o", tmp_path / "v.json"]):
        line = refused(_run(*cmd), expect)
        assert len(line) < 2000  # a 10 MB value is not echoed whole
    assert not (tmp_path / "c.json").exists() and not (tmp_path / "v.json").exists()


def test_a_file_argument_that_is_a_folder_a_loop_or_too_deep_is_named(avg, tmp_path):
    (tmp_path / "folder.json").mkdir()
    (tmp_path / "loop.json").write_text("")
    _loop(tmp_path / "loop.json")
    _deep(tmp_path / "deep.json")
    (tmp_path / "twice.json").write_text((avg / "cal.json").read_text().replace("{", '{"method": "x", ', 1))
    for cal, expect in (("folder.json", "is a directory"), ("loop.json", "symbolic link that leads nowhere"),
                        ("deep.json", "nested too deep"), ("twice.json", "key 'method' appears twice")):
        for cmd in ("apply", "validate"):
            refused(_run(cmd, tmp_path / cal, avg / "set", "-o", tmp_path / "out"), cal, expect)
    (tmp_path / "set_loop").symlink_to("set_loop")
    refused(_run("calibrate", tmp_path / "set_loop", "-o", tmp_path / "c.json"), "symbolic link that leads nowhere")
    (tmp_path / "model.py").mkdir()
    refused(_run("calibrate", avg / "set", "--add", tmp_path / "model.py", "-o", tmp_path / "c.json"),
            "a folder, where a model file")
    refused(_run("montecarlo", "--effect-file", tmp_path / "loop.json", "--trials", 100, "-o", tmp_path / "m.json"),
            "symbolic link that leads nowhere")


def test_inputs_in_one_plane_are_refused_by_the_multiposition_method_too(tmp_path):
    """Rate runs all about axes of one plane leave the gyro's M along its normal to the Earth rate of the
    statics (10 deg/h against 36,000): the multi-position regression gave M_yy 0.94 (truth 1.0) without a
    word. Refused, naming the plane's normal, as the norm methods refuse one."""
    import shutil
    plan = ["outer_deg,middle_deg,inner_deg"] + [f"0,0,{b}" for b in range(0, 360, 30)]
    (tmp_path / "plan.csv").write_text("\n".join(plan) + "\n")
    assert _run("simulate", "-o", tmp_path / "s", "--plan", tmp_path / "plan.csv", "--seed", 1).exit_code == 0
    from simucal.io import read_set
    off = [s.segment for s in read_set(tmp_path / "s").segments if s.kind == "rate" and s.middle_deg != 0.0]
    assert off  # the simulator's run about another axis: left out, the rate runs are coplanar
    shutil.copytree(tmp_path / "s", tmp_path / "cop")
    for name in ("segments.csv", "samples.csv"):
        _csv_edit(tmp_path / "cop", name, lambda ln: "\n".join(r for r in ln if r.split(",")[0] not in
                                                                 {str(k) for k in off}) + "\n")
    refused(_run("calibrate", tmp_path / "cop", "--method", "multiposition", "-o", tmp_path / "c.json"),
            "gyro input directions lie in one plane", "[-0.0, 1.0, 0.0]")
    assert _run("calibrate", tmp_path / "s", "--method", "multiposition", "-o", tmp_path / "c.json").exit_code == 0


@pytest.mark.slow
def test_a_term_in_the_model_file_and_in_the_library_is_named(tmp_path):
    """A model file's own z quadratic beside the library's acc.quadratic.z: montecarlo blamed the plan
    (a noise-free trial failing); now both say the same term is there twice, naming it."""
    (tmp_path / "quad.py").write_text(
        "from simucal.derive.frames import f_b\nfrom simucal.derive.models import Term\n"
        "from simucal.derive.models.baseline import ACC_BASELINE\n"
        'MODELS = [ACC_BASELINE.with_terms("acc_twice_mc", [Term("Kq_z", "z", 2 * f_b[2] ** 2, "g/g^2", "mine")])]\n')
    expect = ("acc.quadratic.z", "Kq_z", "the same term")
    refused(_run("montecarlo", "--effect-file", tmp_path / "quad.py", "--set", "Kq_z=1e-4", "--effect",
                 "acc.quadratic.z=1e-4", "--trials", 100, "-o", tmp_path / "m.json"), *expect)
    write(tmp_path / "set", Scenario(plan="fibonacci48"), 1)
    refused(_run("calibrate", tmp_path / "set", "--add", tmp_path / "quad.py", "--add", "acc.quadratic.z", "-o",
                 tmp_path / "c.json"), *expect)
    r = _run("montecarlo", "--effect-file", tmp_path / "quad.py", "--set", "Kq_z=1e-4", "--effect",
             "acc.quadratic.x=1e-4", "--trials", 100, "-o", tmp_path / "m.json")
    assert r.exit_code == 0, r.output  # another axis's quadratic is another term


@pytest.mark.slow
def test_a_model_file_that_never_returns_is_said_at_once_and_stopped_at_its_limit(tmp_path, monkeypatch):
    """A model file in an endless loop waited 120 s in silence: what runs and its limit are said at once,
    its seconds every Wait.EVERY_S off a terminal, and at the limit the child is killed and refused."""
    import time

    from simucal import progress
    write(tmp_path / "set", Scenario(), 1)
    (tmp_path / "hang.py").write_text("while True:\n    pass\n")
    monkeypatch.setenv("SIMUCAL_DERIVE_TIMEOUT_S", "3")
    monkeypatch.setattr(progress.Wait, "EVERY_S", 1.0)
    start = time.monotonic()
    r = _run("calibrate", tmp_path / "set", "--add", tmp_path / "hang.py", "-o", tmp_path / "c.json")
    took = time.monotonic() - start
    refused(r, "hang.py", "more than 3 s", "SIMUCAL_DERIVE_TIMEOUT_S")
    said = r.stderr.splitlines()
    assert said[0].startswith(f"deriving {tmp_path / 'hang.py'}") and "at most 3 s" in said[0], said
    assert sum("so far, at most 3 s" in x for x in said) >= 1, said  # progress while it runs
    assert took < 15, took  # stopped at its limit, not left running


@pytest.mark.slow
def test_the_diagnosis_next_command_keeps_every_add_and_agrees_with_the_verdicts(tmp_path):
    """The page's Next dropped the --add that made the model pass, its verdict said another
    command, and the gyro's Next omitted the accelerometer's --add. One next command for the set now
    holds every --add (the ones diagnose ran with and what each failing verdict adds), on the console
    and the page, and running it makes both models pass."""
    import html as _html
    write(tmp_path / "two", Scenario(plan="fibonacci48", acc_effects={"acc.quadratic.z": 2e-4},
                                     gyro_effects={"gyro.scale_asymmetry.z": 1e-4}), 1)
    r = _run("diagnose", tmp_path / "two", "-o", tmp_path / "d.json", "--html", tmp_path / "d.html")
    assert r.exit_code == 0, r.output
    d = json.loads((tmp_path / "d.json").read_text())
    cmd = f"simucal calibrate {tmp_path / 'two'} --add acc.quadratic.z --add gyro.scale_asymmetry.z -o calibration.json"
    assert f"next: {cmd}" in r.output
    assert f"Next: <code>{_html.escape(cmd)}</code>" in (tmp_path / "d.html").read_text()
    for s, eid in (("acc", "acc.quadratic.z"), ("gyro", "gyro.scale_asymmetry.z")):
        assert f"Add it: --add {eid}." in d[s]["verdict"]  # the verdict's effect is the one in next
    # run with one --add: the passing model keeps it, the failing one adds its own
    r = _run("diagnose", tmp_path / "two", "--add", "acc.quadratic.z", "-o", tmp_path / "d2.json")
    assert "explains the data" in json.loads((tmp_path / "d2.json").read_text())["acc"]["verdict"]
    assert f"next: {cmd}" in r.output, r.output
    r = _run(*cmd.split()[1:-2], "-o", tmp_path / "c.json")  # the next command, as printed
    cal = json.loads((tmp_path / "c.json").read_text())
    assert r.exit_code == 0 and cal["acc"]["verdict"] == cal["gyro"]["verdict"] == "passes", r.output


def test_every_calibration_block_has_its_verdict_and_a_batch_says_a_failing_model(tmp_path):
    """The README listed a verdict key that no file had; a batch's summary line hid a failing model."""
    from simucal.io import calibration
    write(tmp_path / "bad", Scenario(plan="fibonacci48", acc_effects={"acc.quadratic.z": 2e-4}), 1)
    write(tmp_path / "good", Scenario(plan="fibonacci48"), 2)
    r = _run("calibrate", tmp_path / "bad", tmp_path / "good", "-o", tmp_path / "many")
    assert r.exit_code == 0, r.output
    line = next(x for x in r.output.splitlines() if "wrote" in x and "bad.json" in x)
    assert "acc p = " in line and "THE MODEL FAILS" in line.split("gyro")[0], line
    assert "FAILS" not in next(x for x in r.output.splitlines() if "wrote" in x and "good.json" in x)
    for name, acc in (("bad", "fails"), ("good", "passes")):
        d = json.loads((tmp_path / "many" / f"{name}.json").read_text())
        assert (d["acc"]["verdict"], d["gyro"]["verdict"]) == (acc, "passes")
        assert (d["acc"]["p_value"] < 1e-3) == (acc == "fails")
        again = calibration.load(tmp_path / "many" / f"{name}.json").to_json()
        assert again["acc"]["verdict"] == acc and "verdict" not in calibration.load(
            tmp_path / "many" / f"{name}.json").acc.details  # derived, not carried twice
    r = _run("calibrate", tmp_path / "good", "--method", "multiposition", "-o", tmp_path / "mp.json")
    assert json.loads((tmp_path / "mp.json").read_text())["acc"]["verdict"] == "untested"


def test_a_noise_file_far_above_averaged_rows_is_refused_by_their_residuals(raw, tmp_path):
    """One averaged row per segment and no stated noise: nothing of the data's own to compare a noise
    file with before the fit, so the fit's residuals judge it. A file 1e4 times too large made every
    model pass with a warning and stds 1e4 too large; refused, naming the file."""
    write(tmp_path / "avg", Scenario(plan="table1", state_noise=False), 5)
    _meta(tmp_path / "avg", average_s=10.0)
    d = json.loads((raw / "n.json").read_text())
    for ax in d["acc"]["axes"].values():
        ax["terms"] = {k: v * 1e4 for k, v in ax["terms"].items()}
    (tmp_path / "big.json").write_text(json.dumps(d))
    refused(_run("calibrate", tmp_path / "avg", "--noise", tmp_path / "big.json", "-o", tmp_path / "c.json"),
            "big.json", "acc residuals are", "times its noise")
    assert not (tmp_path / "c.json").exists()


def test_an_imported_recording_cut_mid_number_and_a_damaged_truth_json(avg, tmp_path):
    """A recording to import cut short mid-number (no line end) is refused as a set's CSV is; a
    truth.json beside a set, read by diagnose for scoring only, is left out where it is damaged (nested
    100,000 deep, or of another shape) instead of ending in an internal error."""
    import shutil
    from pathlib import Path
    src = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris" / "example_ferraris_session.csv"
    (tmp_path / "cut.csv").write_bytes(src.read_bytes().rstrip(b"\n")[:-3])
    refused(_run("import", "imucal-ferraris", tmp_path / "cut.csv", "-o", tmp_path / "imp", "--latitude-deg", 45),
            "cut.csv, line", "no line end")
    assert not (tmp_path / "imp").exists()
    d = tmp_path / "set"
    shutil.copytree(avg / "set", d)
    for damaged in ("[" * 100_000 + "]" * 100_000, '{"acc": [1], "gyro": {"params": {"x": "a"}, "T": 5}}'):
        (d / "truth.json").write_text(damaged)
        r = _run("diagnose", d, "--add", "acc.quadratic.z", "-o", tmp_path / "d.json")
        assert r.exit_code == 0, r.output
        assert "truth" not in json.loads((tmp_path / "d.json").read_text())["acc"]["added"]["params"]["acc.quadratic.z"]


def test_a_noise_file_without_a_sensor_says_whose_noise_is_used(raw, tmp_path):
    d = json.loads((raw / "n.json").read_text())
    del d["gyro"]
    (tmp_path / "acc_only.json").write_text(json.dumps(d))
    r = _run("calibrate", raw / "raw", "--noise", tmp_path / "acc_only.json", "-o", tmp_path / "c.json")
    assert r.exit_code == 0, r.output
    assert "acc_only.json: holds no gyro curve, so the gyro noise is the data's own" in r.output
    assert any("holds no gyro curve" in w for w in json.loads((tmp_path / "c.json").read_text())["warnings"])


def test_one_error_base_caught_in_one_place(tmp_path, monkeypatch):
    """Every refusal subclasses errors.SimucalError, which the command line alone catches
    (exit 2, one line); anything else escaping a command is a bug: exit 3 with its traceback, even a KeyError
    or a ValueError (until now a bug's KeyError exited 2 like a user's mistake); no command catches them
    itself."""
    import inspect
    import pkgutil

    import simucal
    from simucal import api, cli
    from simucal.errors import SimucalError
    from simucal.fit.catalog import ModelFileError
    from simucal.io import MeasurementSetError
    from simucal.io.calibration_checks import CalibrationFileError
    from simucal.io.importers import ImportError_
    from simucal.io.outputs import OutputError
    for cls in (MeasurementSetError, CalibrationFileError, ModelFileError, OutputError, ImportError_):
        assert issubclass(cls, SimucalError), cls
    for m in pkgutil.iter_modules(cli.__path__):
        src = inspect.getsource(__import__(f"simucal.cli.{m.name}", fromlist=["x"]))
        # a refusal's own handler
        assert not re.search(r"except [^:]*(Error|Exception)[^:]* as e:\s*fail\(e\)", src), m.name
    write(tmp_path / "s", Scenario(plan="table1"), 1)
    refused(_run("simulate", "-o", tmp_path / "t", "--sequence", "nosuch"), "--sequence nosuch")  # an InputError
    for bug in (KeyError("acc"), ValueError("shapes (3,) and (4,) not aligned")):
        def broken(*a, bug=bug, **k):
            raise bug
        monkeypatch.setattr(api, "calibrate", broken)
        r = _run("calibrate", tmp_path / "s", "-o", tmp_path / "c.json")
        assert r.exit_code == 3 and "internal error" in r.stderr and "Traceback" in r.stderr, (r.exit_code, r.stderr)
    assert simucal.calibrate is api.calibrate  # one home: the package's name is the API's function, nothing bound apart
