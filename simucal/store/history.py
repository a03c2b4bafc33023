"""A unit's history: its calibrations in time order, each parameter's change since the unit's last and since
its first calibration by the same method and model in units of the combined std, and the changes the stds
do not explain.

The change between two calibrations is report/lot_figures.drift's, entry by entry of the one vocabulary
(report/vocabulary.py: M, bias, effects, the method's own name beside each): later minus earlier, its std from both
files' covariances, and per sensor the joint chi^2 of no change. A unit's history is one family of such tests
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
from simucal.io.calibration import loads
from simucal.report.lot_figures import Determined, Limit, determined, drift, outside, own_aliases, read_limits
from simucal.report.unit_history import Change, History, HistoryEntry
from simucal.store import queries, trend
from simucal.store.schema import RecordRow, shown

FORMAT = "simucal.history/1"


def _change(earlier: tuple[RecordRow, Determined], later: tuple[RecordRow, Determined]) -> Change:
    """The change from record `earlier` to `later` (each (record, its lot_figures.determined)):
    report/lot_figures.drift's, with its parameters' z the change in units of the combined std."""
    (r1, d1), (r2, d2) = earlier, later
    d = drift(r1["id"], d1, r2["id"], d2, r2["serial"])
    return {"since": r1["id"], "since_utc": r1["calibrated_utc"],
            "sensors": {s: {"chi2": v["chi2"], "dof": v["dof"], "p_value": v["p_value"]}
                        for s, v in d["sensors"].items()},
            "parameters": [{"name": p["name"], "own_name": p["own_name"], "unit": p["unit"], "change": p["drift"],
                            "std": p["std"], "z": p["z"]} for p in d["parameters"]]}


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


def _with_aliases(known: dict[str, str], aliases: dict[str, str]) -> dict[str, str]:
    """The names a limits file may give: the one vocabulary's, and the method's own where an own parameter is an
    entry itself (lot_figures.own_aliases)."""
    return {**known, **{own: known[entry] for own, entry in aliases.items() if entry in known}}


def _by_entry(limits: dict[str, Limit], aliases: dict[str, str], path) -> dict[str, Limit]:
    """Limits by the one vocabulary's names (an own name's limit is its entry's); an entry named twice (b_x and
    bias_x) is refused, naming the file."""
    out: dict[str, Limit] = {}
    for name, lim in limits.items():
        entry = aliases.get(name, name)
        if entry in out:
            raise StoreError(f"{path}: limits.{name}: {entry} is bounded twice (by its own name and the method's); "
                             "give one of the two")
        out[entry] = lim
    return out


def history(engine, url: str, serial: str, limits_path=None, spec_path=None) -> History:
    """The history of unit `serial` (module doc): {format, store, serial, records, level, tests, flagged, verdict,
    trend}."""
    recs = queries.records(engine, url, serial=serial)
    if not recs:
        raise StoreError(f"{shown(url)}: no calibration of unit {serial!r}; record one: simucal store add CAL.json "
                         f"--serial {serial}")
    raw = queries.files(engine, url, [r["id"] for r in recs])
    cals = [(r, loads(raw[r["id"]].decode("utf-8"), f"{shown(url)} record {r['id']}")) for r in recs]
    firsts: dict[tuple[str, str], tuple[RecordRow, Determined]] = {}
    lasts: dict[tuple[str, str], tuple[RecordRow, Determined]] = {}
    entries: list[HistoryEntry] = []
    for r, cal in cals:
        key = (r["method"], r["model"])  # another method or model: its own line of changes
        e: HistoryEntry = {"id": r["id"], "calibrated_utc": r["calibrated_utc"], "station": r["station"],
                           "method": r["method"], "model": r["model"], "tool_version": r["tool_version"]}
        this = (r, determined(cal))
        if key in lasts:
            e["since_last"] = _change(lasts[key], this)
            if firsts[key][0]["id"] != lasts[key][0]["id"]:
                e["since_first"] = _change(firsts[key], this)
        firsts.setdefault(key, this)
        lasts[key] = this
        entries.append(e)
    aliases = own_aliases(cals[-1][1])  # a limits file naming the method's own parameters (b_x for bias_x)
    known = {p["name"]: p["unit"] for e in entries for change in (e.get("since_last"), e.get("since_first"))
             if change for p in change["parameters"]}
    limits = (_by_entry(read_limits(limits_path, _with_aliases(known, aliases)), aliases, limits_path)
              if limits_path else {})
    method, model = recs[-1]["method"], recs[-1]["model"]  # the trend's line: the last calibration's (trend.py)
    units = {f"{p['sensor']}.{p['name']}": p["unit"]
             for p in queries.parameters(engine, url, serial=serial, method=method, model=model)}
    spec = (_by_entry(read_limits(spec_path, _with_aliases(units, aliases),
                                  f"unit {serial}'s trend (its calibrations by {method}, {model}, as its last one was "
                                  "made: a spec bounds that line's parameters)"), aliases, spec_path)
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
