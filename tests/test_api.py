"""The public Python API as a notebook user meets it (numpy arrays, a DataFrame),
the same files as the command line, and the docs' example (docs/api.md) run as written."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import simucal
from simucal.cli import main
from simucal.errors import CalibrationError
from simucal.handheld.simulate import HandheldScenario, write_handheld
from simucal.io import MeasurementSetError
from simucal.turntable.simulate import Scenario, simulate, write

ROOT = Path(__file__).resolve().parents[1]
RAW = ("ax", "ay", "az", "gx", "gy", "gz")
KEYS = ("latitude_deg", "acc_pulses_per_g", "gyro_pulses_per_arcsec")


def _recording(seed, effects=None):
    """One turntable test of the dong2018 unit (the same unit at every seed) as arrays: raw pulse/s."""
    meta, samples, segments, truth = simulate(Scenario(acc_effects=effects or {}), seed)
    return np.column_stack([samples[c] for c in RAW]), samples, segments, meta, truth


def _set(raw, samples, segments, meta, name):
    return simucal.MeasurementSet.from_arrays(raw[:, :3], raw[:, 3:], acc_unit="pulse/s", gyro_unit="pulse/s",
                                              t_s=samples["t_s"], segment=samples["segment"], segments=segments,
                                              meta={k: meta[k] for k in KEYS}, name=name)


def _static_norm_error_g(f_g, samples, segments):
    static = {s.segment for s in segments if s.kind == "static"}
    rows = np.isin(samples["segment"], list(static))
    return np.linalg.norm(f_g[rows], axis=1) - 1.0


def test_notebook_flow_on_numpy_arrays(monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # numpy alone: pandas cannot be imported, tables are rows
    raw, samples, segments, meta, truth = _recording(1, {"acc.quadratic.z": 2e-4})
    ms = _set(raw, samples, segments, meta, "lab_run_1")
    cal = simucal.calibrate(ms, add=["acc.quadratic.z"])
    assert isinstance(cal, simucal.Calibration) and ms.temperature_ref_c is None  # the caller's set untouched
    assert isinstance(simucal.parameters(cal), list) and isinstance(simucal.parameters(cal)[0], simucal.Entry)
    assert isinstance(simucal.parameters(cal, "own")[0], simucal.Parameter)
    table = {(r.sensor, r.name): r for r in simucal.parameters(cal, "own")}
    for name in ("dK_x", "dK_y", "dK_z", "b_z"):  # the truth within 5 std of each estimate
        r = table[("acc", name)]
        assert abs(r.value - truth["acc"]["params"][name]) < 5 * r.std, r
    q = table[("acc", "acc.quadratic.z")]
    assert abs(q.value - 2e-4) < 5 * q.std and q.unit and q.meaning
    raw2, samples2, segments2, meta2, _ = _recording(2, {"acc.quadratic.z": 2e-4})
    out = simucal.apply(cal, raw2)  # pulse/s in: g and deg/h out
    assert out.shape == raw2.shape and isinstance(out, np.ndarray)
    nominal = raw2[:, :3] / np.asarray(meta2["acc_pulses_per_g"])
    before = _static_norm_error_g(nominal, samples2, segments2)
    after = _static_norm_error_g(out[:, :3], samples2, segments2)
    assert np.sqrt(np.mean(after ** 2)) < 3e-5 < 0.1 * np.sqrt(np.mean(before ** 2))
    # the caller's units: the same data in m/s^2 come back in m/s^2; one sensor as (n, 3)
    acc_mps2 = simucal.apply(cal, nominal * 9.80665, acc_unit="m/s^2", sensor="acc")
    np.testing.assert_allclose(acc_mps2, out[:, :3] * 9.80665, rtol=1e-9)
    v = simucal.validate(cal, _set(raw2, samples2, segments2, meta2, "lab_run_2"))
    assert v.independent and set(v.verdict) == {"acc", "gyro"}
    assert v.verdict["acc"] in ("at the noise floor", "better"), v.verdict
    acc_norm = next(c for c in v.checks if c.sensor == "acc" and c.unit == "g")
    assert acc_norm.calibrated_rms < 0.1 * acc_norm.nominal_rms
    assert not simucal.validate(cal, ms).independent  # its own data, told by the arrays' hash


def test_notebook_flow_on_dataframes():
    import pandas as pd  # the test extra holds it; the API itself works without it (test above)
    names = {c: f"{'acc' if c[0] == 'a' else 'gyr'}_{c[1]}" for c in RAW}

    def frame(seed):
        raw, samples, segments, meta, _ = _recording(seed)
        df = pd.DataFrame(raw, columns=[names[c] for c in RAW])
        return df.assign(time=samples["t_s"], seg=samples["segment"]), segments, meta

    df, segments, meta = frame(1)
    cols = {**names, "t_s": "time", "segment": "seg"}
    ms = simucal.MeasurementSet.from_dataframe(df, columns=cols, acc_unit="pulse/s", gyro_unit="pulse/s",
                                               segments=segments, meta={k: meta[k] for k in KEYS})
    cal = simucal.calibrate(ms)
    params = simucal.parameters(cal, "own")  # a DataFrame, pandas being installed
    assert (isinstance(params, pd.DataFrame)
            and list(params.columns) == ["name", "sensor", "value", "std", "unit", "meaning"])
    assert (params["std"] > 0).all() and len(params) == 18
    common = simucal.parameters(cal)  # by default every method's M and bias
    assert list(common.columns) == ["sensor", "name", "value", "std", "unit", "own_name", "meaning"]
    assert len(common) == 24 and set(common["own_name"].dropna()) <= set(params["name"])
    df2, segments2, meta2 = frame(2)
    out = simucal.apply(cal, df2, columns=names)
    assert isinstance(out, pd.DataFrame) and list(out.columns) == list(df2.columns)
    assert (out["time"] == df2["time"]).all() and not np.allclose(out[names["az"]], df2[names["az"]])
    ms2 = simucal.MeasurementSet.from_dataframe(df2, columns=cols, acc_unit="pulse/s", gyro_unit="pulse/s",
                                                segments=segments2, meta={k: meta2[k] for k in KEYS})
    v = simucal.validate(cal, ms2)
    assert v.independent and "WORSE" not in " ".join(v.verdict.values())
    checks = v.checks
    assert isinstance(checks, pd.DataFrame)
    assert (checks["calibrated_rms"] <= checks["nominal_rms"]).all()


def test_api_and_cli_write_identical_calibration_files(tmp_path):
    write(tmp_path / "table", Scenario(), seed=3)
    write_handheld(tmp_path / "stream", HandheldScenario(poses=20), seed=3)
    for name, add in (("table", ["acc.quadratic.z"]), ("stream", [])):
        data = str(tmp_path / name)
        res = CliRunner().invoke(main, ["calibrate", data, "-o", str(tmp_path / f"{name}_cli.json")]
                                 + [x for a in add for x in ("--add", a)])
        assert res.exit_code == 0, res.output
        simucal.save(tmp_path / f"{name}_api.json", simucal.calibrate(data, add=add))
        cli, api = ((tmp_path / f"{name}_{k}.json").read_text() for k in ("cli", "api"))
        assert cli == api, name
        assert simucal.load(tmp_path / f"{name}_api.json").to_json() == json.loads(api)


def test_refusals_name_the_argument_and_the_fix():
    acc = np.tile([0.0, 0.0, 1.0], (10, 1))
    with pytest.raises(MeasurementSetError, match="rate_hz= .* or as t_s="):
        simucal.MeasurementSet.from_arrays(acc, None, acc_unit="g", gyro_unit="deg/h")
    bad = acc.copy()
    bad[4, 1] = np.nan
    with pytest.raises(MeasurementSetError, match="row 4, column ay: nan is not finite"):
        simucal.MeasurementSet.from_arrays(bad, None, acc_unit="g", gyro_unit="deg/h", rate_hz=10.0)
    with pytest.raises(MeasurementSetError, match="latitude_deg is required"):
        simucal.MeasurementSet.from_arrays(acc, acc, acc_unit="g", gyro_unit="deg/h", rate_hz=10.0)
    with pytest.raises(MeasurementSetError, match="row 3: t_s must increase"):
        simucal.MeasurementSet.from_arrays(acc, None, acc_unit="g", gyro_unit="deg/h",
                                           t_s=[0, 1, 2, 2, 3, 4, 5, 6, 7, 8])
    with pytest.raises(MeasurementSetError, match=r"shape \(10, 2\), expected \(10, 3\)"):
        simucal.MeasurementSet.from_arrays(acc, acc[:, :2], acc_unit="g", gyro_unit="deg/h", rate_hz=1.0,
                                           meta={"latitude_deg": 45.0})


@pytest.mark.slow
def test_the_docs_api_example_runs(tmp_path):
    section = (ROOT / "docs" / "api.md").read_text().split("\n## Reference", 1)[0]  # the page's example
    setup = re.search(r"After `(simucal simulate [^`]+)`", section).group(1)
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}"}
    subprocess.run(setup, shell=True, cwd=tmp_path, env=env, check=True, capture_output=True)
    res = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "acc.dK_x" not in res.stdout and "dK_x" in res.stdout and "'acc':" in res.stdout
    # on clean data both sensors at the floor (the gravity-direction check, limited by the table's
    # unstated angle errors, no longer pulls the accelerometer down to "better")
    assert "{'acc': 'at the noise floor', 'gyro': 'at the noise floor'}" in res.stdout, res.stdout
    assert json.loads((tmp_path / "cal.json").read_text())["format"] == "simucal.calibration/2"


def test_apply_refuses_leaving_out_an_input_the_model_reads():
    raw, samples, segments, meta, _ = _recording(4, {"acc.bias_drift_time.z": 2e-7})
    cal = simucal.calibrate(_set(raw, samples, segments, meta, "run"), add=["acc.bias_drift_time.z"])
    with pytest.raises(CalibrationError, match="drifting in time: give each row's t_s="):
        simucal.apply(cal, raw)
    drift = cal.acc.effects["acc.bias_drift_time.z"].value
    late = (simucal.apply(cal, raw, t_s=samples["t_s"] + 1000.0)[:, 2]
            - simucal.apply(cal, raw, t_s=samples["t_s"])[:, 2])
    assert abs(drift - 2e-7) < 2e-8  # planted, found
    np.testing.assert_allclose(late, -1000.0 * drift / cal.acc.M[2, 2], rtol=1e-2)  # z: the drift taken out


def test_python_m_simucal_runs_the_command_line():
    res = subprocess.run([sys.executable, "-m", "simucal", "--help"], capture_output=True, text=True)
    assert res.returncode == 0 and "calibrate" in res.stdout and "Usage: simucal" in res.stdout, res.stderr


def test_import_stays_light():
    """`import simucal` loads no API (numpy, the methods) until a name of it is used."""
    code = ("import sys, simucal; assert 'numpy' not in sys.modules and 'simucal.api' not in sys.modules; "
            "simucal.read_set; assert 'simucal.api' in sys.modules; import simucal.api.calibrating; "
            "assert callable(simucal.calibrate) and callable(simucal.validate)")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr[-1000:]


def test_a_diagnosis_of_a_set_in_memory_names_the_call_and_of_a_folder_the_command(tmp_path):
    """A set that lives in memory has no folder for `simucal calibrate`: its next step is the Python call
    (which, run, makes the model pass); a set read from a folder gets the command on that folder."""
    ms = simucal.simulate(plan="fibonacci24", seed=1, effects={"acc.quadratic.z": 3e-4})
    d = simucal.diagnose(ms)
    assert d.next_command == "simucal.calibrate(data, add=['acc.quadratic.z'])"
    assert simucal.calibrate(ms, add=["acc.quadratic.z"]).acc.p_value > 1e-3
    ms.write(tmp_path / "s")
    assert simucal.diagnose(tmp_path / "s").next_command == (
        f"simucal calibrate {tmp_path / 's'} --add acc.quadratic.z -o calibration.json")


def test_a_set_written_reads_back_with_its_truth(tmp_path):
    """write writes a simulated set's truth.json and every reader of the folder reads it back (the set's own
    reader, so the API and the commands see one set); a folder without one has none."""
    from simucal import io
    ms = simucal.simulate(seed=2)
    ms.write(tmp_path / "s")
    assert simucal.read_set(tmp_path / "s").truth == io.read_set(tmp_path / "s").truth == ms.truth is not None
    (tmp_path / "s" / "truth.json").unlink()
    assert simucal.read_set(tmp_path / "s").truth is None


def test_the_public_names_are_all_of_the_api():
    """`import simucal` has __all__, the names the lazy API gives (a type checker's and `from simucal
    import *`'s list)."""
    import simucal
    assert set(simucal.__all__) == {"__version__", *simucal._API}
    assert all(getattr(simucal, n) is not None for n in simucal.__all__)


def test_a_sets_repr_is_one_line():
    """Repr(MeasurementSet) printed every array (8 kB); now one line says where, what, how much."""
    import simucal
    r = repr(simucal.simulate("handheld", seed=1))
    assert "\n" not in r and len(r) < 200 and "stream, 27,030 rows over 270.3 s, acc in counts, gyro in counts" in r


def test_other_tools_recordings_and_the_commands_from_python(tmp_path):
    """Imucal's own Ferraris session read from Python (simucal.read_set on its CSV said "not a folder";
    a notebook shelled out to `simucal import`), calibrated, applied to a set and converted, by the API alone."""
    from pathlib import Path

    from simucal.errors import SimucalError
    data = Path(__file__).resolve().parents[2] / "shared" / "data" / "imucal-ferraris"
    ms = simucal.import_recording("imucal-ferraris", [data / "example_ferraris_session.csv",
                                                       data / "example_ferraris_session_list.json"],
                                  tmp_path / "set", latitude_deg=49.6)
    assert isinstance(ms, simucal.MeasurementSet) and ms.segments and ms.has_acc and ms.has_gyro
    with pytest.raises(SimucalError, match="force"):
        simucal.import_recording("imucal-ferraris", [data / "example_ferraris_session.csv"], tmp_path / "set")
    cal = simucal.calibrate(ms)
    calibrated = simucal.apply_set(cal, ms)
    assert calibrated.meta["acc_unit"] == "g" and len(calibrated.samples["t_s"]) == len(ms.samples["t_s"])
    calibrated.write(tmp_path / "calibrated")
    path, rows = simucal.convert(tmp_path / "calibrated", tmp_path / "columnar", "parquet")
    assert path.name == "samples.parquet" and rows == len(ms.samples["t_s"])
    assert simucal.read_set(tmp_path / "columnar").meta["acc_unit"] == "g"


def test_short_reprs_and_notebook_views():
    """A set, a calibration and every result print one short line and show a small HTML table in a
    notebook; a set in memory is told from the calibration's own data (its missing file hash said 'own')."""
    ms, other = simucal.simulate(seed=1), simucal.simulate(seed=2)
    cal = simucal.calibrate(ms)
    results = [ms, cal, simucal.validate(cal, other), simucal.diagnose(ms),
               simucal.noise(simucal.simulate(seed=4, rate_hz=20))]
    for r in results:
        assert len(repr(r)) < 600 and "\n" not in repr(r), repr(r)[:200]
        html = r._repr_html_()
        assert html.startswith("<table>") and html.count("<tr>") >= 2 and "<script" not in html
    assert results[2].independent and not simucal.validate(cal, ms).independent
