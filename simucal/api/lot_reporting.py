"""`simucal.lot` (`simucal lot CAL_FOLDER`): the units of a production lot side by side, from their calibration files.

Per parameter, in the one vocabulary of every method (api/vocabulary.py: each block's M entries and bias,
effects by id; named `sensor.name`, acc.M_xx, gyro.bias_z, with the method's own name beside it), the lot's robust
centre (the median) and spread (1.4826 x the median absolute
deviation, the std of a normal lot), and the spread of the units themselves with the calibrations' own noise taken out:
tau, at which the z below have the median |z| of a normal (`_z`).

Outliers: a unit's parameter is judged in its own std combined with the lot's spread of units,
z = (x - median) / sqrt(tau^2 + std^2); a unit is flagged where any of its K parameters has |z| above
the threshold at which a unit of a normal lot would be flagged with chance OUTLIER_P (`threshold`:
simulated lots with this lot's units, stds and spreads; a median and MAD of few units scatter, so the
threshold rises as the lot shrinks; benchmarks/bench_lot.py measures the rate and the power).
Spec limits (limits.json, `read_limits`: by those names or the method's own, acc.b_x), each block's model test,
and the drift between two calibrations of one `unit_serial` by one method and model (entry by entry of the one
vocabulary, each file's covariance of them through M(p); later minus earlier in file-name order, its std from both
covariances: d^T (C_1 + C_2)^+ d is chi^2 on the rank of C_1 + C_2 where nothing drifted). Units are grouped by
method, model (with its effects), thermal or not, and units of the data: each group's distribution is its own (a
lot of mixed files is grouped, never refused); a unit calibrated more than once enters it with its last
calibration. An entry whose std the file does not give (the linear method's gyro M, through a C_b^d without a std)
is not judged.
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from simucal.arguments import checked
from simucal.errors import CalibrationError, InputError, StoreError
from simucal.io.calibration import Calibration, load
from simucal.io.calibration_checks import SERIAL, CalibrationFileError
from simucal.report.console import n_units
from simucal.report.lot_figures import (DRIFT_P, Determined, Drift, Limit, LotGroup, LotParameter, LotReport,
                                        LotUnit, NamedOutlier, NotCalibration, UnitTest, block_parameters, determined,
                                        drift, model_name, outside, read_limits)

FORMAT = "simucal.lot/1"
OUTLIER_P = 1e-3   # the chance that a unit of a normal lot is flagged at all (over its K parameters)
MAD_TO_STD = 1.4826  # the median absolute deviation of a normal sample, times this, is its std
MIN_UNITS = 20     # fewer units: no outlier test (said in the report): a median and MAD of 6 scatter too much
SIMULATED_UNITS = 50_000  # units of normal lots simulated for the threshold: its 1e-3 tail holds 50


def read_folder(folder: str | os.PathLike[str]) -> tuple[list[tuple[str, Calibration]], list[NotCalibration]]:
    """The calibrations of a folder, by file name, and every other file in it named with why."""
    folder = Path(folder)
    cals: list[tuple[str, Calibration]] = []
    others: list[NotCalibration] = []
    for p in sorted(folder.iterdir()):
        if p.is_dir():
            others.append({"file": p.name, "why": "a folder, not a calibration file"})
            continue
        try:
            cals.append((p.name, load(p)))
        except CalibrationFileError as e:
            others.append({"file": p.name, "why": str(e)})
    if not cals:
        raise CalibrationError(f"{folder}: holds no calibration file ({len(others)} other files); calibrate the lot "
                               "first: simucal calibrate DIR1 DIR2 ... -o FOLDER")
    return cals, others


def _group_key(cal: Calibration) -> str:
    units = [f"{s} {cal.layout.get(s + '_unit')}" for s in cal.sensors]
    return f"{cal.method}: {model_name(cal)}; " + ", ".join(units)


def _parameters(d: Determined) -> dict[str, tuple[float, float, str, str | None]]:
    """{sensor.name: (value, std, unit, the method's own name)} of every block in the one vocabulary
    (report/vocabulary.py: M_xx .. M_zz, bias_x .. bias_z, the effects by id) that the file determines (d: its
    lot_figures.determined; a std above 0: an entry the model fixes is no unit's)."""
    return {f"{s}.{e.name}": (e.value, e.std, e.unit, e.own_name) for s, (es, _) in d.items() for e in es}


def _limited(cal: Calibration, d: Determined) -> dict[str, tuple[float, float, str]]:
    """What a limits file may name: the entries of the one vocabulary, and each method's own parameters
    (report/lot_figures.block_parameters: acc.b_x, acc.dK_x), as the limits files written before it name them."""
    own = {f"{s}.{n}": v for s, b in cal.blocks() for n, v in block_parameters(b).items()}
    return {**own, **{n: (v, s, u) for n, (v, s, u, _) in _parameters(d).items()}}


def _z(x: NDArray[np.float64], s: NDArray[np.float64],
       steps: int = 24) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """z of each unit (axis -2) for each parameter (axis -1) of one lot or a stack of lots, the median,
    the spread and tau: the spread of units at which the z's median |z| is a normal's (0.6745), found
    by bisection (0 where the stds alone explain the scatter). Consistent where the units' stds differ,
    as max(spread^2 - median(std^2), 0) is not (a lot with stds 0.05 to 2 times tau: 9 % flagged at a
    chance of 5 %)."""
    centre = np.median(x, axis=-2, keepdims=True)
    dev = np.abs(x - centre)
    spread = MAD_TO_STD * np.median(dev, axis=-2, keepdims=True)
    lo, hi = np.zeros_like(spread), MAD_TO_STD * dev.max(axis=-2, keepdims=True) + 1e-300
    for _ in range(steps):  # the median |z| falls as tau grows
        mid = 0.5 * (lo + hi)
        wide = np.median(dev / np.sqrt(mid ** 2 + s ** 2), axis=-2, keepdims=True) > 1 / MAD_TO_STD
        lo, hi = np.where(wide, mid, lo), np.where(wide, hi, mid)
    tau = np.where(np.median(dev / s, axis=-2, keepdims=True) > 1 / MAD_TO_STD, 0.5 * (lo + hi), 0.0)
    return (x - centre) / np.sqrt(tau ** 2 + s ** 2), centre, spread, tau


def threshold(tau: NDArray[np.float64], s: NDArray[np.float64], p: float = OUTLIER_P, units: int = SIMULATED_UNITS,
              seed: int = 0) -> float:
    """The |z| a unit of a normal lot exceeds in any of its parameters with chance p: the 1 - p quantile
    of each unit's largest |z| over `units` simulated units in lots like this one (its units' stds s
    (n, k), its spreads of units tau (k,)); a median and MAD from few units scatter, so it is above
    the normal's (4.03 for 18 parameters) the fewer units there are. Seeded: one lot, one threshold."""
    n, k = s.shape
    rng = np.random.default_rng(seed)
    lots = -(-units // n)
    x = tau * rng.standard_normal((lots, n, k)) + s * rng.standard_normal((lots, n, k))
    z = _z(x, np.broadcast_to(s, x.shape))[0]
    return float(np.quantile(np.abs(z).max(axis=-1), 1.0 - p))


def _group(key: str, names: Sequence[str], dets: Mapping[str, Determined]) -> LotGroup:
    """One group's (key: its method and model; names: its units' files, dets their lot_figures.determined)
    parameters (those every unit's file gives with a std): each one's distribution over the units and its
    outliers, by the rule of the module doc."""
    per_unit = [_parameters(dets[n]) for n in names]
    params = sorted(set.intersection(*(set(d) for d in per_unit)))
    x = np.array([[d[p][0] for p in params] for d in per_unit]).reshape(len(names), len(params))
    s = np.array([[d[p][1] for p in params] for d in per_unit]).reshape(x.shape)
    z, centre, spread, tau = _z(x, s)
    tested = len(names) >= MIN_UNITS and params
    z_max = threshold(tau[0], s) if tested else None
    rows: list[LotParameter] = [{"name": p, "unit": per_unit[0][p][2], "own_name": per_unit[0][p][3],
             "centre": float(centre[0, j]), "spread": float(spread[0, j]),
             "spread_of_units": float(tau[0, j]), "median_std": float(np.median(s[:, j])),
             "values": x[:, j].tolist(), "stds": s[:, j].tolist(), "z": z[:, j].tolist(),
             "outliers": [{"unit": names[i], "value": float(x[i, j]), "std": float(s[i, j]), "z": float(z[i, j])}
                          for i in range(len(names)) if tested and abs(z[i, j]) > z_max]}
            for j, p in enumerate(params)]
    rule = (f"|z| > {z_max:.3g} in any of {len(params)} parameters, z = (x - median) / sqrt(tau^2 + std^2): a unit "
            f"of a normal lot is flagged with a chance of {OUTLIER_P:g}" if tested else
            f"not tested: {n_units(len(names))}, fewer than {MIN_UNITS}")
    left = sorted(set().union(*per_unit) - set(params))
    return {"key": key, "units": list(names), "parameters": rows, "outlier_rule": rule, "z_threshold": z_max,
            **({"not_compared": left} if left else {})}


def _by_serial(cals: Sequence[tuple[str, Calibration]], dets: Mapping[str, Determined]
               ) -> tuple[list[tuple[str, Calibration]], list[str], list[Drift]]:
    """The calibration each unit enters the lot with (its last by file name), the earlier ones, and the
    drift between each unit's consecutive calibrations (dets: each file's lot_figures.determined)."""
    last: dict[tuple[str, object], tuple[str, Calibration]] = {}
    earlier: list[str] = []
    drifts: list[Drift] = []
    for i, (name, cal) in enumerate(cals):
        serial = cal.layout.get(SERIAL)  # one unit in one group: another method's calibration is no drift
        key = (_group_key(cal), serial) if serial is not None else ("file", i)
        if key in last:
            drifts.append(drift(last[key][0], dets[last[key][0]], name, dets[name], serial))
            earlier.append(last[key][0])
        last[key] = (name, cal)
    return sorted(last.values(), key=lambda nc: nc[0]), earlier, drifts


def _drifted(d: Drift) -> list[str]:
    return [s for s, v in d["sensors"].items() if v["verdict"] == "drifted"]


def _unit(name: str, cal: Calibration, d: Determined, group: str, limits: Mapping[str, Limit],
          outliers: list[NamedOutlier], drifted: list[Drift]) -> LotUnit:
    """One unit: its model tests, limits broken, outliers, and its status with the reasons."""
    tests: dict[str, UnitTest] = {s: {"verdict": b.verdict, "p_value": b.p_value} for s, b in cal.blocks()}
    fails = [f"{s} model test fails (p = {t['p_value']:.2g})" for s, t in tests.items() if t["verdict"] == "fails"]
    fails += [f"{s} not calibrated ({why})" for s, why in cal.not_calibrated.items()]
    fails += [f"{s} left at nominal" for s, t in tests.items() if t["verdict"] == "nominal"]
    params = _limited(cal, d)
    broken = {n: outside(params[n][0], params[n][1], lim) for n, lim in limits.items() if n in params}
    fails += [f"{n} {why}" for n, why in broken.items() if why]
    flags = [f"outlier: {o['name']} z = {o['z']:.3g}" for o in outliers]
    flags += [f"drifted since {d['earlier']} ({', '.join(_drifted(d))} p = "
              f"{min(v['p_value'] for v in d['sensors'].values()):.2g})" for d in drifted]
    status = "fails" if fails else "flagged" if flags else "passes"
    return {"file": name, "serial": cal.layout.get(SERIAL), "input": cal.input, "group": group, "tests": tests,
            "outside_limits": {n: w for n, w in broken.items() if w}, "outliers": outliers, "status": status,
            "why": fails + flags}


def _next(units: list[LotUnit], folder: str | os.PathLike[str]) -> str:
    """The command to run next: diagnose the first unit whose model fails, else validate the first unit
    failed or flagged on another recording of it, else apply."""
    for u in units:
        if any(t["verdict"] == "fails" for t in u["tests"].values()):
            return f"simucal diagnose {u['input']} -o diagnosis.json --html diagnosis.html"
    for u in units:
        if u["status"] != "passes":
            return f"simucal validate {Path(folder) / u['file']} OTHER_RECORDING_OF_THE_UNIT -o v.json --html v.html"
    return f"simucal apply {Path(folder) / units[0]['file']} DATA_OF_THAT_UNIT -o OUT (each unit its own file)"


def verdict_lines(report: LotReport) -> list[str]:
    """The lot's verdict in words: how many pass, which fail and why, which are flagged."""
    units = report["units"]
    by = {s: [u for u in units if u["status"] == s] for s in ("passes", "fails", "flagged")}
    out = [f"{len(by['passes'])} of {n_units(len(units))} pass, {len(by['fails'])} fail, {len(by['flagged'])} flagged"
           + (f" ({len(report['groups'])} groups of method and model, each its own distribution)"
              if len(report["groups"]) > 1 else "")]
    out += [f"{u['file']} {u['status'].upper()}: " + "; ".join(u["why"]) for u in by["fails"] + by["flagged"]]
    out += [f"no outlier test for {g['key']}: {g['outlier_rule']}" for g in report["groups"]
            if g["z_threshold"] is None]
    if report["superseded"]:
        out.append("calibrated again, so left out of the distributions: " + ", ".join(report["superseded"]))
    out += [f"not a calibration: {o['file']} ({o['why']})" for o in report["not_calibrations"]]
    return out


@checked
def lot(folder: str | os.PathLike[str] | None = None, limits: str | os.PathLike[str] | None = None, *,
        store: str | os.PathLike[str] | None = None, since: str | None = None, until: str | None = None,
        method: str | None = None, model: str | None = None, station: str | None = None) -> LotReport:
    """The lot report of the calibration files in a folder, or of a store's records: the dict `simucal lot -o
    lot.json` writes.

    Parameters
    ----------
    folder : str or os.PathLike
        A folder of calibration files, one per unit (``simucal calibrate DIR1 DIR2 ... -o FOLDER``);
        other files in it are named under ``not_calibrations``.
    limits : str or os.PathLike, optional
        A limits.json (format ``simucal.limits/1``): spec limits per parameter, in the calibrations' units.
    store : str or os.PathLike, optional
        Instead of a folder: a calibration store's URL (``simucal.Store``), its records that match since and
        until (calibrated_utc, inclusive), method, model and station; each unit enters with its last.

    Returns
    -------
    dict
        ``verdict`` (lines: how many units pass, which fail and why), ``next`` (the command to run next),
        ``units`` (each unit's status, model tests, limits broken, outliers), ``groups`` (per method and
        model, each parameter's median, spread, spread of units, values, stds and z), ``drift`` (between
        calibrations of one unit_serial) and ``not_calibrations``.

    Raises
    ------
    simucal.errors.CalibrationError
        A folder with no calibration file, or a bad limits file, in one line naming the file and entry.

    Examples
    --------
    >>> import simucal.api
    >>> report = simucal.api.lot("cals")  # doctest: +SKIP
    >>> report["verdict"][0]  # doctest: +SKIP
    '11 of 12 units pass, 0 fail, 1 flagged'
    """
    if (folder is None) == (store is None):
        raise InputError("lot: give a folder of calibration files or store=URL, one of the two")
    if store is None:
        if any(v is not None for v in (since, until, method, model, station)):
            raise InputError("lot: since, until, method, model and station select a store's records; give store=URL")
        assert folder is not None  # one of the two, refused above otherwise
        return lot_report(folder, limits, *read_folder(folder))
    from simucal.store import CalibrationStore  # SQLAlchemy loads only for a store, not for every command
    st = CalibrationStore(os.fspath(store))
    cals = st.calibrations(since=since, until=until, method=method, model=model, station=station)
    if not cals:
        raise StoreError(f"{st.shown}: no record matches (since {since}, until {until}, method {method}, model "
                         f"{model}, station {station}); Store.records() lists them")
    return lot_report(st.shown, limits, cals, [])


def lot_report(folder: str | os.PathLike[str], limits: str | os.PathLike[str] | None,
               cals: Sequence[tuple[str, Calibration]], others: list[NotCalibration]) -> LotReport:
    """The lot report (module doc) of cals, (name, Calibration) each, read from `folder` (or what names them: a
    store), beside `others`, the folder's files that are not calibrations."""
    dets = {n: determined(c) for n, c in cals}
    latest, earlier, drifts = _by_serial(cals, dets)
    keys = [_group_key(c) for _, c in latest]
    groups = [_group(k, [n for (n, _), kk in zip(latest, keys) if kk == k], dets) for k in dict.fromkeys(keys)]
    known = {u: v[2] for n, c in latest for u, v in _limited(c, dets[n]).items()}
    limits_of = read_limits(limits, known) if limits else {}
    outliers: dict[str, list[NamedOutlier]] = {}  # per unit: its outlying parameters
    for g in groups:
        for p in g["parameters"]:
            for o in p["outliers"]:
                outliers.setdefault(o["unit"], []).append({"name": p["name"], "z": o["z"]})
    units = [_unit(n, c, dets[n], k, limits_of, outliers.get(n, []),
                   [d for d in drifts if d["later"] == n and _drifted(d)])
             for (n, c), k in zip(latest, keys)]
    report: LotReport = {"format": FORMAT, "folder": str(folder), "units": units, "groups": groups,
                         "limits": limits_of, "drift": drifts, "superseded": earlier, "not_calibrations": others,
                         "outlier_p": OUTLIER_P, "drift_p": DRIFT_P, "verdict": [], "next": _next(units, folder)}
    report["verdict"] = verdict_lines(report)
    return report
