"""A unit's history: its calibrations in time order, each parameter's change since the unit's last and since
its first calibration by the same method and model in units of the combined std, and the changes the stds
do not explain.

The change between two calibrations is report/lot_figures.drift's: later minus earlier, its std from both files'
covariances, and per sensor the joint chi^2 of no change. A unit's history is one family of such tests
(each later record's since-last and, from the third on, since-first test per sensor): a record is flagged
where a test's p is below ALPHA / (the family's count), Bonferroni, so that a unit that never moved is
flagged with a chance of at most ALPHA over its whole history. A lab's limits (a limits.json as `simucal lot`
reads, here bounding each parameter's change since the first calibration) flag a record too. Beside the changes,
each parameter's trend and the unit's due date by the lab's spec (trend.py; the spec a limits.json bounding
each parameter's value, as `simucal lot --limits` reads it).
"""
from __future__ import annotations

from simucal.errors import StoreError
from simucal.fit.results import ALPHA
from simucal.io.calibration import Calibration, loads
from simucal.report.lot_figures import drift, outside, read_limits
from simucal.report.unit_history import Change, History, HistoryEntry
from simucal.store import queries, trend
from simucal.store.schema import RecordRow, shown

FORMAT = "simucal.history/1"


def _change(earlier, later) -> Change:
    """The change from record `earlier` to `later` (each (record, calibration)): report/lot_figures.drift's, with its
    parameters' z the change in units of the combined std."""
    (r1, c1), (r2, c2) = earlier, later
    d = drift(r1["id"], c1, r2["id"], c2)
    return {"since": r1["id"], "since_utc": r1["calibrated_utc"],
            "sensors": {s: {"chi2": v["chi2"], "dof": v["dof"], "p_value": v["p_value"]}
                        for s, v in d["sensors"].items()},
            "parameters": [{"name": p["name"], "unit": p["unit"], "change": p["drift"], "std": p["std"], "z": p["z"]}
                           for p in d["parameters"]]}


def _judge(entries, limits) -> tuple[float, int]:
    """Flag the entries by the module doc's rule; the level and the family's count."""
    tests = sum(len(e[k]["sensors"]) for e in entries for k in ("since_last", "since_first") if e.get(k))
    level = ALPHA / max(tests, 1)
    for e in entries:
        why = []
        for k, words in (("since_last", "since the last"), ("since_first", "since the first")):
            change = e.get(k)
            if not change:
                continue
            why += [f"{s} moved {words} (record {change['since']}): chi2 {v['chi2']:.3g} on {v['dof']}, p = "
                    f"{v['p_value']:.2g} < {level:.2g}" for s, v in change["sensors"].items() if v["p_value"] < level]
        first = e.get("since_first") or e.get("since_last")
        for p in (first["parameters"] if first else []):
            broken = outside(p["change"], p["std"], limits[p["name"]]) if p["name"] in limits else None
            if broken:
                why.append(f"{p['name']} changed {broken.replace(' its ', ' the lab limit ')} since the first")
        e["flagged"], e["why"] = bool(why), why
    return level, tests


def history(engine, url: str, serial: str, limits_path=None, spec_path=None) -> History:
    """The history of unit `serial` (module doc): {format, store, serial, records, level, tests, flagged, verdict,
    trend}."""
    recs = queries.records(engine, url, serial=serial)
    if not recs:
        raise StoreError(f"{shown(url)}: no calibration of unit {serial!r}; record one: simucal store add CAL.json "
                         f"--serial {serial}")
    raw = queries.files(engine, url, [r["id"] for r in recs])
    cals = [(r, loads(raw[r["id"]].decode("utf-8"), f"{shown(url)} record {r['id']}")) for r in recs]
    firsts: dict[tuple[str, str], tuple[RecordRow, Calibration]] = {}
    lasts: dict[tuple[str, str], tuple[RecordRow, Calibration]] = {}
    entries: list[HistoryEntry] = []
    for r, cal in cals:
        key = (r["method"], r["model"])  # another method or model: its own line of changes
        e: HistoryEntry = {"id": r["id"], "calibrated_utc": r["calibrated_utc"], "station": r["station"],
                           "method": r["method"], "model": r["model"], "tool_version": r["tool_version"]}
        if key in lasts:
            e["since_last"] = _change(lasts[key], (r, cal))
            if firsts[key][0]["id"] != lasts[key][0]["id"]:
                e["since_first"] = _change(firsts[key], (r, cal))
        firsts.setdefault(key, (r, cal))
        lasts[key] = (r, cal)
        entries.append(e)
    known = {p["name"]: p["unit"] for e in entries for change in (e.get("since_last"), e.get("since_first"))
             if change for p in change["parameters"]}
    limits = read_limits(limits_path, known) if limits_path else {}
    method, model = recs[-1]["method"], recs[-1]["model"]  # the trend's line: the last calibration's (trend.py)
    units = {f"{p['sensor']}.{p['name']}": p["unit"]
             for p in queries.parameters(engine, url, serial=serial, method=method, model=model)}
    spec = (read_limits(spec_path, units, f"unit {serial}'s trend (its calibrations by {method}, {model}, as its "
                                          "last one was made: a spec bounds that line's parameters)")
            if spec_path else {})
    level, tests = _judge(entries, limits)
    flagged = [e["id"] for e in entries if e["flagged"]]
    verdict = (f"unit {serial}: {len(entries)} calibrations, " +
               (f"{len(flagged)} flagged (records {', '.join(map(str, flagged))})" if flagged else
                f"no change beyond the stds (each test at {level:.2g}: ALPHA {ALPHA:g} over {tests} tests)"
                + (" or the lab's limits" if limits else "")))
    return {"format": FORMAT, "store": shown(url), "serial": serial, "alpha": ALPHA, "level": level, "tests": tests,
            "limits": limits, "records": entries, "flagged": flagged, "verdict": verdict,
            "trend": trend.trend(engine, url, serial, spec)}


def lines(report) -> list[str]:
    """The history in words: one line per calibration, its largest changes in std, and the verdict."""
    out = []
    for e in report["records"]:
        head = f"record {e['id']} {e['calibrated_utc']} {e['station']} {e['method']} ({e['model']})"
        parts = []
        for k, words in (("since_last", "since last"), ("since_first", "since first")):
            change = e.get(k)
            if change and change["parameters"]:
                top = max(change["parameters"], key=lambda p: abs(p["z"]))
                parts.append(f"{words}: largest {top['name']} {top['z']:+.2f} std")
        flag = ("  FLAGGED: " + "; ".join(e["why"])) if e["flagged"] else ""
        out.append(head + (": " + ", ".join(parts) if parts else ": the first") + flag)
    return out + [report["verdict"], report["trend"]["verdict"]]
