"""The `simucal` command."""
from __future__ import annotations

import sys
from pathlib import Path

import click


@click.group()
@click.version_option(package_name="simucal")
def main():
    """Strapdown IMU calibration: derive, simulate, calibrate, audit."""


@main.command()
@click.option("--check", is_flag=True, help="Fail if generated/ differs from what derive writes now.")
@click.option("--model", "model_files", multiple=True, type=click.Path(exists=True, dir_okay=False),
              help="A Python file defining MODELS = [ErrorModel, ...]; generated beside the baseline.")
def derive(check, model_files):
    """Derive the models and (re)write generated/."""
    from simucal import derive_cmd
    stale, secs = derive_cmd.run(check=check, model_files=model_files)
    if check:
        if stale:
            click.echo("generated/ is stale; run `simucal derive`. Differs: " + ", ".join(stale), err=True)
            sys.exit(1)
        click.echo(f"generated/ is up to date ({secs:.1f} s)")
    else:
        click.echo(f"wrote {derive_cmd.generated_dir()} ({secs:.1f} s)")


if __name__ == "__main__":
    main()


def _fail(e):
    click.echo(f"error: {e}", err=True)
    sys.exit(2)


@main.command()
@click.argument("out_dir", type=click.Path(file_okay=False))
@click.option("--scenario", type=click.Choice(["paper", "field"]), default="paper", show_default=True,
              help="Preset: 'paper' is dong2018 section 4 (turntable); 'field' is ruan2019 (three positions, no table).")
@click.option("--heading-error-deg", type=float, default=None, help="field: the north reference's error, uniform +- this.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--plan", default=None,
              help="table1, dodecahedron20, fibonacci24, fibonacci48, or a CSV of outer_deg,middle_deg,inner_deg.")
@click.option("--rate-hz", type=float, default=None, help="Write raw samples at this rate instead of one row per position.")
@click.option("--position-error-arcmin", type=float, default=None, help="Uniform +- angular position error.")
@click.option("--acc-model", default=None, help="Generated model for the truth (may hold terms calibration lacks).")
@click.option("--gyro-model", default=None, help="Generated gyro model for the truth.")
@click.option("--acc-unit", type=click.Choice(["g", "m/s^2", "pulse/s"]), default=None)
@click.option("--gyro-unit", type=click.Choice(["deg/h", "deg/s", "rad/s", "pulse/s"]), default=None)
def simulate(out_dir, scenario, heading_error_deg, seed, plan, rate_hz, position_error_arcmin, acc_model, gyro_model,
             acc_unit, gyro_unit):
    """Simulate a test; write a measurement set and truth.json."""
    from simucal.simulate import ARCMIN, SCENARIOS, write
    if scenario == "field":
        from simucal.simulate_field import FieldScenario, write_field
        fs = FieldScenario()
        if heading_error_deg is not None:
            fs.heading_error_deg = heading_error_deg
        if rate_hz is not None:
            fs.rate_hz = rate_hz
        write_field(out_dir, fs, seed)
        click.echo(f"wrote {out_dir} (field scenario, seed {seed})")
        return
    sc = SCENARIOS[scenario]()
    for key, val in (("plan", plan), ("rate_hz", rate_hz), ("acc_model", acc_model), ("gyro_model", gyro_model),
                     ("acc_unit", acc_unit), ("gyro_unit", gyro_unit)):
        if val is not None:
            setattr(sc, key, val)
    if position_error_arcmin is not None:
        sc.position_error_rad = position_error_arcmin * ARCMIN
    try:
        write(out_dir, sc, seed)
    except (ValueError, KeyError) as e:
        _fail(e)
    click.echo(f"wrote {out_dir} (scenario {scenario}, seed {seed})")


@main.command()
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="calibration.json", show_default=True)
@click.option("--method", type=click.Choice(["exact", "linear", "multiposition"]), default="exact", show_default=True)
@click.option("--acc-model", default="acc_baseline", show_default=True)
@click.option("--gyro-model", default="gyro_baseline", show_default=True)
@click.option("--init-rest-s", type=float, default=None, help="Stream: length of the initial rest (default: found from the data).")
@click.option("--threshold-factor", type=float, default=6.0, show_default=True, help="Stream: static threshold, times the rest's variance.")
@click.option("--window-s", type=float, default=1.0, show_default=True, help="Stream: moving-variance window.")
@click.option("--min-static-s", type=float, default=1.0, show_default=True, help="Stream: shortest static interval.")
def calibrate(data_dir, output, method, acc_model, gyro_model, init_rest_s, threshold_factor, window_s, min_static_s):
    """Calibrate a measurement set; write calibration.json.

    With segments.csv: a turntable test (dong2018). Without: a continuous stream
    from a hand-placed session (static poses found from the data; Tedaldi)."""
    import json

    from simucal.calibrate import calibrate as run
    from simucal.io import MeasurementSetError
    from simucal.norm_fit import CalibrationError
    try:
        result = run(Path(data_dir), method, acc_model, gyro_model,
                     dict(init_rest_s=init_rest_s, factor=threshold_factor, window_s=window_s, min_s=min_static_s))
    except (MeasurementSetError, CalibrationError, KeyError) as e:
        _fail(e)
    Path(output).write_text(json.dumps(result, indent=2, default=float) + "\n")
    click.echo(f"wrote {output}: method {result['method']}; residual rms " +
               ", ".join(f"{k} {v:.3g} {result[k].get('residual_unit', result[k]['bias_unit'])}"
                         for k, v in result["residual_rms"].items()))


@main.command()
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="audit.md", show_default=True)
def audit(output):
    """Check the paper's printed equations (5)-(27) and Table 1 against the derivation."""

    from simucal.derive.audit import run_audit
    from tqdm import tqdm
    report = run_audit(progress=lambda items: tqdm(items, desc="audit", unit="check"))
    Path(output).write_text(report.markdown())
    click.echo(f"wrote {output}: {report.summary()}")


@main.command()
@click.option("-o", "--out-dir", type=click.Path(file_okay=False), default="out", show_default=True)
@click.option("--seed", type=int, default=0, show_default=True)
def demo(out_dir, seed):
    """The main job end to end on built-in simulated data:
    derive --check, simulate (paper scenario), calibrate (all methods), audit, report, diagnose."""
    import json

    from simucal import derive_cmd, report
    from simucal.calibrate import calibrate as run
    from simucal.derive.audit import run_audit
    from simucal.simulate import SCENARIOS, write

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stale, secs = derive_cmd.run(check=True)
    if stale:
        _fail("generated/ is stale; run `simucal derive`. Differs: " + ", ".join(stale))
    click.echo(f"derive: generated/ matches the derivation ({secs:.1f} s)")
    write(out / "paper", SCENARIOS["paper"](), seed)
    click.echo(f"simulate: {out / 'paper'} (dong2018 section 4 settings, seed {seed})")
    results = {}
    for method in ("exact", "linear", "multiposition"):
        results[method] = run(out / "paper", method)
        (out / f"calibration_{method}.json").write_text(json.dumps(results[method], indent=2) + "\n")
    click.echo("calibrate: " + ", ".join(f"calibration_{m}.json" for m in results))
    audit_report = run_audit()
    (out / "audit.md").write_text(audit_report.markdown())
    click.echo(f"audit: {out / 'audit.md'}: {audit_report.summary()}")
    truth = json.loads((out / "paper" / "truth.json").read_text())
    text = report.compare_table(results, truth)
    (out / "report.md").write_text(text)
    click.echo(text)
    from simucal.diagnose import diagnose as run_diagnose
    from simucal.report_html import render
    diag = run_diagnose(out / "paper")
    (out / "diagnosis.json").write_text(json.dumps(diag, indent=1, default=float) + "\n")
    (out / "diagnosis.html").write_text(render(diag))
    click.echo(f"diagnose: {out / 'diagnosis.html'}: {diag['verdict']}")


@main.command()
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="diagnosis.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None, help="Also write a self-contained HTML report.")
@click.option("--add", "add", multiple=True,
              help="Effect id to add, e.g. acc.quadratic.z, or a model file (MODELS = [...]) with your own SymPy "
                   "terms, which is derived, generated and used (repeatable).")
@click.option("--acc-model", default="acc_baseline", show_default=True)
@click.option("--gyro-model", default="gyro_baseline", show_default=True)
@click.option("--acc-noise-g", type=float, default=None, help="Stated noise of one acc row (g), when the data cannot give it.")
@click.option("--gyro-noise-dph", type=float, default=None, help="Stated noise of one gyro row (deg/h).")
def diagnose(data_dir, output, html_path, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph):
    """Compare model and measurements; rank the candidate missing effects."""
    import json

    from simucal.diagnose import diagnose as run
    from simucal.io import MeasurementSetError
    from simucal.norm_fit import CalibrationError
    files = [a for a in add if a.endswith(".py")]
    add = tuple(a for a in add if not a.endswith(".py"))
    if files:  # a user's own terms: derive, generate, then diagnose with those models
        from simucal import derive_cmd
        from simucal.derive.registry import load_model_file
        from simucal.models import load
        try:
            models = [m for f in files for m in load_model_file(f)]
        except (FileNotFoundError, ValueError) as e:
            _fail(e)
        _, secs = derive_cmd.run(model_files=files)
        load.cache_clear()
        click.echo(f"derived and generated {', '.join(m.name for m in models)} ({secs:.1f} s)")
        for m in models:
            acc_model, gyro_model = (m.name, gyro_model) if m.sensor == "acc" else (acc_model, m.name)
    try:
        result = run(Path(data_dir), add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph)
    except (MeasurementSetError, CalibrationError, KeyError) as e:
        _fail(e)
    Path(output).write_text(json.dumps(result, indent=1, default=float) + "\n")
    if html_path:
        from simucal.report_html import render
        Path(html_path).write_text(render(result))
    click.echo(result["verdict"])
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))


@main.command("field-drift")
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="drift.json", show_default=True)
@click.option("--plot", type=click.Path(dir_okay=False), default=None, help="PNG of each position's filter estimate (paper Fig. 4).")
@click.option("--heading-accuracy-deg", type=float, default=5.0, show_default=True,
              help="Stated accuracy of the north reference; its effect enters the uncertainty.")
def field_drift(data_dir, output, plot, heading_accuracy_deg):
    """Three-position field calibration of gyro constant drift (ruan2019)."""
    import json

    from simucal.field import field_drift as run, plot_history
    from simucal.io import MeasurementSetError
    from simucal.norm_fit import CalibrationError
    try:
        result, hist = run(Path(data_dir), heading_accuracy_deg=heading_accuracy_deg)
    except (MeasurementSetError, CalibrationError) as e:
        _fail(e)
    Path(output).write_text(json.dumps(result, indent=2) + "\n")
    if plot:
        plot_history(hist, plot)
    d, s = result["gyro_drift_dph"], result["std_dph"]
    click.echo("gyro drift (deg/h, body FUR): " + ", ".join(f"{a} {v:+.3f} +- {e:.3f}" for a, v, e in zip("xyz", d, s)))
    click.echo(f"wrote {output}" + (f" and {plot}" if plot else ""))


@main.command("import")
@click.argument("fmt", type=click.Choice(["imu_tk", "imucal-ferraris", "imucal-annotated", "csv"]))
@click.argument("sources", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
@click.option("-o", "--out-dir", required=True, type=click.Path(file_okay=False))
@click.option("--latitude-deg", type=float, default=None, help="Site latitude (the spec needs it with gyro data).")
@click.option("--acc-counts-per-g", type=float, default=None, help="imu_tk: nominal accelerometer LSB per g.")
@click.option("--gyro-counts-per-dps", type=float, default=None, help="imu_tk: nominal gyro LSB per deg/s.")
@click.option("--gravity-mps2", type=float, default=None)
@click.option("--rate-hz", type=float, default=None, help="Sample rate where the file has no time column.")
@click.option("--columns", default=None, help="csv: map, e.g. 't_s=time,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,gz=gyr_z'.")
@click.option("--acc-unit", default=None)
@click.option("--gyro-unit", default=None)
@click.option("--turn-deg", type=float, default=-360.0, show_default=True,
              help="Ferraris: the protocol's turn angle (imucal's default -360, clockwise).")
def import_cmd(fmt, sources, out_dir, latitude_deg, acc_counts_per_g, gyro_counts_per_dps, gravity_mps2, rate_hz,
               columns, acc_unit, gyro_unit, turn_deg):
    """Write a measurement set from another tool's recording."""
    from simucal import importers as im
    try:
        if fmt == "imu_tk":
            if len(sources) != 2 or not acc_counts_per_g or not gyro_counts_per_dps:
                raise im.ImportError_("imu_tk needs ACC_FILE GYRO_FILE, --acc-counts-per-g and --gyro-counts-per-dps")
            im.import_imu_tk(sources[0], sources[1], out_dir, acc_counts_per_g, gyro_counts_per_dps, latitude_deg,
                             gravity_mps2)
        elif fmt == "imucal-ferraris":
            if len(sources) == 2:  # with the section list: poses and turns as segments
                im.import_ferraris_sections(sources[0], sources[1], out_dir, rate_hz or 102.4, latitude_deg, turn_deg)
            else:  # a continuous stream: poses found by static detection
                im.import_ferraris(sources[0], out_dir, rate_hz or 102.4, latitude_deg)
        elif fmt == "imucal-annotated":
            im.import_imucal_annotated(sources[0], out_dir, rate_hz or 204.8, acc_counts_per_g or 2048.0,
                                       gyro_counts_per_dps or 16.4, latitude_deg, turn_deg)
        else:
            if not columns or not acc_unit or not gyro_unit:
                raise im.ImportError_("csv needs --columns, --acc-unit and --gyro-unit")
            cmap = dict(kv.split("=", 1) for kv in columns.split(","))
            im.import_csv(sources[0], out_dir, cmap, acc_unit, gyro_unit, rate_hz, latitude_deg)
    except im.ImportError_ as e:
        _fail(e)
    click.echo(f"wrote {out_dir}")
