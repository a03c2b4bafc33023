"""The `simucal` command."""
from __future__ import annotations

import math
import os
import sys
import warnings
from pathlib import Path

import click

from simucal import methods


class _Commands(click.Group):
    """Every refusal is one line (_fail, exit 2). Anything else escaping a command is a bug:
    one line too, exit 3, and the traceback with SIMUCAL_DEBUG=1."""

    def invoke(self, ctx):
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy's, printed before a clear error otherwise
        try:
            return super().invoke(ctx)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException, KeyboardInterrupt):
            raise
        except BrokenPipeError:  # the reader went away (| head): not an error of ours or the user's
            sys.stdout = open(os.devnull, "w")
            sys.exit(141)
        except Exception as e:
            from simucal.errors import CalibrationError
            from simucal.io import MeasurementSetError
            if isinstance(e, (CalibrationError, MeasurementSetError)):  # a refusal that reached the top
                _fail(e)
            if os.environ.get("SIMUCAL_DEBUG"):
                raise
            click.echo(f"error: internal error ({type(e).__name__}: {e}); this is a bug in simucal: please report it "
                       "with the command and the data (SIMUCAL_DEBUG=1 shows the traceback)", err=True)
            sys.exit(3)


@click.group(cls=_Commands)
@click.version_option(package_name="simucal")
def main():
    """Strapdown IMU calibration: derive, simulate, calibrate, audit."""


def _fail(e):
    """One line on stderr, exit 2: the refusal of bad input (nothing is written)."""
    click.echo(f"error: {e.args[0] if isinstance(e, KeyError) and e.args else e}", err=True)
    sys.exit(2)


class _Refused(click.ClickException):
    """A refusal while the options are read: one line and exit 2, as _fail."""
    exit_code = 2

    def show(self, file=None):
        click.echo(f"error: {self.message}", err=True)


class Number(click.ParamType):
    """A finite number in a range: NaN, infinities and values outside it are refused, naming the
    option, the value and the range (click's FloatRange lets NaN through)."""
    name = "number"

    def __init__(self, low=None, high=None, low_open=False, integer=False, what=""):
        self.low, self.high, self.low_open, self.integer, self.what = low, high, low_open, integer, what

    def convert(self, value, param, ctx):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            v = float(value)  # a default
        else:
            try:
                v = float(str(value).strip())
            except ValueError:
                raise _Refused(f"{self._name(param)} {self._shown(value)}: not a number") from None
        if not math.isfinite(v):
            raise _Refused(f"{self._name(param)} {self._shown(value)}: must be a finite number")
        if self.integer and v != round(v):
            raise _Refused(f"{self._name(param)} {value}: must be a whole number")
        below = self.low is not None and (v <= self.low if self.low_open else v < self.low)
        if below or (self.high is not None and v > self.high):
            lo = None if self.low is None else f"{'>' if self.low_open else '>='} {self.low:g}"
            hi = None if self.high is None else f"<= {self.high:g}"
            raise _Refused(f"{self._name(param)} {value}: must be " + " and ".join(x for x in (lo, hi) if x)
                           + (f" ({self.what})" if self.what else ""))
        return int(round(v)) if self.integer else v

    @staticmethod
    def _shown(value):
        return value if str(value).isprintable() and str(value).strip() else repr(value)

    @staticmethod
    def _name(param):
        return max(param.opts, key=len) if param is not None and param.opts else "value"


_MODEL_FILE_RUNS = ("A model file is Python: like any plugin, its code runs when it is derived (once, in a child "
                    "process with a time limit; never again once in the cache), so use only files you trust.")
POSITIVE = Number(0.0, low_open=True)
SEED = Number(0, 2 ** 32 - 1, integer=True, what="numpy's seeds")
NOISE_G = Number(0.0, 1.0, low_open=True, what="the std of one row, g")
NOISE_DPH = Number(0.0, 1e6, low_open=True, what="the std of one row, deg/h")
LATITUDE = Number(-90.0, 90.0, what="degrees")
SIM_RATE_HZ = Number(0.0, 2000.0, low_open=True, what="the simulator writes raw rows up to 2 kHz")
MAX_TRIALS = 10_000_000  # ~1.4 GB of estimates, about two minutes compiled

_FORCE = click.option("--force", is_flag=True,
                      help="Replace a measurement set already in the output folder (never one of the inputs).")


def _guard(inputs=(), files=(), sets=(), folders=(), force=False):
    """Refuse outputs that would write into or over an input, or replace a measurement set
    without --force (io/outputs.py); before any work, so nothing is lost."""
    from simucal.io.outputs import OutputError, check
    try:
        check(inputs, files, sets, folders, force)
    except OutputError as e:
        _fail(e)


@main.command()
@click.option("--check", is_flag=True, help="Fail if generated/ differs from what derive writes now.")
@click.option("--model", "model_files", multiple=True, type=click.Path(exists=True, dir_okay=False),
              help="A Python file defining MODELS = [ErrorModel, ...]: derived into the cache "
                   "(not generated/), then usable by name from any folder. " + _MODEL_FILE_RUNS)
def derive(check, model_files):
    """Derive the built-in models and (re)write generated/; or derive your own model file."""
    from simucal import derive_cmd
    if model_files:
        from simucal.fit.catalog import derive_model_file
        for f in model_files:
            try:
                names, _ = derive_model_file(f)
            except (FileNotFoundError, ValueError, SyntaxError) as e:
                _fail(e)
            click.echo(f"derived {', '.join(names)} from {f} into the cache")
        return
    stale, secs, diff = derive_cmd.run(check=check)
    if check:
        if stale:
            click.echo(diff + "generated/ is stale; run `simucal derive`. Differs: " + ", ".join(stale), err=True)
            sys.exit(1)
        click.echo(f"generated/ is up to date ({secs:.1f} s)")
    else:
        click.echo(f"wrote {derive_cmd.generated_dir()} ({secs:.1f} s)")


@main.command()
@click.argument("out_dir", type=click.Path(file_okay=False))
@click.option("--scenario", type=click.Choice(["paper", "field"]), default="paper", show_default=True,
              help="Preset: 'paper' is dong2018 section 4 (turntable); 'field' is ruan2019 (three positions, no table).")
@click.option("--heading-error-deg", type=Number(0.0, 180.0), default=None,
              help="field: the north reference's error, uniform +- this.")
@click.option("--seed", type=SEED, default=0, show_default=True)
@click.option("--plan", default=None,
              help="table1, dodecahedron20, fibonacci24, fibonacci48, or a CSV of outer_deg,middle_deg,inner_deg.")
@click.option("--rate-hz", type=SIM_RATE_HZ, default=None,
              help="Write raw samples at this rate (Hz, up to 2000) instead of one row per position.")
@click.option("--position-error-arcmin", type=Number(0.0, 10800.0), default=None, help="Uniform +- angular position error.")
@click.option("--acc-model", default=None, help="Generated model for the truth (may hold terms calibration lacks).")
@click.option("--gyro-model", default=None, help="Generated gyro model for the truth.")
@click.option("--acc-unit", type=click.Choice(["g", "m/s^2", "pulse/s"]), default=None)
@click.option("--gyro-unit", type=click.Choice(["deg/h", "deg/s", "rad/s", "pulse/s"]), default=None)
@click.option("--effect", "effects", multiple=True, metavar="ID=VALUE",
              help="Plant a candidate effect in the truth, in the unit its term declares, e.g. "
                   "acc.quadratic.z=6e-5 or gyro.g_sensitivity.xz=0.3 (repeatable).")
@click.option("--effect-file", default=None, type=click.Path(dir_okay=False),
              help="A model file of your own terms (MODELS = [...]); its models become the truth models. "
                   + _MODEL_FILE_RUNS)
@click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
              help="With --effect-file: the true value of one of its parameters (repeatable).")
@click.option("--column", "columns", multiple=True, metavar="NAME=LOW:HIGH",
              help="Write an auxiliary column, one value per segment drawn uniformly in [LOW, HIGH], e.g. "
                   "supply_v=4.5:5.5 (one your --effect-file terms read) or temp_c=20:40; repeatable.")
@click.option("--no-noise-stated", is_flag=True, help="Leave acc_noise_g / gyro_noise_dph out of meta.json.")
@_FORCE
def simulate(out_dir, scenario, heading_error_deg, seed, plan, rate_hz, position_error_arcmin, acc_model, gyro_model,
             acc_unit, gyro_unit, effects, effect_file, sets, columns, no_noise_stated, force):
    """Simulate a test; write a measurement set and truth.json."""
    from simucal.turntable.simulate import ARCMIN, SCENARIOS, plant, write
    _guard([plan if plan and Path(plan).exists() else None, effect_file], sets=[out_dir], force=force)
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
        plant(sc, effects, effect_file, sets, columns)
        write(out_dir, sc, seed)
    except (ValueError, KeyError, FileNotFoundError, SyntaxError) as e:
        _fail(e)
    click.echo(f"wrote {out_dir} (scenario {scenario}, seed {seed})")


HEADING_ACCURACY = click.option(
    "--heading-accuracy-deg", type=Number(0.0, 180.0), default=5.0, show_default=True,
    help="Field sets: the stated accuracy of the north reference; its effect enters the uncertainty.")
_ADD_HELP = ("Effect id to add, e.g. acc.quadratic.z (exact ids; unknown ones are refused), or a model file "
             "(MODELS = [...]) with your own SymPy terms, derived into the cache (repeatable). " + _MODEL_FILE_RUNS)
_ADD_AUTO_HELP = (_ADD_HELP + " Also 'auto': the library effects a failing model needs, chosen one at a time by the "
                  "same test as diagnose, each also predicting left-out positions better.")


def _sensor_lines(result):
    """One line per sensor: the test, and when the model fails what to add."""
    for s in ("acc", "gyro"):
        out = [x["segment"] for x in result.get("excluded_segments", []) if x["sensor"] == s]
        if out:
            yield (f"{s}: {len(out)} segments left out, their samples clipped (at full_scale or repeating the rail): "
                   f"{out[:10]}{' ...' if len(out) > 10 else ''}")
        b = result.get(s)
        if not b or b.get("nominal"):
            continue
        if "thermal" in b:
            yield from _thermal_lines(s, b)
            continue
        if b.get("residual_rms") is None:  # a method without a fit of its own rows (field: the drift alone)
            yield (f"{s}: bias ({b['bias_unit']}, {b['description']}): " + ", ".join(
                f"{a} {v:+.4g} +- {e:.2g}" for a, v, e in zip("xyz", b["bias"], b["std"]["bias"])))
            continue
        unit = b.get("residual_unit", b.get("bias_unit"))
        rows = f" over {b['rows']}" if b.get("rows") else ""
        test = (f"chi2 {b['chi2']:.1f}, dof {b['dof']}{rows}, p = {b['p_value']:.3g}" if b.get("chi2") is not None
                else f"p = {b['p_value']:.3g} ({b.get('test', '')}{rows})" if b.get("p_value") is not None
                else "no test (" + b.get("test", "no noise estimate") + ")")
        eff = "".join(f"; {e} = {v['value']:.4g} +- {v['std']:.2g} {v['unit']}" for e, v in b.get("effects", {}).items())
        cv = b.get("cross_validation")
        held = (f"; |u| - rho {cv['in_sample_rms']:.3g} {cv['unit']} rms on the fit's rows, {cv['held_out_rms']:.3g} "
                f"on rows left out ({cv['rows']} rows, one at a time)" if cv and cv.get("held_out_rms") else "")
        yield f"{s}: residual rms {b['residual_rms']:.3g} {unit}; {test}{eff}{held}"
        if (b.get("noise") or {}).get("text"):
            yield f"{s}: noise {b['noise']['text']}"
        if b.get("noise_warning"):
            yield f"{s}: WARNING: {b['noise_warning']}"
        if b.get("saturation"):
            yield (f"{s}: saturated (clipped) samples: " + ", ".join(
                f"{x['count']} on {x['axis']} from line {x['first_row'] + 2} of samples.csv" for x in b["saturation"]))
        if b.get("moves_skipped"):
            why = sorted({m["reason"] for m in b["moves_skipped"]})
            yield f"{s}: {len(b['moves_skipped'])} of {b['moves_used'] + len(b['moves_skipped'])} moves left out ({'; '.join(why)})"
        if b.get("model_choice"):
            yield (f"{s}: T chosen by the moves left out one at a time: " + ", ".join(
                f"{k} {v['held_out_rms_deg']:.3g} deg" for k, v in b["model_choice"].items())
                + f" rms; {b['gyro_model']} taken (the best predictor of the moves left out)")
        if "auto" in b:
            yield (f"{s}: --add auto chose " + (", ".join(x["id"] for x in b["auto"]) + " (one at a time, each passing "
                   "the candidate test and predicting left-out rows better)" if b["auto"] else "nothing")
                   + (f"; {b['auto_stopped']}" if b.get("auto_stopped") else ""))
        if b.get("p_value") is not None and b["p_value"] < 1e-3:
            what = b.get("advice")
            stds = ("stds are inflated by sqrt(chi2/dof) (std_raw keeps the unscaled ones)" if "std_raw" in b else
                    b["std_note"] if b.get("std_note") else f"stds include a model-error std {b['model_error_std_g']:.2g} g per pose"
                    if b.get("model_error_std_g") else "stds assume the model is right")
            yield (f"{s}: THE MODEL FAILS (p = {b['p_value']:.2g} < 1e-3): "
                   + ("the stated noise may be too small (the warning above); " if b.get("noise_too_small") else "")
                   + (f"diagnose would add {what}; " if what else
                      f"see simucal diagnose {result['input']} for what is missing; ") + stds)
    u = result.get("unification")
    if u and "std_rad" in u:
        yield (f"frames: C_b^d by {u['method'].replace('_', ' ')} ({u['pairs']} pairs), std "
               f"{max(u['std_rad']):.2g} rad, residual {u['direction_residual_rms_rad']:.2g} rad rms"
               + "".join(f"; noise of the {k.replace('_', ' ')}: {v['text']}" for k, v in u.get("noise", {}).items()
                         if k != "table_angles")
               + (f"; cross-check: {u['cross_check']['note']}" if "cross_check" in u else "")
               + (f"; {u['note']}" if u.get("note") else ""))
    for line in result.get("consistency", {}).get("lines", []):
        yield line
    for s in ("acc", "gyro"):
        und = (result.get(s) or {}).get("undetermined") or {}
        if und:
            alone = [v["std_moves_alone"] for v in und.values() if "std_moves_alone" in v]
            first = next(iter(und.values()))
            yield (f"{s}: {', '.join(und)} not determined by these data"
                   + (f" (std alone {max(alone):.2g})" if alone else "")
                   + f": estimated under a soft prior {first['held_at']:g} +- {first['prior_std']:g} (a prior, not a "
                   "measurement: the estimate may leave it; \"determined\": false in the file); "
                   f"to determine them, " + "; ".join(sorted({v["to_determine"] for v in und.values()})))
    for s in ("acc", "gyro"):
        poor = (result.get(s) or {}).get("poorly_determined") or {}
        if poor:
            unit = {k: "" if u == "1" else f" {u}" for k, u in (result[s].get("param_units") or {}).items()}
            yield (f"{s}: POORLY DETERMINED by this plan: " + ", ".join(
                f"{k} (std {v['std']:.2g}{unit.get(k, '')}, {v['inflation']:.0f}x an uncorrelated design's)"
                for k, v in sorted(poor.items(), key=lambda kv: -kv[1]["inflation"]))
                + "; they are nearly confounded with other parameters: add positions with other input directions "
                "(simucal plan --score PLAN shows the correlations)")
    for sensor, why in result.get("not_calibrated", {}).items():
        yield f"{sensor}: NOT CALIBRATED: {why}"
    for line in result.get("warnings", []):
        yield f"WARNING: {line}"


def _thermal_lines(s, b):
    """A thermal block: the plateaus' tests, then every parameter that follows temperature."""
    th = b["thermal"]
    yield (f"{s}: {len(th['plateaus_c'])} plateaus at " + ", ".join(f"{t:.4g}" for t in th["plateaus_c"])
           + f" degC, T_ref {th['t_ref_c']:.4g} degC; per plateau p = "
           + ", ".join("-" if x["p_value"] is None else f"{x['p_value']:.3g}" for x in b["plateaus"]))
    moving = {n: f for n, f in th["parameters"].items() if f["degree"] > 0}
    for n, f in moving.items():
        unit = b.get("param_units", {}).get(n, "")
        terms = " ".join((f"{c:.4g}" if not k else f"{'+' if c >= 0 else '-'} {abs(c):.4g}")
                         + (f" dT^{k}" if k > 1 else " dT" if k else "") for k, c in enumerate(f["coefficients"]))
        yield f"{s}: {n} = {terms} ({unit}; dT = T - T_ref in degC; degree {f['degree']} chosen by the data)"
    yield (f"{s}: {len(th['parameters']) - len(moving)} of {len(th['parameters'])} parameters constant over the "
           "plateaus (a temperature dependence below their noise)")


@main.command()
@click.argument("data_dirs", nargs=-1, required=True, type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(), default="calibration.json", show_default=True,
              help="The calibration file; with several sets, a folder that gets one <set>.json each (with "
                   "--thermal: one file).")
@click.option("--thermal", is_flag=True, help="The sets are one unit at several temperature plateaus (temp_c): every "
              "parameter a polynomial in T - T_ref, applied at each row's temp_c.")
@click.option("--thermal-degree", type=click.IntRange(0, 3), default=None,
              help="--thermal: the polynomials' degree (default: chosen by the data per parameter).")
@click.option("--html", "html_out", type=click.Path(dir_okay=False), default=None,
              help="--thermal: a page with each parameter against temperature and its fitted polynomial.")
@click.option("--t-ref-c", type=Number(-60.0, 150.0), default=None,
              help="T_ref of temperature terms, degC (default: the mean of temp_c; --thermal: of the plateaus).")
@click.option("--method", type=click.Choice(("auto",) + methods.NAMES), default="auto", show_default=True,
              help="auto: the default for the set's data. " + " ".join(
                  f"{m.name}: {m.summary} ({methods.DATA[m.data]})." for m in methods.METHODS.values()))
@click.option("--acc-model", default="acc_baseline", show_default=True)
@click.option("--gyro-model", default="gyro_baseline", show_default=True)
@click.option("--add", "add", multiple=True, help=_ADD_AUTO_HELP)
@click.option("--acc-noise-g", type=NOISE_G, default=None, help="Noise of one acc row (g), where the data cannot give it.")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None, help="Noise of one gyro row (deg/h).")
@click.option("--noise", "noise_file", type=click.Path(exists=True, dir_okay=False), default=None,
              help="A noise.json of simucal noise: each segment's noise from its Allan curve at the segment's length "
                   "(averaged rows: meta.json's average_s).")
@click.option("--init-rest-s", type=POSITIVE, default=None, help="Stream: length of the initial rest (default: found from the data).")
@click.option("--threshold-factor", type=Number(1.0, 1e6, low_open=True), default=6.0, show_default=True,
              help="Stream: static threshold, times the rest's variance.")
@click.option("--window-s", type=POSITIVE, default=1.0, show_default=True, help="Stream: moving-variance window.")
@click.option("--min-static-s", type=POSITIVE, default=1.0, show_default=True, help="Stream: shortest static interval.")
@HEADING_ACCURACY
@click.option("--scheduler", default="local", show_default=True,
              help="Several sets: local, processes (a Dask LocalCluster) or a Dask scheduler's address.")
def calibrate(data_dirs, output, thermal, thermal_degree, html_out, t_ref_c, method, acc_model, gyro_model, add, acc_noise_g,
              gyro_noise_dph, noise_file, init_rest_s, threshold_factor, window_s, min_static_s, heading_accuracy_deg, scheduler):
    """Calibrate measurement sets; write calibration.json (one per set into a folder for several).

    With segments.csv and table angles: a turntable test (dong2018). Without segments.csv: a
    continuous stream from a hand-placed session (static poses found from the data; Tedaldi).
    With heading_ref_deg and no table angles: a field set (ruan2019's gyro drift)."""
    from simucal.calibrate import calibrate_to_file
    from simucal.handheld.static_detect import DetectSettings
    kwargs = dict(method=method, acc_model=acc_model, gyro_model=gyro_model,
                  detect=DetectSettings(window_s, threshold_factor, min_static_s, init_rest_s), add=add,
                  acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, heading_accuracy_deg=heading_accuracy_deg,
                  noise=noise_file)
    inputs = list(data_dirs) + [a for a in add if a.endswith(".py")] + ([noise_file] if noise_file else [])
    if thermal or thermal_degree is not None:
        return _calibrate_thermal(data_dirs, output, thermal_degree, t_ref_c, kwargs, inputs, html_out)
    if html_out:
        _fail("--html: a page of a thermal calibration (with --thermal); for one set use simucal diagnose --html")
    kwargs["t_ref_c"] = t_ref_c
    if len(data_dirs) == 1:
        _guard(inputs, files=[output])
        result, error = calibrate_to_file(Path(data_dirs[0]), output, kwargs)
        if error:
            _fail(error)
        for line in _sensor_lines(result):
            click.echo(line)
        click.echo(f"wrote {output} (method {result['method']})")
        return
    from simucal import progress
    from simucal.errors import CalibrationError
    from simucal.sweeps import map_tasks
    out = Path(output)
    names = [Path(d).resolve().name for d in data_dirs]
    if out.suffix == ".json" or (out.exists() and not out.is_dir()):
        _fail(f"-o {output}: with {len(data_dirs)} sets, -o names a folder (one <set>.json each)")
    if len(set(names)) < len(names):
        _fail(f"two sets share a folder name ({sorted(n for n in names if names.count(n) > 1)[0]}): their files "
              "would collide; calibrate them separately")
    tasks = [(Path(d), out / f"{n}.json", kwargs) for d, n in zip(data_dirs, names)]
    _guard(inputs, files=[path for _, path, _ in tasks], folders=[out])
    made = not out.exists()
    out.mkdir(exist_ok=True)
    try:
        done = map_tasks(calibrate_to_file, tasks, scheduler, progress=progress.bar("calibrate", "set"))
    except CalibrationError as e:  # no scheduler: leave nothing behind
        if made:
            out.rmdir()
        _fail(e)
    failed = 0
    for (d, path, _), (result, error) in zip(tasks, done):
        if error:
            failed += 1
            click.echo(f"{d}: error: {error}", err=True)
        else:
            tests = ", ".join(f"{k} p = {result[k]['p_value']:.3g}" for k in ("acc", "gyro")
                              if result.get(k, {}).get("p_value") is not None)
            click.echo(f"{d}: wrote {path}" + (f" ({tests})" if tests else ""))
    click.echo(f"{len(tasks) - failed} of {len(tasks)} sets calibrated into {out}")
    if failed:
        sys.exit(2)


def _calibrate_thermal(data_dirs, output, degree, t_ref_c, kwargs, inputs, html_out):
    from simucal.calibrate import calibrate_thermal
    from simucal.errors import CalibrationError
    from simucal.io import calibration, outputs
    _guard(inputs, files=[output] + ([html_out] if html_out else []))
    try:
        result = calibrate_thermal([Path(d) for d in data_dirs], degree, t_ref_c, **kwargs)
        calibration.save(output, result)
    except (ValueError, KeyError, CalibrationError, FileNotFoundError) as e:
        _fail(e)
    for line in _sensor_lines(result):
        click.echo(line)
    if html_out:
        from simucal.report.thermal_html import thermal_page
        outputs.write_text(html_out, thermal_page(result))
        click.echo(f"wrote {html_out}")
    click.echo(f"wrote {output} (method {result['method']}; calibrated from {result['temperature_range_c'][0]:.4g} to "
               f"{result['temperature_range_c'][1]:.4g} degC)")


@main.command("apply")
@click.argument("calibration_file", type=click.Path(exists=True, dir_okay=False))
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", "--out-dir", "out_dir", required=True, type=click.Path(file_okay=False),
              help="The output folder (a measurement set).")
@_FORCE
def apply_cmd(calibration_file, data_dir, out_dir, force):
    """Apply a calibration to raw data: a measurement set in g and deg/h, frame b."""
    from simucal import io
    from simucal.fit.apply import apply
    from simucal.io import calibration
    _guard([calibration_file, data_dir], sets=[out_dir], force=force)
    try:
        cal = calibration.load(calibration_file)
        meta, samples, segments = apply(cal, Path(data_dir), calibration_file)
    except (ValueError, KeyError) as e:  # MeasurementSetError, CalibrationError, CalibrationFileError
        _fail(e)
    io.write_set(out_dir, meta, samples, segments)
    for line in meta.get("warnings", []):
        click.echo(f"WARNING: {line}")
    click.echo(f"wrote {out_dir}: {len(samples['t_s'])} rows in g and deg/h (frame b), calibrated by "
               f"{calibration_file}")


@main.command()
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="audit.md", show_default=True)
@click.option("--seeds", type=Number(0, 10000, integer=True), default=20, show_default=True,
              help="Simulated tests per setting for the Monte Carlo of the paper's claims (0: skip it).")
def audit(output, seeds):
    """Check the paper's printed equations (4)-(27), Table 1 and 2, term by term at the section-4
    values, and its numeric claims (abstract, Tables 3 and 4) against a Monte Carlo."""
    from simucal import progress
    from simucal.io import outputs
    from simucal.report.paper_claims import full_audit
    _guard(files=[output])
    report = full_audit(seeds, progress=progress.bar("audit", "item"))
    outputs.write_text(output, report.markdown())
    click.echo(f"wrote {output}: {report.summary()}")


@main.command()
@click.option("-o", "--output", "--out-dir", "out_dir", type=click.Path(file_okay=False), default="out", show_default=True)
@click.option("--seed", type=SEED, default=0, show_default=True)
@_FORCE
def demo(out_dir, seed, force):
    """The main job end to end on built-in simulated data: a hidden effect found, added,
    calibrated with and applied; then dong2018's methods, the audit and the diagnosis."""
    from simucal import demo as demo_mod
    out = Path(out_dir)  # its sets may be replaced where an earlier demo wrote them (its demo.json)
    _guard(sets=[out] + [out / d for d in demo_mod.SETS], force=force or (out / demo_mod.MARKER).is_file())
    try:
        demo_mod.run(out_dir, seed, click.echo)
    except RuntimeError as e:
        _fail(e)


def _added_lines(result):
    """diagnose --add: the residual and p before and after, per sensor, with units."""
    for s in ("acc", "gyro"):
        a = result.get(s, {}).get("added")
        if a:
            u = a.get("residual_unit", "")
            p0, p1 = a["p_value_before"], a["p_value_after"]
            fmt = lambda p: "n/a" if p is None else f"{p:.3g}"
            yield (f"{s} with {', '.join(a['effects'])}: residual rms {a['residual_rms_before']:.3g} -> "
                   f"{a['residual_rms_after']:.3g} {u}, p {fmt(p0)} -> {fmt(p1)}")
            for k, row in a["params"].items():
                if row["before"] is None:
                    err = f", truth {row['truth']:.4g}" if "truth" in row else ""
                    yield f"    {k} = {row['after']:.4g} +- {row['std_after']:.2g}{err}"


def _shape_model_path(output, sensor):
    return Path(output).with_name(f"{Path(output).stem}_{sensor}_model.py")


def _write_shape_models(result, output):
    """Each sensor's found term as a ready model file beside the diagnosis; returns the paths."""
    from simucal.io import outputs
    paths = []
    for s in ("acc", "gyro"):
        shape = result.get(s, {}).get("shape")
        if shape and not shape.get("catalog_id"):
            path = _shape_model_path(output, s)
            outputs.write_text(path, shape["model_file"])
            shape["model_file_path"] = str(path)
            paths.append(path)
    return paths


@main.command()
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="diagnosis.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None, help="Also write a self-contained HTML report.")
@click.option("--add", "add", multiple=True, help=_ADD_HELP)
@click.option("--acc-model", default="acc_baseline", show_default=True)
@click.option("--gyro-model", default="gyro_baseline", show_default=True)
@click.option("--acc-noise-g", type=NOISE_G, default=None, help="Stated noise of one acc row (g), when the data cannot give it.")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None, help="Stated noise of one gyro row (deg/h).")
def diagnose(data_dir, output, html_path, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph):
    """Compare model and measurements; rank the candidate missing effects."""
    import json

    from simucal.diagnose import diagnose as diagnose_set
    from simucal.errors import CalibrationError
    from simucal.io import MeasurementSetError, outputs
    if "auto" in add:
        _fail(f"--add auto is calibrate's: diagnose already ranks every candidate; run simucal calibrate {data_dir} "
              "--add auto")
    _guard([data_dir] + [a for a in add if a.endswith(".py")],
           files=[output, html_path, _shape_model_path(output, "acc"), _shape_model_path(output, "gyro")])
    try:
        result = diagnose_set(Path(data_dir), add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph)
    except (MeasurementSetError, CalibrationError, KeyError, FileNotFoundError, ValueError) as e:
        _fail(e)
    models = _write_shape_models(result, output)
    outputs.write_text(output, json.dumps(result, indent=1, default=float) + "\n")
    if html_path:
        from simucal.report.html import render
        outputs.write_text(html_path, render(result))
    for line in result["verdict"].split(" | ") + result.get("notes", []):
        click.echo(line)
    for line in _added_lines(result):
        click.echo(line)
    for m in models:
        click.echo(f"wrote {m}: the found term as a model file; try: simucal diagnose {data_dir} --add {m}")
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))


@main.command()
@click.option("--scenario", type=click.Choice(["paper"]), default="paper", show_default=True,
              help="dong2018 section 4 (simulate's defaults).")
@click.option("--plan", default=None, help="table1 (default), dodecahedron20, fibonacci24, fibonacci48 or plan.csv.")
@click.option("--trials", type=Number(2, MAX_TRIALS, integer=True), default=10000, show_default=True)
@click.option("--seed", type=SEED, default=0, show_default=True)
@click.option("--effect", "effects", multiple=True, metavar="ID=VALUE",
              help="Plant a candidate effect in the truth and fit it (repeatable; slower: fit_exact per trial).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="montecarlo.json", show_default=True)
@click.option("--scheduler", default="local", show_default=True,
              help="local (this process), processes (a Dask LocalCluster, one worker per core) or a Dask "
                   "scheduler's address: the same numbers on any.")
def montecarlo(scenario, plan, trials, seed, effects, output, scheduler):
    """Monte Carlo of a scenario: simulate, exact fits, unification; std against the Cramer-Rao bound."""
    import json

    from simucal import progress
    from simucal.io import outputs
    from simucal.turntable.montecarlo import run
    from simucal.turntable.simulate import SCENARIOS, plant
    _guard([plan if plan and Path(plan).exists() else None], files=[output])
    if effects and trials > MAX_TRIALS // 10:  # their fits run in numpy, ~10x slower
        _fail(f"--trials {trials}: with --effect at most {MAX_TRIALS // 10} (about two minutes); split the run "
              "over seeds")
    sc = SCENARIOS[scenario]()
    if plan:
        sc.plan = plan
    try:
        plant(sc, effects)
        result = run(sc, trials, seed, scheduler=scheduler,
                     progress=progress.bar("montecarlo", "batch"))
    except (ValueError, KeyError, FileNotFoundError) as e:
        _fail(e)
    outputs.write_text(output, json.dumps(result, indent=1) + "\n")
    click.echo(f"{trials} trials in {result['seconds']:.2f} s ({result['trials_per_s']:.0f}/s, {result['backend']}, "
               f"scheduler {scheduler}); "
               f"{result['failed']} failed")
    click.echo(f"{'parameter':18} {'truth':>12} {'mean':>12} {'std':>10} {'CRLB':>10} {'std/CRLB':>9}")
    for name, v in result["parameters"].items():
        click.echo(f"{name:18} {v['truth']:12.5g} {v['mean']:12.5g} {v['std']:10.3g} {v['crlb']:10.3g} "
                   f"{v['std_over_crlb']:9.3f}")
    click.echo(f"wrote {output}")


@main.command()
@click.option("--score", "score_plan", default=None, metavar="PLAN",
              help="Score a plan: table1, dodecahedron20, fibonacci24, fibonacci48 or a CSV (outer_deg,middle_deg,inner_deg).")
@click.option("--model", "model_name", default="acc_baseline", show_default=True, help="Generated model (acc or gyro).")
@click.option("--add", "add", multiple=True, help="Candidate effect ids to add to the model (repeatable).")
@click.option("--positions", type=Number(1, 300, integer=True), default=None, help="Design a plan with this many positions.")
@click.option("--criterion", type=click.Choice(["D", "A"]), default="D", show_default=True)
@click.option("--rate-dps", type=Number(-3600.0, 3600.0), default=10.0, show_default=True,
              help="Gyro models: the outer-axis rate of the rate runs.")
@click.option("--rates", default=None, metavar="R1,R2,...", help="Gyro design: rates (deg/s) to choose from, e.g. 5,10,20.")
@click.option("--table", "kind", type=click.Choice(["three-axis", "hand"]), default="three-axis", show_default=True,
              help="Design for a three-axis table (angles) or hand-placed poses (gravity directions in the unit).")
@click.option("--sigma", type=POSITIVE, default=None,
              help="Noise of one position's mean (default: section 4's, 1e-5 g or 0.01 deg/h).")
@click.option("--separate", "pair", default=None, metavar="ID1,ID2",
              help="With --score: the positions to add so that these two candidate effects are told apart.")
@click.option("--sizes", default=None, metavar="Q1,Q2", help="With --separate: the effects' sizes, in their units.")
@click.option("--power", "target", type=Number(0.0, 1.0, low_open=True), default=0.9, show_default=True,
              help="With --separate: the power to reach.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Design: the plan CSV (a JSON sidecar with its scores beside it); score: the JSON.")
def plan(score_plan, model_name, add, positions, criterion, rate_dps, rates, kind, sigma, pair, sizes, target, output):
    """Score a test plan (Fisher information, CRLB, correlations, D and A criteria) or design one."""
    import json

    import numpy as np

    from simucal.errors import CalibrationError
    from simucal.fit.augmented import AugmentedModel
    from simucal.turntable import plans
    from simucal.turntable.plan_design import design, directions_k, plan_rows, score
    from simucal.io.calibration import PARAM_LIMIT
    from simucal.io.units import DPH_PER_DPS
    if (score_plan is None) == (positions is None):
        _fail("give --score PLAN to score a plan, or --positions N to design one")
    from simucal.io import outputs
    if output:
        _guard([score_plan if score_plan and Path(score_plan).exists() else None],
               files=[output] + ([str(Path(output).with_suffix(".json"))] if positions is not None else []))
    elif positions is not None:
        _guard(files=["plan.csv", "plan.json"])
    try:
        model = AugmentedModel(model_name, tuple(add))
        gyro = model.sensor == "gyro"
        if gyro and rate_dps == 0:
            raise ValueError(f"--rate-dps {rate_dps}: a rate run needs a non-zero rate (deg/s)")
        rate_list = [float(x) for x in rates.split(",")] if rates else [rate_dps]
        if gyro and not all(abs(x) > 0 for x in rate_list):
            raise ValueError(f"--rates {rates}: a rate run needs a non-zero rate (deg/s)")
        rho = abs(rate_dps) * DPH_PER_DPS if gyro else 1.0
        sigma = sigma if sigma is not None else (0.01 if gyro else 1e-5)
        if score_plan is not None:
            rows = plans.PLANS[score_plan]() if score_plan in plans.PLANS else plans.read_csv(score_plan)
            u, name = directions_k(rows), score_plan
        else:
            u, rho = design(model, positions, np.abs(rate_list) * DPH_PER_DPS if gyro else 1.0, sigma, criterion)
            name = f"{criterion}-optimal, {positions} positions"
        result = {"plan": name, **score(model, u, rho, sigma)}
        if pair:
            if score_plan is None or not sizes:
                raise ValueError("--separate needs --score PLAN (the plan you have) and --sizes Q1,Q2")
            from simucal.fit.augmented import check_effect
            from simucal.turntable.plan_design import separate
            ids = [x.strip() for x in pair.split(",")]
            q = [float(x) for x in sizes.split(",")]
            if len(ids) != 2 or len(q) != 2:
                raise ValueError("--separate ID1,ID2 and --sizes Q1,Q2: two of each")
            if ids[0] == ids[1]:
                raise ValueError(f"--separate {pair}: an effect cannot be told from itself; name two different effects")
            if not all(np.isfinite(x) and 0 < abs(x) <= PARAM_LIMIT for x in q):
                raise ValueError(f"--sizes {sizes}: each size must be a finite, non-zero number (the effect's expected "
                                 f"value, in its unit) of at most {PARAM_LIMIT:g}")
            for e in ids:
                check_effect(e, model.sensor)
            rates = (np.array([0.5, 1.0, 2.0]) * rho) if gyro else ()
            result["separation"] = separate(model.base, ids[0], ids[1], u, rho, sigma, q, rates, target)
    except (ValueError, KeyError, CalibrationError, FileNotFoundError) as e:
        _fail(e)
    unit = model.unit
    click.echo(f"{name}: {model.name}, noise {sigma:g} {unit} per position"
               + (f", rate runs at {', '.join(f'{x:g}' for x in sorted(set(np.round(np.atleast_1d(rho) / DPH_PER_DPS, 6))))} "
                  "deg/s" if gyro else ""))
    click.echo(f"  D per position {result['D_per_position']:.6g}, A {result['A']:.4g}, "
               f"largest |correlation| {result['max_abs_correlation']:.2f}")
    for k, v in result["crlb"].items():
        click.echo(f"  {k:16} CRLB {v:.3g} {result['units'][k]}")
    sep = result.get("separation")
    if sep:
        from simucal.generated.effects import SEPARATE
        a, b = sep["effects"]
        click.echo(f"separate {a} from {b}: on this plan the expected likelihood ratios are "
                   f"{sep['start']['noncentrality'][0]:.3g} and {sep['start']['noncentrality'][1]:.3g} "
                   f"(power {sep['start']['power'][0]:.2f}, {sep['start']['power'][1]:.2f} at alpha {sep['alpha']})")
        if sep["added"]:
            click.echo(f"  {len(sep['added'])} added positions give {sep['noncentrality'][0]:.3g} and "
                       f"{sep['noncentrality'][1]:.3g} (power {sep['power'][0]:.2f}, {sep['power'][1]:.2f}): "
                       + ("the target is reached" if sep["reached"] else f"short of {sep['target_power']}"))
            for x in plan_rows(np.array([d["direction_k"] for d in sep["added"]]))[:48]:
                click.echo(f"    outer {x[0]:8.3f}  middle {x[1]:9.4f}  inner {x[2]:9.4f} deg")
        elif sep["reached"]:
            click.echo("  the plan already tells them apart at the target power")
        if not sep["reached"]:
            hints = sorted({SEPARATE[e.split(".")[1]] for e in (a, b)})
            click.echo("  no positions on the sphere separate them" + (" further" if sep["added"] else "")
                       + ": they differ in what the plan cannot vary by direction; " + "; ".join(hints))
    if positions is not None:
        out = Path(output or "plan.csv")
        if kind == "hand":  # a pose is where gravity (or the turn axis) points in the unit's own axes
            rows = [(i + 1, *map(float, d)) for i, d in enumerate(u)]
            cols = "pose,f_x,f_y,f_z"
        else:
            rows = plan_rows(u, np.asarray(rho) / DPH_PER_DPS if gyro else None)
            cols = "outer_deg,middle_deg,inner_deg" + (",outer_rate_dps" if gyro else "")
        outputs.write_text(out, cols + "\n" + "".join(",".join(f"{x:.6f}" for x in r) + "\n" for r in rows))
        result["rows"] = rows
        outputs.write_text(out.with_suffix(".json"), json.dumps(result, indent=1) + "\n")
        click.echo(f"wrote {out} and {out.with_suffix('.json')}")
    elif output:
        outputs.write_text(output, json.dumps(result, indent=1) + "\n")
        click.echo(f"wrote {output}")


@main.command()
@click.option("--json", "json_path", type=click.Path(dir_okay=False), default=None, help="Also write the figures as JSON.")
@click.option("--before", type=click.Path(exists=True, dir_okay=False), default=None,
              help="A previous run's --json (e.g. benchmarks/bench_4a889b5.json), printed beside this run's figures.")
def bench(json_path, before):
    """Measure the speed figures (fits, Monte Carlo, whole commands) on this machine."""
    from simucal.bench import run
    if json_path:
        _guard([before] if before else [], files=[json_path])
    run(json_path, click.echo, before)


@main.command("field-drift")
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="drift.json", show_default=True,
              help="The calibration file (apply corrects the gyro drift with it).")
@click.option("--plot", type=click.Path(dir_okay=False), default=None, help="PNG of each position's filter estimate (paper Fig. 4).")
@HEADING_ACCURACY
def field_drift(data_dir, output, plot, heading_accuracy_deg):
    """Three-position field calibration of gyro constant drift (ruan2019): `calibrate --method field`, with the
    paper's Fig. 4."""
    from simucal.calibrate import calibrate_to_file
    from simucal.field.drift import plot_history
    _guard([data_dir], files=[output, plot])
    result, error = calibrate_to_file(Path(data_dir), output, dict(method="field",
                                                                  heading_accuracy_deg=heading_accuracy_deg))
    if error:
        _fail(error)
    if plot:
        plot_history(result["field"]["history"], plot)
    for line in _sensor_lines(result):
        click.echo(line)
    click.echo(f"wrote {output}" + (f" and {plot}" if plot else ""))


@main.command("import")
@click.argument("fmt", type=click.Choice(["imu_tk", "imucal-ferraris", "imucal-annotated", "csv"]))
@click.argument("sources", nargs=-1, required=True, type=click.Path(exists=True, dir_okay=False))
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
@_FORCE
def import_cmd(fmt, sources, out_dir, latitude_deg, acc_counts_per_g, gyro_counts_per_dps, gravity_mps2, rate_hz,
               columns, acc_unit, gyro_unit, turn_deg, force):
    """Write a measurement set from another tool's recording."""
    from simucal.io import importers as im
    _guard(sources, sets=[out_dir], force=force)
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
        _fail(e)
    click.echo(f"wrote {out_dir}")


@main.command()
@click.argument("calibration_file", type=click.Path(exists=True, dir_okay=False))
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="validation.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None, help="Also write a page with a plot.")
def validate(calibration_file, data_dir, output, html_path):
    """Apply a calibration to an independent set: the error before (nominal) and after, against the noise floor."""
    import json

    from simucal.errors import CalibrationError
    from simucal.io import MeasurementSetError, outputs
    from simucal.validate import html_page, lines
    from simucal.validate import validate as run
    _guard([calibration_file, data_dir], files=[output, html_path])
    try:
        report = run(calibration_file, data_dir)
    except (MeasurementSetError, CalibrationError, ValueError) as e:
        _fail(e)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    if html_path:
        outputs.write_text(html_path, html_page(report))
    for line in lines(report):
        click.echo(line)
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))


@main.command()
@click.argument("data_dir", type=click.Path(exists=True, file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="noise.json", show_default=True)
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page with the Allan deviation plot.")
@click.option("--kalibr", "kalibr_path", type=click.Path(dir_okay=False), default=None,
              help="Also write Kalibr's imu.yaml (noise densities and random walks, SI).")
@click.option("--tau-max-s", type=POSITIVE, default=None,
              help="The longest tau (s); default a ninth of the longest still stretch.")
def noise(data_dir, output, html_path, kalibr_path, tau_max_s):
    """Allan deviation of a still recording and its IEEE 952 noise terms (ARW, bias instability, ...)."""
    import json

    from simucal import allan, io
    from simucal.errors import CalibrationError
    from simucal.io import MeasurementSetError, outputs
    _guard([data_dir], files=[output, html_path, kalibr_path])
    try:
        report = allan.characterise(io.read_set(data_dir), tau_max_s)
    except (MeasurementSetError, CalibrationError) as e:
        _fail(e)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    if html_path:
        outputs.write_text(html_path, allan.html_page(report))
    if kalibr_path:
        outputs.write_text(kalibr_path, allan.kalibr_yaml(report))
    for line in allan.lines(report):
        click.echo(line)
    click.echo(f"wrote {output}" + "".join(f" and {p}" for p in (html_path, kalibr_path) if p))


if __name__ == "__main__":
    main()
