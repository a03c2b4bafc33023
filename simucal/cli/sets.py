"""The commands that write or read measurement sets: simulate, import, apply, validate, noise, convert."""
from __future__ import annotations

from pathlib import Path

import click

from simucal.cli.common import (
    EFFECT_FILE,
    FORCE,
    LATITUDE,
    SETS,
    POSITIVE,
    SEED,
    SIM_RATE_HZ,
    SCHEDULER_TRUST,
    InputPath,
    Number,
    fail,
    guard,
    main,
    refuse_unused,
)


@main.command()
@click.argument("out_dir", required=False, type=click.Path(file_okay=False))
@click.option("-o", "--output", type=click.Path(file_okay=False), default=None,
              help="The output folder (a measurement set and truth.json); may also be given as the argument.")
@click.option("--scenario", type=click.Choice(["paper", "field"]), default="paper", show_default=True,
              help="Preset: 'paper' is dong2018 section 4 (turntable); 'field' is ruan2019 (three positions, no table).")
@click.option("--heading-accuracy-deg", "--heading-error-deg", "heading_error_deg", type=Number(0.0, 180.0), default=None,
              help="field: the north reference's accuracy; its error is drawn uniform +- this.")
@click.option("--seed", type=SEED, default=0, show_default=True)
@click.option("--plan", default=None,
              help="table1, dodecahedron20, fibonacci24, fibonacci48, or a CSV of outer_deg,middle_deg,inner_deg.")
@click.option("--rate-hz", type=SIM_RATE_HZ, default=None,
              help="Write raw samples at this rate (Hz, up to 2000) instead of one row per position.")
@click.option("--position-error-arcmin", type=Number(0.0, 10800.0), default=None, help="Uniform +- angular position error.")
@click.option("--acc-model", default=None, help="Generated model for the truth (may hold terms calibration lacks).")
@click.option("--gyro-model", default=None, help="Generated gyro model for the truth.")
@click.option("--acc-unit", type=click.Choice(["g", "m/s^2", "pulse/s"]), default=None,
              help="The accelerometer outputs' unit in samples.csv (default pulse/s, the paper's pulse counts; the field "
                   "scenario writes m/s^2).")
@click.option("--gyro-unit", type=click.Choice(["deg/h", "deg/s", "rad/s", "pulse/s"]), default=None,
              help="The gyro outputs' unit in samples.csv (default pulse/s, the paper's pulse counts; the field scenario "
                   "writes deg/s).")
@click.option("--effect", "effects", multiple=True, metavar="ID=VALUE",
              help="Plant a candidate effect in the truth, in the unit its term declares, e.g. "
                   "acc.quadratic.z=6e-5 or gyro.g_sensitivity.xz=0.3 (repeatable).")
@EFFECT_FILE
@SETS
@click.option("--column", "columns", multiple=True, metavar="NAME=LOW:HIGH",
              help="Write an auxiliary column, one value per segment drawn uniformly in [LOW, HIGH], e.g. "
                   "supply_v=4.5:5.5 (one your --effect-file terms read) or temp_c=20:40; repeatable.")
@click.option("--temperature-c", default=None, metavar="T|T0:T1",
              help="Write temp_c: one plateau at T degC, or a ramp from T0 to T1 degC over the segments; the unit's "
                   "temperature effects (--effect ...bias_temperature..., scale_temperature...) act from --t-ref-c.")
@click.option("--t-ref-c", type=Number(-55.0, 125.0), default=25.0, show_default=True,
              help="With --temperature-c: the unit's T_ref, degC, the temperature at which its parameters are the "
                   "truth's (fixed, so that a plateau away from it shows the planted temperature effects).")
@click.option("--temperature-wander-c", type=Number(0.0, 10.0), default=0.0, show_default=True,
              help="With --temperature-c: each segment's temperature off the plateau or ramp by a uniform draw "
                   "within +- this, degC (a chamber's wander).")
@click.option("--no-noise-stated", is_flag=True, help="Leave acc_noise_g / gyro_noise_dph out of meta.json.")
@FORCE
def simulate(out_dir, output, scenario, heading_error_deg, seed, plan, rate_hz, position_error_arcmin, acc_model, gyro_model,
             acc_unit, gyro_unit, effects, effect_file, sets, columns, temperature_c, t_ref_c, temperature_wander_c,
             no_noise_stated, force):
    """Simulate a test; write a measurement set and truth.json (simucal simulate -o FOLDER [options])."""
    if out_dir and output and Path(out_dir) != Path(output):
        fail(f"two output folders ({out_dir} and -o {output}): give one")
    out_dir = output or out_dir
    if not out_dir:
        fail("no output folder: give -o FOLDER")
    from simucal.turntable.simulate import ARCMIN, SCENARIOS, at_temperature, plant, write
    table_only = {"--plan": plan, "--position-error-arcmin": position_error_arcmin, "--acc-model": acc_model,
                  "--gyro-model": gyro_model, "--acc-unit": acc_unit, "--gyro-unit": gyro_unit, "--effect": effects,
                  "--effect-file": effect_file, "--set": sets, "--column": columns, "--no-noise-stated": no_noise_stated,
                  "--temperature-c": temperature_c}
    given = [k for k, v in table_only.items() if v not in (None, False, ())]
    if scenario == "field":
        at_a_temperature = "a turntable test at a temperature (--temperature-c)"
        refuse_unused({"t_ref_c": at_a_temperature, "temperature_wander_c": at_a_temperature})
    if scenario == "field" and given:
        fail(f"{', '.join(given)}: a turntable test's (--scenario paper); the field scenario takes --seed, --rate-hz "
             "and --heading-accuracy-deg")
    if scenario != "field" and heading_error_deg is not None:
        fail(f"--heading-accuracy-deg {heading_error_deg:g}: the field scenario's north reference (--scenario field); "
             f"a {scenario} test has a turntable")
    guard([plan if plan and Path(plan).exists() else None, effect_file], sets=[out_dir], force=force)
    if scenario == "field":
        from simucal.field.simulate import FieldScenario, write_field
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
    sc.state_noise = not no_noise_stated
    try:
        at_temperature(sc, temperature_c, t_ref_c, temperature_wander_c, columns)
        plant(sc, effects, effect_file, sets, columns)
        write(out_dir, sc, seed)
    except (ValueError, KeyError, FileNotFoundError, SyntaxError) as e:
        fail(e)
    click.echo(f"wrote {out_dir} (scenario {scenario}, seed {seed})")


@main.command("import")
@click.argument("fmt", type=click.Choice(["imu_tk", "imucal-ferraris", "imucal-annotated", "csv"]))
@click.argument("sources", nargs=-1, required=True, type=InputPath(exists=True, dir_okay=False))
@click.option("-o", "--output", "--out-dir", "out_dir", required=True, type=click.Path(file_okay=False),
              help="The output folder (a measurement set).")
@click.option("--latitude-deg", type=LATITUDE, default=None, help="Site latitude (the spec needs it with gyro data).")
@click.option("--acc-counts-per-g", type=POSITIVE, default=None, help="imu_tk: nominal accelerometer LSB per g.")
@click.option("--gyro-counts-per-dps", type=POSITIVE, default=None, help="imu_tk: nominal gyro LSB per deg/s.")
@click.option("--gravity-mps2", type=Number(9.7, 9.9, what="m/s^2 on Earth"), default=None)
@click.option("--rate-hz", type=Number(0.0, 1e6, low_open=True), default=None,
              help="Sample rate where the file has no time column.")
@click.option("--columns", default=None, help="csv: map, e.g. 't_s=time,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,gz=gyr_z'.")
@click.option("--acc-unit", default=None)
@click.option("--gyro-unit", default=None)
@click.option("--turn-deg", type=Number(-3600.0, 3600.0), default=-360.0, show_default=True,
              help="Ferraris: the protocol's turn angle (imucal's default -360, clockwise).")
@FORCE
def import_cmd(fmt, sources, out_dir, latitude_deg, acc_counts_per_g, gyro_counts_per_dps, gravity_mps2, rate_hz,
               columns, acc_unit, gyro_unit, turn_deg, force):
    """Write a measurement set from another tool's recording."""
    from simucal.io import importers as im
    guard(sources, sets=[out_dir], force=force)
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
            if not columns:
                raise im.ImportError_("csv needs --columns (and --acc-unit, --gyro-unit for the triads it maps)")
            cmap = im.parse_columns(columns)
            for triad, unit, option in (("ax", acc_unit, "--acc-unit"), ("gx", gyro_unit, "--gyro-unit")):
                if triad in cmap and not unit:
                    raise im.ImportError_(f"csv: --columns maps {triad}, so give {option}")
            im.import_csv(sources[0], out_dir, cmap, acc_unit, gyro_unit, rate_hz, latitude_deg)
    except im.ImportError_ as e:
        fail(e)
    click.echo(f"wrote {out_dir}")


@main.command("apply")
@click.argument("calibration_file", type=InputPath(exists=True, dir_okay=False))
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", "--out-dir", "out_dir", required=True, type=click.Path(file_okay=False),
              help="The output folder (a measurement set).")
@FORCE
def apply_cmd(calibration_file, data_dir, out_dir, force):
    """Apply a calibration to raw data: a measurement set in g and deg/h, frame b."""
    from simucal import io
    from simucal.fit.apply import apply
    from simucal.io import calibration
    guard([calibration_file, data_dir], sets=[out_dir], force=force)
    try:
        cal = calibration.load(calibration_file)
        meta, samples, segments = apply(cal, Path(data_dir), calibration_file)
    except (ValueError, KeyError) as e:  # MeasurementSetError, CalibrationError, CalibrationFileError
        fail(e)
    io.write_set(out_dir, meta, samples, segments)
    for line in meta.get("warnings", []):
        click.echo(f"WARNING: {line}")
    click.echo(f"wrote {out_dir}: {len(samples['t_s'])} rows in g and deg/h (frame b), calibrated by "
               f"{calibration_file}")


@main.command()
@click.argument("calibration_file", type=InputPath(exists=True, dir_okay=False))
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="validation.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None, help="Also write a page with a plot.")
def validate(calibration_file, data_dir, output, html_path):
    """Apply a calibration to an independent set: the error before (nominal) and after, against the noise floor."""
    import json

    from simucal.errors import CalibrationError
    from simucal.io import MeasurementSetError, outputs
    from simucal.validate import html_page, lines
    from simucal.validate import validate as run
    guard([calibration_file, data_dir], files={"-o": output, "--html": html_path})
    try:
        report = run(calibration_file, data_dir)
    except (MeasurementSetError, CalibrationError, ValueError) as e:
        fail(e)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    if html_path:
        outputs.write_text(html_path, html_page(report))
    for line in lines(report):
        click.echo(line)
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))


@main.command()
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="noise.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page with the Allan deviation plot.")
@click.option("--kalibr", "kalibr_path", type=click.Path(dir_okay=False), default=None,
              help="Also write Kalibr's imu.yaml (noise densities and random walks, SI); refused unless both sensors "
                   "give them.")
@click.option("--tau-max-s", type=POSITIVE, default=None,
              help="The longest tau (s); default a ninth of the longest still stretch.")
@click.option("--scheduler", default="local", show_default=True,
              help="Where the sums over a stream's rows run: local (this process, the recording's cumulative sums in "
                   "memory, 48 bytes a row), processes (a Dask LocalCluster on 127.0.0.1; the sums on disk in TMPDIR, "
                   "for a recording larger than memory) or a Dask scheduler's address (its workers must see TMPDIR): "
                   "the same numbers on any. " + SCHEDULER_TRUST)
def noise(data_dir, output, html_path, kalibr_path, tau_max_s, scheduler):
    """Allan deviation of a still recording and its IEEE 952 noise terms (ARW, bias instability, ...); a stream is
    read a chunk at a time."""
    import json

    from simucal import allan
    from simucal.errors import CalibrationError
    from simucal.io import MeasurementSetError, outputs
    guard([data_dir], files={"-o": output, "--html": html_path, "--kalibr": kalibr_path})
    try:
        report = allan.characterise_folder(data_dir, tau_max_s, scheduler)
        yaml = allan.kalibr_yaml(report) if kalibr_path else None  # refused before anything is written
    except (MeasurementSetError, CalibrationError) as e:
        fail(e)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    if html_path:
        outputs.write_text(html_path, allan.html_page(report))
    if kalibr_path:
        outputs.write_text(kalibr_path, yaml)
    for line in allan.lines(report):
        click.echo(line)
    click.echo(f"wrote {output}" + "".join(f" and {p}" for p in (html_path, kalibr_path) if p))



@main.command()
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(file_okay=False), required=True,
              help="The new set's folder (meta.json and segments.csv copied, the samples converted).")
@click.option("--to", "to", type=click.Choice(["parquet", "csv"]), required=True,
              help="The samples' format: samples.parquet (columnar, binary: smaller and faster to read) or samples.csv.")
@FORCE
def convert(data_dir, output, to, force):
    """Copy a measurement set with its samples as samples.parquet or samples.csv, read and written a chunk at a time
    (every row checked as it is read); the input is never changed."""
    from simucal.io import MeasurementSetError, columnar
    guard([data_dir], sets=[output], force=force)
    try:
        path, rows = columnar.convert(data_dir, output, to)
    except MeasurementSetError as e:
        fail(e)
    click.echo(f"wrote {path}: {rows} rows")
