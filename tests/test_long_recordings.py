"""Long recordings: `simucal noise` a chunk at a time gives the whole-file path's
numbers (simulated and the real Xsens stream, CSV and Parquet, here and on Dask), with memory that
holds theta and no table; samples.parquet is read wherever a set is; `simucal convert` round-trips
every bit, never over its input, all or nothing; bad rows are named by line or row."""
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import refused, run

from simucal import io, methods
from simucal.fit import allan_sums
from simucal.api.calibrating import calibrate
from simucal.fit.allan_noise import characterise, characterise_folder
from simucal.fit.allan_terms import allan_variance, taus
from simucal.errors import CalibrationError
from simucal.handheld.simulate import write_still
from simucal.io import columnar
from simucal.io.importers import import_imu_tk
from simucal.turntable.simulate import Scenario, write

DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"
PART = 1000  # theta's part and a task's rows, small: every sum crosses parts and tasks


@pytest.fixture(scope="module")
def still(tmp_path_factory):
    """10 min at 100 Hz, with a rate random walk (so a term besides the white noise is seen), as
    samples.csv and converted to samples.parquet."""
    tmp = tmp_path_factory.mktemp("still")
    write_still(tmp / "csv", seconds=600.0, dt=0.01, rrw_dph_sqrt_s=1.0, seed=3)
    assert run("convert", tmp / "csv", "-o", tmp / "parquet", "--to", "parquet").exit_code == 0
    return tmp


def _small_reads(monkeypatch):
    monkeypatch.setattr(columnar, "BLOCK_BYTES", 40_000)  # about 400 rows a chunk of CSV
    monkeypatch.setattr(columnar, "BATCH_ROWS", 777)


def _same(a, b, rtol):
    """The two reports' Allan deviations and terms agree to rtol (the stds and bounds too)."""
    for sensor in ("acc", "gyro"):
        assert a[sensor]["tau_s"] == b[sensor]["tau_s"] and a[sensor]["rate_hz"] == b[sensor]["rate_hz"]
        for axis in "xyz":
            x, y = a[sensor]["axes"][axis], b[sensor]["axes"][axis]
            np.testing.assert_allclose(x["adev"], y["adev"], rtol=rtol)
            for k, t in x["sheet"].items():
                assert t["status"] == y["sheet"][k]["status"], (sensor, axis, k)
                for f in ("value", "std", "bound_95"):
                    if t.get(f) is not None:
                        np.testing.assert_allclose(t[f], y["sheet"][k][f], rtol=100 * rtol, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["csv", "parquet"])
def test_noise_in_chunks_is_the_whole_file_path(still, monkeypatch, fmt):
    whole = characterise(ms := io.read_set(still / "csv"), methods.kind_of(ms))
    _small_reads(monkeypatch)
    chunked = characterise_folder(still / fmt, methods.kind_of, size=PART)
    # the whole-file path sums theta of y with its bias (1 g on az): its last digits, not the chunks', differ
    _same(whole, chunked, rtol=1e-7)
    assert whole["gyro"]["axes"]["x"]["sheet"]["K"]["status"] == "seen"


@pytest.mark.slow
def test_noise_on_dask_is_the_same(still, dask_cluster):
    here = characterise_folder(still / "parquet", methods.kind_of, size=20_000)
    on_dask = characterise_folder(still / "parquet", methods.kind_of, scheduler=dask_cluster, size=20_000)
    _same(here, on_dask, rtol=1e-12)


@pytest.mark.slow
def test_the_real_xsens_stream_in_chunks(tmp_path, monkeypatch):
    """The real Xsens session (hand-placed, it moves: noise refuses it alike on both paths); its
    channels' Allan variances summed part by part are the whole arrays' to rounding."""
    import_imu_tk(DATA / "imu_tk-xsens" / "xsens_acc.mat", DATA / "imu_tk-xsens" / "xsens_gyro.mat", tmp_path / "x",
                  4096.0, 6258 * np.pi / 180, 45.4, 9.81744)
    ms = io.read_set(tmp_path / "x")
    with pytest.raises(CalibrationError, match="the unit moves") as whole:
        characterise(ms, methods.kind_of(ms))
    _small_reads(monkeypatch)
    with pytest.raises(CalibrationError, match="the unit moves") as chunked:
        characterise_folder(tmp_path / "x", methods.kind_of, size=PART)
    assert str(whole.value) == str(chunked.value)
    kept, steps = allan_sums.read_pass(tmp_path / "x", ms.meta, ["acc", "gyro"], None, PART)
    assert np.array_equal(steps, np.diff(ms.samples["t_s"]))
    m = taus(len(steps) + 1)
    for sensor, y in (("acc", ms.acc_g()), ("gyro", ms.gyro_dph())):
        cols = io.SAMPLE_COLS[:3] if sensor == "acc" else io.SAMPLE_COLS[3:]
        parts = allan_sums.allan_variances([kept.theta[c] for c in cols], m)
        for j, c in enumerate(cols):
            np.testing.assert_allclose(parts[j], allan_variance([y[:, j]], 1.0, m)[0], rtol=1e-9)
            assert (kept.lo[c], kept.hi[c], kept.first[c]) == (y[:, j].min(), y[:, j].max(), y[0, j])


@pytest.mark.slow
def test_memory_holds_theta_not_the_table(tmp_path, monkeypatch):
    """numpy's allocations (tracemalloc sees them) in reading and summing peak near theta's 8 bytes a
    row and channel plus the steps of t_s, below what reading the set whole takes: its arrays and the
    file, which it maps and parses whole, every page of it resident (tracemalloc does not see mapped
    pages, so the file's size is added to its count) (the fit's covariance, the same on both paths,
    grows with the taus, not the rows)."""
    write_still(tmp_path / "s", seconds=3000.0, dt=0.01)
    rows = 300_000
    _small_reads(monkeypatch)
    meta = io.read_meta(tmp_path / "s")

    def chunked():
        kept, _ = allan_sums.read_pass(tmp_path / "s", meta, ["acc", "gyro"], None, 1 << 14)
        allan_sums.allan_variances(list(kept.theta.values()), taus(rows))
    peaks = {}
    for name, fn in (("whole", lambda: io.read_set(tmp_path / "s")), ("chunked", chunked)):
        tracemalloc.start()
        fn()
        peaks[name] = tracemalloc.get_traced_memory()[1] / rows
        tracemalloc.stop()
    peaks["whole"] += (tmp_path / "s" / "samples.csv").stat().st_size / rows  # the file, mapped whole as it is parsed
    assert peaks["chunked"] < 6 * 8 + 2 * 8 + 16, peaks  # theta, the steps (in chunks, then joined), a chunk
    assert peaks["chunked"] < 0.6 * peaks["whole"], peaks


def test_a_parquet_set_is_read_wherever_a_set_is(tmp_path):
    """calibrate of a turntable set of raw rows: the same numbers from samples.parquet as from samples.csv."""
    write(tmp_path / "csv", Scenario(rate_hz=20.0, static_s=20.0), 2)
    assert run("convert", tmp_path / "csv", "-o", tmp_path / "pq", "--to", "parquet").exit_code == 0
    a, b = io.read_set(tmp_path / "csv"), io.read_set(tmp_path / "pq")
    assert a.samples.keys() == b.samples.keys() and a.sha256 != b.sha256 and a.sample_digests() == b.sample_digests()
    assert all(np.array_equal(a.samples[c], b.samples[c]) and a.samples[c].dtype == b.samples[c].dtype
               for c in a.samples)
    ca, cb = calibrate(tmp_path / "csv").to_json(), calibrate(tmp_path / "pq").to_json()
    assert ca["acc"]["M"] == cb["acc"]["M"] and ca["gyro"]["bias"] == cb["gyro"]["bias"]
    r = run("noise", tmp_path / "pq", "-o", tmp_path / "n.json")
    assert r.exit_code == 0 and "static segments, pooled" in r.output


def test_convert_round_trips_every_bit_and_keeps_its_input(still, tmp_path):
    assert run("convert", still / "parquet", "-o", tmp_path / "back", "--to", "csv").exit_code == 0
    a, b = io.read_set(still / "csv"), io.read_set(tmp_path / "back")
    assert all(np.array_equal(a.samples[c], b.samples[c]) for c in a.samples)
    assert (still / "csv" / "meta.json").read_bytes() == (tmp_path / "back" / "meta.json").read_bytes()
    refused(run("convert", still / "csv", "-o", still / "csv", "--to", "parquet", "--force"),
            "never changes its inputs")
    refused(run("convert", still / "csv", "-o", tmp_path / "back", "--to", "parquet"),
            "already holds a measurement set")
    assert run("convert", still / "csv", "-o", tmp_path / "back", "--to", "parquet", "--force").exit_code == 0
    assert sorted(p.name for p in (tmp_path / "back").iterdir()) == ["meta.json", "samples.parquet"]


def test_a_bad_row_is_named_and_nothing_is_written(still, tmp_path, monkeypatch):
    _small_reads(monkeypatch)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "meta.json").write_bytes((still / "csv" / "meta.json").read_bytes())
    lines = (still / "csv" / "samples.csv").read_text().splitlines(keepends=True)
    (bad / "samples.csv").write_text("".join(lines[:5001] + [lines[4000]] + lines[5001:]))  # t_s steps back
    refused(run("convert", bad, "-o", tmp_path / "out", "--to", "parquet"), "samples.csv, line 5002",
            "t_s must increase")
    assert not (tmp_path / "out").exists()
    refused(run("noise", bad, "-o", tmp_path / "n.json"), "samples.csv, line 5002")
    (bad / "samples.csv").write_text("".join(lines[:7001] + [lines[7001].replace(",", ",nan,", 1)[:-1] + "\n"]
                                             + lines[7002:]))
    refused(run("noise", bad, "-o", tmp_path / "n.json"), "line 7002")
    assert not (tmp_path / "n.json").exists()


def test_parquet_refusals_name_the_row_and_column(still, tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq
    table = pq.read_table(still / "parquet" / "samples.parquet")
    for name, change, words in (
            ("text", lambda t: t.set_column(1, "ax", pa.array(["x"] * len(t))), ["column ax holds string"]),
            ("nan", lambda t: t.set_column(4, "gx", pa.array(np.r_[np.zeros(99), np.nan, np.zeros(len(t) - 100)])),
             ["not a finite number"]),
            ("huge", lambda t: t.set_column(4, "gx", pa.array(np.r_[np.zeros(99), 1e15, np.zeros(len(t) - 100)])),
             ["row 100", "column gx"])):
        folder = tmp_path / name
        folder.mkdir()
        (folder / "meta.json").write_bytes((still / "csv" / "meta.json").read_bytes())
        pq.write_table(change(table), folder / "samples.parquet")
        refused(run("noise", folder, "-o", tmp_path / "n.json"), "samples.parquet", *words)
        refused(run("calibrate", folder, "-o", tmp_path / "c.json"), "samples.parquet", *words)
    (tmp_path / "huge" / "samples.csv").write_text("t_s,gx,gy,gz\n")
    refused(run("noise", tmp_path / "huge", "-o", tmp_path / "n.json"), "both samples.csv and samples.parquet")
    assert not (tmp_path / "n.json").exists()


def test_convert_keeps_numeric_columns_and_leaves_notes_out(still, tmp_path, monkeypatch):
    """As the whole-file reader does: a user's supply_v is kept, a column of notes left out."""
    _small_reads(monkeypatch)
    folder = tmp_path / "aux"
    folder.mkdir()
    (folder / "meta.json").write_bytes((still / "csv" / "meta.json").read_bytes())
    lines = (still / "csv" / "samples.csv").read_text().splitlines()[:3001]
    (folder / "samples.csv").write_text("\n".join([lines[0] + ",supply_v,note"] + [
        f"{x},{5 + i * 1e-4!r},{'ok' if i % 2 else 'warm'}" for i, x in enumerate(lines[1:])]) + "\n")
    assert run("convert", folder, "-o", tmp_path / "pq", "--to", "parquet").exit_code == 0
    a, b = io.read_set(folder), io.read_set(tmp_path / "pq")
    assert "note" not in a.samples and set(a.samples) == set(b.samples) and "supply_v" in b.samples
    assert all(np.array_equal(a.samples[c], b.samples[c]) for c in a.samples)


PEAK = """import sys, tracemalloc, pyarrow as pa
from simucal.io import columnar
columnar.BLOCK_BYTES, columnar.BATCH_ROWS = 100_000, 2000
tracemalloc.start()
if sys.argv[1] == "chunks":
    for _ in columnar.chunks(sys.argv[2], ["t_s", "ax", "ay", "az", "gx", "gy", "gz"]):
        pass
else:
    columnar.convert(sys.argv[2], sys.argv[3], sys.argv[1])
print(tracemalloc.get_traced_memory()[1] + pa.default_memory_pool().max_memory())"""


def _peak_bytes(*args) -> int:
    """numpy's (tracemalloc) and Arrow's (its pool's) peak allocations of one run in a fresh process."""
    import subprocess
    import sys
    out = subprocess.run([sys.executable, "-c", PEAK, *map(str, args)], capture_output=True, text=True, check=True)
    return int(out.stdout)


@pytest.mark.slow
def test_memory_of_convert_and_of_parquet_reads_stays_bounded_as_the_record_grows(tmp_path):
    """A record 4x as long peaks within a few batches of the short one's (convert both ways, and the
    chunks `noise` reads from samples.parquet): no file held whole (Arrow's pre_buffer read all of
    samples.parquet ahead, 1.1 GB of a 24 h record), while the data grow by 3x 7 columns of 8 bytes."""
    peaks = {}
    for seconds in (300.0, 1200.0):
        folder = tmp_path / f"{seconds:g}"
        write_still(folder / "csv", seconds=seconds, dt=0.01)
        peaks[seconds] = (_peak_bytes("parquet", folder / "csv", folder / "pq"),
                          _peak_bytes("csv", folder / "pq", folder / "back"),
                          _peak_bytes("chunks", folder / "pq"))
    grown = 3 * 100 * 300 * 7 * 8  # the bytes the longer record adds
    for short, long in zip(peaks[300.0], peaks[1200.0]):
        assert long - short < 0.15 * grown, (peaks, grown)
