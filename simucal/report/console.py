"""A calibration on the console: one line per fact, the failures loud (`simucal calibrate`,
`simucal field-drift`); a diagnosis's one next command (`simucal diagnose`, its page); a noise report's terms,
verdicts and next step (`simucal noise`, its page)."""
from __future__ import annotations


from simucal.fit import allan_fit, allan_terms, family
from simucal.fit.candidates import undecided_twins
from simucal.fit.results import DiagnosisReport, diagnosis_blocks
from simucal.fit.validation import ValidationReport
from simucal.io import SENSOR_COLS
from simucal.io.calibration import ALPHA, Calibration, SensorBlock
from simucal.io.details import SensorDetails
from simucal.report.kalibr import kalibr_missing


def n_units(n: int) -> str:
    """'1 unit', '2 units': a count of units in words."""
    return f"{n} unit" + "s" * (n != 1)


def skipped_sensors(present) -> list[str]:
    """A line for each sensor not among `present`: the spec lets a set record one kind of sensor only, so a
    command that works on the other alone says what it left out (calibrate, diagnose, validate, noise)."""
    return [f"{s}: skipped (the data have no {' '.join(cols)} columns)" for s, cols in SENSOR_COLS.items()
            if s not in present]


def calibration_lines(cal: Calibration, units: str = "spec"):
    """Each line of the calibration on the console (_lines), in the unit system asked (report/units.py)."""
    if units == "spec":
        return list(_lines(cal))
    from simucal.report import units as shown
    g = shown.gravity_of(cal.input)
    return shown.lines_in(_lines(shown.calibration_in(cal, units, g)), units, g)


def _lines(cal: Calibration):
    """Per sensor its test and effects (and what to add when the model fails), then the frames'
    unification, the consistency checks, what the plan leaves undetermined, and the warnings."""
    stamps = cal.details.get("timestamps")
    if stamps and (stamps["irregular"] or stamps.get("gaps") or not stamps["chosen_by"].startswith("auto")):
        yield stamps["text"]
    zero = cal.details.get("systematic", {}).get("zero_position")
    if zero:
        yield zero["text"]
    for s in ("acc", "gyro"):
        out = [x["segment"] for x in cal.details.get("excluded_segments", []) if x["sensor"] == s]
        if out:
            yield (f"{s}: {len(out)} segments left out, their samples clipped (at full_scale or repeating the rail): "
                   f"{out[:10]}{' ...' if len(out) > 10 else ''}")
        b = getattr(cal, s)
        if b is None or b.nominal:
            continue
        if b.thermal is not None:
            yield from _thermal_lines(s, b)
        elif b.residual_rms is None:  # a method without a fit of its own rows (field: the drift alone)
            yield (f"{s}: bias ({b.bias_unit}, {b.description}): " + ", ".join(
                f"{a} {v:+.4g} +- {e:.2g}" for a, v, e in zip("xyz", b.bias, b.std["bias"])))
        else:
            yield from _fit_lines(s, b, cal.input)
    u = cal.unification
    if u and "std_rad" in u:
        means = (u.get("noise") or {}).get("acc_rate_run_means")
        yield (f"frames: C_b^d by {u['method'].replace('_', ' ')} ({u['pairs']} pairs), std "
               f"{max(u['std_rad']):.2g} rad, residual {u['direction_residual_rms_rad']:.2g} rad rms"
               + (f"; noise of the acc rate run means: {means['text']}" if means else "")
               + (f"; cross-check: {u['cross_check']['note']}" if "cross_check" in u else "")
               + (f"; {u['note']}" if u.get("note") else ""))
    yield from cal.details.get("consistency", {}).get("lines", [])
    for s, b in cal.blocks():
        yield from _determination_lines(s, b)
    for sensor, why in cal.not_calibrated.items():
        yield f"{sensor}: NOT CALIBRATED: {why}"
    yield from skipped_sensors([*cal.sensors, *cal.not_calibrated])  # the layout is the data's sensors
    for line in cal.warnings:
        yield f"WARNING: {line}"


def _test_text(b: SensorBlock) -> str:
    d = b.details
    rows = f" over {d['rows']}" if d.get("rows") else ""
    if b.dof == 0 and "warmup" in (b.thermal or {}):  # a warm-up's holds: no power beyond the degree to test
        return "no test possible (each axis's degree is as high as its temperatures allow: hold a third temperature)"
    if b.chi2 is not None and b.p_value is None:  # as many rows as parameters: the fit passes through them all
        return (f"chi2 {b.chi2:.2g}, dof {b.dof}{rows}: no test possible (as many rows as parameters; add positions "
                "or poses to test the model)")
    if b.chi2 is not None:
        return f"chi2 {b.chi2:.1f}, dof {b.dof}{rows}, p = {b.p_value:.3g}"
    if b.p_value is not None:
        return f"p = {b.p_value:.3g} ({d.get('test', '')}{rows})"
    return "no test (" + d.get("test", "no noise estimate") + ")"


def _fit_lines(s, b: SensorBlock, source):
    """A fitted block: residual and test, effects, held-out error, noise, and what a failure means."""
    d = b.details
    eff = "".join(f"; {e} = {v.value:.4g} +- {v.std:.2g} {v.unit}" for e, v in b.effects.items())
    cv = d.get("cross_validation")
    held = (f"; |u| - rho {cv['in_sample_rms']:.3g} {cv['unit']} rms on the fit's rows, {cv['held_out_rms']:.3g} "
            f"on rows left out ({cv['rows']} rows, one at a time)" if cv and cv.get("held_out_rms") else "")
    yield f"{s}: residual rms {b.residual_rms:.3g} {b.residual_unit or b.bias_unit}; {_test_text(b)}{eff}{held}"
    if (d.get("noise") or {}).get("text"):
        yield f"{s}: noise {d['noise']['text']}"
    if (d.get("static_rows") or {}).get("p_value") is not None:  # the gyro's rows at rest, in its model test
        yield f"{s}: at rest: {d['static_rows']['verdict']}"
    if d.get("noise_warning"):
        yield f"{s}: WARNING: {d['noise_warning']}"
    if d.get("tilt_note"):
        yield f"{s}: {d['tilt_note']}"
    if d.get("saturation"):
        yield (f"{s}: saturated (clipped) samples: " + ", ".join(
            f"{x['count']} on {x['axis']} from line {x['first_row'] + 2} of samples.csv" for x in d["saturation"]))
    if d.get("moves_skipped"):
        why = sorted({m["reason"] for m in d["moves_skipped"]})
        yield (f"{s}: {len(d['moves_skipped'])} of {d['moves_used'] + len(d['moves_skipped'])} moves left out "
               f"({'; '.join(why)})")
    if d.get("model_choice"):
        yield (f"{s}: T chosen by the moves left out one at a time: " + ", ".join(
            f"{k} {v['held_out_rms_deg']:.3g} deg" for k, v in d["model_choice"].items())
            + f" rms; {d['gyro_model']} taken (the best predictor of the moves left out)")
    if "auto" in d:
        yield (f"{s}: --add auto chose " + (", ".join(x["id"] for x in d["auto"]) + " (one at a time, each passing "
               "the candidate test and predicting the data left out better)" if d["auto"] else "nothing")
               + (f"; {d['auto_stopped']}" if d.get("auto_stopped") else ""))
        for x in d["auto"]:
            if x.get("twin_choice"):
                yield f"{s}: --add auto chose {x['twin_choice']}"
    if b.verdict == "fails":
        what = d.get("advice")
        stds = ("stds are inflated by sqrt(chi2/dof) (std_raw keeps the unscaled ones)" if "std_raw" in d else
                d["std_note"] if d.get("std_note")
                else f"stds include a model-error std {d['model_error_std_g']:.2g} g "
                "per pose" if d.get("model_error_std_g") else "stds assume the model is right")
        yield (f"{s}: THE MODEL FAILS (p = {b.p_value:.2g} < {ALPHA:.0e}): ".replace("e-0", "e-")
               + ("the stated noise may be too small (the warning above); " if d.get("noise_too_small") else "")
               + (f"{what}; " if what and what.startswith("no library effect") else
                  f"diagnose would add {what}{_twins_said(d, what)}; " if what
                  else "the rows at rest misfit (above) by a term the rate runs "
                  "cannot see; " if (d.get("static_rows") or {}).get("p_value", 1.0) < ALPHA else
                  f"see simucal diagnose {source} for what is missing; ")
               + stds)


def _twins_said(d: SensorDetails, what: str) -> str:
    """' (or its twin X: ...)' where the model test's targeted tests name twins of the effect advised."""
    t = d.get("targeted") or {}
    return (f" (or its twin {', '.join(t['twins'])}: these data cannot tell them apart)"
            if t.get("strongest") == what and t.get("twins") else "")


def _determination_lines(s, b: SensorBlock):
    """Parameters the data do not determine (held under a prior) or determine poorly (confounded)."""
    und = b.details.get("undetermined") or {}
    if und:
        alone = [v["std_moves_alone"] for v in und.values() if "std_moves_alone" in v]
        first = next(iter(und.values()))
        yield (f"{s}: {', '.join(und)} not determined by these data"
               + (f" (std alone {max(alone):.2g})" if alone else "")
               + f": estimated under a soft prior {first['held_at']:g} +- {first['prior_std']:g} (a prior, not a "
               "measurement: the estimate may leave it; \"determined\": false in the file); "
               "to determine them, " + "; ".join(sorted({v["to_determine"] for v in und.values()})))
    poor = b.details.get("poorly_determined") or {}
    if poor:
        unit = {k: "" if u == "1" else f" {u}" for k, u in b.param_units.items()}
        yield (f"{s}: POORLY DETERMINED by this plan: " + ", ".join(
            f"{k} (std {v['std']:.2g}{unit.get(k, '')}, {v['inflation']:.0f}x an uncorrelated design's)"
            for k, v in sorted(poor.items(), key=lambda kv: -kv[1]["inflation"]))
            + "; they are nearly confounded with other parameters: add positions with other input directions "
            "(simucal plan --score PLAN shows the correlations)")


def _p(x) -> str:
    return "-" if x is None else f"{x:.2g}"


def _where(th, b: SensorBlock) -> str:
    """The plateaus' or a ramp's bands' temperatures and T_ref, in words."""
    return (f"{len(th['plateaus_c'])} " + ("plateaus" if b.details.get("plateaus", True) else "bands of a ramp")
            + " at " + ", ".join(f"{t:.4g}" for t in th["plateaus_c"]) + f" degC, T_ref {th['t_ref_c']:.4g} degC"
            + (f"; {th['rows']}" if th.get("rows") else ""))


def _thermal_lines(s, b: SensorBlock):
    """A thermal block: the joint model test (whole fit and each plateau or band, beside each plateau
    alone), then every parameter that follows temperature."""
    th = b.thermal
    assert th is not None  # a thermal block (the caller asks)
    groups = b.details.get("groups")
    if "warmup" in th:
        yield (f"{s}: a still warm-up ({th['warmup']}, {th['temperature_range_c'][0]:.4g} to "
               f"{th['temperature_range_c'][1]:.4g} degC, T_ref {th['t_ref_c']:.4g} degC): what is left against "
               f"temperature, per axis p = " + ", ".join(_p(th["parameters"][f"b_{a}"]["p_value"]) for a in "xyz")
               + ("; THE MODEL FAILS" if b.verdict == "fails" else ""))
    elif groups is None:
        plateaus = b.details["plateaus"]
        assert isinstance(plateaus, list)  # a fit per plateau (calibrate._thermal_block): a list, not the joint's bool
        yield f"{s}: {_where(th, b)}; per plateau p = " + ", ".join(_p(x["p_value"]) for x in plateaus)
    else:
        fails = b.verdict == "fails"
        yield (f"{s}: one model, every row at its own temperature ({_where(th, b)}): chi2 {b.chi2:.4g} / {b.dof} dof, "
               f"p = {_p(b.p_value)}" + ("; THE MODEL FAILS" if fails else ""))
        yield (f"{s}: under it each {'plateau' if b.details.get('plateaus') else 'band'} p = "
               + ", ".join(_p(g["p_value"]) for g in groups)
               + ("; each plateau alone, at one temperature, p = " + ", ".join(_p(g["own_p_value"]) for g in groups)
                  if b.details.get("plateaus") else ""))
    moving = {n: f for n, f in th["parameters"].items() if f["degree"] > 0}
    for n, f in moving.items():
        terms = " ".join((f"{c:.4g}" if not k else f"{'+' if c >= 0 else '-'} {abs(c):.4g}")
                         + (f" dT^{k}" if k > 1 else " dT" if k else "") for k, c in enumerate(f["coefficients"]))
        chosen = f.get("degree_from", "the data")
        yield (f"{s}: {n} = {terms} ({b.param_units.get(n, '')}; dT = T - T_ref in degC; degree {f['degree']} "
               + ("chosen by the data)" if chosen == "the data" else f"from {chosen})"))
    yield (f"{s}: {len(th['parameters']) - len(moving)} of {len(th['parameters'])} parameters constant over "
           "temperature (a temperature dependence below their noise)")
    if "warmup" in th:  # a warm-up's effects (its temperature rates) beside the polynomials, and auto's choice
        for e, v in b.effects.items():
            yield f"{s}: {e} = {v.value:.4g} +- {v.std:.2g} {v.unit} (added)"
        if "auto" in b.details:
            yield f"{s}: --add auto chose " + (", ".join(x["id"] for x in b.details["auto"]) or "nothing")
    exact = [n for n, f in th["parameters"].items() if f.get("dof") == 0]
    if exact:
        yield (f"{s}: {len(exact)} polynomials pass through every plateau (degree = plateaus - 1): no plateau is left "
               "to test them; give fewer degrees or more plateaus")


def to_add(diag: DiagnosisReport, sensor: str) -> tuple[list[str] | None, str]:
    """(what the verdict adds for one sensor, why): [] where its model passes (or was not tested: the
    why says so), the verdict's effects where it fails (the found term's model file when it beats
    every library effect and was written, the effects chosen together on a stream's moves, else the
    strongest significant effect or the library's match of the found term), None where nothing
    found explains the misfit."""
    b = diagnosis_blocks(diag)[sensor]
    p = b["model_test"]["p_value"]
    if p is None:
        return [], f"{sensor}: no test (too few degrees of freedom): state the noise or add positions"
    if p >= diag["alpha"]:
        return [], ""
    if b.get("explained_by"):  # a test shared with the other sensor, whose effect explains it (a sequence's filter)
        return [], ""
    shape, shares = b.get("shape"), b.get("misfit_shares")
    steps = shares["steps"] if shares else []
    written = shape.get("model_file_path") if shape else None  # the found term's model file
    outside = None if written or steps else family.outside_library(b["model_test"], b["candidates"])
    if outside:
        return None, f"{sensor}: {outside['text']}"
    sig = [c["id"] for c in b["candidates"] if c.get("significant")]
    lead = next((c for c in b["candidates"] if c.get("significant")), None)
    if lead and lead.get("twins_undecided") and not (written or steps):
        return [], f"{sensor}: {undecided_twins(lead, b['candidates'])}"
    catalog_id = shape["catalog_id"] if shape else None
    found = [written] if written else [x["id"] for x in steps] if steps else sig[:1] or ([catalog_id] if catalog_id
                                                                                          else None)
    return found, "" if found else f"{sensor}: nothing found explains the misfit; the plots below show where it is"


def next_command(diag: DiagnosisReport) -> tuple[str, list[str]]:
    """(the one calibrate command for the set, the notes beside it): next_adds as --add options; where
    calibrate would refuse these data (a sequence that leaves a parameter unobserved), the plan that scores
    a sequence before it is recorded, and why."""
    refused = calibrate_refusal(diag)
    if refused:
        return refused
    adds, notes = next_adds(diag)
    return f"simucal calibrate {diag['input']}{''.join(f' --add {a}' for a in adds)} -o calibration.json", notes


def calibrate_refusal(diag: DiagnosisReport) -> tuple[str, list[str]] | None:
    """(what to do instead, why) where calibrate would refuse the diagnosed data (a sequence that leaves a
    parameter unobserved, or whose passes do not converge: systematic/method.refusal), else None."""
    block = next((b for b in diagnosis_blocks(diag).values() if b.get("calibrate_refuses")), None)
    if block is None:
        return None
    instead = block["next_instead"]
    return instead["command"], [f"{block['calibrate_refuses']}; calibrate refuses these data: {instead['note']}"]


def next_adds(diag: DiagnosisReport) -> tuple[list[str], list[str]]:
    """(what the next calibration adds, the notes beside it): every --add the diagnosis was run with
    (both sensors' effects and model files) and, for each sensor whose model fails, what its verdict
    adds; so the command that made a model pass keeps its --add, and the gyro's keeps the
    accelerometer's."""
    adds: list[str] = []
    notes: list[str] = []
    blocks = diagnosis_blocks(diag)
    for b in blocks.values():
        adds += b["added"]["effects"] if "added" in b else []
    for s in blocks:
        found, why = to_add(diag, s)
        adds += found or []
        notes += [why] if why else []
    return list(dict.fromkeys(adds)), notes


def validation_next(report: ValidationReport) -> tuple[str, list[str]]:
    """(the command after `simucal validate`, why): another recording where these are the calibration's
    own rows, a diagnosis of these data where a sensor is no better than nominal, else apply."""
    cal, data = report["calibration"], report["data"]
    if report["note"]:
        return f"simucal validate {cal} OTHER_RECORDING -o validation.json --html validation.html", [report["note"]]
    bad = [s for s, v in report["verdict"].items()
           if not v.startswith(("better", "at the noise floor", "not calibrated"))]
    if bad:
        return (f"simucal diagnose {data} -o diagnosis.json --html diagnosis.html",
                [f"{', '.join(bad)}: the calibration does not hold on these data; the diagnosis shows what its "
                 "model lacks"])
    return f"simucal apply {cal} {data} -o calibrated", []


def _term_text(t) -> str:
    """One term: value +- std where seen, else "not seen" and its bound, or the length it needs (the page's
    cells: report/noise_html.py)."""
    if t["status"] == "seen":
        return f"{t['value']:.3g} +- {t['std']:.2g} {t['unit']}"
    if t["status"] == "not seen":
        return f"not seen (< {t['bound_95']:.2g} {t['unit']}, 95 %)"
    return f"record too short (needs {t['needs_s']:.3g} s)"


def noise_lines(report, written=None, units: str = "spec"):
    """The console: each axis's terms in a data sheet's units (or SI), seen or not; written: noise_next's."""
    if units == "spec":
        return list(_noise_lines(report, written))
    from simucal.report import units as shown
    g = shown.gravity_of(report.get("data"))
    return shown.lines_in(_noise_lines(shown.noise_in(report, units, g), written), units, g)


def _noise_lines(report, written=None):
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        b = report[sensor]
        yield (f"{sensor}: Allan deviation over {b['rows']}, {b['rate_hz']:.4g} Hz, tau {b['tau_s'][0]:.3g} to "
               f"{b['tau_s'][-1]:.3g} s; terms fitted with the estimates' covariance, reported where beyond "
               f"{allan_fit.SEEN:g} std")
        for a, ax in b["axes"].items():
            if "stuck" in ax:
                yield f"  {a}: {ax['stuck']}"
                continue
            yield f"  {a}: " + ", ".join(f"{t['name']} {_term_text(t)}" for t in ax["sheet"].values())
    for _, text in noise_verdicts(report):
        yield text
    yield from skipped_sensors([s for s in ("acc", "gyro") if s in report])
    yield "next: " + noise_next(report, written)[0]


def _axes_of(axes, status, k) -> list[str]:
    return [a for a, ax in axes.items() if "stuck" not in ax and ax["sheet"][k]["status"] == status]


def noise_verdicts(report) -> list[tuple[bool, str]]:
    """Per sensor (ok, the verdict): an axis stuck, else the white noise, the terms seen beyond it and
    those not seen (each with its 95 % bound in the table) or the record too short to tell."""
    out = []
    for sensor in ("acc", "gyro"):
        if sensor not in report:
            continue
        axes = report[sensor]["axes"]
        stuck = [f"{a} {ax['stuck']}" for a, ax in axes.items() if "stuck" in ax]
        n = [axes[a]["sheet"]["N"] for a in _axes_of(axes, "seen", "N")]
        text = (f"{sensor}: {allan_terms.SHEET[sensor]['N'][0]} "
                + (f"{min(t['value'] for t in n):.3g} to {max(t['value'] for t in n):.3g} "
                   f"{n[0]['unit']}" if n else "not seen")
                + " on " + ", ".join(_axes_of(axes, "seen", "N") or ["no axis"]))
        for status, say in (("seen", "seen beyond it"), ("not seen", "not seen (95 % bounds below)"),
                            ("too short", "the record too short to tell")):
            terms = [f"{allan_terms.SHEET[sensor][k][0]} ({', '.join(_axes_of(axes, status, k))})"
                     for k in allan_terms.SHEET[sensor] if k != "N" and _axes_of(axes, status, k)]
            text += f"; {say}: {', '.join(terms)}" if terms else ""
        out.append((not stuck and len(n) == len(axes), text + "".join(f"; STUCK: {x}" for x in stuck)))
    if report.get("temperature", {}).get("warning"):
        out.append((False, "WARNING: " + report["temperature"]["warning"]))
    return out


def noise_next(report, written=None) -> tuple[str, list[str]]:
    """(the command after `simucal noise`, why): Kalibr's imu.yaml where the record gives it, else what to record;
    written ({"-o": noise.json, "--kalibr": imu.yaml}) once imu.yaml is written: a calibration weighed by the
    noise curves (calibrate --noise), not the command just run."""
    missing = kalibr_missing(report)
    if written and written.get("--kalibr"):
        return (f"simucal calibrate TEST_SET --noise {written['-o']} -o calibration.json",
                [f"{written['--kalibr']} is written: Kalibr reads it as its --imu file"])
    if not missing:
        return f"simucal noise {report['data']} -o noise.json --kalibr imu.yaml", []
    return ("simucal noise LONGER_STILL_RECORDING -o noise.json --html noise.html",
            ["Kalibr's imu.yaml would lack " + "; ".join(missing)])
