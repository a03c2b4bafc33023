"""What every command shares: the group whose refusals are one line, finite numbers in a range,
the output guard (no output into or over an input)."""
from __future__ import annotations

import math
import os
import sys
import traceback
import warnings
from pathlib import Path

import click

from simucal.errors import InputError, SimucalError


class _Commands(click.Group):
    """Every refusal (errors.SimucalError, or an OSError on a named file) is one line (fail, exit 2).
    Anything else escaping a command is a bug: its traceback and one line, exit 3 (_bug)."""

    def invoke(self, ctx):
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy's, printed before a clear error otherwise
        warnings.formatwarning = _one_line
        from simucal.io.outputs import all_or_nothing
        try:
            with all_or_nothing():  # a command's outputs (those its guard names) all written, or none
                return super().invoke(ctx)
        except click.UsageError as e:  # a missing file, a bad choice: one line, not click's usage block
            where = " ".join(["simucal"] + (e.ctx.command_path.split()[1:] if e.ctx is not None else []))
            click.echo(f"error: {e.format_message()} (see {where} --help)", err=True)
            sys.exit(2)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException, KeyboardInterrupt):
            raise
        except BrokenPipeError:  # the reader went away (| head): not an error of ours or the user's
            sys.stdout = open(os.devnull, "w")
            sys.exit(141)
        except SimucalError as e:  # every refusal (errors.py), caught here alone
            fail(e)
        except OSError as e:
            if e.filename is None:
                _bug(e)
            fail(f"{e.filename}: {e.strerror or e}")  # the user's file system: a file missing, unreadable, full
        except Exception as e:
            _bug(e)


def _bug(e: Exception):
    """Anything else that escapes a command: a bug in simucal, exit 3 with its traceback (re-raised
    whole where SIMUCAL_DEBUG is set)."""
    if os.environ.get("SIMUCAL_DEBUG"):
        raise e
    traceback.print_exception(e, file=sys.stderr)
    click.echo(f"error: internal error ({type(e).__name__}: {_short(str(e))}); this is a bug in simucal: "
               "please report it with the command, the data and the traceback above", err=True)
    sys.exit(3)


def _one_line(message, category, filename, lineno, line=None, _python=warnings.formatwarning):
    """A warning of the cache (a library not loaded, or rebuilt) is one line, as a refusal is;
    any other as Python prints it."""
    from simucal.errors import CacheWarning
    if issubclass(category, CacheWarning):
        return f"warning: {message}\n"
    return _python(message, category, filename, lineno, line)


@click.group(cls=_Commands)
@click.version_option(package_name="simucal")
def main():
    """Strapdown IMU calibration: derive, simulate, calibrate, audit."""


def fail(e):
    """One line on stderr, exit 2: the refusal of bad input (nothing is written)."""
    click.echo(f"error: {_short(str(e.args[0] if isinstance(e, KeyError) and e.args else e))}", err=True)
    sys.exit(2)


LONGEST = 1500  # characters of a message: one that quotes a 10 MB cell or line is cut in its middle


def _short(text: str) -> str:
    """text of at most about LONGEST characters: a value quoted from hostile input is cut."""
    if len(text) <= LONGEST:
        return text
    return f"{text[:LONGEST - 300]} ... ({len(text) - LONGEST:,} characters left out) ... {text[-300:]}"


class _Refused(click.ClickException):
    """A refusal while the options are read: one line and exit 2, as fail."""
    exit_code = 2

    def show(self, file=None):
        click.echo(f"error: {self.message}", err=True)


class InputPath(click.Path):
    """click.Path for an input that must exist, saying so where it is a symbolic link that leads nowhere
    (a loop of links, or a missing target), which click calls a file that does not exist."""

    def convert(self, value, param, ctx):
        if isinstance(value, (str, os.PathLike)) and os.path.islink(value) and not os.path.exists(value):
            self.fail(f"{os.fspath(value)!r} is a symbolic link that leads nowhere (a loop of links, or its target is "
                      "missing): give the file or folder itself", param, ctx)
        return super().convert(value, param, ctx)


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
            raise _Refused(f"{self._name(param)} {self._shown(value)}: must be a whole number")
        below = self.low is not None and (v <= self.low if self.low_open else v < self.low)
        if below or (self.high is not None and v > self.high):
            lo = None if self.low is None else f"{'>' if self.low_open else '>='} {self.low:g}"
            hi = None if self.high is None else f"<= {self.high:g}"
            raise _Refused(f"{self._name(param)} {self._shown(value)}: must be "
                           + " and ".join(x for x in (lo, hi) if x) + (f" ({self.what})" if self.what else ""))
        return int(round(v)) if self.integer else v

    @staticmethod
    def _shown(value):
        return value if str(value).isprintable() and str(value).strip() else repr(value)

    @staticmethod
    def _name(param):
        return max(param.opts, key=len) if param is not None and param.opts else "value"



MODEL_FILE_RUNS = ("A model file is Python: like any plugin, its code runs when it is derived (once, in a child "
                    "process with a time limit; never again once in the cache), so use only files you trust.")
SCHEDULER_TRUST = ("An address must be a cluster you trust: tasks and results travel as pickles, which run code; "
                   "tls://ADDRESS uses the TLS credentials of Dask's configuration.")
POSITIVE = Number(0.0, low_open=True)
SEED = Number(0, 2 ** 32 - 1, integer=True, what="numpy's seeds")
SEED_HELP = "numpy's seed of the simulated noise and errors: the same seed, the same numbers."
NOISE_G = Number(0.0, 1.0, low_open=True, what="the std of one row, g")
NOISE_DPH = Number(0.0, 1e6, low_open=True, what="the std of one row, deg/h")
LATITUDE = Number(-90.0, 90.0, what="degrees")
SIM_RATE_HZ = Number(0.0, 2000.0, low_open=True, what="the simulator writes raw rows up to 2 kHz")
MAX_TRIALS = 10_000_000  # ~1.4 GB of estimates, about two minutes compiled
def rates_dps(text: str) -> list[float]:
    """--rates-dps R1,R2,...: outer-axis rates of rate runs in deg/s, each finite, non-zero and within
    the spec's 2000 deg/s."""
    try:
        rates = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"--rates-dps {text}: write rates in deg/s separated by commas, e.g. 10,-10") from None
    if not all(0 < abs(r) <= 2000 for r in rates):  # NaN fails too
        raise InputError(f"--rates-dps {text}: a rate run needs a non-zero rate within 2000 deg/s")
    return rates


EFFECT_FILE = click.option(
    "--effect-file", default=None, type=InputPath(exists=True, dir_okay=False),
    help="A model file of your own terms (MODELS = [...]); its models become the truth models (in montecarlo "
         "the fitted ones too). " + MODEL_FILE_RUNS)
SETS = click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
                    help="With --effect-file: the true value of one of its parameters (repeatable).")
UNIT_SYSTEMS = ("spec", "si")  # io/units.py's, written here so that the command line starts without numpy
UNITS = click.option(
    "--units", type=click.Choice(UNIT_SYSTEMS), default="spec", show_default=True,
    help="The numbers printed (and a page's) in the spec's units (g, deg/h, a data sheet's noise units) or in SI "
         "(m/s^2, rad/s, rad/sqrt(s), a sensor's angle error in rad, ...); a scale factor, a latitude or an attitude "
         "is the same in both. "
         "The reports and calibration files written keep the spec's units; apply's set is written in the units asked "
         "(si: m/s^2 and rad/s).")
FORCE = click.option("--force", is_flag=True,
                      help="Replace a measurement set already in the output folder (never one of the inputs).")


def refuse_unused(options: dict) -> None:
    """Refuse an option given on the command line that this run will not use, naming what it
    applies to ({parameter name: what}); an option left at its default passes."""
    from click.core import ParameterSource
    ctx = click.get_current_context()
    for name, where in options.items():
        if ctx.get_parameter_source(name) not in (None, ParameterSource.DEFAULT):
            param = next(p for p in ctx.command.params if p.name == name)
            fail(f"{max(param.opts, key=len)}: applies to {where}, which this run is not; leave it out")


def guard(inputs=(), files=(), sets=(), folders=(), force=False, together=True):
    """Refuse outputs that would write into or over an input, or over each other, or where nothing
    can be written, or replace a measurement set without --force (io/outputs.py); before any work,
    so nothing is lost. together: the outputs are written all or none, when the command ends (the
    demo, which reads what it wrote, writes each at once)."""
    from simucal.io import cache, outputs
    outputs.check(inputs, files, sets, folders, force)
    cache.check_outside(inputs)
    page = files.get("--html") if isinstance(files, dict) else None
    if page and Path(page).suffix.lower() not in (".html", ".htm"):  # a browser opens a page by its name
        fail(f"--html {page}: a page is HTML; end its name in .html (e.g. {Path(page).with_suffix('.html')})")
    if together:
        outputs.hold(files.values() if isinstance(files, dict) else files, list(sets) + list(folders))
