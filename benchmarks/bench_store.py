"""The calibration store's times on a store of N records (default 10,000; docs/lab.md): one `add` (a file checked,
its record and its rows, an entry each of the one vocabulary, in one transaction, the commit on disk), a unit's
history, a unit's records, every record and every entry's row as DataFrames, and `lot` of the whole store.

The store is filled first in one transaction per 1,000 records (N files of N / 4 simulated units, four
calibrations each, through simucal's own writer); then each operation is timed `--repeats` times (the best and
the median are printed). --store URL: an empty database of a SQL server (postgresql://user@host/db) instead of
a temporary SQLite file.

    python3 benchmarks/bench_store.py [--records 10000] [--adds 20] [--repeats 3] [--store URL]
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import simucal
from simucal.store import CalibrationStore, records
from simucal.store.schema import CALIBRATIONS, PARAMETERS

VISITS = 4


def _files(base_text: str, n: int, prefix: str = "B"):
    """n calibration files' bytes: units of VISITS calibrations each (the base with the unit's serial; each visit's
    file its own bytes by its trailing white space, which JSON reads past)."""
    for i in range(n):
        serial = f"{prefix}-{i // VISITS:05d}"
        text = base_text.replace('"sensors"', f'"unit_serial": "{serial}", "sensors"', 1) + " " * (i % VISITS)
        yield serial, i % VISITS, text.encode()


def _fill(store: CalibrationStore, base_text: str, n: int) -> float:
    """The store filled with n records in transactions of 1,000; the seconds it took."""
    t0 = time.perf_counter()
    engine = store._db(create=True)
    made = [records.record_of(raw, serial, calibrated_utc=f"{2020 + visit}-06-01")
            for serial, visit, raw in _files(base_text, n)]
    for start in range(0, n, 1000):
        with engine.connect().execution_options(write=True) as conn, conn.begin():
            for row, params in made[start:start + 1000]:
                rid = conn.execute(CALIBRATIONS.insert().values(**row)).inserted_primary_key[0]
                conn.execute(PARAMETERS.insert(), [{"calibration_id": rid, **p} for p in params])
    return time.perf_counter() - t0


def _timed(f, repeats: int) -> tuple[float, float, float]:
    """f's best and median wall time and its best CPU time (this process's: the machine may be shared), s."""
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        f()
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(times), statistics.median(times), min(cpu)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=int, default=10_000)
    ap.add_argument("--adds", type=int, default=20, help="files added one by one, each timed")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--store", default=None, help="an empty database's URL (default: a temporary SQLite file)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-store-") as folder:
        _run(args, Path(folder))


def _run(args, tmp: Path) -> None:
    base = tmp / "base.json"
    simucal.save(base, simucal.calibrate(simucal.simulate(seed=1)))
    base_text = base.read_text()
    url = args.store or str(tmp / "lab.db")
    store = CalibrationStore(url)
    fill_s = _timed(lambda: _fill(store, base_text, args.records - args.adds), 1)
    paths = []
    for k, (_, _, raw) in enumerate(_files(base_text, args.adds, prefix="ADD")):
        paths.append(tmp / f"add{k}.json")
        paths[-1].write_bytes(raw)
    adds = [_timed(lambda: store.add(path, station="bench"), 1) for path in paths]
    api = simucal.Store(url)
    api.records(serial="B-00001")  # pandas imported before the timings (a notebook has it already)
    rows = [("fill (transactions of 1,000)", args.records - args.adds, *fill_s),
            ("add one file", len(adds), min(a[0] for a in adds), statistics.median(a[0] for a in adds),
             min(a[2] for a in adds))]
    unit = "B-00000"
    entries = len(api.parameters())  # the rows, an entry each of the one vocabulary per record
    for name, n, f in (("history of a unit (4 calibrations)", VISITS, lambda: api.history(unit)),
                       ("a unit's records", VISITS, lambda: api.records(serial=unit)),
                       ("every record (DataFrame)", args.records, api.records),
                       ("every entry's row (DataFrame)", entries, api.parameters)):
        rows.append((name, n, *_timed(f, args.repeats)))
    rows.append((f"lot of the store ({args.records // VISITS} units' last of {args.records} records)", args.records,
                 *_timed(lambda: simucal.lot(store=url), 1)))  # once: the lot of every unit's last calibration
    print(f"store: {store.shown}, {args.records} records\n")
    print("| operation | rows | best s | median s | best CPU s |\n|---|---|---|---|---|")
    for name, n, best, median, cpu in rows:
        print(f"| {name} | {n} | {best:.4f} | {median:.4f} | {cpu:.4f} |")
    store.close()
    api.close()


if __name__ == "__main__":
    main()
