"""The calibration store (simucal/store/, simucal.Store, `simucal store add`, `calibrate --store`, `history`) on
SQLite (a temporary file) and on a real PostgreSQL server started here: records byte for byte and never
replaced; a store of schema 1 migrated on opening; a database not the tool's, or of a newer schema, refused in one
line; a password never printed; two writer processes at once losing nothing; a lot with a planted drift on some
units whose history flags exactly those."""
import json
import subprocess
import sys

import numpy as np
import pytest

import simucal
from cli_helpers import run
from simucal.errors import StoreError
from simucal.store import CalibrationStore, opening, records, schema
from store_helpers import DRIFT_ENTRY, DRIFT_PARAM, Postgres, base_calibration, unit_files

ENGINES = ("sqlite", "postgresql")
WRITES = 500  # per writer process: two at once


@pytest.fixture(scope="module")
def server():
    pg = Postgres()
    yield pg
    pg.stop()


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    return base_calibration(tmp_path_factory.mktemp("base"))


@pytest.fixture(params=ENGINES)
def url(request, tmp_path):
    """An empty store's URL on each engine."""
    if request.param == "sqlite":
        return str(tmp_path / "lab.db")
    return request.getfixturevalue("server").url()


def test_a_record_keeps_the_file_byte_for_byte_and_is_never_replaced(url, base, tmp_path):
    files = unit_files(base, tmp_path / "cals", units=1, visits=2, prefix="A")["A-0000"]
    store = simucal.Store(url)
    first = store.add(files[0], station="bench 1", time="2026-01-05")
    second = store.add(files[1], station="bench 2", time="2026-07-05T10:00:00Z")
    assert store.file(first) == files[0].read_bytes() and store.file(second) == files[1].read_bytes()
    with pytest.raises(StoreError, match=r"already recorded \(record 1, unit A-0000.*never replaced"):
        store.add(files[0])
    recs = store.records(serial="A-0000")
    assert list(recs["id"]) == [first, second] and list(recs["station"]) == ["bench 1", "bench 2"]
    assert recs["calibrated_utc"][0] == "2026-01-05T00:00:00.000000Z" and recs["tool_version"][0] == simucal.__version__
    cal = simucal.load(files[1])
    assert recs["input_sha256"][1] == cal.input_sha256 and recs["method"][1] == cal.method == "exact"
    params = store.parameters(serial="A-0000", since="2026-07-01")  # the one vocabulary, as simucal.parameters
    common = simucal.parameters(cal)
    common = common[np.isfinite(common["std"]) & (common["std"] > 0)]
    assert len(params) == len(common) == 21 and set(params["calibration_id"]) == {second}
    assert list(zip(params["sensor"], params["name"], params["own_name"])) == \
        sorted(zip(common["sensor"], common["name"], common["own_name"]))
    row = params[(params["sensor"] == "gyro") & (params["name"] == "bias_z")].iloc[0]
    assert row["own_name"] == "b_z" and row["unit"] == "deg/h" and row["value"] == cal.gyro.params["b_z"]
    assert np.isclose(row["std"], cal.gyro.std["b_z"], rtol=1e-6)
    assert len(store.records(station="bench 3")) == 0 and len(store.records(until="2026-02-01")) == 1


def test_a_store_of_schema_1_opens_after_its_migration(url, base, tmp_path):
    """A store as schema 1 held it (no calibrated_utc; the rows by the method's own parameters, dK_x, b_x, as
    earlier revisions wrote them) migrates to schema 3: its times, and its rows rewritten from its file in the one
    vocabulary with the own name beside each, the file itself untouched."""
    from sqlalchemy import create_engine, select
    from simucal.report.lot_figures import block_parameters
    opening.make_at(url, 1)
    path = unit_files(base, tmp_path / "cals", units=1, visits=1, prefix="OLD")["OLD-0000"][0]
    row, _ = records.record_of(path.read_bytes(), path)
    cal = simucal.load(path)
    own_rows = [{"sensor": s, "name": n, "value": v, "std": std, "unit": u}  # schema 1's and 2's rows
                for s, b in cal.blocks() for n, (v, std, u) in block_parameters(b).items()]
    _, _, cals_v1, params_v1 = schema.tables(1)
    engine = create_engine(schema.engine_url(url))
    with engine.begin() as conn:
        rid = conn.execute(cals_v1.insert().values({k: v for k, v in row.items() if k != "calibrated_utc"})
                           ).inserted_primary_key[0]
        conn.execute(params_v1.insert(), [{"calibration_id": rid, **p} for p in own_rows])
    store = CalibrationStore(url)
    (rec,) = store.records()
    assert rec["calibrated_utc"] == rec["recorded_utc"] == row["recorded_utc"]
    assert store.files([rid])[rid] == row["file"]
    rows = store.parameters()
    assert len(own_rows) == 18 and len(rows) == 21 and {r["name"] for r in rows} >= {"M_xx", "M_yx", "bias_z"}
    assert [(r["sensor"], r["name"], r["value"], r["std"], r["unit"], r["own_name"]) for r in rows] == \
        [(r["sensor"], r["name"], r["value"], r["std"], r["unit"], r["own_name"]) for r in
         sorted(records.parameter_rows(cal), key=lambda r: (r["sensor"], r["name"]))]
    assert [e["id"] for e in store.history("OLD-0000")["records"]] == [rid]
    with engine.connect() as conn:
        versions = [r.version for r in conn.execute(select(schema.SCHEMA_TABLE).order_by("version"))]
    engine.dispose()
    assert versions == list(range(1, schema.SCHEMA + 1)) == [1, 2, 3]


def test_a_migration_that_cannot_read_a_records_file_leaves_the_store_as_it_was(url, base, tmp_path):
    """Schema 3 rewrites the rows from the files: a record whose file this simucal cannot read stops it, naming
    the store and the record, and the store stays at schema 2 with its rows."""
    from sqlalchemy import create_engine, func, select
    opening.make_at(url, 2)
    path = unit_files(base, tmp_path / "cals", units=1, visits=1, prefix="BAD")["BAD-0000"][0]
    row, _ = records.record_of(path.read_bytes(), path)
    _, _, cals_v2, params_v2 = schema.tables(2)
    engine = create_engine(schema.engine_url(url))
    with engine.begin() as conn:
        rid = conn.execute(cals_v2.insert().values({**row, "file": b'{"format": "not a calibration"}'})
                           ).inserted_primary_key[0]
        conn.execute(params_v2.insert(), [{"calibration_id": rid, "sensor": "acc", "name": "b_x", "value": 0.0,
                                           "std": 1.0, "unit": "g"}])
    with pytest.raises(StoreError, match=rf"migration to schema 3 .* stopped, the store left as it was: record {rid}"):
        CalibrationStore(url).records()
    with engine.connect() as conn:
        assert conn.execute(select(func.max(schema.SCHEMA_TABLE.c.version))).scalar() == 2
        assert conn.execute(select(func.count()).select_from(params_v2)).scalar() == 1
    engine.dispose()


def test_a_database_not_the_tools_or_newer_is_refused_in_one_line_and_left_as_it_was(url, base, tmp_path):
    from sqlalchemy import create_engine, inspect, text
    path = unit_files(base, tmp_path / "cals", units=1, visits=1, prefix="B")["B-0000"][0]
    engine = create_engine(schema.engine_url(url))
    with engine.begin() as conn:
        conn.execute(text("CREATE TABLE orders (id INTEGER)"))
    with pytest.raises(StoreError, match=r"not a simucal calibration store \(it has the tables orders"):
        simucal.Store(url).add(path)
    with engine.connect() as conn:
        assert inspect(conn).get_table_names() == ["orders"]
    with engine.begin() as conn:
        conn.execute(text("DROP TABLE orders"))
    simucal.Store(url).add(path)
    with engine.begin() as conn:
        conn.execute(schema.SCHEMA_TABLE.insert().values(version=schema.SCHEMA + 1, applied_utc="later", what="x"))
    engine.dispose()
    r = run("history", "B-0000", "--store", url, "-o", tmp_path / "h.json")
    assert r.exit_code == 2 and r.output.count("\n") == 1
    assert f"schema {schema.SCHEMA + 1} is newer than this simucal's {schema.SCHEMA}" in r.output
    assert not (tmp_path / "h.json").exists()


def test_a_password_in_the_url_is_never_printed(server, base, tmp_path):
    secret = "Sw0rdf1sh-x9"
    url = server.url(password=secret)
    missing = url.rsplit("/", 1)[0] + "/nosuchdb"
    for args in (["history", "X", "--store", missing, "-o", tmp_path / "h.json"],
                 ["store", "add", base, "--store", missing, "--serial", "X"]):
        r = run(*args)
        assert r.exit_code == 2 and secret not in r.output and "simucal:***@" in r.output, r.output
    assert secret not in repr(simucal.Store(url)) and schema.shown(url).count("***") == 1


def test_calibrate_and_store_add_record_from_the_command_line(tmp_path):
    db = tmp_path / "lab.db"
    ms = simucal.simulate(seed=2)
    ms.meta["unit_serial"] = "CLI-1"
    ms.write(tmp_path / "set")
    r = run("calibrate", tmp_path / "set", "-o", tmp_path / "cal.json", "--store", db)
    assert r.exit_code == 0 and "recorded as record 1 in Store(" in r.output, r.output
    store = simucal.Store(db)
    assert store.file(1) == (tmp_path / "cal.json").read_bytes()
    r = run("store", "add", tmp_path / "cal.json", "--store", db)
    assert r.exit_code == 2 and "already recorded (record 1, unit CLI-1" in r.output
    r = run("store", "add", tmp_path / "cal.json", "--store", db, "--serial", "OTHER")
    assert r.exit_code == 2 and "--serial OTHER:" in r.output and "made for unit 'CLI-1'" in r.output


_WRITER = """
import sys
from simucal.store import CalibrationStore
store = CalibrationStore(sys.argv[1])
for path in open(sys.argv[2]).read().split():
    store.add(path, station=sys.argv[3])
"""


@pytest.mark.slow
def test_two_writers_at_once_lose_nothing_and_duplicate_nothing(url, base, tmp_path):
    files = [p for ps in unit_files(base, tmp_path / "cals", units=2 * WRITES, visits=1, prefix="W").values()
             for p in ps]
    procs = []
    for k in range(2):  # both open the empty store at once: its creation is raced too
        listing = tmp_path / f"writer{k}.txt"
        listing.write_text("\n".join(map(str, files[k::2])))
        procs.append(subprocess.Popen([sys.executable, "-c", _WRITER, url, str(listing), f"station {k}"],
                                      stderr=subprocess.PIPE, text=True))
    errors = [p.communicate(timeout=600)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [e[-2000:] for e in errors]
    recs = simucal.Store(url).records()
    assert len(recs) == 2 * WRITES and recs["id"].is_unique and recs["file_sha256"].is_unique
    assert sorted(recs["serial"]) == sorted(f"W-{i:04d}" for i in range(2 * WRITES))
    assert (recs["station"].value_counts() == WRITES).all()
    assert len(simucal.Store(url).parameters()) == 21 * 2 * WRITES


@pytest.mark.slow
def test_a_lot_of_200_units_history_flags_exactly_the_drifting_and_the_trend_holds_its_stds(url, base, tmp_path):
    """200 units calibrated three times four months apart, seven with a planted drift of 12 std per calibration in
    gyro b_z: history flags exactly those seven, lot of the store equals lot of the folder, and every parameter's
    trend (its slope against the planted one, over 200 units and 21 entries of the one vocabulary) is off by its std
    as often as its std says."""
    drifting = {3, 8, 17, 60, 111, 150, 199}
    units = unit_files(base, tmp_path / "cals", units=200, visits=3, drifting=drifting, seed=7)
    store = CalibrationStore(url)
    for serial, paths in units.items():
        for month, path in enumerate(paths):
            store.add(path, station="line 1", calibrated_utc=f"2026-{1 + 4 * month:02d}-15")
    flagged, z_slope, tied = set(), [], []
    sensor, name = DRIFT_PARAM.split(".")
    planted_per_year = 12.0 * getattr(simucal.load(base), sensor).std[name] * 365.25 / 120  # 12 std per 120 days
    for serial in units:
        h = store.history(serial)
        assert [len(e.get("since_first", {}).get("parameters", [])) for e in h["records"]] == [0, 0, 21]
        if h["flagged"]:
            flagged.add(int(serial.split("-")[1]))
            last = h["records"][-1]
            assert any("gyro moved" in w for w in last["why"])
            z = {p["name"]: p["z"] for p in last["since_first"]["parameters"]}
            assert abs(z[DRIFT_ENTRY]) > 10 > max(abs(v) for k, v in z.items() if k != DRIFT_ENTRY)
        for p in h["trend"]["parameters"]:
            truth = planted_per_year if p["name"] == DRIFT_ENTRY and int(serial.split("-")[1]) in drifting else 0.0
            z_slope.append((p["slope_per_year"] - truth) / p["slope_std"])
            tied.append(p["name"].startswith("gyro.M_"))
    assert flagged == drifting
    # 4,200 slopes: the rms of error/std within 5 % of 1, none beyond 5 std; the gyro's M in b carries C_b^d's
    # std (std_M), which unit_files does not draw (it draws the parameters alone), so there it is below 1
    z_slope, tied = np.array(z_slope), np.array(tied)
    assert len(z_slope) == 4200 and tied.sum() == 1800 and np.max(np.abs(z_slope)) < 5
    assert 0.95 < np.sqrt(np.mean(z_slope[~tied] ** 2)) < 1.05 and np.sqrt(np.mean(z_slope[tied] ** 2)) < 0.95
    of_folder, of_store = simucal.lot(tmp_path / "cals"), simucal.lot(store=url)
    assert len(of_store["units"]) == 200
    assert [(u["serial"], u["status"]) for u in of_store["units"]] == \
        [(u["serial"], u["status"]) for u in of_folder["units"]]
    for g_store, g_folder in zip(of_store["groups"], of_folder["groups"]):
        assert [(p["name"], p["values"], p["stds"]) for p in g_store["parameters"]] == \
            [(p["name"], p["values"], p["stds"]) for p in g_folder["parameters"]]
    drifted = [{d["later"][:7] for d in report["drift"] if d["sensors"]["gyro"]["verdict"] == "drifted"}
               for report in (of_store, of_folder)]  # lot's drift: each pair at ALPHA, 800 tests here
    assert drifted[0] == drifted[1] and len(drifted[0] - {f"SN-{u:04d}" for u in drifting}) <= 2
    assert {f"SN-{u:04d}" for u in drifting} <= drifted[0]
    r = run("history", "SN-0003", "--store", url, "-o", tmp_path / "h.json")
    assert r.exit_code == 0 and "FLAGGED" in r.output and "unit SN-0003: 3 calibrations, " in r.output
    assert json.loads((tmp_path / "h.json").read_text())["flagged"] == store.history("SN-0003")["flagged"]
    changes = simucal.Store(url).changes("SN-0003")
    row = changes[(changes["name"] == DRIFT_ENTRY) & (changes["record"] == max(changes["record"]))].iloc[0]
    assert row["flagged"] and row["z_since_first"] > 12 and 5 < row["z_since_last"] < row["z_since_first"]


def test_lot_of_the_store_equals_lot_of_the_folder(url, base, tmp_path):
    units = unit_files(base, tmp_path / "cals", units=21, visits=2, drifting={4}, seed=5)
    store = simucal.Store(url)
    for paths in units.values():
        for month, path in enumerate(paths):
            store.add(path, time=f"2026-{1 + 6 * month:02d}-01")
    of_folder, of_store = simucal.lot(tmp_path / "cals"), simucal.lot(store=url)
    assert [u["status"] for u in of_store["units"]] == [u["status"] for u in of_folder["units"]]
    drifted = [d["later"] for d in of_store["drift"] if d["sensors"]["gyro"]["verdict"] == "drifted"]
    assert len(of_store["units"]) == 21 and len(drifted) == 1 and drifted[0].startswith("SN-0004_2026-07-01T00:00")
    for g_store, g_folder in zip(of_store["groups"], of_folder["groups"]):
        assert [(p["name"], p["values"], p["stds"], p["outliers"] == []) for p in g_store["parameters"]] == \
            [(p["name"], p["values"], p["stds"], p["outliers"] == []) for p in g_folder["parameters"]]
    assert len(simucal.lot(store=url, until="2026-02-01")["superseded"]) == 0
    r = run("lot", "--store", url, "--since", "2026-06-01", "-o", tmp_path / "lot.json")
    later = json.loads((tmp_path / "lot.json").read_text())  # the second calibrations alone: SN-0004 moved 12 std
    assert r.exit_code == 0 and later["verdict"][0] == "20 of 21 units pass, 0 fail, 1 flagged" and not later["drift"]
    assert [u["serial"] for u in later["units"] if u["status"] == "flagged"] == ["SN-0004"]
