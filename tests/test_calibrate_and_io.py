"""Calibration of simulated sets, spec refusals, the CLI and the audit."""
import csv
import json
import shutil

import numpy as np
import pytest
from click.testing import CliRunner

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.cli import main
from simucal.errors import CalibrationError, NotConverged


def test_exact_within_3_sigma_of_truth(paper_set):
    folder, truth = paper_set
    r = calibrate(folder, method="exact").to_json()
    for sensor in ("acc", "gyro"):
        for name, est in r[sensor]["params"].items():
            err = est - truth[sensor]["params"][name]
            assert abs(err) < 3 * r[sensor]["std"][name] + 1e-15, (sensor, name, err, r[sensor]["std"][name])
    assert r["acc"]["p_value"] > 1e-3  # the baseline model explains its own data


def test_norm_beats_multiposition_on_gyro_bias(paper_set):
    folder, truth = paper_set
    tb = np.array(truth["gyro"]["bias"])
    err = {m: np.abs(np.array(calibrate(folder, method=m).to_json()["gyro"]["bias"]) - tb).max()
           for m in ("exact", "multiposition")}
    assert err["exact"] < err["multiposition"] / 10


def _copy(folder, tmp_path):
    dst = tmp_path / "set"
    shutil.copytree(folder, dst)
    return dst


def test_nan_cell_named_with_line(paper_set, tmp_path):
    dst = _copy(paper_set[0], tmp_path)
    lines = (dst / "samples.csv").read_text().splitlines()
    cells = lines[3].split(",")
    cells[2] = "nan"
    lines[3] = ",".join(cells)
    (dst / "samples.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(io.MeasurementSetError, match=r"samples.csv, line 4: column ax: nan is not finite"):
        io.read_set(dst)


def test_unknown_unit_and_missing_latitude(paper_set, tmp_path):
    dst = _copy(paper_set[0], tmp_path)
    meta = json.loads((dst / "meta.json").read_text())
    (dst / "meta.json").write_text(json.dumps({**meta, "acc_unit": "mg"}))
    with pytest.raises(io.MeasurementSetError, match="not a known unit"):
        io.read_set(dst)
    meta.pop("latitude_deg")
    (dst / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(io.MeasurementSetError, match="latitude_deg is required"):
        io.read_set(dst)


def test_empty_cell_named(paper_set, tmp_path):
    dst = _copy(paper_set[0], tmp_path)
    lines = (dst / "samples.csv").read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[4], "", 1)
    (dst / "samples.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(io.MeasurementSetError, match="line 6: column .* is empty"):
        io.read_set(dst)


def test_paper_unification_needs_table2(paper_set, tmp_path):
    dst = _copy(paper_set[0], tmp_path)
    segs = (dst / "segments.csv").read_text().splitlines()
    keep = [segs[0]] + [s for s in segs[1:] if s.split(",")[3] not in ("90.0",) or s.split(",")[1] == "rate"]
    kept_ids = {s.split(",")[0] for s in keep[1:]}
    (dst / "segments.csv").write_text("\n".join(keep) + "\n")
    rows = (dst / "samples.csv").read_text().splitlines()
    (dst / "samples.csv").write_text("\n".join([rows[0]] + [r for r in rows[1:] if r.split(",")[0] in kept_ids]) + "\n")
    with pytest.raises(CalibrationError, match="Table 2"):
        calibrate(dst, method="linear")


def test_cli_simulate_calibrate(tmp_path):
    runner = CliRunner()
    res = runner.invoke(main, ["simulate", str(tmp_path / "s"), "--seed", "1", "--gyro-unit", "deg/s"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(main, ["calibrate", str(tmp_path / "s"), "-o", str(tmp_path / "c.json")])
    assert res.exit_code == 0, res.output
    cal = json.loads((tmp_path / "c.json").read_text())
    truth = json.loads((tmp_path / "s" / "truth.json").read_text())
    assert np.abs(np.array(cal["gyro"]["bias"]) - truth["gyro"]["bias"]).max() < 0.05
    res = runner.invoke(main, ["calibrate", str(tmp_path / "nope")])
    assert res.exit_code != 0


def test_audit_covers_eq5_to_27_and_table1(audit_report):
    rep = audit_report
    covered = set()
    for f in rep.findings:
        label = f.eq.split()[0]
        if "-" in label:
            a, b = label.split("-")
            covered |= set(range(int(a), int(b) + 1))
        elif label.isdigit():
            covered.add(int(label))
    assert set(range(5, 28)) <= covered, sorted(set(range(5, 28)) - covered)
    assert any(f.eq == "Table 1" for f in rep.findings)
    phi = next(f for f in rep.findings if f.what == "gyro back-substitution phi_zy")
    assert phi.max_abs_diff > 1e-6  # the paper's K_4 for phi_zy is caught
    for name, r in rep.remainders:
        assert 3.5 < r["ratio"] < 4.5, (name, r)  # every linearisation is second order


def test_raw_samples_within_3_sigma(tmp_path):
    from simucal.turntable.simulate import Scenario, write
    truth = write(tmp_path / "raw", Scenario(rate_hz=20.0, static_s=5.0, acc_unit="m/s^2", gyro_unit="rad/s"), seed=5)
    r = calibrate(tmp_path / "raw", method="exact")
    for sensor, block in r.blocks():
        for name, est in block.params.items():
            assert abs(est - truth[sensor]["params"][name]) < 3 * block.std[name], (sensor, name)
        assert block.p_value > 1e-3


def test_not_converged_is_reported(paper_set):
    from simucal.fit.catalog import load
    from simucal.fit.norm_fit import fit_exact
    from simucal.turntable.observations import segment_observations
    obs, _ = segment_observations(io.read_set(paper_set[0]), "acc")
    with pytest.raises(NotConverged, match="did not converge"):  # its type, not its words, tells callers
        fit_exact(load("acc_baseline"), obs, p0=[0.3] * 9, max_iter=1)


@pytest.mark.slow
def test_user_model_file_goes_to_the_cache_not_the_package(tmp_path, monkeypatch, paper_set):
    """A user's model is derived into the cache, keyed by its file; generated/ stays as it was,
    the model works by name from any folder, and a second use needs no derivation."""
    from simucal.fit.catalog import derive_model_file, load
    from simucal.fit.models import generated_dir
    before = {p.name: p.read_bytes() for p in generated_dir().iterdir() if p.is_file()}
    model_file = tmp_path / "my_model.py"
    model_file.write_text(
        "from simucal.derive.models.baseline import ACC_BASELINE\n"
        "from simucal.derive.models.effects import acc_quadratic\n"
        "MODELS = [ACC_BASELINE.with_terms('acc_mine', [acc_quadratic('x')])]\n")
    names, derived = derive_model_file(model_file)
    assert names == ["acc_mine"] and derived
    assert derive_model_file(model_file) == (["acc_mine"], False)  # cached: no SymPy the second time
    assert {p.name: p.read_bytes() for p in generated_dir().iterdir() if p.is_file()} == before
    monkeypatch.chdir(tmp_path.parent)  # from another folder, by name
    load.cache_clear()
    m = load("acc_mine")
    assert m.params[-1] == "K2_x" and m.source == str(model_file.resolve())
    result = calibrate(paper_set[0], method="exact", acc_model="acc_mine")
    assert result.acc.model == "acc_mine" and "K2_x" in result.acc.params


def test_unit_mixup_named(paper_set, tmp_path):
    dst = _copy(paper_set[0], tmp_path)
    meta = json.loads((dst / "meta.json").read_text())
    meta["acc_unit"] = "m/s^2"  # the outputs are really pulse/s; and a g-labelled m/s^2 set below
    meta.pop("acc_pulses_per_g")
    (dst / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(CalibrationError, match="times the known input"):
        calibrate(dst, method="exact")
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "ms2", Scenario(acc_unit="m/s^2"), 1)
    meta = json.loads((tmp_path / "ms2" / "meta.json").read_text())
    meta["acc_unit"] = "g"
    (tmp_path / "ms2" / "meta.json").write_text(json.dumps(meta))
    with pytest.raises(CalibrationError, match="m/s\\^2 labelled g"):
        calibrate(tmp_path / "ms2", method="exact")


def test_saturated_segment_left_out_and_reported(tmp_path):
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "s", Scenario(rate_hz=20.0, static_s=3.0, acc_unit="g"), 2)
    meta = json.loads((tmp_path / "s" / "meta.json").read_text())
    meta["full_scale"] = {"acc": [-0.98, 0.98]}  # clips the positions nearest an axis
    (tmp_path / "s" / "meta.json").write_text(json.dumps(meta))
    rows = list(csv.reader(open(tmp_path / "s" / "samples.csv")))
    cols = [rows[0].index(c) for c in ("ax", "ay", "az")]
    for row in rows[1:]:  # the sensor stops at its rails
        for j in cols:
            row[j] = repr(min(max(float(row[j]), -0.98), 0.98))
    csv.writer(open(tmp_path / "s" / "samples.csv", "w", newline="")).writerows(rows)
    try:
        r = calibrate(tmp_path / "s", method="exact")
    except CalibrationError as e:  # too few left is also an honest answer
        assert "positions" in str(e)
        return
    excluded = r.details["excluded_segments"]
    assert excluded and all(e["reason"] == "saturated samples" for e in excluded)


def test_a_sets_hash_and_segment_rows_are_of_the_files_as_read(tmp_path):
    """read_set hashes the bytes it parsed (a byte-order mark included: the file's bytes) into the
    calibration's input_sha256, and groups a segment's rows wherever they lie in the file."""
    import hashlib
    from simucal.turntable.simulate import Scenario, write
    d = tmp_path / "d"
    write(d, Scenario(rate_hz=2.0), seed=1)
    header, *rows = (d / "samples.csv").read_text().splitlines(keepends=True)
    col = header.split(",").index("segment")
    by_segment = {}
    for r in rows:
        by_segment.setdefault(r.split(",")[col], []).append(r)
    # the segments' rows dealt in turn: each segment's rows in order, none of them contiguous
    dealt = [r for k in range(max(map(len, by_segment.values()))) for g in by_segment.values() if k < len(g)
             for r in [g[k]]]
    (d / "samples.csv").write_bytes(b"\xef\xbb\xbf" + (header + "".join(dealt)).encode())
    ms = io.read_set(d)
    h = hashlib.sha256()
    for name in ("meta.json", "segments.csv", "samples.csv"):
        h.update(name.encode() + b"\0" + (d / name).read_bytes())
    assert ms.sha256 == h.hexdigest()
    seg = ms.samples["segment"]
    assert len(seg) > 2 * len(ms.segments) and not np.all(np.diff(seg) >= 0)
    for s in ms.segments:
        assert np.array_equal(ms.rows(s.segment), np.nonzero(seg == s.segment)[0])
    assert ms.rows(10 ** 6).size == 0
    assert calibrate(ms, method="exact").input_sha256 == ms.sha256


@pytest.mark.parametrize("case", ["header over 64 KiB", "carriage returns alone", "not UTF-8 in a label column",
                                  "not UTF-8 in a number"])
def test_unusual_samples_files_read_as_csv_reads_them(tmp_path, case):
    """The fast reader takes a plain header line alone: a header longer than 64 KiB or lines ended by
    carriage returns alone are read as before, and a byte that is not UTF-8 is refused with its line
    even in a column no model reads."""
    from simucal.turntable.simulate import Scenario, write
    d = tmp_path / "s"
    write(d, Scenario(rate_hz=2.0), seed=1)
    header, body = (d / "samples.csv").read_bytes().replace(b"\r\n", b"\n").split(b"\n", 1)
    rows = body.splitlines()
    data = {"header over 64 KiB": header + b"," + b"x" * 70000 + b"\n" + b"".join(r + b",1\n" for r in rows),
            "carriage returns alone": (header + b"\n" + body).replace(b"\n", b"\r"),
            "not UTF-8 in a label column": header + b",my note\n" + b"".join(r + b",caf\xe9\n" for r in rows),
            "not UTF-8 in a number": (header + b"\n" + b"\n".join(rows[:5] + [rows[5] + b"\xb0"] + rows[6:])
                                      + b"\n")}[case]
    (d / "samples.csv").write_bytes(data)
    if case.startswith("not UTF-8"):  # the C parser stops at the byte; the check after it names the line
        with pytest.raises(io.MeasurementSetError, match=f"line {2 if 'label' in case else 7}: not UTF-8"):
            io.read_set(d)
    else:
        assert len(io.read_set(d).samples["t_s"]) == len(rows)


@pytest.mark.slow
def test_reading_a_set_imports_no_pandas(paper_set):
    """pyarrow's to_numpy imports pandas where it is installed (0.25 s of calibrate --thermal's 1 s):
    samples.csv's columns are read from Arrow's buffers instead, the same numbers."""
    import subprocess
    import sys
    folder, _ = paper_set
    code = ("import sys, numpy as np, pyarrow.csv as pc; from simucal import io; ms = io.read_set(sys.argv[1]); "
            "assert 'pandas' not in sys.modules, 'pandas imported'; t = pc.read_csv(sys.argv[1] + '/samples.csv'); "
            "assert all(np.array_equal(ms.samples[c], t.column(c).to_numpy().astype(float)) for c in t.column_names "
            "if c in ms.samples)")
    r = subprocess.run([sys.executable, "-c", code, str(folder)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_calibrating_a_csv_set_imports_no_pandas_matplotlib_dask_or_scipy(paper_set, tmp_path):
    """`simucal calibrate` of a samples.csv set imports what its path needs (a whole process of
    the 400 Hz set in about a second): pandas only for a DataFrame, matplotlib only for --html, dask only
    for --scheduler, scipy nowhere on it, nor CasADi (the models' Jacobians by their numpy modules)."""
    import subprocess
    import sys
    folder, _ = paper_set
    code = ("import sys; from simucal.cli import main\ntry:\n    main(sys.argv[1:], prog_name='simucal')\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "print(' '.join(sorted({m.split('.')[0] for m in sys.modules})))")
    r = subprocess.run([sys.executable, "-c", code, "calibrate", str(folder), "-o", str(tmp_path / "c.json")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    imported = set(r.stdout.split("\n")[-2].split())
    assert {"numpy", "simucal"} <= imported and (tmp_path / "c.json").is_file()
    assert not imported & {"pandas", "matplotlib", "dask", "distributed", "scipy", "sympy", "casadi"}, imported


@pytest.mark.slow
def test_the_reports_import_no_pandas(tmp_path):
    """validate, diagnose and noise write their reports without the API's tables, which alone need pandas
    (api/tables.TableOf builds one when it is read: 0.4 s of a process)."""
    import subprocess
    import sys
    folder = tmp_path / "raw"  # raw rows: noise reads samples
    subprocess.run([sys.executable, "-m", "simucal", "simulate", "-o", str(folder), "--rate-hz", "5"], check=True)
    code = ("import sys; from simucal.cli import main\nfor args in (sys.argv[1:6], sys.argv[6:10], sys.argv[10:]):\n"
            "    try:\n        main(args, prog_name='simucal')\n    except SystemExit as e:\n        assert not "
            "e.code, e.code\nprint('pandas' in sys.modules)")
    cal = tmp_path / "c.json"
    assert subprocess.run([sys.executable, "-m", "simucal", "calibrate", str(folder), "-o", str(cal)]).returncode == 0
    r = subprocess.run([sys.executable, "-c", code, "validate", str(cal), str(folder), "-o", str(tmp_path / "v.json"),
                        "diagnose", str(folder), "-o", str(tmp_path / "d.json"), "noise", str(folder), "-o",
                        str(tmp_path / "n.json")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[-2] == "False" and all((tmp_path / f).is_file() for f in ("v.json", "d.json", "n.json"))


def test_median_rows_is_numpys_median():
    """The glitch test's medians by one partition are np.median's numbers, bit for bit: odd and even
    counts, ties, one row and three, a transposed view."""
    from simucal.turntable.observations import median_rows
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 4, 11, 1000, 9041):
        for k in (1, 3):
            x = rng.normal(size=(k, n)) * 10 ** rng.uniform(-3, 6)
            x[:, : n // 3] = np.round(x[:, : n // 3])  # ties
            assert np.array_equal(median_rows(x), np.median(x, axis=1))
            assert np.array_equal(median_rows(x.T.copy().T), np.median(x, axis=1))


@pytest.mark.parametrize("native", [True, False])
@pytest.mark.parametrize("blank_at", [None, 0.25, 0.75])
def test_samples_read_in_pieces_are_the_careful_readers(tmp_path, monkeypatch, blank_at, native):
    """csv_columns parses a large samples.csv in pieces, two at a time on two threads, into one (n, 3)
    block per triad, by csv_numbers.c (native; a blank line sends the file to pyarrow) or pyarrow (no
    compiler): the careful reader's numbers, row for row, with a blank line in either half too;
    MeasurementSet.raw is that block (no copy)."""
    from simucal.io import csv_columns
    from simucal.turntable.simulate import Scenario, write
    folder = tmp_path / "s"
    write(folder, Scenario(rate_hz=5.0), seed=1)
    if blank_at is not None:
        lines = (folder / "samples.csv").read_text().splitlines(keepends=True)
        at = int(len(lines) * blank_at)
        (folder / "samples.csv").write_text("".join(lines[:at] + ["\n"] + lines[at:]))
    monkeypatch.setattr(csv_columns, "PIECE_BYTES", 100_000)
    if not native:
        monkeypatch.setattr(csv_columns, "_native", lambda: None)
    calls = {"native": [], "arrow": []}
    monkeypatch.setattr(csv_columns, "_parse_native", lambda *a, _f=csv_columns._parse_native: calls["native"].append(
        _f(*a)) or calls["native"][-1])
    monkeypatch.setattr(csv_columns, "_parse_into", lambda *a, _f=csv_columns._parse_into: calls["arrow"].append(a)
                        or _f(*a))
    fast = io.read_set(folder)
    assert len(calls["native"] if native else calls["arrow"]) >= 3
    assert bool(calls["arrow"]) == (not native or blank_at is not None)  # the C parser stops at a blank line
    assert -1 in calls["native"] if native and blank_at is not None else -1 not in calls["native"]
    monkeypatch.setattr(io, "read_columns", lambda *a: (None, False))  # the careful reader, line by line
    careful = io.read_set(folder)
    assert fast.samples.keys() == careful.samples.keys()
    for c, v in careful.samples.items():
        assert fast.samples[c].dtype == v.dtype and np.array_equal(fast.samples[c], v), c
    from simucal.io.sensor_checks import column_extremes
    seeded = {k for k in fast.__dict__.get("_cache", {}) if k[0] == "extremes"}  # by the C parser, as it parsed
    assert seeded == ({("extremes", "acc"), ("extremes", "gyro")} if native and blank_at is None else set())
    for sensor, c in (("acc", "ax"), ("gyro", "gx")):
        assert np.shares_memory(fast.raw(sensor), fast.samples[c]) and not np.shares_memory(careful.raw(sensor),
                                                                                            careful.samples[c])
        assert np.array_equal(fast.raw(sensor), careful.raw(sensor))
        assert column_extremes(fast, sensor) == column_extremes(careful, sensor)  # the C parser's: no pass over them


def test_the_rows_at_each_extreme_are_counted_over_the_pieces_and_a_split_run_at_a_rail_is_found(tmp_path, monkeypatch):
    """csv_numbers.c counts the rows at each column's least and greatest as it parses, summed over the pieces
    that reach them; the clipping check scans for a run at an extreme only where that count allows one. A run
    at the rail whose rows lie in two pieces, and a column whose extremes are single rows, are read alike by
    the count and by the scan of every row."""
    from simucal.io import csv_columns
    from simucal.io.sensor_checks import saturated_rows
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "s", Scenario(rate_hz=20.0), seed=2)
    text = (tmp_path / "s" / "samples.csv").read_text().splitlines(keepends=True)
    header = text[0].strip().split(",")
    rows = np.array([[float(v) for v in line.split(",")] for line in text[1:]])
    ax, n = header.index("ax"), len(rows)
    rail = rows[:, ax].max() + 1000
    for start in (n // 3 - 2, n // 2, 2 * n // 3):  # three runs of 4 (the first across the pieces' border)
        rows[start:start + 4, ax] = rail
    rows[10, header.index("gz")] = rows[:, header.index("gz")].min()  # two rows at its least, one piece apart
    body = text[0] + "".join(",".join(repr(float(v)) if j != 0 else str(int(v)) for j, v in enumerate(r)) + "\n"
                             for r in rows)
    (tmp_path / "s" / "samples.csv").write_text(body)
    monkeypatch.setattr(csv_columns, "PIECE_BYTES", len(body) // 3 + 7)  # the first run's rows in two pieces
    _, extremes = csv_columns.read_columns(memoryview(body.encode()), header, header, [], 1e12)
    for j, c in enumerate(header):
        v = rows[:, j]
        assert extremes[c] == (v.min(), v.max(), np.sum(v == v.min()), np.sum(v == v.max())), c
    assert extremes["ax"][3] == 12 and extremes["gz"][2] >= 2
    fast = io.read_set(tmp_path / "s")
    monkeypatch.setattr(io, "read_columns", lambda *a: (None, False))  # no counts: every extreme scanned
    careful = io.read_set(tmp_path / "s")
    for sensor in ("acc", "gyro"):
        assert np.array_equal(saturated_rows(fast, sensor)[0], saturated_rows(careful, sensor)[0])
        assert saturated_rows(fast, sensor)[1] == saturated_rows(careful, sensor)[1]
    assert saturated_rows(fast, "acc")[0].sum() == 12


def test_the_c_parsers_numbers_are_pyarrows_and_floats_bit_for_bit(monkeypatch):
    """csv_numbers.c rounds every decimal it takes as float() and pyarrow do (its fast path, 15 digits
    by a power of ten up to 22, and strtod beyond), the sign of zero too, CRLF line ends too; a cell
    it does not take (a space, NaN, a bare sign or point, an exponent without digits) stops it, and
    pyarrow reads the file (the same numbers)."""
    from simucal.io import csv_columns
    rng = np.random.default_rng(7)
    x = np.concatenate([rng.normal(size=2000) * 10.0 ** rng.integers(-30, 30, 2000), [0.0, -0.0, 5e-324, 1.7e308]])
    cells = [repr(float(v)) for v in x] + [f"{v:.3f}" for v in x[:500]] + [f"{v:.20e}" for v in x[:500]] + [
        "-0", "+1.5", "1.", ".5", "-.25", "007", "12345678901234567890123", "0.1234567890123456789012", "1e22",
        "1e23", "123456789012345e-22", "9007199254740993", "2.2250738585072011e-308", "1E5", "1e+5",
        "00000000000000000001", "1234567890123456", "0.000000000000000000000000001", "1e-400", "4.9e-324", "-0.0e7"]
    cells += [""] * (-len(cells) % 4)
    cells = [c or "1" for c in cells]
    text = "a,b,c,d\n" + "".join(",".join(cells[i:i + 4]) + ("\r\n" if i % 8 else "\n")
                                 for i in range(0, len(cells), 4))
    body, header, big = memoryview(text.encode()), ["a", "b", "c", "d"], np.finfo(float).max
    assert csv_columns._native() is not None  # a compiler: the suite runs where one is
    seen = []
    monkeypatch.setattr(csv_columns, "_parse_native", lambda *a, _f=csv_columns._parse_native: seen.append(_f(*a))
                        or seen[-1])
    native, extremes = csv_columns.read_columns(body, header, header, [], big)
    assert seen == [len(cells) // 4] and extremes == {c: (v.min(), v.max(), np.sum(v == v.min()), np.sum(v == v.max()))
                                                      for c, v in native.items()}
    want = np.array([float(c) for c in cells]).reshape(-1, 4)
    for j, c in enumerate(header):
        assert np.array_equal(native[c].view(np.int64), want[:, j].view(np.int64)), c
    with monkeypatch.context() as m:
        m.setattr(csv_columns, "_native", lambda: None)
        arrow, extremes = csv_columns.read_columns(body, header, header, [], big)
    assert extremes is None and all(np.array_equal(native[c].view(np.int64), arrow[c].view(np.int64)) for c in header)
    for bad in (" 1", "1 ", "nan", "-", ".", "1e", "e5", "1,5", "1e400", "-2e308"):
        seen.clear()
        odd = text + f"{bad},1,1,1\n"
        got, extremes = csv_columns.read_columns(memoryview(odd.encode()), header, header, [], big)
        assert seen == [-1] and extremes is None, bad
        assert (got is None) == (bad not in (" 1", "1 ")), bad  # pyarrow takes spaces
    quoted = memoryview((text + '"x",1,1,1\n').encode())
    for piece in (body, quoted, body[:1000], body[:0]):  # the line ends and quotes counted by C, then by numpy
        counts = [csv_columns._line_ends(piece)]
        with monkeypatch.context() as m:
            m.setattr(csv_columns, "_native", lambda: None)
            counts.append(csv_columns._line_ends(piece))
        assert counts[0] == counts[1] == (bytes(piece).count(b"\n"), b'"' in bytes(piece))
    seen.clear()
    got, extremes = csv_columns.read_columns(body, header, header, [], 1e12)  # beyond it: pyarrow, the caller checks
    assert seen == [-1] and extremes is None and np.array_equal(got["a"], native["a"])
@pytest.mark.parametrize("shuffled", [False, True])
def test_segment_rows_refused_by_line_in_file_order_or_not(tmp_path, shuffled):
    """_check_samples finds a set's segments without a sort where the file holds them one after the
    other, and by one where it does not: either way a time step backwards, an unknown segment id and
    a fractional one are refused naming the file's line."""
    from simucal.turntable.simulate import Scenario, write
    folder = tmp_path / "s"
    write(folder, Scenario(rate_hz=2.0), seed=1)
    header, *rows = (folder / "samples.csv").read_text().splitlines()
    if shuffled:  # the first segment's rows after the second's: ids no longer in order
        first = [r for r in rows if r.split(",")[0] == rows[0].split(",")[0]]
        rows = [r for r in rows if r not in first][:50] + first + [r for r in rows if r not in first][50:]
    seg_col, t_col = header.split(",").index("segment"), header.split(",").index("t_s")

    def refused(k, col, value, *words):
        cells = rows[k].split(",")
        cells[col] = value
        (folder / "samples.csv").write_text("\n".join([header, *rows[:k], ",".join(cells), *rows[k + 1:]]) + "\n")
        with pytest.raises(io.MeasurementSetError) as e:
            io.read_set(folder)
        assert all(w in str(e.value) for w in words), str(e.value)
    k = 60  # within the 50 rows moved ahead (shuffled), or the first segment
    assert rows[k].split(",")[0] == rows[k + 1].split(",")[0]
    refused(k + 1, t_col, rows[k].split(",")[t_col], f"line {k + 3}", "t_s must increase within segment")
    refused(k, seg_col, "999", f"line {k + 2}", "segment 999 is not in segments.csv")
    refused(len(rows) - 1, seg_col, "999", f"line {len(rows) + 1}", "segment 999 is not")  # ids still in order
    refused(k, seg_col, "1.5", "segment ids must be integers")


def test_a_copy_for_its_own_t_ref_takes_no_entry_found_at_the_other(tmp_path):
    """MeasurementSet.copy keeps what the reader and the checks found where only T_ref changes, but no entry
    that depends on T_ref: the gyro's static rows, found at the set's own T_ref (as diagnose finds them),
    are found again for the copy's (calibrate --t-ref-c after it fitted temperature terms about the old one)."""
    from simucal.turntable import consistency
    from simucal.turntable.simulate import Scenario, write
    write(tmp_path / "s", Scenario(rate_hz=2.0, temp_c=(20.0, 30.0)), seed=1)
    ms = io.read_set(tmp_path / "s")
    segs = [s for s in ms.segments if s.kind == "static"]
    own = consistency.static_gyro_rows(ms, segs)[1][2].values["t_ref_c"]
    copy = ms.copy(temperature_ref_c=0.0)
    assert copy.raw("acc") is ms.raw("acc") and own == ms.t_ref_c != 0.0  # the reader's blocks kept
    assert consistency.static_gyro_rows(copy, segs)[1][2].values["t_ref_c"] == 0.0
    assert ms.copy(segments=None).__dict__.get("_cache") is None  # other changes: nothing kept
