"""Bad input: one line naming the cause, a non-zero exit, no traceback, nothing written.

A corpus of the cases found by trying the tool as a new user would, each run through the
command line, and a property test of the readers on random bytes, CSV shapes and meta.
"""
import csv
import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from simucal import io
from simucal.cli import main
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.turntable.simulate import Scenario, write


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    root = tmp_path_factory.mktemp("good")
    write(root / "table", Scenario(), 1)
    write(root / "acc_only", Scenario(), 1)
    for c in ("gx", "gy", "gz"):
        _drop_column(root / "acc_only", c)
    write_handheld(root / "stream", HandheldScenario(poses=14, rest_s=10.0), 1)
    return root


def _drop_column(folder, col):
    rows = list(csv.reader(open(folder / "samples.csv")))
    j = rows[0].index(col)
    csv.writer(open(folder / "samples.csv", "w", newline="")).writerows([r[:j] + r[j + 1:] for r in rows])


def _rows(folder):
    return list(csv.reader(open(folder / "samples.csv")))


def _put_rows(folder, rows):
    csv.writer(open(folder / "samples.csv", "w", newline="")).writerows(rows)


def _meta(folder, **kw):
    m = json.loads((folder / "meta.json").read_text())
    m.update(kw)
    (folder / "meta.json").write_text(json.dumps(m))


def run_refused(args, *expect, out=None):
    """The command refuses: exit 2, no traceback, one line on stderr containing each of expect,
    and the output path not written."""
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), (r.exit_code, r.output, r.exception)
    lines = [x for x in r.stderr.splitlines() if x.strip() and not x.startswith("deriving ")]  # a model file's
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr  # derivation is said with its time limit
    for e in expect:
        assert e.lower() in lines[0].lower(), (e, lines[0])
    if out is not None:
        assert not Path(out).exists()
    return lines[0]


def _copy(sets, name, tmp_path):
    return Path(shutil.copytree(sets / name, tmp_path / name))


# --- files that are not text, or not the spec's CSV -------------------------------------------

@pytest.mark.slow
def test_binary_samples(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    (d / "samples.csv").write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR" + bytes(range(256)))
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "samples.csv", "binary", out=tmp_path / "c.json")


def test_not_utf8(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    rows = (d / "segments.csv").read_bytes().replace(b"static", "statique\u00e9".encode("latin-1"), 1)
    (d / "segments.csv").write_bytes(rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "segments.csv", "line 2", "UTF-8")


def test_meta_not_utf8(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    (d / "meta.json").write_bytes((d / "meta.json").read_bytes().replace(b"simucal simulate", b"caf\xe9"))
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "meta.json", "UTF-8")


def test_utf8_bom_is_read(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    for name in ("samples.csv", "segments.csv", "meta.json"):
        (d / name).write_bytes(b"\xef\xbb\xbf" + (d / name).read_bytes())
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("sep,named", [("\t", "tabs"), (";", "semicolons")])
def test_other_delimiter_named(sets, tmp_path, sep, named):
    d = _copy(sets, "table", tmp_path)
    (d / "samples.csv").write_text((d / "samples.csv").read_text().replace(",", sep))
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "samples.csv", named, "comma")


def test_huge_value(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    rows = _rows(d)
    rows[5][rows[0].index("ax")] = "1e300"
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "samples.csv", "line 6", "ax", "1e+300")


def test_timestamps_backwards_in_a_stream(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    j = rows[0].index("t_s")
    rows[500][j] = str(float(rows[400][j]))
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "samples.csv", "line 501", "t_s must increase")


def test_identical_repeated_rows(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    _put_rows(d, [rows[0]] + [rows[1]] * 3000)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "t_s")


# --- streams that cannot be used --------------------------------------------------------------

def test_one_row_stream(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    _put_rows(d, _rows(d)[:2])
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "1 row")


def test_all_rest_stream(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    _put_rows(d, rows[:900])  # the initial rest only
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "no motion")


def test_nan_after_detection_is_named(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    rows[4000][rows[0].index("gy")] = "nan"
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "line 4001", "gy")


def test_acc_and_gyro_swapped(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    h = rows[0]
    for a, g in zip(("ax", "ay", "az"), ("gx", "gy", "gz")):
        h[h.index(a)], h[h.index(g)] = "tmp", a
        h[h.index("tmp")] = g
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "swapped")


def test_rail_stuck_gyro_channel(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    j = rows[0].index("gx")
    for r in rows[1:]:
        r[j] = "65535"
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "gx", "stuck")


# --- turntable sets ---------------------------------------------------------------------------

def test_coplanar_gravity_without_gyro(tmp_path):
    """Static positions turned about the inner axis only: gravity directions in one plane, no gyro data."""
    plan = tmp_path / "plan.csv"
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(f"0,0,{b}\n" for b in range(0, 360, 30)))
    write(tmp_path / "s", Scenario(plan=str(plan), unify_positions=False, outer_rate_dps=()), 1)
    for c in ("gx", "gy", "gz"):
        _drop_column(tmp_path / "s", c)
    run_refused(["calibrate", tmp_path / "s", "-o", tmp_path / "c.json"], "unobservable")


@pytest.mark.parametrize("value", [0, -9.8])
def test_gravity_not_a_magnitude_in_diagnose(sets, tmp_path, value):
    d = _copy(sets, "table", tmp_path)
    _meta(d, gravity_mps2=value)
    run_refused(["diagnose", d, "-o", tmp_path / "d.json"], "gravity_mps2", out=tmp_path / "d.json")


# --- command-line arguments -------------------------------------------------------------------

@pytest.mark.parametrize("cmd", ["calibrate", "diagnose"])
def test_output_in_missing_folder(sets, tmp_path, cmd):
    run_refused([cmd, sets / "table", "-o", tmp_path / "no" / "x.json"], "does not exist")


def test_html_in_missing_folder_writes_nothing(sets, tmp_path):
    run_refused(["diagnose", sets / "table", "-o", tmp_path / "d.json", "--html", tmp_path / "no" / "d.html"],
                "does not exist", out=tmp_path / "d.json")


def test_missing_plan_file(tmp_path):
    run_refused(["simulate", tmp_path / "s", "--plan", tmp_path / "nope.csv"], "nope.csv", "table1")


@pytest.mark.parametrize("scenario", ["paper", "handheld"])
def test_temperature_effect_without_a_temperature(tmp_path, scenario):
    """Planted with temp_c at T_ref the effect is zero: the samples were those without it while truth.json
    listed it planted; refused, saying how to give a temperature. With one it is planted."""
    run_refused(["simulate", tmp_path / "s", "--scenario", scenario, "--effect", "gyro.bias_temperature.x=1e-3"],
                "temp_c stays at T_ref", "--temperature-c T", out=tmp_path / "s")
    if scenario == "paper":
        r = CliRunner().invoke(main, ["simulate", "-o", str(tmp_path / "t"), "--effect", "gyro.bias_temperature.x=1e-3",
                                      "--column", "temp_c=20:40"])
        assert r.exit_code == 0 and (tmp_path / "t" / "truth.json").exists(), r.output


@pytest.mark.parametrize("rate", ["0", "-5"])
def test_rate_not_positive(tmp_path, rate):
    run_refused(["simulate", tmp_path / "s", "--rate-hz", rate], "rate", out=tmp_path / "s")


@pytest.mark.parametrize("eid,named", [("quadratic", "acc.quadratic"), ("ACC.QUADRATIC.Z", "acc.quadratic.z")])
def test_effect_id_exact(sets, tmp_path, eid, named):
    run_refused(["calibrate", sets / "table", "-o", tmp_path / "c.json", "--add", eid], named)


@pytest.mark.parametrize("columns,named", [("t_s", "t_s=NAME"), ("t_s=time,ax", "ax"),
                                           ("t_s=time,ax=a,ay=b,az=c,qq=d", "qq")])
def test_malformed_import_columns(tmp_path, columns, named):
    src = tmp_path / "in.csv"
    src.write_text("time,a,b,c\n0,0,0,1\n0.01,0,0,1\n")
    run_refused(["import", "csv", src, "-o", tmp_path / "o", "--columns", columns, "--acc-unit", "g",
                 "--gyro-unit", "deg/s"], named,
                out=tmp_path / "o")


def test_no_warning_before_the_error(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    _put_rows(d, _rows(d)[:2])
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "c.json")])
    assert "Warning" not in r.output and len(r.stderr.strip().splitlines()) == 1


# --- the readers, on anything ------------------------------------------------------------------

_cells = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers().map(str),
                   st.text(max_size=4), st.just(""))
_good_header = ["segment", "t_s", "ax", "ay", "az", "gx", "gy", "gz"]
_GOOD_META = {"format": "simucal.measurements/1", "latitude_deg": 45.0, "acc_unit": "g", "gyro_unit": "deg/h"}


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(samples=st.one_of(st.binary(max_size=300),
                         st.lists(st.lists(_cells, min_size=0, max_size=9), max_size=6).map(
                             lambda rows: "\n".join(",".join(r) for r in [_good_header] + rows).encode())),
       meta=st.one_of(st.binary(max_size=100), st.dictionaries(  # a valid meta with random keys overridden
           st.sampled_from(["format", "latitude_deg", "gravity_mps2", "earth_rate_dph", "acc_unit", "gyro_unit",
                            "acc_pulses_per_g", "full_scale"]),
           st.one_of(st.none(), st.booleans(), st.floats(), st.text(max_size=5), st.lists(st.floats(), max_size=4)),
           max_size=2).map(lambda over: json.dumps({**_GOOD_META, **over}).encode())))
def test_reader_gives_a_set_or_a_clean_error(tmp_path, samples, meta):
    d = tmp_path / "h"
    d.mkdir(exist_ok=True)
    (d / "samples.csv").write_bytes(samples)
    (d / "meta.json").write_bytes(meta)
    try:
        ms = io.read_set(d)
    except io.MeasurementSetError as e:
        assert str(d) in str(e)
        return
    assert len(ms.samples["t_s"]) > 0 and all(np.all(np.isfinite(v)) for v in ms.samples.values())


def test_time_gap_in_a_move_leaves_that_move_out(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    good = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "a.json")])
    assert good.exit_code == 0, good.output
    rests = json.loads((tmp_path / "a.json").read_text())["static_detection"]["intervals_s"]
    t_gap = (rests[3][1] + rests[4][0]) / 2  # the middle of the fourth move
    rows = _rows(d)
    j = rows[0].index("t_s")
    _put_rows(d, [rows[0]] + [r for r in rows[1:] if abs(float(r[j]) - t_gap) > 0.2])
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "b.json")])
    assert r.exit_code == 0, r.output
    skipped = json.loads((tmp_path / "b.json").read_text())["gyro"]["moves_skipped"]
    assert [s["from_pose"] for s in skipped if "time gap" in s["reason"]] == [3], skipped


def test_gyro_scale_in_the_wrong_unit_named(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    meta = json.loads((d / "meta.json").read_text())
    _meta(d, gyro_counts_per_dps=[v * 180 / np.pi for v in meta["gyro_counts_per_dps"]])  # LSB per rad/s
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "gyro_unit", "rad/s labelled deg/s")


@pytest.fixture(scope="module")
def raw_table(tmp_path_factory):
    d = tmp_path_factory.mktemp("raw") / "t"
    write(d, Scenario(rate_hz=20.0, static_s=5.0), 2)
    return d


@pytest.mark.parametrize("cmd", ["calibrate", "diagnose"])
def test_single_glitch_named_with_its_line(raw_table, tmp_path, cmd):
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    rows = _rows(d)
    rate = {r[0] for r in csv.reader(open(d / "segments.csv")) if r[1] == "rate"}
    i = next(k for k, r in enumerate(rows) if r[0] in rate) + 40  # a sample inside the first rate run
    rows[i][rows[0].index("gy")] = "1e10"
    _put_rows(d, rows)
    run_refused([cmd, d, "-o", tmp_path / "c.json"], f"line {i + 1}", "gy", "glitch")


def test_the_accelerometers_glitch_is_named_before_the_gyros(raw_table, tmp_path):
    """The two sensors' segments are averaged on two threads (turntable/observations.read_observations):
    with a glitch in each, the accelerometer's is named, as when they were averaged one after the other."""
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    rows = _rows(d)
    kind = {r[0]: r[1] for r in csv.reader(open(d / "segments.csv"))}
    i = next(k for k, r in enumerate(rows) if kind.get(r[0]) == "rate") + 40
    j = max(k for k, r in enumerate(rows) if kind.get(r[0]) == "static") - 40
    rows[i][rows[0].index("gy")] = "1e10"
    rows[j][rows[0].index("ax")] = "1e10"
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], f"line {j + 1}", "ax", "glitch")


def test_dead_column_on_a_turntable_set(raw_table, tmp_path):
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    rows = _rows(d)
    for r in rows[1:]:
        r[rows[0].index("gz")] = "0"
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "column gz holds 0 in every row")


def test_diagnose_refuses_reversed_rate_runs(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    seg = list(csv.reader(open(d / "segments.csv")))
    for r in seg[1:]:
        if r[1] == "rate":
            r[5] = str(-float(r[5]))
    csv.writer(open(d / "segments.csv", "w", newline="")).writerows(seg)
    run_refused(["diagnose", d, "-o", tmp_path / "d.json"], "opposite to the commanded rate")


def test_accelerometer_at_a_rail_on_the_poses(sets, tmp_path):
    """An accelerometer range too small: most poses clip; refused naming the poses and the rail."""
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    for c in ("ax", "ay", "az"):
        j = rows[0].index(c)
        vals = np.array([float(r[j]) for r in rows[1:]])
        lo, hi = np.percentile(vals, 15), np.percentile(vals, 85)
        for r in rows[1:]:
            r[j] = repr(float(np.clip(float(r[j]), lo, hi)))
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "poses hold accelerometer samples at a rail", "saturates")


def test_a_settling_table_is_no_glitch(raw_table, tmp_path):
    """A smooth excursion at each segment's start (the table settling) is data, not a glitch."""
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    rows = _rows(d)
    j, seg, k = rows[0].index("ax"), None, 0
    for r in rows[1:]:
        seg, k = (r[0], 0) if r[0] != seg else (seg, k + 1)
        if k < 20:
            r[j] = repr(float(float(r[j]) * (1 + 2e-3 * np.exp(-k / 5))))
    _put_rows(d, rows)
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output


# --- options, calibration files, model files, importers, columns --------------------

@pytest.mark.parametrize("args,named", [
    (["calibrate", "{table}", "--acc-noise-g", "-1"], "--acc-noise-g -1"),
    (["calibrate", "{table}", "--acc-noise-g", "nan"], "finite"),
    (["calibrate", "{table}", "--gyro-noise-dph", "inf"], "finite"),
    (["calibrate", "{stream}", "--window-s", "0"], "--window-s 0"),
    (["calibrate", "{stream}", "--threshold-factor", "-2"], "--threshold-factor"),
    (["diagnose", "{table}", "--acc-noise-g", "0"], "--acc-noise-g 0"),
    (["field-drift", "{table}", "--heading-accuracy-deg", "-5"], "--heading-accuracy-deg -5"),
    (["simulate", "{tmp}/s", "--position-error-arcmin", "nan"], "finite"),
    (["simulate", "{tmp}/s", "--rate-hz", "1e6"], "2000"),
    (["simulate", "{tmp}/s", "--seed", "-3"], "--seed"),
    (["montecarlo", "--trials", "1000000000000", "-o", "{tmp}/m.json"], "--trials"),
    (["montecarlo", "--trials", "2000000", "--effect", "acc.quadratic.z=1e-4", "-o", "{tmp}/m.json"], "--effect"),
    (["plan", "--score", "table1", "--acc-noise-g", "0"], "--acc-noise-g 0"),
    (["plan", "--score", "table1", "--power", "1.5"], "--power"),
    (["import", "imu_tk", "{table}/samples.csv", "{table}/samples.csv", "-o", "{tmp}/o", "--acc-counts-per-g", "-5",
      "--gyro-counts-per-dps", "100"], "--acc-counts-per-g -5"),
    (["import", "csv", "{table}/samples.csv", "-o", "{tmp}/o", "--latitude-deg", "95"], "--latitude-deg 95"),
    (["simulate", "{tmp}/s", "--column", "supply_v=5:4"], "LOW <= HIGH"),
])
def test_option_values_out_of_range_are_refused(sets, tmp_path, args, named):
    """Every numeric option: a range and finiteness, checked before any work; nothing is written."""
    args = [a.format(table=sets / "table", stream=sets / "stream", tmp=tmp_path) for a in args]
    run_refused(args, named)
    assert not [p for p in tmp_path.iterdir()]


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(value=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6)))
@example(value="0\r")  # a number with a carriage return: the refusal quotes it, on one line
def test_noise_option_any_value(sets, tmp_path, value):
    """Any value of a numeric option: a calibration with a finite chi-square, or a one-line refusal."""
    out = tmp_path / "c.json"
    r = CliRunner().invoke(main, ["calibrate", str(sets / "table"), "-o", str(out), "--acc-noise-g", str(value)])
    assert r.exit_code in (0, 2), (value, r.output)
    if r.exit_code == 2:
        assert len(r.stderr.strip().splitlines()) == 1 and r.stderr.startswith("error: ")
    else:
        cal = json.loads(out.read_text())
        assert np.isfinite(cal["acc"]["chi2"]) and 0 < float(value) <= 1
        out.unlink()


@pytest.fixture(scope="module")
def table_cal(sets, tmp_path_factory):
    path = tmp_path_factory.mktemp("cal") / "cal.json"
    r = CliRunner().invoke(main, ["calibrate", str(sets / "table"), "-o", str(path)])
    assert r.exit_code == 0, r.output
    return json.loads(path.read_text())


def _edited(cal, edit):
    cal = json.loads(json.dumps(cal))
    edit(cal)
    return cal


@pytest.mark.parametrize("edit,named", [
    (lambda c: c["acc"]["params"].update(dK_x=float("nan")), "acc.params.dK_x"),
    (lambda c: c["acc"]["params"].update(b_z=1e30), "acc.params.b_z"),
    (lambda c: c["gyro"].update(C_b_model=(2 * np.array(c["gyro"]["C_b_model"])).tolist()), "proper rotation"),
    (lambda c: c.pop("layout"), "lacks 'layout'"),
    (lambda c: c["acc"].update(M=[[1, 0], [0, 1]]), "shape [2, 2]"),
    (lambda c: c["acc"].update(bias="zero"), "acc.bias"),
    (lambda c: c["gyro"]["M"][2].__setitem__(2, -1.0), "reversed axis"),
    (lambda c: c["acc"]["M"][0].__setitem__(0, 3.0), "scale factors outside"),
    (lambda c: c["acc"]["effects"].update({"acc.warp.q": {"value": 1.0}}), "acc.warp.q"),
    (lambda c: c["acc"].pop("bias"), "lacks 'bias'"),
    # parts that must tell one story: params against M, bias and C_b_model
    (lambda c: c["acc"]["params"].update(b_x=16.5), "acc.bias disagrees with what acc.params give"),
    (lambda c: c["gyro"]["params"].update(b_x=5e5), "gyro.bias disagrees"),
    (lambda c: c["acc"]["params"].update(dK_x=0.45), "acc.M disagrees"),
    (lambda c: c["acc"].update(M=(1.05 * np.array(c["acc"]["M"])).tolist()), "acc.M disagrees"),
    (lambda c: c["gyro"].pop("C_b_model"), "no C_b_model"),
    (lambda c: c["acc"]["params"].pop("dK_x"), "acc.params lacks 'dK_x'"),
    (lambda c: c["acc"].update(model="gyro_baseline"), "acc.params lacks"),
])
def test_hand_edited_calibration_is_refused_naming_the_entry(sets, tmp_path, table_cal, edit, named):
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(_edited(table_cal, edit)))
    run_refused(["apply", path, sets / "table", "-o", tmp_path / "out"], "edited.json", named, out=tmp_path / "out")


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_numeric_edit_of_a_calibration_applies_finite_or_is_refused(sets, tmp_path, table_cal, data):
    """Replace one number of the file by anything: apply writes finite inputs or refuses in one line."""
    cal = json.loads(json.dumps(table_cal))
    sensor = data.draw(st.sampled_from(["acc", "gyro"]))
    key = data.draw(st.sampled_from(["M", "bias", "params", "C_b_model"] if sensor == "gyro"
                                    else ["M", "bias", "params"]))
    value = data.draw(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([0.0, -1.0, 1e30])))
    block = cal[sensor]
    if key == "params":
        block["params"][data.draw(st.sampled_from(sorted(block["params"])))] = value
    elif key == "bias":
        block["bias"][data.draw(st.integers(0, 2))] = value
    else:
        block[key][data.draw(st.integers(0, 2))][data.draw(st.integers(0, 2))] = value
    path, out = tmp_path / "c.json", tmp_path / "out"
    path.write_text(json.dumps(cal))
    shutil.rmtree(out, ignore_errors=True)
    r = CliRunner().invoke(main, ["apply", str(path), str(sets / "table"), "-o", str(out)])
    assert r.exit_code in (0, 2), r.output
    if r.exit_code == 0:
        ms = io.read_set(out)
        assert all(np.all(np.isfinite(ms.samples[c])) for c in io.SAMPLE_COLS)
    else:
        assert len(r.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize("command", ["calibrate", "diagnose"])
@pytest.mark.parametrize("fault, named", [(("az",), "az reversed"), (("gx",), "gx reversed"),
                                          (("ay",), "ay reversed"), (("gx", "gy"), "gx and gy swapped")])
def test_a_reversed_or_swapped_column_in_a_stream_is_named(sets, tmp_path, command, fault, named):
    """The norm fits cannot see a reflected triad; the moves can (handheld.moves.WIRING_FAULTS)."""
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    j = [rows[0].index(c) for c in fault]
    for row in rows[1:]:
        if len(j) == 1:
            row[j[0]] = repr(65536.0 - float(row[j[0]]))  # unsigned 16-bit counts, reversed
        else:
            row[j[0]], row[j[1]] = row[j[1]], row[j[0]]
    _put_rows(d, rows)
    run_refused([command, d, "-o", tmp_path / "c.json"], named, "samples.csv", out=tmp_path / "c.json")


def test_a_wrong_nominal_scale_is_named(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    meta = json.loads((d / "meta.json").read_text())
    _meta(d, acc_counts_per_g=[v / 0.65 for v in meta["acc_counts_per_g"]])
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    assert "WARNING: acc: scale factors" in r.output and "acc_counts_per_g" in r.output
    assert json.loads((tmp_path / "c.json").read_text())["warnings"]


@pytest.mark.parametrize("header,named", [
    (["segment", "t_s", "acc_x", "acc_y", "acc_z", "gx", "gy", "gz"], "acc_x, acc_y, acc_z look like acc data"),
    (["segment", "t_s", "ax", "ay", "az", "gx", "gy", "ax"], "column ax appears 2 times"),
])
def test_sensor_columns_under_other_names_or_twice(sets, tmp_path, header, named):
    d = _copy(sets, "table", tmp_path)
    rows = _rows(d)
    _put_rows(d, [header] + rows[1:])
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "samples.csv", named)


def test_angles_in_radians_are_named(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    rows = list(csv.reader(open(d / "segments.csv")))
    for row in rows[1:]:
        for j in range(2, 6):
            row[j] = repr(np.radians(float(row[j]))) if row[j] else ""
    csv.writer(open(d / "segments.csv", "w", newline="")).writerows(rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "radians")


@pytest.mark.parametrize("name", ["meta.json", "samples.csv", "segments.csv"])
def test_a_folder_named_like_a_set_file(sets, tmp_path, name):
    d = _copy(sets, "table", tmp_path)
    (d / name).unlink()
    (d / name).mkdir()
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], name, "is a folder")


def test_noise_of_zero_in_meta_is_named(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    _meta(d, acc_noise_g=0)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "acc_noise_g", "> 0")


@pytest.mark.parametrize("text,named", [
    ("import sympy as sp\nMODELS = [\n", "line 2: syntax error"),
    ("x = 1\nraise RuntimeError('boom')\n", "line 2: RuntimeError: boom"),
    ("from simucal.derive.models.baseline import ACC_BASELINE\nfrom simucal.derive.models.effects import acc_quadratic"
     "\nMODELS = [ACC_BASELINE.with_terms('../../evil', [acc_quadratic('z')])]\n", "must be a Python identifier"),
    ("MODELS = 3\n", "must define MODELS"),
])
def test_a_broken_model_file_is_the_users_error(sets, tmp_path, monkeypatch, text, named):
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    f = tmp_path / "mine.py"
    f.write_text(text)
    run_refused(["calibrate", sets / "table", "-o", tmp_path / "c.json", "--add", f], "mine.py", named)


@pytest.mark.slow
def test_a_model_file_that_never_ends_is_stopped(sets, tmp_path, monkeypatch):
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("SIMUCAL_DERIVE_TIMEOUT_S", "1")
    f = tmp_path / "loop.py"
    f.write_text("while True:\n    pass\n")
    run_refused(["derive", "--model", f], "loop.py", "more than 1 s", "SIMUCAL_DERIVE_TIMEOUT_S")


@pytest.mark.slow
def test_a_model_file_runs_in_a_child_and_never_again(sets, tmp_path, monkeypatch):
    """Its code runs once, in another process (a side effect there leaves this one alone), and a cached
    file is loaded without running it."""
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    f, marks = tmp_path / "mine.py", tmp_path / "ran.txt"
    f.write_text("import os\nfrom simucal.derive.models.baseline import ACC_BASELINE\n"
                 "from simucal.derive.models.effects import acc_quadratic\n"
                 f"open({str(marks)!r}, 'a').write(str(os.getpid()) + '\\n')\n"
                 "MODELS = [ACC_BASELINE.with_terms('acc_runs_once', [acc_quadratic('z')])]\n")
    for _ in range(2):
        r = CliRunner().invoke(main, ["derive", "--model", str(f)])
        assert r.exit_code == 0, r.output
    pids = marks.read_text().split()
    assert len(pids) == 1 and int(pids[0]) != os.getpid()


@pytest.mark.parametrize("sections,named", [
    ('{"x_p": {"start": 0, "end": 99999}}', "outside the recording"),
    ('{"x_p": ', "not valid JSON"),
    ('{"x_p": {"begin": 0}}', "needs whole-number"),
    ('[1, 2]', "must map each section label"),
])
def test_ferraris_section_list_errors(tmp_path, sections, named):
    src = tmp_path / "s.csv"
    src.write_text("acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n" + "0,0,9.81,0,0,0\n" * 20)
    (tmp_path / "l.json").write_text(sections)
    run_refused(["import", "imucal-ferraris", src, tmp_path / "l.json", "-o", tmp_path / "o", "--latitude-deg", "45"],
                "l.json", named, out=tmp_path / "o")


@pytest.mark.parametrize("text,named", [
    ("acc_x,acc_y,gyr_x,gyr_y,gyr_z\n0,0,0,0,0\n", "no columns ['acc_z']"),
    ("part,samples,acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\nx_p,0,1,2\n", "row ends before"),
])
def test_importer_files_missing_columns(tmp_path, text, named):
    src = tmp_path / "a.csv"
    src.write_text(text)
    fmt = "imucal-annotated" if text.startswith("part") else "imucal-ferraris"
    run_refused(["import", fmt, src, "-o", tmp_path / "o", "--latitude-deg", "45"], "a.csv", named, out=tmp_path / "o")


def test_a_plan_on_one_great_circle_names_what_it_cannot_determine(tmp_path):
    """Gravity directions on one great circle (the inner axis turned alone, middle at 0): the fit runs,
    and the console names the parameters the plan confounds; a good plan names none."""
    plan = tmp_path / "circle.csv"
    plan.write_text("outer_deg,middle_deg,inner_deg\n" + "".join(f"0,0,{a}\n" for a in range(0, 360, 30)))
    write(tmp_path / "circle", Scenario(plan=str(plan)), 1)
    write(tmp_path / "good", Scenario(), 1)
    for name, named in (("circle", True), ("good", False)):
        r = CliRunner().invoke(main, ["calibrate", str(tmp_path / name), "-o", str(tmp_path / f"{name}.json")])
        assert r.exit_code == 0, r.output
        poor = json.loads((tmp_path / f"{name}.json").read_text())["acc"].get("poorly_determined", {})
        assert ("acc: POORLY DETERMINED" in r.output) == named and bool(poor) == named
        if named:
            assert poor["b_y"]["inflation"] > 100


def test_a_stream_calibration_whose_T_was_edited_is_refused(sets, tmp_path):
    out = tmp_path / "c.json"
    assert CliRunner().invoke(main, ["calibrate", str(sets / "stream"), "-o", str(out)]).exit_code == 0
    cal = json.loads(out.read_text())
    cal["gyro"]["T"] = (2 * np.array(cal["gyro"]["T"])).tolist()
    out.write_text(json.dumps(cal))
    run_refused(["apply", out, sets / "stream", "-o", tmp_path / "o"], "gyro.T is not the inverse", out=tmp_path / "o")


@pytest.mark.parametrize("meta,named", [
    ({"latitude_deg": True}, "latitude_deg"),
    ({"full_scale": {"acc": 5}}, "full_scale"),
    ({"full_scale": [0, 1]}, "full_scale"),
    ({"full_scale": {"acc": [1, -1]}}, "lo < hi"),
])
def test_meta_values_of_the_wrong_shape_are_named(sets, tmp_path, meta, named):
    shutil.copytree(sets / "table", tmp_path / "t")
    m = json.loads((tmp_path / "t" / "meta.json").read_text())
    (tmp_path / "t" / "meta.json").write_text(json.dumps({**m, **meta}))
    for cmd in ("calibrate", "diagnose"):
        run_refused([cmd, tmp_path / "t", "-o", tmp_path / "o.json"], "meta.json", named, out=tmp_path / "o.json")


@pytest.mark.slow
@pytest.mark.parametrize("args,named", [
    (["simulate", "{tmp}/s", "--effect", "acc.quadratic.z=nan"], "finite"),
    (["simulate", "{tmp}/s", "--effect", "acc.quadratic.z=1e300"], "finite"),
    (["montecarlo", "--effect", "acc.quadratic.z=inf", "-o", "{tmp}/m.json"], "finite"),
    (["montecarlo", "--effect", "acc.bias_drift_time.x=1e-6", "-o", "{tmp}/m.json"], "never vary"),
    (["simulate", "{tmp}/s", "--rate-hz", "1e-3"], "0 rows"),
])
def test_simulated_values_that_would_write_nonsense_are_refused(tmp_path, args, named):
    run_refused([a.format(tmp=tmp_path) for a in args], named)
    assert not list(tmp_path.iterdir())


def test_a_stated_noise_far_above_the_scatter_is_named(sets, tmp_path):
    r = CliRunner().invoke(main,
                           ["calibrate", str(sets / "table"), "-o", str(tmp_path / "c.json"), "--acc-noise-g", "0.1"])
    assert r.exit_code == 0 and "acc: WARNING: the residuals are" in r.output
    assert "noise_warning" in json.loads((tmp_path / "c.json").read_text())["acc"]


@pytest.mark.slow
def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(sets, tmp_path, monkeypatch):
    monkeypatch.setenv("SIMUCAL_SCHEDULER_TIMEOUT_S", "1")  # the wait is not what is tested
    run_refused(["calibrate", sets / "table", sets / "acc_only", "-o", tmp_path / "out", "--scheduler",
                 "tcp://127.0.0.1:1"], "no Dask scheduler answers", out=tmp_path / "out")


# --- second corpus: silent-wrong and unclear cases ----------------------------------

def test_a_stated_noise_far_below_the_scatter_is_named_before_any_effect(sets, tmp_path):
    """acc_noise_g 1e4 times too small: the misfit has no structure, so the noise is named first,
    and --add auto adds nothing (no effect predicts the rows left out better)."""
    out = tmp_path / "c.json"
    r = CliRunner().invoke(main, ["calibrate", str(sets / "table"), "-o", str(out), "--acc-noise-g", "1e-9",
                                  "--add", "auto"])
    assert r.exit_code == 0, r.output
    assert "stated noise is likely too small" in r.output and "the stated noise may be too small" in r.output
    acc = json.loads(out.read_text())["acc"]
    assert acc["noise_too_small"] and acc["auto"] == []


def test_diagnose_names_a_stated_noise_far_above_the_scatter(sets, tmp_path):
    r = CliRunner().invoke(main, ["diagnose", str(sets / "table"), "-o", str(tmp_path / "d.json"),
                                  "--acc-noise-g", "0.1"])
    assert r.exit_code == 0 and "WARNING: the residuals are" in r.output


def test_diagnose_refuses_a_reversed_accelerometer_axis_on_a_table(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    rows = _rows(d)
    j = rows[0].index("ay")
    for row in rows[1:]:
        row[j] = repr(-float(row[j]))
    _put_rows(d, rows)
    run_refused(["diagnose", d, "-o", tmp_path / "d.json"], "reversing the accelerometer's y axis")


@pytest.mark.parametrize("column, named", [("ax", "column ax does not follow gravity")])
def test_a_dead_accelerometer_axis_on_a_table_is_named(sets, tmp_path, column, named):
    d = _copy(sets, "table", tmp_path)
    rows = _rows(d)
    j = rows[0].index(column)
    rng = np.random.default_rng(0)
    for row in rows[1:]:
        row[j] = repr(float(rng.normal(0.0, 1.0)))
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], named)


@pytest.mark.parametrize("name, column, value, where, named", [
    ("raw", "ay", "-10400.0", lambda i, n, row: row[0] == "3", ("column ay holds -10400", "segment 3")),
    ("stream", "az", "36000", lambda i, n, row: i > n // 2, ("column az holds 36000", "while ax and ay vary")),
])
def test_a_channel_stuck_for_part_of_the_recording_is_named(sets, raw_table, tmp_path, name, column, value, where,
                                                             named):
    d = Path(shutil.copytree(raw_table if name == "raw" else sets / name, tmp_path / "d"))
    rows = _rows(d)
    j = rows[0].index(column)
    for i, row in enumerate(rows[1:], start=1):
        if where(i, len(rows), row):
            row[j] = value
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], *named)


def test_a_stream_timed_in_milliseconds_is_named(sets, tmp_path):
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    for row in rows[1:]:
        row[0] = repr(float(row[0]) * 1000)
    _put_rows(d, rows)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "milliseconds")


def test_a_gyro_clipped_inside_full_scale_is_found_and_its_moves_left_out(sets, tmp_path):
    """The amplifier clips at +-40 deg/s while full_scale states the register's rails: the pile-up
    at the clip level is found (sensor_checks.repeat_is_clipping) and the moves through it left out."""
    d = _copy(sets, "stream", tmp_path)
    rows = _rows(d)
    j = rows[0].index("gy")
    for row in rows[1:]:
        row[j] = repr(min(max(float(row[j]), 32768 - 656), 32768 + 656))
    _put_rows(d, rows)
    r = CliRunner().invoke(main, ["calibrate", str(d), "-o", str(tmp_path / "c.json")])
    assert r.exit_code == 0, r.output
    assert "saturated (clipped) samples" in r.output and "moves left out" in r.output
    assert json.loads((tmp_path / "c.json").read_text())["gyro"]["saturation"][0]["axis"] == "y"


def test_clipped_segments_leaving_too_few_are_named(raw_table, tmp_path):
    """A range of 0.5 g: every segment with an axis past it clips there and is left out."""
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    rows = _rows(d)
    cols = [rows[0].index(c) for c in ("ax", "ay", "az")]
    rail = 0.5 * max(abs(float(r[j])) for r in rows[1:] for j in cols)
    for r in rows[1:]:
        for j in cols:
            r[j] = repr(min(max(float(r[j]), -rail), rail))
    _put_rows(d, rows)
    _meta(d, full_scale={"acc": [-rail, rail]})
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "hold clipped samples", "left out")


def test_a_full_scale_the_data_exceed_is_named(raw_table, tmp_path):
    d = Path(shutil.copytree(raw_table, tmp_path / "t"))
    _meta(d, full_scale={"acc": [-1.0, 1.0]})
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "outside full_scale", "meta.json")


def test_rates_in_radians_per_second_name_the_rates_not_the_unit(sets, tmp_path):
    d = _copy(sets, "table", tmp_path)
    seg = list(csv.reader(open(d / "segments.csv")))
    for r in seg[1:]:
        if r[1] == "rate":
            r[5] = repr(float(np.radians(float(r[5]))))
    csv.writer(open(d / "segments.csv", "w", newline="")).writerows(seg)
    run_refused(["calibrate", d, "-o", tmp_path / "c.json"], "outer_rate_dps in segments.csv that is off")


@pytest.mark.parametrize("args, named", [
    (["--separate", "acc.quadratic.z,acc.quadratic.z", "--sizes", "1e-4,1e-4"], "cannot be told from itself"),
    (["--separate", "acc.quadratic.z,acc.scale_asymmetry.z", "--sizes", "nan,1e-4"], "finite, non-zero"),
    (["--separate", "acc.quadratic.z,acc.scale_asymmetry.z", "--sizes", "0,0"], "finite, non-zero"),
])
def test_plan_separation_needs_two_effects_of_real_sizes(tmp_path, args, named):
    run_refused(["plan", "--score", "table1", *args, "-o", tmp_path / "s.json"], named, out=tmp_path / "s.json")


@pytest.mark.parametrize("body, named", [("nan,0,0\n", "must be finite"), ("", "has no positions"),
                                         ("0,0,0\n" * 12, "unobservable")])
def test_a_plan_file_of_nonsense_positions_is_named(tmp_path, body, named):
    p = tmp_path / "p.csv"
    p.write_text("outer_deg,middle_deg,inner_deg\n" + body)
    run_refused(["plan", "--score", p, "-o", tmp_path / "s.json"], named, out=tmp_path / "s.json")


def test_ferraris_overlapping_sections_and_a_zero_turn_are_refused(tmp_path):
    src = tmp_path / "s.csv"
    src.write_text("acc_x,acc_y,acc_z,gyr_x,gyr_y,gyr_z\n" + "0,0,9.81,0,0,0\n" * 40)
    (tmp_path / "l.json").write_text('{"x_p": {"start": 0, "end": 20}, "x_a": {"start": 10, "end": 30}}')
    base = ["import", "imucal-ferraris", src, tmp_path / "l.json", "-o", tmp_path / "o", "--latitude-deg", "45"]
    run_refused(base, "overlap", out=tmp_path / "o")
    (tmp_path / "l.json").write_text('{"x_p": {"start": 0, "end": 20}, "x_rot": {"start": 20, "end": 40}}')
    run_refused(base + ["--turn-deg", "0"], "--turn-deg 0", out=tmp_path / "o")


def test_csv_import_maps_each_source_column_once_and_needs_no_gyro_arguments_without_gyros(tmp_path):
    src = tmp_path / "x.csv"
    src.write_text("t,a1,a2,a3\n" + "".join(f"{i * 0.01},0,0,1\n" for i in range(30)))
    run_refused(["import", "csv", src, "-o", tmp_path / "o", "--columns", "t_s=t,ax=a1,ay=a1,az=a3",
                 "--acc-unit", "g"], "mapped to both ax and ay", out=tmp_path / "o")
    r = CliRunner().invoke(main, ["import", "csv", str(src), "-o", str(tmp_path / "o"), "--columns",
                                  "t_s=t,ax=a1,ay=a2,az=a3", "--acc-unit", "g"])
    assert r.exit_code == 0, r.output
    ms = io.read_set(tmp_path / "o")
    assert ms.has_acc and not ms.has_gyro


def test_a_model_file_that_exits_is_the_users_error(sets, tmp_path, monkeypatch):
    monkeypatch.setenv("SIMUCAL_CACHE", str(tmp_path / "cache"))
    m = tmp_path / "m.py"
    m.write_text("import sys\nsys.exit(0)\n")
    run_refused(["calibrate", sets / "table", "-o", tmp_path / "c.json", "--add", m], "m.py", "ended the process")


@pytest.mark.parametrize("args,expect", [
    (["validate", "nosuch.json", "nosuch_dir"], ("'nosuch.json' does not exist", "simucal validate --help")),
    (["calibrate", "--method", "bogus", "x"], ("'bogus' is not one of", "simucal calibrate --help")),
    (["no-such-command"], ("No such command", "simucal --help")),
    (["montecarlo", "--effect", "acc.quadratic.z=1e-4", "--effect", "acc.quadratic.z=2e-4"], ("given twice",)),
    (["montecarlo", "--rates-dps", "10,abc"], ("--rates-dps 10,abc", "e.g. 10,-10")),
])
def test_a_usage_error_is_one_line_naming_the_help(tmp_path, args, expect):
    """click's own refusals (a missing file, a bad choice, an unknown command) are one line, as
    simucal's are, naming the help to read; a value given twice is refused, not the last one kept."""
    run_refused(args + ["-o", str(tmp_path / "o.json")] if args[0] == "montecarlo" else args, *expect)


def test_import_csv_reads_a_loggers_whitespace_text(tmp_path):
    """Whitespace-separated text with a '#' header line (as many loggers write), '#' comments and blank
    lines within: read as the CSV with the same numbers; a short row is named by its line."""
    from simucal import io
    src = tmp_path / "log.txt"
    src.write_text("# t ax ay az gx gy gz\n0.00  0.01 0.02 1.0  0.1 0.2 0.3\n0.01\t0.02 0.03 0.9 0.4 0.5 0.6\n"
                   "# paused\n\n0.02 0.03 0.04 0.8 0.7 0.8 0.9\n")
    args = ["import", "csv", str(src), "--columns", "t_s=t,ax=ax,ay=ay,az=az,gx=gx,gy=gy,gz=gz", "--acc-unit", "g",
            "--gyro-unit", "deg/s", "--latitude-deg", "45"]
    r = CliRunner().invoke(main, args + ["-o", str(tmp_path / "o")])
    assert r.exit_code == 0, r.output
    s = io.read_set(tmp_path / "o").samples
    assert s["t_s"].tolist() == [0.0, 0.01, 0.02] and s["gz"].tolist() == [0.3, 0.6, 0.9]
    src.write_text(src.read_text() + "0.03 0.03 0.04 0.8 0.7\n")
    r = CliRunner().invoke(main, args + ["-o", str(tmp_path / "o2")])
    assert r.exit_code != 0 and "log.txt, line 7: the row ends before column" in r.output + (r.stderr or "")


@pytest.mark.slow
def test_diagnose_never_sends_a_user_to_a_refusal(tmp_path):
    """A sequence that turns only the outer axis passes its model test, but calibrate refuses it
    (parameters unobserved); diagnose's next line was `simucal calibrate SET`. Now it is a command that runs,
    and it says why calibrate would refuse."""
    import shlex

    from simucal import api
    seq = tmp_path / "outer.csv"
    seq.write_text("axis,angle_deg,rate_dps,rest_s\n" + "outer,90,10,20\n" * 4 + "outer,-360,20,20\n")
    api.simulate(sequence=seq).write(tmp_path / "oo")
    d = api.diagnose(str(tmp_path / "oo"))
    assert "unobserved" in " ".join(d.next_notes)
    r = CliRunner().invoke(main, shlex.split(d.next_command)[1:])
    assert r.exit_code == 0, (d.next_command, r.output)
    refused_cli = CliRunner().invoke(main, ["calibrate", str(tmp_path / "oo"), "-o", str(tmp_path / "c.json")])
    assert refused_cli.exit_code == 2 and "unobserved" in refused_cli.stderr


def test_a_turntable_set_with_a_run_relabelled_move_names_the_segments_and_the_rule(tmp_path):
    import csv

    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "t", Scenario(rate_hz=5.0), 1)
    rows = list(csv.reader((tmp_path / "t" / "segments.csv").open()))
    first = next(r for r in rows[1:] if r[1] == "rate")
    first[1], first[2:6] = "move", ["", "", "", ""]
    with (tmp_path / "t" / "segments.csv").open("w", newline="") as fh:
        csv.writer(fh).writerows(rows)
    r = CliRunner().invoke(main, ["calibrate", str(tmp_path / "t"), "--method", "systematic", "-o",
                                  str(tmp_path / "c.json")])
    assert r.exit_code == 2 and f"move segments (segment {first[0]})" in r.stderr
    assert "a rotation sequence is rests (static) and the moves between them" in r.stderr


# --- a set of one sensor (the spec lets samples.csv hold the accelerometers' or the gyros' columns only) ----------

OTHER = {"acc": "gyro", "gyro": "acc"}


def _one_sensor(src, dst, keep):
    """A copy of src with the other sensor's columns dropped, and its meta.json fields as the spec then allows: no
    scale factors or noise of it (its unit, required, in a physical unit), no latitude without a gyro."""
    d = Path(shutil.copytree(src, dst))
    for c in io.SENSOR_COLS[OTHER[keep]]:
        _drop_column(d, c)
    m = json.loads((d / "meta.json").read_text())
    m = {k: v for k, v in m.items() if not k.startswith(OTHER[keep] + "_")
         and not (keep == "acc" and k == "latitude_deg")}
    m[OTHER[keep] + "_unit"] = "deg/h" if keep == "acc" else "g"
    (d / "meta.json").write_text(json.dumps(m))
    return d


def _ran(args):
    r = CliRunner().invoke(main, [str(a) for a in args])
    assert r.exit_code == 0 and "Traceback" not in r.output, (args, r.output, r.exception)
    return r.output


@pytest.mark.parametrize("keep", ["acc", "gyro"])
def test_a_turntable_set_of_one_sensor_is_worked_on_and_the_other_said_skipped(raw_table, tmp_path, keep):
    """An accelerometer-only set ended in an internal error (TypeError) in calibrate; now every command does the
    one sensor's work and says which it skipped."""
    d = _one_sensor(raw_table, tmp_path / "one", keep)
    skipped = f"{OTHER[keep]}: skipped (the data have no {' '.join(io.SENSOR_COLS[OTHER[keep]])} columns)"
    cal = tmp_path / "c.json"
    out = _ran(["calibrate", d, "-o", cal])
    assert skipped in out and f"{keep}: residual rms" in out
    assert json.loads(cal.read_text())["layout"]["sensors"] == [keep]
    assert skipped in _ran(["diagnose", d, "-o", tmp_path / "d.json"])
    assert skipped in _ran(["validate", cal, d, "-o", tmp_path / "v.json"])
    assert skipped in _ran(["noise", d, "-o", tmp_path / "n.json"])
    assert f"{OTHER[keep]} skipped (not in {d})" in _ran(["apply", cal, d, "-o", tmp_path / "applied"])


@pytest.mark.parametrize("keep", ["acc", "gyro"])
def test_a_sequence_of_one_sensor_is_refused_naming_the_columns(tmp_path, keep):
    """Systematic calibration navigates with both sensors: a gyro-only sequence was a KeyError ('ax'), an
    accelerometer-only one was sent to add a latitude it did not need."""
    from simucal import api
    seq = tmp_path / "seq.csv"
    seq.write_text("axis,angle_deg,rate_dps,rest_s\n" + "outer,90,10,15\n" * 2 + "inner,90,10,15\n" * 2)
    api.simulate(sequence=str(seq), rate_hz=20.0).write(tmp_path / "seq")
    d = _one_sensor(tmp_path / "seq", tmp_path / "one", keep)
    for cmd in ("calibrate", "diagnose"):
        run_refused([cmd, d, "-o", tmp_path / "o.json"], f"{d / 'samples.csv'}: has no "
                    f"{' '.join(io.SENSOR_COLS[OTHER[keep]])} columns", "both sensors", out=tmp_path / "o.json")


def test_noise_of_a_moving_stream_without_accelerometers_is_refused_by_its_rate(sets, tmp_path):
    """Without accelerometers noise could not tell a hand-placed session from a still recording, and gave its
    moves as a rate random walk; the gyro's 1-s means tell it now."""
    d = _one_sensor(sets / "stream", tmp_path / "gyro_only", "gyro")
    run_refused(["noise", d, "-o", tmp_path / "n.json"], "the unit moves", "1-s mean rate", out=tmp_path / "n.json")


def test_simulate_a_sequence_says_the_sequence_scenario(tmp_path):
    """--scenario sequence --sequence NAME was an internal error (KeyError: 'sequence'); --sequence alone wrote a
    sequence and said "paper scenario"."""
    seq = tmp_path / "seq.csv"
    seq.write_text("axis,angle_deg,rate_dps,rest_s\nouter,90,10,5\n")
    for i, args in enumerate((["--scenario", "sequence", "--sequence", seq], ["--sequence", seq])):
        out = _ran(["simulate", "-o", tmp_path / f"s{i}", *args])
        assert f"wrote {tmp_path / f's{i}'} (sequence scenario, seed 0)" in out
        assert any(s.kind == "move" for s in io.read_set(tmp_path / f"s{i}").segments)
    run_refused(["simulate", "-o", tmp_path / "s2", "--scenario", "handheld", "--sequence", seq],
                "sequence (--sequence)", "--scenario paper or sequence", out=tmp_path / "s2")
