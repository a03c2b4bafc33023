"""dong2018's numeric claims (abstract, section 4, conclusions, Tables 3 and 4) against a
Monte Carlo of its stated settings (simulate.Scenario's defaults are section 4).

Each claim becomes one row: the claim, the measured value (over `seeds` simulated
tests), and whether it holds. Each printed Table 3 and Table 4 entry is compared with
the Monte Carlo distribution of its method: reproducible when it lies within 3 std of
the Monte Carlo mean. "norm observation" is the paper's own method as printed
(--method linear: eq. 8/12 and 25-27); the exact method is shown beside it.
"""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, TypedDict

import numpy as np

from simucal import io, methods
from simucal.options import CalibrateOptions
from simucal.io import units
from simucal.report import markdown as report
from simucal.turntable.simulate import ARCMIN, ARCSEC, Scenario, write

if TYPE_CHECKING:  # derive/ loads for the audit alone
    from simucal.derive.audit import Report

# Table 3 as printed (norm observation, previous method), in report.ENTRIES order.
PAPER_T3 = {
    "linear": [0.002, -0.001494, -0.001492, -0.3363, 0.1664, -0.0509, 0.000094, 0.000082, 0.000211,
               0.000003, -0.000585, 0.000597, 0.00194, 0.00802, 0.00601, 0.000795, -0.00101, -0.003182,
               0.000099, 0.000062, 0.000161],
    "multiposition": [0.00195, -0.001463, -0.001484, -0.2912, 0.2527, 0.0770, -0.001320, -0.000414, 0.001626,
                      -0.003502, -0.000017, 0.004044, 0.00192, 0.00805, 0.00600, 0.000797, -0.00093,
                      -0.003275, 0.001538, 0.000670, 0.003689],
}
# Table 4 as printed: calibration errors at angular position errors 1", 1', 10', 1 deg, 10 deg.
PAPER_T4 = {("dK_x^a", "linear"): [5.72e-5, 5.72e-5, 5.72e-5, 5.72e-5, 5.53e-5],
            ("dK_x^a", "multiposition"): [2.86e-5, 8.27e-5, 5.736e-4, 3.4293e-3, 0.0478571],
            ("b_y^g deg/h", "linear"): [3.5948e-3, 3.5805e-3, 3.4497e-3, 3.7272e-3, -4.2393e-3],
            ("b_y^g deg/h", "multiposition"): [-0.0392233, -0.0827004, -0.0932480, -3.5974274, -1.8023093]}
LEVELS = [("1\"", ARCSEC), ("1'", ARCMIN), ("10'", 10 * ARCMIN), ("1 deg", 60 * ARCMIN), ("10 deg", 600 * ARCMIN)]
METHODS = methods.for_any_plan(methods.TURNTABLE)  # exact, linear, multiposition


class Section4Values(TypedDict):
    """The section-4 values derive.audit_terms substitutes (section4_values), from a Scenario."""
    acc: dict[str, float]             # the accelerometer model's parameters by name (the model's units)
    gyro: dict[str, float]            # the gyro model's
    theta4: list[float]               # C_b^k's angles, rad
    lambda4: list[float]              # C_d^k's angles, rad
    tilt: list[float]                 # the table's errors, rad: the outer axis's tilt, ...
    nonperp: list[float]              # ... its axes' non-perpendicularities ...
    zero: list[float]                 # ... and their zero errors
    w_T_dph: float                    # the outer axis's rate, deg/h
    w_e_dph: float                    # the Earth rate, deg/h
    latitude_deg: float               # the test site's, deg


def section4_values(sc: Scenario | None = None) -> Section4Values:
    """The section-4 values for derive.audit_terms: both models' parameters, the mountings, the
    table's errors (no random position errors), the rates and the latitude."""
    sc = sc or Scenario()
    return {"acc": dict(sc.acc_params), "gyro": dict(sc.gyro_params), "theta4": list(sc.theta4_rad),
            "lambda4": list(sc.lambda4_rad), "tilt": list(sc.tilt_rad), "nonperp": list(sc.nonperp_rad),
            "zero": list(sc.zero_rad), "w_T_dph": sc.outer_rate_dps[0] * units.DPH_PER_DPS,
            "w_e_dph": units.DEFAULT_EARTH_RATE_DPH, "latitude_deg": sc.latitude_deg}


def monte_carlo(sc: Scenario, seeds: int, names=METHODS, progress=None):
    """(truth entries, {method: (seeds, entries) array}) over simulated tests of scenario sc."""
    est: dict[str, list[np.ndarray]] = {m: [] for m in names}
    truth = None
    with tempfile.TemporaryDirectory() as tmp:
        for seed in (progress(range(seeds)) if progress else range(seeds)):
            folder = Path(tmp) / str(seed)
            truth = report.entries(write(folder, sc, seed))
            for m in names:
                est[m].append(report.entries(methods.METHODS[m].run(io.read_set(folder), CalibrateOptions())))
    return np.array(truth), {m: np.array(v) for m, v in est.items()}


def _holds(ok: bool) -> str:
    return "agrees" if ok else "claim not supported"


def _index(label):
    return [e[0] for e in report.ENTRIES].index(label)


class Claim(TypedDict):
    """One claim of the paper and what the Monte Carlo measures of it (claims)."""
    source: str                       # where in the paper
    claim: str
    measured: str
    holds: str                        # in words


def claims(seeds=20, progress=None) -> list[Claim]:
    """One row per claim: source, claim, measured, holds."""
    rows: list[Claim] = []
    truth, est = monte_carlo(Scenario(), seeds, progress=progress)
    err = {m: est[m] - truth for m in est}
    labels = [e[0] for e in report.ENTRIES]
    groups = {"scale": [i for i, lab in enumerate(labels) if lab.startswith("dK")],
              "mounting": [i for i, lab in enumerate(labels) if lab.startswith(("m_", "theta"))],
              "acc bias": [i for i, lab in enumerate(labels) if lab.startswith("b_") and lab.endswith("g")
                           and "^a" in lab],
              "gyro bias": [i for i, lab in enumerate(labels) if lab.startswith("b_") and "^g" in lab]}

    def worst(m, group, q=95):
        return float(np.percentile(np.abs(err[m][:, groups[group]]).max(axis=1), q))

    def rms(m, group):
        return float(np.sqrt(np.mean(err[m][:, groups[group]] ** 2)))
    for m in ("linear", "exact"):
        name = "paper's method (eq. 8/12, 25-27)" if m == "linear" else "exact method (simucal)"
        for group, limit, unit in (("scale", 1e-5, ""), ("mounting", 1e-5, " rad"), ("acc bias", 1e-5, " g"),
                                   ("gyro bias", 0.01, " deg/h")):
            w = worst(m, group)
            rows.append({"source": "abstract", "claim": f"{group} errors < {limit:g}{unit} at <= 1' position errors "
                                                        f"({name}; 95th percentile of the largest)",
                         "measured": f"{w:.3g}{unit} (rms {rms(m, group):.2g})", "holds": _holds(w < limit)})
    for group in ("mounting", "gyro bias"):
        a = float(np.sqrt(np.mean(err["linear"][:, groups[group]] ** 2)))
        b = float(np.sqrt(np.mean(err["multiposition"][:, groups[group]] ** 2)))
        rows.append({"source": "section 4, Table 3", "claim": f"norm observation beats the previous method on {group}",
                     "measured": f"rms error {a:.3g} vs {b:.3g}", "holds": _holds(a < b)})
    for m in ("linear", "multiposition"):
        mean, sd = est[m].mean(0), est[m].std(0, ddof=1)
        z = (np.array(PAPER_T3[m]) - mean) / np.maximum(sd, 1e-300)
        bad = [f"{labels[i]} ({z[i]:+.0f} std)" for i in np.argsort(-np.abs(z)) if abs(z[i]) > 3]
        rows.append({"source": "Table 3",
                     "claim": f"every printed {'norm observation' if m == 'linear' else 'previous method'} "
                                                   "entry is reproducible (within 3 std of the Monte Carlo)",
                     "measured": f"{len(labels) - len(bad)} of {len(labels)} within 3 std"
                                 + (f"; not: {', '.join(bad[:6])}" + (" ..." if len(bad) > 6 else "") if bad else ""),
                     "holds": _holds(not bad)})
    # Table 4: errors against the position error
    t4: dict[tuple[str, str], list[np.ndarray]] = {}  # (entry, method): per level, the errors over seeds
    for name, level in LEVELS:
        tr, e4 = monte_carlo(Scenario(position_error_rad=level), seeds, ("linear", "multiposition"))
        for key in PAPER_T4:
            i = _index(key[0])
            t4.setdefault(key, []).append(e4[key[1]][:, i] - tr[i])
    for key, printed in PAPER_T4.items():
        errs = np.array(t4[key])  # (levels, seeds)
        for (lv, _), p, e in zip(LEVELS, printed, errs):
            z = (p - e.mean()) / e.std(ddof=1)
            rows.append({"source": "Table 4",
                         "claim": f"{key[0]}, {'norm observation' if key[1] == 'linear' else 'previous'}"
                                                       f", position errors {lv}: printed error {p:.3g}",
                         "measured": f"{e.mean():+.3g} +- {e.std(ddof=1):.2g} (z = {z:+.1f})",
                         "holds": "reproducible" if abs(z) <= 3 else "not reproducible"})
    for key in PAPER_T4:
        rms_at = np.sqrt(np.mean(np.array(t4[key]) ** 2, axis=1))  # per level (the function rms is Table 3's)
        if key[1] == "linear":
            ratio = rms_at[3] / rms_at[0]
            rows.append({"source": "section 4", "claim": f"norm observation: {key[0]} error does not change noticeably "
                                                         "up to 1 deg position errors",
                         "measured": f"rms at 1 deg / at 1\" = {ratio:.3g}", "holds": _holds(ratio < 1.5)})
        else:
            grows = bool(np.all(np.diff(rms_at[:4]) > 0))
            rows.append({"source": "section 4",
                         "claim": f"previous method: {key[0]} error grows with the position error",
                         "measured": "rms " + ", ".join(f"{r:.2g}" for r in rms_at), "holds": _holds(grows)})
    return rows


def full_audit(seeds: int = 20, progress: Callable[[Iterable[Any]], Iterable[Any]] | None = None) -> Report:
    """derive.audit's report with the term-by-term check at the section-4 values and, for seeds > 0,
    the claims' Monte Carlo (progress: wraps an iterable, e.g. tqdm)."""
    from simucal.derive.audit import run_audit
    from simucal.progress import status
    status("audit: the paper's equations 4-27 and Table 1 against the derivation, term by term")
    rep = run_audit(progress=progress, values=section4_values())
    if seeds > 0:
        status(f"audit: the numeric claims against a Monte Carlo of {seeds} simulated tests per setting")
        rep.claims = claims(seeds, progress)
    return rep
