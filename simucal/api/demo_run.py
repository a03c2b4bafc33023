"""`simucal demo` (api/tools.demo): the product's loop on built-in simulated data, then the paper's comparison.

The loop: simulate a turntable test with a hidden effect (written only to
truth.json), calibrate with the baseline model (it fails, and says what to
add), diagnose (which effect is missing), calibrate with it, apply both
calibrations to the raw outputs, and show the error falling; then validate both on
another recording of the same unit (a set they were not made from). Then the same
unit over temperature (three wandering plateaus simulated as `simulate --temperature-c` does,
`calibrate --thermal`, validated between them against one plateau's calibration) and the noise of a still recording
(Allan deviation, IEEE 952 terms); then dong2018's section 4 test by the three methods, the
audit, and the diagnosis report.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Mapping, TypedDict, cast

import numpy as np

from simucal.errors import CalibrationError, InputError
from simucal import derive_cmd, io, methods
from simucal.api.calibrating import calibrate_set, calibrate_thermal
from simucal.api.diagnosing import diagnosis_report
from simucal.fit.apply import apply
from simucal.io import calibration, outputs
from simucal.options import CalibrateOptions, Method
from simucal.report import markdown as report
from simucal.report.html import render
from simucal.turntable.simulate import SCENARIOS, Scenario, plant, write

HIDDEN = {"acc.quadratic.z": 2e-4}  # g/g^2: a z accelerometer second-order nonlinearity
SETS = ("loop", "loop_applied", "loop_other", "thermal_0", "thermal_25", "thermal_50", "thermal_35", "still",
        "paper")  # the measurement sets it writes under its folder
MARKER = "demo.json"  # written last: the folder is a demo's, and a later demo may replace its sets


def _rest_error(cal: calibration.Calibration, folder: Path) -> float:
    """rms of |f| - 1 g over the static rows after applying cal (g)."""
    _, samples, segments = apply(cal, folder)
    static = np.isin(samples["segment"], [s.segment for s in segments if s.kind == "static"])
    f = np.column_stack([samples[c] for c in ("ax", "ay", "az")])[static]
    return float(np.sqrt(np.mean((np.linalg.norm(f, axis=1) - 1.0) ** 2)))


class DemoRecord(TypedDict, total=False):
    """The demo's record (demo.json): the loop's figures, in the sensors' units."""
    found: str                       # the hidden effect diagnose found
    rest_error_before: float         # |f| - 1 g at rest, rms, g: the baseline's and with the effect
    rest_error_after: float
    validation: dict[str, float]     # each calibration's first acc check on another recording, rms, g
    thermal: dict[str, tuple[float, float]]  # per sensor: the thermal and the 25 degC calibration's at 35 degC


def loop(out: Path, seed: int, echo: Callable[[str], Any]) -> DemoRecord:
    sc = SCENARIOS["paper"]()
    sc.plan, sc.acc_effects = "fibonacci48", dict(HIDDEN)
    data = out / "loop"
    truth = write(data, sc, seed)
    echo(f"1 simulate: {data} (fibonacci48 plan; a hidden effect is in {data / 'truth.json'} only)")
    base = calibrate_set(data)
    assert base.acc is not None  # the demo's set has an accelerometer
    calibration.save(out / "loop_calibration_baseline.json", base)
    echo(f"2 calibrate (baseline model): acc chi2 {base.acc.chi2:.1f} on {base.acc.dof} dof, "
         f"p = {base.acc.p_value:.2g}; advice: add {base.acc.details['advice']}")
    diag = diagnosis_report(data)
    outputs.write_text(out / "loop_diagnosis.json", json.dumps(diag, indent=1, default=float) + "\n")
    outputs.write_text(out / "loop_diagnosis.html", render(diag))
    found = [c["id"] for c in diag["acc"]["candidates"] if c.get("significant")][:1]
    echo(f"3 diagnose: {diag['acc']['verdict']}")
    if not found:
        raise CalibrationError("the demo's hidden effect was not found: " + diag["acc"]["verdict"])
    fixed = calibrate_set(data, CalibrateOptions(add=tuple(found)))
    assert fixed.acc is not None
    calibration.save(out / "loop_calibration_added.json", fixed)
    e = fixed.acc.effects[found[0]]
    echo(f"4 calibrate --add {found[0]}: acc chi2 {fixed.acc.chi2:.1f} on {fixed.acc.dof} dof, "
         f"p = {fixed.acc.p_value:.2g}; {found[0]} = {e.value:.4g} +- {e.std:.2g} {e.unit} "
         f"(truth {truth['acc']['params'][found[0]]:.4g})")
    err0, err1 = _rest_error(base, data), _rest_error(fixed, data)
    meta, samples, segments = apply(fixed, data)
    io.write_set(out / "loop_applied", meta, samples, segments)
    rows = [("|f| - 1 g at rest, rms (g)", err0, err1)]
    for k in ("dK_z", "b_z", "dK_x"):
        t = truth["acc"]["params"][k]
        rows.append((f"{k} error", base.acc.params[k] - t, fixed.acc.params[k] - t))
    echo(f"5 apply: {out / 'loop_applied'}; the error falls (noise of one row {sc.acc_noise_g:.1g} g):")
    echo(f"   {'':28} {'baseline':>11} {'with ' + found[0]:>24}")
    for label, a, b in rows:
        echo(f"   {label:28} {a:11.3g} {b:24.3g}")
    other = _validate(out, sc, seed, echo)
    return {"found": found[0], "rest_error_before": err0, "rest_error_after": err1, "validation": other}


def _validate(out: Path, sc: Scenario, seed: int, echo: Callable[[str], Any]) -> dict[str, float]:
    """Step 6: both calibrations on another recording of the same unit (the Table 1 plan, raw rows)."""
    from simucal.api.validating import html_page, validation_report
    sc.plan, sc.rate_hz, sc.static_s = "table1", 20.0, 5.0  # meta.json states the table (simulate's default)
    write(out / "loop_other", sc, seed + 1)
    reps = {name: validation_report(out / f"loop_calibration_{name}.json", out / "loop_other")
            for name in ("baseline", "added")}
    for name, rep in reps.items():
        outputs.write_text(out / f"loop_validation_{name}.json", json.dumps(rep, indent=1) + "\n")
        outputs.write_text(out / f"loop_validation_{name}.html", html_page(rep))
    echo(f"6 validate on {out / 'loop_other'} (the same unit, another plan, raw rows; data neither fit saw):")
    checks = reps["baseline"]["checks"]["acc"]
    w = max(len(_label(c)) for c in checks)
    echo(f"   {'':{w}} {'nominal':>9} {'baseline':>9} {'added':>9} {'floor':>9}")
    for c, a in zip(checks, reps["added"]["checks"]["acc"]):
        fl = "-" if c["floor_rms"] is None else f"{c['floor_rms']:.3g}"
        echo(f"   {_label(c):{w}} {c['before_rms']:9.3g} {c['after_rms']:9.3g} {a['after_rms']:9.3g} {fl:>9}  "
             f"{c['unit']}")
    echo("   verdict against the nominal scale factors: "
         + "; ".join(f"{n} {r['verdict']['acc']}" for n, r in reps.items()))
    return {n: r["checks"]["acc"][0]["after_rms"] for n, r in reps.items()}


def _label(check: Mapping[str, Any]) -> str:
    """A validation check's name for a table row, whole: its text up to the first comma or the floor's note."""
    what: str = check["what"]
    return what.split(" (floor")[0].split(",")[0]


THERMAL = {"acc.bias_temperature.x": 1e-5, "acc.bias_temperature2.x": 1e-7, "acc.scale_temperature.z": 1e-5,
           "gyro.bias_temperature.z": 0.01, "gyro.scale_temperature.x": 2e-6}


def thermal(out: Path, seed: int, echo: Callable[[str], Any]) -> dict[str, tuple[float, float]]:
    """The unit over temperature: plateaus at 0, 25 and 50 degC that wander +-0.3 degC, simulated as
    `simulate --temperature-c T --t-ref-c 25 --temperature-wander-c 0.3` does and calibrated with
    --thermal (one fit, every row at its own temperature); it and the 25 degC plateau's calibration
    validated at 35 degC on another plan; the page with the verdicts and the validation."""
    from simucal.report.thermal_html import thermal_page
    from simucal.turntable.simulate import at_temperature
    from simucal.api.validating import validation_report

    def plateau(T: int, k: int, plan: str = "fibonacci48") -> Path:
        sc = SCENARIOS["paper"]()
        sc.plan = plan
        at_temperature(sc, str(T), t_ref_c=25.0, wander_c=0.3)
        plant(sc, [f"{e}={v}" for e, v in THERMAL.items()])
        write(out / f"thermal_{T}", sc, seed + k)
        return out / f"thermal_{T}"
    sets = [plateau(T, k) for k, T in enumerate((0, 25, 50))]
    cal = calibrate_thermal(sets, CalibrateOptions(t_ref_c=25.0))
    assert cal.acc is not None and cal.gyro is not None  # the plateaus hold both sensors
    calibration.save(out / "thermal_calibration.json", cal)
    calibration.save(out / "thermal_calibration_25.json", calibrate_set(sets[1]))
    moving = [f"{s}.{n} degree {f['degree']}" for s in ("acc", "gyro")
              for n, f in getattr(cal, s).thermal["parameters"].items() if f["degree"]]
    echo(f"7 simulate --temperature-c T --t-ref-c 25 --temperature-wander-c 0.3 (T = 0, 25, 50); calibrate "
         f"{' '.join(p.name for p in sets)} --thermal: joint test acc p = {cal.acc.p_value:.2g}, gyro p = "
         f"{cal.gyro.p_value:.2g}; following temperature: {', '.join(moving)} (planted: {', '.join(THERMAL)})")
    other = plateau(35, 7, "table1")
    reps = {n: validation_report(out / f"thermal_calibration{n}.json", other) for n in ("", "_25")}
    outputs.write_text(out / "thermal.html", thermal_page(cal, [reps[""]], str(out / "thermal_calibration.json")))
    w = max(len(_label(reps[""]["checks"][s][0])) for s in ("acc", "gyro"))
    echo(f"   validate at 35 degC ({other}):")
    echo(f"   {'':{w}} {'thermal':>9} {'25 degC only':>13} {'floor':>9}")
    for s in ("acc", "gyro"):
        a, b = reps[""]["checks"][s][0], reps["_25"]["checks"][s][0]
        echo(f"   {_label(a):{w}} {a['after_rms']:9.3g} {b['after_rms']:13.3g} {a['floor_rms']:9.3g} {a['unit']}")
    return {s: (reps[""]["checks"][s][0]["after_rms"], reps["_25"]["checks"][s][0]["after_rms"])
            for s in ("acc", "gyro")}


def noise(out: Path, seed: int, echo: Callable[[str], Any]) -> None:
    """The noise of a still recording: Allan deviation and the IEEE 952 terms, with the plot."""
    from simucal.fit.allan_noise import characterise
    from simucal.handheld.simulate import write_still
    from simucal.report.noise_html import noise_page
    write_still(out / "still", seconds=600.0, seed=seed)
    rep = characterise(still := io.read_set(out / "still"), methods.kind_of(still))
    outputs.write_text(out / "noise.json", json.dumps(rep, indent=1) + "\n")
    outputs.write_text(out / "noise.html", noise_page(rep))
    g, a = rep["gyro"]["axes"]["x"]["sheet"]["N"], rep["acc"]["axes"]["x"]["sheet"]["N"]
    echo(f"8 noise of a still recording ({out / 'still'}, 10 min at 100 Hz): x gyro ARW {g['value']:.3g} +- "
         f"{g['std']:.2g} {g['unit']} (simulated 0.1), x acc VRW {a['value']:.3g} +- {a['std']:.2g} {a['unit']} "
         f"(simulated 50); Allan plot {out / 'noise.html'}")


def paper(out: Path, seed: int, echo: Callable[[str], Any]) -> None:
    from simucal.report.paper_claims import full_audit
    write(out / "paper", SCENARIOS["paper"](), seed)
    echo(f"simulate: {out / 'paper'} (dong2018 section 4 settings, seed {seed})")
    results = {}
    for method in methods.for_any_plan(methods.TURNTABLE):
        results[method] = calibrate_set(out / "paper", CalibrateOptions(method=cast(Method, method)))
        calibration.save(out / f"calibration_{method}.json", results[method])
    echo("calibrate: " + ", ".join(f"calibration_{m}.json" for m in results))
    audit_report = full_audit(seeds=8)
    outputs.write_text(out / "audit.md", audit_report.markdown())
    echo(f"audit: {out / 'audit.md'}: {audit_report.summary()}")
    truth = json.loads((out / "paper" / "truth.json").read_text())
    text = report.compare_table(results, truth)
    outputs.write_text(out / "report.md", text)
    echo(text)
    diag = diagnosis_report(out / "paper")
    outputs.write_text(out / "diagnosis.json", json.dumps(diag, indent=1, default=float) + "\n")
    outputs.write_text(out / "diagnosis.html", render(diag))
    echo(f"diagnose: {out / 'diagnosis.html'}: {diag['verdict']}")


def run(out_dir: str | os.PathLike[str], seed: int, echo: Callable[[str], Any]) -> DemoRecord:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stale, secs, diff = derive_cmd.run(check=True)
    if stale:
        raise InputError(diff + "generated/ is stale; run `simucal derive`. Differs: " + ", ".join(stale))
    echo(f"derive: generated/ matches the derivation ({secs:.1f} s)")
    echo("== the loop: a hidden effect found, added, calibrated with, applied, validated ==")
    result = loop(out, seed, echo)
    echo("== the same unit over temperature, and its noise ==")
    result["thermal"] = thermal(out, seed, echo)
    noise(out, seed, echo)
    echo("== dong2018 section 4: exact, linear and multi-position methods ==")
    paper(out, seed, echo)
    outputs.write_text(out / MARKER, json.dumps(result, indent=1) + "\n")
    return result
