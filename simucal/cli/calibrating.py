"""The commands that fit a model: calibrate (one set, several, or thermal plateaus), field-drift, diagnose."""
from __future__ import annotations

import sys
from pathlib import Path

import click

from simucal import methods
from simucal.cli.common import (MODEL_FILE_RUNS, NOISE_DPH, NOISE_G, POSITIVE, SCHEDULER_TRUST, UNITS, InputPath,
                                Number, fail, guard, main, refuse_unused)
from simucal.cli.store import record, store_option


TIMESTAMPS = click.option(
    "--timestamps", type=click.Choice(("auto", "nominal", "recorded")), default="auto", show_default=True,
    help="Stream: integrate on the recorded t_s, or on the sensor's clock (nominal: evenly spaced at the mean step, "
         "for a logger's arrival times); auto: nominal where the stamps jitter yet stay within 2 median steps of an "
         "even clock.")
_HEADING_HELP = "Field sets: the stated accuracy of the north reference (deg); its effect enters the uncertainty."
HEADING_ACCURACY = click.option("--heading-accuracy-deg", type=Number(0.0, 180.0), default=5.0, show_default=True,
                                help=_HEADING_HELP)
_MODEL_HELP = ("The {} model fitted: a built-in (derive/models/) or one derived from your model file "
               "(simucal derive --model FILE).")
ACC_MODEL = click.option("--acc-model", default="acc_baseline", show_default=True,
                         help=_MODEL_HELP.format("accelerometer"))
GYRO_MODEL = click.option("--gyro-model", default="gyro_baseline", show_default=True, help=_MODEL_HELP.format("gyro"))
_ADD_HELP = ("Effect id to add, e.g. acc.quadratic.z (exact ids; unknown ones are refused), or a model file "
             "(MODELS = [...]) with your own SymPy terms, derived into the cache (repeatable). " + MODEL_FILE_RUNS)
_ADD_AUTO_HELP = (_ADD_HELP + " Also 'auto': the library effects a failing model needs, chosen one at a time by the "
                  "same test as diagnose, each also predicting left-out positions better.")


@main.command()
@click.argument("data_dirs", nargs=-1, required=True, type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(), default="calibration.json", show_default=True,
              help="The calibration file; with several sets, a folder that gets one <set>.json each (with "
                   "--thermal: one file).")
@click.option("--thermal", is_flag=True, help="The sets are one unit at several temperature plateaus, or one set whose "
              "temperature ramps (temp_c, degC): one fit of every row at its own temperature, every parameter a "
              "polynomial in T - T_ref, applied at each row's temp_c.")
@click.option("--thermal-degree", type=click.IntRange(0, 3), default=None,
              help="--thermal: one degree for every parameter's polynomial, at most the distinct temperatures "
                   "(2 degC apart) less one (default: chosen per parameter by the model test and by plateaus or "
                   "bands of a ramp left out).")
@click.option("--html", "html_out", type=click.Path(dir_okay=False), default=None,
              help="--thermal: a page opening with each sensor's verdict, then each parameter against temperature "
                   "with its polynomial.")
@click.option("--px4", type=click.Path(dir_okay=False), default=None,
              help="--thermal: also PX4's thermal compensation (TC_A{n}_*, TC_G{n}_*, n the log's instance: bias "
                   "polynomials X0..X3 in m/s^2 and rad/s, TREF, TMIN, TMAX, the device ids), a QGroundControl .params "
                   "file; sets of several instances (import --instance all): each calibrated apart, -o and --html "
                   "get _instance<n> each, this one file every slot. The data's sensor axes are taken as PX4's "
                   "sensor axes (sensor_accel, sensor_gyro); scale-factor and misalignment drift are not expressible "
                   "(warned).")
@click.option("--ardupilot", type=click.Path(dir_okay=False), default=None,
              help="--thermal: also ArduPilot's INS_TCAL{n+1}_* (bias polynomials about 35 degC, TMIN, TMAX), a .param "
                   "file (NAME,VALUE). The data's sensor axes are taken as ArduPilot's IMU axes; as --px4.")
@click.option("--t-ref-c", type=Number(-55.0, 125.0), default=None,
              help="T_ref of temperature terms, degC (default: the mean of temp_c; --thermal: of the plateaus).")
@click.option("--method", type=click.Choice(("auto",) + methods.NAMES), default="auto", show_default=True,
              help="auto: the default for the set's data. " + " ".join(
                  f"{m.name}: {m.summary} ({methods.DATA[m.data]})." for m in methods.METHODS.values()))
@ACC_MODEL
@GYRO_MODEL
@click.option("--add", "add", multiple=True, help=_ADD_AUTO_HELP)
@click.option("--acc-noise-g", type=NOISE_G, default=None,
              help="Noise of one acc row (g), where the data cannot give it.")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None, help="Noise of one gyro row (deg/h).")
@click.option("--noise", "noise_file", type=InputPath(exists=True, dir_okay=False), default=None,
              help="A noise.json of simucal noise: each segment's noise from its Allan curve at the segment's length "
                   "(averaged rows: meta.json's average_s).")
@TIMESTAMPS
@click.option("--init-rest-s", type=POSITIVE, default=None,
              help="Stream: length of the initial rest, s (default: found from the data).")
@click.option("--threshold-factor", type=Number(1.0, 1e6, low_open=True), default=None, show_default="6",
              help="Stream: static threshold, times the rest's variance.")
@click.option("--window-s", type=POSITIVE, default=None, show_default="1", help="Stream: moving-variance window, s.")
@click.option("--min-static-s", type=POSITIVE, default=None, show_default="1",
              help="Stream: shortest static interval, s.")
@click.option("--gyro-limit-dps", type=POSITIVE, default=None,
              help="Stream: the gyro's limit on a pose's windowed rate less its own level, deg/s (default: from the "
                   "data, the rest's noise or the poses' sway, whichever is larger).")
@click.option("--heading-accuracy-deg", type=Number(0.0, 180.0), default=None, show_default="5", help=_HEADING_HELP)
@click.option("--scheduler", default="local", show_default=True,
              help="Several sets: local, processes (a Dask LocalCluster on 127.0.0.1) or a Dask scheduler's address. "
                   + SCHEDULER_TRUST)
@UNITS
@store_option(False)
def calibrate(data_dirs, output, thermal, thermal_degree, html_out, px4, ardupilot, t_ref_c, method, acc_model,
              gyro_model, add, acc_noise_g, gyro_noise_dph, noise_file, timestamps, init_rest_s, threshold_factor,
              window_s, min_static_s, gyro_limit_dps, heading_accuracy_deg, scheduler, units, store_url):
    """Calibrate measurement sets; write calibration.json (one per set into a folder for several).

    With segments.csv and table angles: a turntable test (dong2018). Without segments.csv: a
    continuous stream from a hand-placed session (static poses found from the data; Tedaldi).
    With heading_ref_deg and no table angles: a field set (ruan2019's gyro drift)."""
    from simucal import api
    stream = dict(window_s=window_s, threshold_factor=threshold_factor, min_static_s=min_static_s,
                  init_rest_s=init_rest_s, gyro_limit_dps=gyro_limit_dps)
    detect = api.DetectSettings(**{k: v for k, v in stream.items() if v is not None}) if any(
        v is not None for v in stream.values()) else None  # given only where set: other data refuse them
    given = dict(method=method, acc_model=acc_model, gyro_model=gyro_model, detect=detect, add=add,
                 acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg,
                 noise=noise_file, timestamps=timestamps, t_ref_c=t_ref_c, thermal_degree=thermal_degree,
                 thermal=thermal)
    options = api.CalibrateOptions(**{k: v for k, v in given.items() if v is not None})  # None: left out
    inputs = list(data_dirs) + [a for a in add if a.endswith(".py")] + ([noise_file] if noise_file else [])
    if len(data_dirs) == 1 or options.thermal:
        refuse_unused({"scheduler": "several sets calibrated one by one (not one set, nor --thermal's plateaus)"})
    if options.thermal:
        refuse_unused({"store_url": "one set's or several sets' calibrations (a thermal one: simucal store add FILE)"})
        return _calibrate_thermal(data_dirs, output, options, inputs, html_out, (px4, ardupilot), units)
    if px4 or ardupilot:
        fail("--px4/--ardupilot: an autopilot's thermal compensation is made from plateaus or a ramp with --thermal")
    if html_out:
        fail("--html: a page of a thermal calibration (with --thermal); for one set use simucal diagnose --html")
    if len(data_dirs) == 1:
        guard(inputs, files=[output])
        result = api.calibrate(data_dirs[0], options)
        api.save(output, result)
        from simucal.report.console import calibration_lines
        for line in calibration_lines(result, units):
            click.echo(line)
        click.echo(f"wrote {output} (method {result.method})")
        if store_url:
            click.echo(record(store_url, result))
        return
    refuse_unused({"units": "what one set's calibration prints (several sets print each one's file and tests)"})
    _calibrate_batch(data_dirs, output, options, inputs, scheduler, store_url)


def _calibrate_batch(data_dirs, output, options, inputs, scheduler, store_url=None):
    """Several sets, one by one (on a scheduler): one <set>.json each into the folder -o (simucal.calibrate_each)."""
    from simucal import api, progress
    out = Path(output)
    guard(inputs, files=api.batch.output_files(data_dirs, out), folders=[out])
    done = api.calibrate_each(data_dirs, out, options=options, scheduler=scheduler,
                              progress=progress.bar("calibrate", "set"))
    for d in done:
        if d.error:
            click.echo(f"{d.data}: error: {d.error}", err=True)
        else:
            assert d.calibration is not None  # set where not refused
            tests = ", ".join(f"{k} p = {b.p_value:.3g}" + (": THE MODEL FAILS" if b.verdict == "fails" else "")
                              for k, b in d.calibration.blocks() if b.p_value is not None)
            click.echo(f"{d.data}: wrote {d.output}" + (f" ({tests})" if tests else ""))
            if store_url:
                click.echo(f"{d.data}: " + record(store_url, d.calibration))
    failed = sum(1 for d in done if d.error)
    click.echo(f"{len(done) - failed} of {len(done)} sets calibrated into {out}")
    if failed:
        from simucal.io import outputs
        outputs.commit()  # the good sets' files are kept: each refused one is named above
        sys.exit(2)


def _calibrate_thermal(data_dirs, output, options, inputs, html_out, autopilot_out=(None, None), units="spec"):
    from simucal import api
    if len(api.imus_of(data_dirs)) > 1:
        return _calibrate_instances(data_dirs, output, options, inputs, html_out, autopilot_out, units)
    from simucal.io import outputs
    guard(inputs, files={"-o": output, "--html": html_out, "--px4": autopilot_out[0], "--ardupilot": autopilot_out[1]})
    result = api.calibrate([Path(d) for d in data_dirs], options)
    exported = result.autopilot_files(data_dirs[0], px4=autopilot_out[0], ardupilot=autopilot_out[1])
    api.save(output, result)
    from simucal.report.console import calibration_lines
    for line in calibration_lines(result, units):
        click.echo(line)
    if html_out:
        api.save(html_out, result, calibration_path=output, units=units)
        click.echo(f"wrote {html_out}")
    for f in exported:  # made before anything was written: a refusal leaves nothing behind
        outputs.write_text(f.path, f.text)
        for w in f.warnings:
            click.echo(f"WARNING: {w}")
        click.echo(f"wrote {f.path}: {f.note}")
    assert result.temperature_range_c is not None  # a thermal calibration's
    lo, hi = result.temperature_range_c
    click.echo(f"wrote {output} (method {result.method}; calibrated from {lo:.4g} to {hi:.4g} degC)")


def _instance_path(path, instance):
    """An output of one IMU, where several are calibrated: its name with _instance<n> (calibration.json ->
    calibration_instance1.json)."""
    return None if path is None else str(Path(path).with_name(f"{Path(path).stem}_instance{instance}"
                                                               f"{Path(path).suffix}"))


def _calibrate_instances(data_dirs, output, options, inputs, html_out, autopilot_out, units):
    """--thermal of sets of several IMUs of a log (simucal.calibrate_instances): each apart, one calibration
    file and page each, and one PX4 and one ArduPilot file holding every IMU's slot."""
    from simucal import api
    from simucal.io import outputs
    from simucal.report.console import calibration_lines
    instances = [None if key is None else key[0] for key in api.imus_of(data_dirs)]
    if None in instances:
        fail(f"--thermal: {', '.join(map(str, data_dirs))} mix sets of a log's IMUs with sets from elsewhere: give "
             "each IMU's sets in a command of its own")
    if len(set(instances)) < len(instances):
        twice = next(n for n in instances if instances.count(n) > 1)
        fail(f"--thermal: two IMUs at instance {twice} (their device ids differ: two boards' logs?): give each "
             "board's sets in a command of its own")
    named = {f"-o ({n})": _instance_path(output, n) for n in instances}
    named.update({f"--html ({n})": _instance_path(html_out, n) for n in instances if html_out})
    guard(inputs, files={**named, "--px4": autopilot_out[0], "--ardupilot": autopilot_out[1]})
    imus = api.calibrate_instances([Path(d) for d in data_dirs], options)
    exported = api.autopilot_files(imus, px4=autopilot_out[0], ardupilot=autopilot_out[1])
    for u in imus:
        path = _instance_path(output, u.instance)
        api.save(path, u.calibration)
        for line in calibration_lines(u.calibration, units):
            click.echo(f"instance {u.instance}: {line}")
        if html_out:
            api.save(_instance_path(html_out, u.instance), u.calibration, calibration_path=path, units=units)
            click.echo(f"wrote {_instance_path(html_out, u.instance)}")
        assert u.calibration.temperature_range_c is not None  # a thermal calibration's
        lo, hi = u.calibration.temperature_range_c
        click.echo(f"wrote {path} (instance {u.instance}, {', '.join(u.sets)}; calibrated from {lo:.4g} to "
                   f"{hi:.4g} degC)")
    for f in exported:
        outputs.write_text(f.path, f.text)
        for w in f.warnings:
            click.echo(f"WARNING: {w}")
        click.echo(f"wrote {f.path} (instances {', '.join(str(u.instance) for u in imus)}): {f.note}")


@main.command("field-drift")
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="drift.json", show_default=True,
              help="The calibration file (apply corrects the gyro drift with it).")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page: the calibration and each position's filter estimate (paper Fig. 4).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, hidden=True,
              help="Deprecated (warns): Fig. 4 alone as an image file (.png, .svg, ...); --html writes it in a page.")
@HEADING_ACCURACY
@UNITS
def field_drift(data_dir, output, html_path, plot, heading_accuracy_deg, units):
    """Three-position field calibration of gyro constant drift (ruan2019): `calibrate --method field`, with the
    paper's Fig. 4."""
    from simucal import api
    from simucal.api import tools
    if plot:
        tools.check_image_name(plot)
    guard([data_dir], files={"-o": output, "--html": html_path, "--plot": plot})
    if plot:  # after the refusals, which are one line
        click.echo("warning: --plot is deprecated: --html PAGE writes Fig. 4 in a page with the calibration", err=True)
    result = api.calibrate(data_dir, method="field", heading_accuracy_deg=heading_accuracy_deg)
    api.save(output, result)
    if html_path:
        api.save(html_path, result, calibration_path=output, units=units)
    if plot:
        tools.plot_field_history(result, plot)
    from simucal.report.console import calibration_lines
    for line in calibration_lines(result, units):
        click.echo(line)
    click.echo(f"wrote {output}" + "".join(f" and {p}" for p in (html_path, plot) if p))


def _added_lines(result):
    """diagnose --add: the residual and p before and after, per sensor, and each added parameter, with units."""
    from simucal.report.units import param_units_of
    for s in ("acc", "gyro"):
        a = result.get(s, {}).get("added")
        if a:
            shown = param_units_of(result[s])
            u = a.get("residual_unit", "")
            p0, p1 = a["p_value_before"], a["p_value_after"]
            fmt = lambda p: "n/a" if p is None else f"{p:.3g}"
            yield (f"{s} with {', '.join(a['effects'])}: residual rms {a['residual_rms_before']:.3g} -> "
                   f"{a['residual_rms_after']:.3g} {u}, p {fmt(p0)} -> {fmt(p1)}")
            for k, row in a["params"].items():
                if row["before"] is None:
                    label = row.get("unit", shown.get(k))
                    unit = f" {label}" if label else ""
                    err = f", truth {row['truth']:.4g}{unit}" if "truth" in row else ""
                    yield f"    {k} = {row['after']:.4g} +- {row['std_after']:.2g}{unit}{err}"


@main.command()
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="diagnosis.json", show_default=True,
              help="The diagnosis (simucal.diagnosis/1): each sensor's model test, the ranked candidates, the verdict; "
                   "a found term that is no library effect also as <stem>_<sensor>_model.py beside it.")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a self-contained HTML report.")
@click.option("--add", "add", multiple=True, help=_ADD_HELP)
@ACC_MODEL
@GYRO_MODEL
@click.option("--acc-noise-g", type=NOISE_G, default=None,
              help="Stated noise of one acc row (g), when the data cannot give it.")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None, help="Stated noise of one gyro row (deg/h).")
@TIMESTAMPS
@UNITS
def diagnose(data_dir, output, html_path, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph, timestamps, units):
    """Compare model and measurements; rank the candidate missing effects. The Python API's simucal.diagnose(DATA)."""
    from simucal import api
    from simucal.api.diagnosing import shape_model_path
    if "auto" in add:
        fail(f"--add auto is calibrate's: diagnose already ranks every candidate; run simucal calibrate {data_dir} "
              "--add auto")
    guard([data_dir] + [a for a in add if a.endswith(".py")],
           files={"-o": output, "--html": html_path, "the acc model file it may write": shape_model_path(output, "acc"),
                  "the gyro model file it may write": shape_model_path(output, "gyro")})
    result = api.diagnose(data_dir, add=add, acc_model=acc_model, gyro_model=gyro_model, acc_noise_g=acc_noise_g,
                          gyro_noise_dph=gyro_noise_dph, timestamps=timestamps)
    api.save(output, result)
    if html_path:
        api.save(html_path, result, units=units)
    from simucal.report.units import diagnosis_in
    report = diagnosis_in(result.report, units)  # the numbers converted, the verdicts written from them
    for line in [*report["verdict"].split(" | "), *report.get("notes", []), *_added_lines(report)]:
        click.echo(line)
    click.echo(f"next: {result.next_command}" + "".join(f" ({n})" for n in result.next_notes))
    for s in result.model_files:
        click.echo(f"wrote {shape_model_path(output, s)}: the found term as a model file; try: simucal diagnose "
                   f"{data_dir} --add {shape_model_path(output, s)}")
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))
