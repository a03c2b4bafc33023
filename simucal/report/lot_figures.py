"""A lot's figures per calibration, shared by the lot report (api/lot_reporting.py) and a lab's store
(store/): each block's own parameters with their stds (what limits files written before the one vocabulary
name), the drift between two calibrations of one unit (each entry's change in the std of both, and per sensor the
joint chi^2 of no drift), a limits file and a value outside its limits, and a calibration's model in words."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Mapping, TypedDict

import numpy as np
from numpy.typing import NDArray

from simucal.errors import CalibrationError
from simucal.fit.distributions import chi2_sf
from simucal.fit.results import ALPHA
from simucal.io.calibration import Calibration
from simucal.io.text_files import unique_keys
from simucal.report.vocabulary import Entry, covariance, entries

LIMITS_FORMAT = "simucal.limits/1"
DRIFT_P = ALPHA    # a drift whose joint chi^2 has a smaller p is reported as drifted (the model test's level)
Parameters = dict[str, tuple[float, float, str]]  # {name: (value, std, unit)}


class Limit(TypedDict, total=False):
    """One parameter's spec limits (read_limits), in its unit."""
    min: float
    max: float
    unit: str


class DriftRow(TypedDict):
    """One entry's change between two calibrations of a unit (drift), in its unit."""
    name: str          # sensor.entry, the one vocabulary
    own_name: str | None  # the method's own parameter of it
    unit: str
    drift: float       # later minus earlier
    std: float         # of the change, from both calibrations
    z: float           # drift / std


class DriftTest(TypedDict):
    """A sensor's joint test of no drift: d^T (C_1 + C_2)^+ d against chi^2 on the rank of C_1 + C_2 (drift)."""
    chi2: float
    dof: int
    p_value: float


class SensorDrift(DriftTest):
    """DriftTest with its verdict (the lot report's)."""
    verdict: str       # "drifted" (p below DRIFT_P) or "no drift seen"


class Drift(TypedDict):
    """The drift between two calibrations of one unit (drift): the lot report's and the store's."""
    serial: str | None
    earlier: str | int  # the earlier calibration: its file's name, or its store record's id
    later: str | int
    sensors: dict[str, SensorDrift]
    parameters: list[DriftRow]


class Outlier(TypedDict):
    """A unit whose parameter lies outside its lot's distribution (the lot report's rule)."""
    unit: str          # the unit's file
    value: float
    std: float
    z: float           # (x - median) / sqrt(tau^2 + std^2)


class LotParameter(TypedDict):
    """One parameter's distribution over a group's units, in its unit (the lot report)."""
    name: str          # sensor.parameter, the one vocabulary
    unit: str
    own_name: str | None  # the method's own name of it
    centre: float      # the median
    spread: float
    spread_of_units: float  # tau: the units' own spread beyond their stds
    median_std: float
    values: list[float]  # per unit, in the group's order
    stds: list[float]
    z: list[float]
    outliers: list[Outlier]


class LotGroup(TypedDict, total=False):
    """The units of one method and model, their parameters and the outlier rule."""
    key: str           # method and model
    units: list[str]
    parameters: list[LotParameter]
    outlier_rule: str  # in words
    z_threshold: float | None  # None: not tested (too few units, or no parameter every unit gives)
    not_compared: list[str]  # parameters not every unit's file gives with a std


class UnitTest(TypedDict):
    """A sensor's model test, as the unit's file gives it."""
    verdict: str
    p_value: float | None


class NamedOutlier(TypedDict):
    """One of a unit's outlying parameters."""
    name: str
    z: float


class LotUnit(TypedDict):
    """One unit in the lot report: its tests, limits broken, outliers, status and why."""
    file: str
    serial: str | None
    input: str | list[str]  # the set it was calibrated from (a thermal calibration's: one per plateau)
    group: str
    tests: dict[str, UnitTest]
    outside_limits: dict[str, str]  # {parameter: how it breaks its limit}
    outliers: list[NamedOutlier]
    status: str        # passes, fails or flagged
    why: list[str]


class NotCalibration(TypedDict):
    """A file of the folder that is not a calibration, and why."""
    file: str
    why: str


class LotReport(TypedDict):
    """What `simucal lot -o` writes (simucal.lot/1; api/lot_reporting.py)."""
    format: str
    folder: str
    units: list[LotUnit]
    groups: list[LotGroup]
    limits: dict[str, Limit]
    drift: list[Drift]
    superseded: list[str]  # the earlier calibrations of units calibrated again
    not_calibrations: list[NotCalibration]
    outlier_p: float
    drift_p: float
    verdict: list[str]
    next: str          # the command to run next


def model_name(cal: Calibration) -> str:
    """Each block's model with its effects, in words: "acc acc_baseline + acc.quadratic.z, gyro gyro_baseline
    (thermal)"."""
    return ", ".join(f"{s} {b.model}" + "".join(f" + {e}" for e in sorted(b.effects)) + (" (thermal)" if b.thermal
                                                                                          else "")
                     for s, b in cal.blocks())


def finite(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and bool(np.isfinite(x))


def block_parameters(b) -> Parameters:
    """{param: (value, std, unit)} of a block's parameters that carry a std: its model's, or for an affine
    block (multiposition, handheld) the entries of M (M_xy: output x per input y) and bias (b_x)."""
    if b.params:
        return {n: (float(v), float(b.std[n]), b.param_units.get(n, "")) for n, v in b.params.items()
                if finite(b.std.get(n))}
    M, bias = np.asarray(b.std.get("M", np.nan), float), np.asarray(b.std.get("bias", np.nan), float)
    out: Parameters = {}
    if M.shape == (3, 3):
        out.update({f"M_{r}{c}": (float(b.M[i, j]), float(M[i, j]), "1") for i, r in enumerate("xyz")
                    for j, c in enumerate("xyz") if finite(float(M[i, j]))})
    if bias.shape == (3,):
        out.update({f"b_{a}": (float(b.bias[i]), float(bias[i]), b.bias_unit) for i, a in enumerate("xyz")
                    if finite(float(bias[i]))})
    return out


def own_aliases(cal: Calibration) -> dict[str, str]:
    """{sensor.own: sensor.entry} of each own parameter (block_parameters) that is itself an entry of the one
    vocabulary (the same value in the same unit: the exact method's b_x is bias_x), by which a limits file written
    before the one vocabulary still names it; an own parameter that is not an entry (dK_x: M_xx is 1 + dK_x) has
    none."""
    out = {}
    for s, b in cal.blocks():
        by_own = {e.own_name: e for e in entries(s, b, terms=False) if e.own_name}
        by_own.update({f"b_{e.name[-1]}": e for e in by_own.values() if e.name.startswith("bias_")})
        for n, (v, _, u) in block_parameters(b).items():
            e = by_own.get(n)
            if e is not None and e.name != n and e.unit == u and np.isclose(e.value, v, rtol=1e-12, atol=0.0):
                out[f"{s}.{n}"] = f"{s}.{e.name}"
    return out


def read_limits(path, known: Mapping[str, str], whose: str = "no calibration of the lot") -> dict[str, Limit]:
    """limits.json: {"format": "simucal.limits/1", "limits": {"acc.b_x": {"min": -0.005, "max": 0.005,
    "unit": "g"}, ...}}, min or max or both, in the unit the calibrations give that parameter (known:
    {name: unit} of the lot; whose: what has none of a name that is not in it, as the refusal says it).
    Anything else is refused in one line naming the file and the entry."""
    def bad(where, why):
        return CalibrationError(f"{path}: {where}: {why} (the format: {{\"format\": \"{LIMITS_FORMAT}\", \"limits\": "
                                "{\"acc.b_x\": {\"min\": -0.005, \"max\": 0.005, \"unit\": \"g\"}}})")
    try:
        d = json.loads(Path(path).read_text(), object_pairs_hook=unique_keys)
    except (OSError, UnicodeDecodeError, ValueError, RecursionError) as e:
        raise CalibrationError(f"{path}: not a readable limits file ({str(e)[:120]})") from None
    if not isinstance(d, dict) or d.get("format") != LIMITS_FORMAT or not isinstance(d.get("limits"), dict):
        raise bad("top level", f"expected an object with format {LIMITS_FORMAT!r} and an object 'limits'")
    out: dict[str, Limit] = {}
    for name, lim in d["limits"].items():
        where = f"limits.{name}"
        if name not in known:
            raise bad(where, f"{whose} has this parameter; it has " + ", ".join(sorted(known)[:40]))
        if not isinstance(lim, dict) or set(lim) - {"min", "max", "unit"} or not ({"min", "max"} & set(lim)):
            raise bad(where, "expected an object with min, max or both, and unit")
        if lim.get("unit") != known[name]:
            raise bad(where, f"unit {lim.get('unit')!r}: the calibrations give {name} in {known[name]!r}; "
                             "state that unit")
        for k in ("min", "max"):
            v = lim.get(k)
            if k in lim and (isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v)):
                raise bad(f"{where}.{k}", f"{v!r} is not a finite number")
        if "min" in lim and "max" in lim and lim["min"] > lim["max"]:
            raise bad(where, f"min {lim['min']} is above max {lim['max']}")
        out[name] = Limit(unit=known[name])
        if "min" in lim:
            out[name]["min"] = float(lim["min"])
        if "max" in lim:
            out[name]["max"] = float(lim["max"])
    return out


def outside(value, std, lim) -> str | None:
    """Why a value breaks its limits (with its distance in its own std), or None."""
    for k, sign, word in (("min", -1, "below"), ("max", 1, "above")):
        if k in lim and sign * (value - lim[k]) > 0:
            return (f"{value:.4g} {lim['unit']} {word} its {k} {lim[k]:.4g} {lim['unit']} "
                    f"({abs(value - lim[k]) / std:.2g} std)")
    return None


Determined = dict[str, tuple[list[Entry], NDArray[np.float64]]]  # {sensor: (entries a file determines, covariance)}


def determined(cal: Calibration) -> Determined:
    """Each block's entries of the one vocabulary that the file determines, and their covariance
    (report/vocabulary.covariance, a gyro tied to b with the unification's std of C_b^d): what drift compares,
    worked out once per calibration."""
    phi_std = (cal.unification or {}).get("std_rad")
    return {s: covariance(s, b, phi_std if s == "gyro" else None) for s, b in cal.blocks()}


def drift(name1: str | int, d1: Determined, name2: str | int, d2: Determined, serial: str | None) -> Drift:
    """The later calibration (d2: its determined) minus the earlier (d1) per entry of the one vocabulary
    (report/vocabulary.py: M, bias and effects) with its std from both, and per sensor the joint chi^2 of no
    drift on the rank of C_1 + C_2 (the entries a model ties together count once); serial: the unit's."""
    sensors: dict[str, SensorDrift] = {}
    rows: list[DriftRow] = []
    for s, (e2, C2) in d2.items():
        if s not in d1:
            continue
        e1, C1 = d1[s]
        at1 = {e.name: i for i, e in enumerate(e1)}
        both = [(at1[e.name], j) for j, e in enumerate(e2) if e.name in at1 and e.unit == e1[at1[e.name]].unit]
        if not both:
            continue
        i1, i2 = [i for i, _ in both], [j for _, j in both]
        d = np.array([e2[j].value - e1[i].value for i, j in both])
        C = C1[np.ix_(i1, i1)] + C2[np.ix_(i2, i2)]
        std = np.sqrt(np.diag(C))
        rows += [{"name": f"{s}.{e2[j].name}", "own_name": e2[j].own_name, "unit": e2[j].unit, "drift": float(d[k]),
                  "std": float(std[k]), "z": float(d[k] / std[k])} for k, j in enumerate(i2)]
        w, V = np.linalg.eigh(C / np.outer(std, std))  # the correlations: free of the entries' scales
        kept = w > 1e-9 * w.max()  # the directions the files determine: their count is the dof
        dof = int(kept.sum())
        chi2 = float(np.sum((V[:, kept].T @ (d / std)) ** 2 / w[kept]))
        p = chi2_sf(chi2, dof)
        sensors[s] = {"chi2": chi2, "dof": dof, "p_value": p,
                      "verdict": "drifted" if p < DRIFT_P else "no drift seen"}
    return {"serial": serial, "earlier": name1, "later": name2, "sensors": sensors, "parameters": rows}
