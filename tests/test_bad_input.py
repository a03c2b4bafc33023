"""Bad input: one line naming the cause, a non-zero exit, no traceback, nothing written (issue 13).

A corpus of the cases found by trying the tool as a new user would, each run through the
command line, and a property test of the readers on random bytes, CSV shapes and meta.
"""
import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
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
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), r.stderr
    for e in expect:
        assert e.lower() in lines[0].lower(), (e, lines[0])
    if out is not None:
        assert not Path(out).exists()
    return lines[0]


def _copy(sets, name, tmp_path):
    return Path(shutil.copytree(sets / name, tmp_path / name))


# --- files that are not text, or not the spec's CSV -------------------------------------------

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
        ms = io.read(d)
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
