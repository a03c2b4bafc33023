"""The project's own tools from Python (`simucal derive`, `audit`, `demo`, `bench` are one call of these plus
printing): the models derived, the paper audited, the demo run (api/demo_run.py), the speed measured.
`simucal.audit` and `simucal.derive_model` are the package's names too; derive, demo and bench are
`simucal.api.tools`'s alone (simucal.derive and simucal.bench are modules of their own)."""
from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any, Callable, NamedTuple

from simucal.arguments import checked

if TYPE_CHECKING:  # the record's type only: the demo's modules load when it runs
    from simucal.api.demo_run import DemoRecord


class Derived(NamedTuple):
    """What `derive` did: the generated files that differ from the derivation (check), the seconds it took, the
    diff, and the folder."""
    stale: list[str]
    seconds: float
    diff: str
    folder: str


def derive(*, check: bool = False) -> Derived:
    """Derive the built-in models (SymPy) and write generated/, or with `check` only compare (generated/ stale
    where `stale` is not empty). Needs the derive extra (sympy, casadi) and a source checkout.

    Examples
    --------
    >>> simucal.api.tools.derive(check=True).stale  # doctest: +SKIP
    []
    """
    from simucal import derive_cmd
    from simucal.fit.models import generated_dir
    stale, secs, diff = derive_cmd.run(check=check)
    return Derived(list(stale), float(secs), diff, str(generated_dir()))


@checked
def derive_model(path: str | os.PathLike[str]) -> list[str]:
    """Derive a user's model file (MODELS = [ErrorModel, ...]) into the cache; returns its models' names, each then
    usable by name (`calibrate(..., acc_model=NAME)`) from any folder.

    Parameters
    ----------
    path : str or os.PathLike
        The model file (docs/own-model.md).

    Examples
    --------
    >>> simucal.derive_model("my_models.py")  # doctest: +SKIP
    ['acc_mine']
    """
    from simucal.fit.catalog import derive_model_file
    names, _ = derive_model_file(path)
    return list(names)


@checked
def audit(seeds: int = 20, progress: Any = None) -> Any:
    """dong2018 audited: its printed equations (4)-(27), Tables 1 and 2 term by term at the section-4 values, and
    its numeric claims against a Monte Carlo of `seeds` tests per setting (0: skipped). The result has
    ``markdown()`` (what `simucal audit -o` writes) and ``summary()``.

    Parameters
    ----------
    seeds : int
        Monte Carlo tests per setting of the numeric claims (0: those skipped).
    progress : callable, optional
        A callable wrapping the iterable of the Monte Carlo's tests (e.g. simucal.progress.bar("audit")).

    Examples
    --------
    >>> print(simucal.audit(seeds=0).summary())  # doctest: +SKIP
    """
    from simucal.report.paper_claims import full_audit
    return full_audit(seeds, progress=progress)


def demo_outputs(out: str | os.PathLike[str]) -> tuple[list[Any], Any]:
    """(the sets the demo writes under `out`, its record's path): a record there is an earlier demo's, whose sets
    it may replace."""
    from pathlib import Path

    from simucal.api import demo_run
    return [Path(out) / d for d in demo_run.SETS], Path(out) / demo_run.MARKER


def demo(out: str | os.PathLike[str], seed: int = 0, echo: Callable[[str], Any] = print) -> DemoRecord:
    """The main job end to end on built-in simulated data (`simucal demo -o OUT`): a hidden effect found, added,
    calibrated with, applied and validated; the unit over temperature; its noise; the paper's methods. Writes
    into `out`; echo prints each step. Returns the demo's record (demo.json)."""
    from simucal.api import demo_run
    return demo_run.run(out, seed, echo)


def bench(json_path: str | os.PathLike[str] | None = None, echo: Callable[[str], Any] = print,
          before: str | os.PathLike[str] | None = None, size: str = "full") -> None:
    """The speed figures on this machine (`simucal bench`): echo prints the table; json_path also writes it;
    before: an earlier run's JSON printed beside; size "quick" runs every step in seconds (a check, no figures)."""
    from simucal.bench import run
    run(json_path, echo, before, size)


def check_image_name(path: str | os.PathLike[str]) -> None:
    """Refused (InputError) where no image format has the name's suffix (.png, .svg, ...)."""
    from pathlib import Path

    from simucal.errors import InputError
    from simucal.field.drift import plot_formats
    if Path(path).suffix.lower().lstrip(".") not in plot_formats():
        raise InputError(f"--plot {path}: not an image file name; end it in .png (or "
                         f"{', '.join('.' + f for f in plot_formats())})")


def plot_field_history(cal: Any, path: str | os.PathLike[str]) -> None:
    """A field calibration's filter history (ruan2019 Fig. 4) as an image file (check_image_name)."""
    from simucal.field.drift import plot_history
    check_image_name(path)
    plot_history(cal.details["field"]["history"], path)
