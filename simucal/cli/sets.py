"""The commands that write or read measurement sets: simulate, import, apply, validate, noise, convert."""
from __future__ import annotations

from pathlib import Path

import click

from simucal import methods

from simucal.cli.common import (
    EFFECT_FILE,
    FORCE,
    LATITUDE,
    NOISE_DPH,
    NOISE_G,
    SETS,
    POSITIVE,
    SEED,
    SEED_HELP,
    SIM_RATE_HZ,
    SCHEDULER_TRUST,
    UNITS,
    InputPath,
    Number,
    fail,
    guard,
    main,
)

# io/units.py's names, written here so that the command line starts without numpy (tests/test_api.py holds them equal)
SCENARIOS = tuple(methods.SCENARIOS)  # methods.SCENARIOS (the command line reads it at start)
ACC_UNITS = ("g", "m/s^2", "pulse/s", "counts")
GYRO_UNITS = ("deg/h", "deg/s", "rad/s", "pulse/s", "counts")
DEFAULT_GRAVITY = 9.80665

# api/imports.py's, for the help (tests/test_api_cli.py holds them equal)
FORMATS = ("imu_tk", "imucal-ferraris", "imucal-annotated", "csv", "ulog", "dataflash", "rosbag")
FERRARIS_HZ, ANNOTATED_HZ, ANNOTATED_ACC, ANNOTATED_GYRO = 102.4, 204.8, 2048.0, 16.4


class _Instances(click.ParamType):
    """--instance: N, N,M,... or all (a list or "all": one set per instance)."""
    name = "instances"

    def convert(self, value, param, ctx):
        if isinstance(value, (int, list)) or value == "all":
            return value
        parts = [p.strip() for p in str(value).split(",")]
        if not all(p.isdigit() and int(p) <= 9 for p in parts):
            self.fail(f"{value!r}: an instance 0 to 9, several as 0,1, or all", param, ctx)
        return int(parts[0]) if len(parts) == 1 else [int(p) for p in parts]


INSTANCES = _Instances()


@main.command()
@click.argument("out_dir", required=False, type=click.Path(file_okay=False))
@click.option("-o", "--output", type=click.Path(file_okay=False), default=None,
              help="The output folder (a measurement set and truth.json); may also be given as the argument.")
@click.option("--scenario", type=click.Choice(SCENARIOS), default="paper", show_default=True,
              help="Preset: 'paper' is dong2018 section 4 (turntable); 'field' is ruan2019 (three positions, no "
                   "table); 'handheld' a hand-placed session (a stream in counts, 30 poses held 5 s between moves); "
                   "'sequence' the turntable turning through psins19 (raw samples; --sequence for another); "
                   "'still' a unit at rest (for noise); 'warmup' a still board warming from 15 to 58 degC "
                   "(for calibrate --thermal).")
@click.option("--heading-accuracy-deg", "--heading-error-deg", "heading_error_deg", type=Number(0.0, 180.0),
              default=None,
              show_default="5", help="field: the north reference's accuracy, deg; its error is drawn uniform +- this.")
@click.option("--seed", type=SEED, default=0, show_default=True,
              help=SEED_HELP + " paper: the unit is the scenario's at every seed; handheld and field: the unit "
                   "(its M and biases, the field's drift) is drawn from the seed too, unless --unit-seed is given.")
@click.option("--unit-seed", type=SEED, default=None, show_default="--seed",
              help="handheld and field: the seed the unit is drawn from, so that two --seed values with one "
                   "--unit-seed are two recordings of one unit (calibrate one, validate on the other).")
@click.option("--plan", default=None, show_default="table1",
              help="table1, dodecahedron20, fibonacci24, fibonacci48, or a CSV of outer_deg,middle_deg,inner_deg.")
@click.option("--sequence", default=None, metavar="NAME|FILE",
              help="A continuous rotation sequence instead of --plan (raw samples, default 100 Hz, while the table "
                   "rests and turns; for calibrate --method systematic): psins19, sysclbt19, dong2018, or a CSV of "
                   "axis,angle_deg,rate_dps,rest_s.")
@click.option("--rate-hz", type=SIM_RATE_HZ, default=None,
              help="Write raw samples at this rate (Hz, up to 2000) instead of one row per position (field, "
                   "handheld: their rate, default 100 Hz).")
@click.option("--position-error-arcmin", type=Number(0.0, 10800.0), default=None, show_default="1",
              help="Uniform +- angular position error of each table axis at each position, arcmin.")
@click.option("--acc-model", default=None, show_default="acc_baseline",
              help="Generated accelerometer model for the truth (may hold terms calibration lacks).")
@click.option("--gyro-model", default=None, show_default="gyro_baseline", help="Generated gyro model for the truth.")
@click.option("--acc-unit", type=click.Choice(["g", "m/s^2", "pulse/s"]), default=None,
              help="The accelerometer outputs' unit in samples.csv (default pulse/s, the paper's pulse counts; "
                   "the field scenario writes m/s^2).")
@click.option("--gyro-unit", type=click.Choice(["deg/h", "deg/s", "rad/s", "pulse/s"]), default=None,
              help="The gyro outputs' unit in samples.csv (default pulse/s, the paper's pulse counts; "
                   "the field scenario writes deg/s).")
@click.option("--effect", "effects", multiple=True, metavar="ID=VALUE",
              help="Plant a candidate effect in the truth, in the unit its term declares, e.g. "
                   "acc.quadratic.z=6e-5 or gyro.g_sensitivity.xz=0.3 (repeatable; paper and handheld).")
@EFFECT_FILE
@SETS
@click.option("--column", "columns", multiple=True, metavar="NAME=LOW:HIGH",
              help="Write an auxiliary column, one value per segment drawn uniformly in [LOW, HIGH], e.g. "
                   "supply_v=4.5:5.5 (one your --effect-file terms read) or temp_c=20:40; repeatable.")
@click.option("--temperature-c", default=None, metavar="T|T0:T1",
              help="Write temp_c: one plateau at T degC, or a ramp from T0 to T1 degC over the segments; the unit's "
                   "temperature effects (--effect ...bias_temperature..., scale_temperature...) act from --t-ref-c.")
@click.option("--t-ref-c", type=Number(-55.0, 125.0), default=None, show_default="25",
              help="With --temperature-c: the unit's T_ref, degC, the temperature at which its parameters are the "
                   "truth's (fixed, so that a plateau away from it shows the planted temperature effects).")
@click.option("--temperature-wander-c", type=Number(0.0, 10.0), default=None, show_default="0",
              help="With --temperature-c: each segment's temperature off the plateau or ramp by a uniform draw "
                   "within +- this, degC (a chamber's wander).")
@click.option("--no-noise-stated", is_flag=True, help="Leave acc_noise_g / gyro_noise_dph out of meta.json.")
@click.option("--duration-s", type=Number(1.0, 86400.0), default=None, show_default="1800 (still), 1500 (warmup)",
              help="still and warmup: the stream's length, s.")
@FORCE
def simulate(out_dir, output, scenario, heading_error_deg, seed, unit_seed, plan, sequence, rate_hz,
             position_error_arcmin, acc_model, gyro_model, acc_unit, gyro_unit, effects, effect_file, sets, columns,
             temperature_c, t_ref_c, temperature_wander_c, no_noise_stated, duration_s, force):
    """Simulate a test; write a measurement set and truth.json (simucal simulate -o FOLDER [options]).
    The Python API's simucal.simulate(...).write(FOLDER)."""
    from simucal import api
    if out_dir and output and Path(out_dir) != Path(output):
        fail(f"two output folders ({out_dir} and -o {output}): give one")
    out_dir = output or out_dir
    if not out_dir:
        fail("no output folder: give -o FOLDER")
    guard([p if p and Path(p).exists() else None for p in (plan, sequence)] + [effect_file], sets=[out_dir],
          force=force)
    ms = api.simulate(scenario, seed=seed, rate_hz=rate_hz, plan=plan, effects=effects,
                      position_error_arcmin=position_error_arcmin, acc_model=acc_model, gyro_model=gyro_model,
                      acc_unit=acc_unit, gyro_unit=gyro_unit, effect_file=effect_file, sets=sets, columns=columns,
                      temperature_c=temperature_c, t_ref_c=t_ref_c, temperature_wander_c=temperature_wander_c,
                      noise_stated=not no_noise_stated, heading_accuracy_deg=heading_error_deg,
                      sequence=sequence, unit_seed=unit_seed, duration_s=duration_s)
    ms.write(out_dir, force=force)
    click.echo(f"wrote {out_dir} ({api.simulation.resolved_scenario(scenario, sequence)} scenario, "  # what was written
               f"seed {seed}"
               + (f", the unit of seed {unit_seed})" if unit_seed is not None else ")"))


@main.command("import")
@click.argument("fmt", type=click.Choice(FORMATS))
@click.argument("sources", nargs=-1, required=True, type=InputPath(exists=True))
@click.option("-o", "--output", "--out-dir", "out_dir", required=True, type=click.Path(file_okay=False),
              help="The output folder (a measurement set).")
@click.option("--latitude-deg", type=LATITUDE, default=None,
              help="Site latitude, deg (the spec needs it with gyro data).")
@click.option("--acc-counts-per-g", type=POSITIVE, default=None, show_default=f"imucal-annotated {ANNOTATED_ACC:g}",
              help="Nominal accelerometer counts (LSB) per g: imu_tk (required), imucal-annotated.")
@click.option("--gyro-counts-per-dps", type=POSITIVE, default=None, show_default=f"imucal-annotated {ANNOTATED_GYRO:g}",
              help="Nominal gyro counts (LSB) per deg/s: imu_tk (required), imucal-annotated.")
@click.option("--gravity-mps2", type=Number(9.7, 9.9, what="m/s^2 on Earth"), default=None,
              show_default=f"{DEFAULT_GRAVITY:g}",
              help="imu_tk: local gravity, m/s^2, written to meta.json (g where a unit is m/s^2).")
@click.option("--rate-hz", type=Number(0.0, 1e6, low_open=True), default=None,
              show_default=f"imucal-ferraris {FERRARIS_HZ:g}, imucal-annotated {ANNOTATED_HZ:g}",
              help="Sample rate, Hz, where the file has no time column.")
@click.option("--columns", default=None, metavar="NAME=COLUMN,...",
              help="csv: map, e.g. 't_s=time,ax=acc_x,ay=acc_y,az=acc_z,gx=gyr_x,gy=gyr_y,gz=gyr_z'.")
@click.option("--acc-unit", type=click.Choice(ACC_UNITS), default=None,
              help="csv: the accelerometer columns' unit (pulse/s and counts need their nominal scale factors).")
@click.option("--gyro-unit", type=click.Choice(GYRO_UNITS), default=None,
              help="csv: the gyro columns' unit (pulse/s and counts need their nominal scale factors).")
@click.option("--turn-deg", type=Number(-3600.0, 3600.0), default=-360.0, show_default=True,
              help="Ferraris: the protocol's turn angle, deg (imucal's default -360, clockwise).")
@click.option("--instance", type=INSTANCES, default=None, metavar="N|N,M,...|all",
              help="ulog, dataflash: the IMU's instance (PX4's multi_id, ArduPilot's IMU.I or IMU2, IMU3); default: "
                   "ulog the highest-rate source, sensor_combined (PX4's primary IMU) included; dataflash the first. "
                   "Several, or all: one set per instance, OUT/instance<n>, the log read once.")
@click.option("--topic", default=None, help="rosbag: the sensor_msgs/Imu topic (default: the bag's only one).")
@FORCE
def import_cmd(fmt, sources, out_dir, latitude_deg, acc_counts_per_g, gyro_counts_per_dps, gravity_mps2, rate_hz,
               columns, acc_unit, gyro_unit, turn_deg, instance, topic, force):
    """Write a measurement set from another tool's recording, or from a PX4 ULog, an ArduPilot DataFlash
    log or a ROS 1 or ROS 2 bag (m/s^2 and rad/s as logged, the sensor frame and device ids in meta.json).
    The Python API's simucal.import_recording(FMT, SOURCES, OUT_DIR, ...)."""
    import warnings

    from simucal import api
    from simucal.errors import LogWarning
    several = isinstance(instance, list) or instance == "all"
    guard(sources, **({"folders": [out_dir]} if several else {"sets": [out_dir]}), force=force)
    if several and len(sources) != 1:
        fail(f"--instance {instance}: {fmt} reads one log: give one file")
    with warnings.catch_warnings(record=True) as said:  # a log's warnings, printed as lines
        warnings.simplefilter("always", LogWarning)
        if several:
            done = api.import_instances(fmt, sources[0], out_dir, instances=None if instance == "all" else instance,
                                        latitude_deg=latitude_deg, force=force, read_back=False)
        else:
            api.import_recording(fmt, sources, out_dir, latitude_deg=latitude_deg, acc_counts_per_g=acc_counts_per_g,
                                 gyro_counts_per_dps=gyro_counts_per_dps, gravity_mps2=gravity_mps2, rate_hz=rate_hz,
                                 columns=columns, acc_unit=acc_unit, gyro_unit=gyro_unit, turn_deg=turn_deg,
                                 instance=instance, topic=topic, force=force, read_back=False)
    for w in said:
        click.echo(f"WARNING: {w.message}", err=not issubclass(w.category, LogWarning))
    for ms in done if several else []:
        log = ms.meta["log"]
        click.echo(f"wrote {ms.path}: instance {log['instance']} ({log.get('source') or log.get('messages')}, "
                   f"{len(ms.samples['t_s']):,} rows)")
    if not several:
        click.echo(f"wrote {out_dir}")


@main.command("apply")
@click.argument("calibration_file", type=InputPath(exists=True, dir_okay=False))
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", "--out-dir", "out_dir", required=True, type=click.Path(file_okay=False),
              help="The output folder (a measurement set).")
@FORCE
@UNITS
def apply_cmd(calibration_file, data_dir, out_dir, force, units):
    """Apply a calibration to raw data: a measurement set in g and deg/h (--units si: m/s^2 and rad/s), frame b.
    The Python API's simucal.apply_set(simucal.load(CAL), DATA)."""
    from simucal import api
    guard([calibration_file, data_dir], sets=[out_dir], force=force)
    calibrated = api.apply_set(api.load(calibration_file), data_dir, where=calibration_file, units=units)
    calibrated.write(out_dir, force=True)  # guarded above, with --force
    for line in calibrated.meta.get("warnings", []):
        click.echo(f"WARNING: {line}")
    written = {"acc": calibrated.meta["acc_unit"], "gyro": calibrated.meta["gyro_unit"]}  # one the data lack: skipped
    click.echo(f"wrote {out_dir}: {len(calibrated.samples['t_s'])} rows in "
               f"{' and '.join(written[s] for s in calibrated.sensors)} (frame b), calibrated by {calibration_file}"
               + "".join(f"; {s} skipped (not in {data_dir})" for s in written if s not in calibrated.sensors))


@main.command()
@click.argument("calibration_file", type=InputPath(exists=True, dir_okay=False))
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="validation.json", show_default=True,
              help="The report (simucal.validation/1): each check's error at nominal, calibrated and its floor.")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page with a plot.")
@click.option("--acc-noise-g", type=NOISE_G, default=None,
              help="Noise of one acc row (g), where the data cannot give it (averaged rows): the checks' floors.")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None, help="Noise of one gyro row (deg/h), likewise.")
@click.option("--timestamps", type=click.Choice(("auto", "nominal", "recorded")), default=None,
              help="Stream: the time stamps as calibrate takes them (its --timestamps); default: as the calibration "
                   "read its own.")
@UNITS
def validate(calibration_file, data_dir, output, html_path, acc_noise_g, gyro_noise_dph, timestamps, units):
    """Apply a calibration to an independent set: the error before (nominal) and after, against the noise floor.
    The Python API's simucal.validate(CAL, DATA)."""
    from simucal import api
    from simucal.api.validating import lines
    guard([calibration_file, data_dir], files={"-o": output, "--html": html_path})
    result = api.validate(calibration_file, data_dir, acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph,
                          timestamps=timestamps)
    _save(result, output, None)
    _save(result, html_path, units=units)
    for line in lines(result.report, units):
        click.echo(line)
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))


def _save(result, *paths, units="spec"):
    """The result's report and page (api.save), where a path is given; a page in the unit system asked."""
    from simucal import api
    for path in paths:
        if path:
            api.save(path, result, units=units)


@main.command()
@click.argument("data_dir", type=InputPath(exists=True))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="noise.json", show_default=True,
              help="The report (simucal.noise/1): per axis the Allan deviation and the IEEE 952 terms.")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page with the Allan deviation plot.")
@click.option("--kalibr", "kalibr_path", type=click.Path(dir_okay=False), default=None,
              help="Also write Kalibr's imu.yaml (noise densities and random walks, SI); refused unless both sensors "
                   "give them.")
@click.option("--tau-max-s", type=POSITIVE, default=None, show_default="a ninth of the longest still stretch",
              help="The longest tau, s.")
@click.option("--scheduler", default="local", show_default=True,
              help="Where the sums over a stream's rows run: local (this process, the recording's cumulative sums in "
                   "memory, 48 bytes a row), processes (a Dask LocalCluster on 127.0.0.1; the sums on disk in TMPDIR, "
                   "for a recording larger than memory) or a Dask scheduler's address (its workers must see TMPDIR): "
                   "the same numbers on any. " + SCHEDULER_TRUST)
@click.option("--topic", default=None, help="DATA a ROS 1 bag or a ROS 2 bag's folder: its sensor_msgs/Imu topic "
                                            "(default: the bag's only one), read as `simucal import rosbag` reads it.")
@UNITS
def noise(data_dir, output, html_path, kalibr_path, tau_max_s, scheduler, topic, units):
    """Allan deviation of a still recording (a measurement set, or a ROS bag) and its IEEE 952 noise terms (ARW,
    bias instability, ...); a stream is read a chunk at a time. The Python API's simucal.noise(DATA)."""
    from simucal import api
    from simucal.io import outputs
    guard([data_dir], files={"-o": output, "--html": html_path, "--kalibr": kalibr_path})
    result = api.noise(data_dir, tau_max_s=tau_max_s, scheduler=scheduler, topic=topic)
    yaml = result.kalibr_yaml() if kalibr_path else None  # refused before anything is written
    written = {"-o": output, "--kalibr": kalibr_path}
    _save(result, output)
    if html_path:  # its next step the console's: the page is written beside the report and imu.yaml
        api.save(html_path, result, units=units, written=written)
    if kalibr_path and yaml is not None:
        outputs.write_text(kalibr_path, yaml)
    for line in result.lines(written, units):
        click.echo(line)
    click.echo(f"wrote {output}" + "".join(f" and {p}" for p in (html_path, kalibr_path) if p))


@main.command()
@click.argument("data_dir", type=InputPath(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(file_okay=False), required=True,
              help="The new set's folder (meta.json and segments.csv copied, the samples converted).")
@click.option("--to", "to", type=click.Choice(["parquet", "csv"]), required=True,
              help="The samples' format: samples.parquet (columnar, binary: smaller and faster to read) "
                   "or samples.csv.")
@FORCE
def convert(data_dir, output, to, force):
    """Copy a measurement set with its samples as samples.parquet or samples.csv, read and written a chunk at a time
    (every row checked as it is read); the input is never changed. The Python API's simucal.convert(DIR, OUT, TO)."""
    from simucal import api
    guard([data_dir], sets=[output], force=force)
    path, rows = api.convert(data_dir, output, to, force=force)
    click.echo(f"wrote {path}: {rows} rows")
