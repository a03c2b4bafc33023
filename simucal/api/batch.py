"""Several sets calibrated one by one into a folder (`simucal calibrate DIR1 DIR2 ... -o FOLDER`), from Python:
a refusal of one set loses no other (each set's file, or its refusal's message)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple, Sequence

from simucal.arguments import checked
from simucal.io.calibration import Calibration
from simucal.errors import InputError
from simucal.options import CalibrateOptions


class Calibrated(NamedTuple):
    """One set of `calibrate_each`: its folder, its calibration file, and the calibration or the refusal."""
    data: Path
    output: Path
    calibration: Calibration | None  # None where refused
    error: str | None    # the refusal's message


def output_files(data_dirs: Sequence[str | os.PathLike[str]], folder: str | os.PathLike[str]) -> list[Path]:
    """Each set's calibration file, FOLDER/<set's folder name>.json; refused where two sets share a folder name."""
    files = [Path(folder) / f"{Path(d).resolve().name}.json" for d in data_dirs]
    for i, f in enumerate(files):
        if (first := files.index(f)) < i:
            raise InputError(f"{data_dirs[first]} and {data_dirs[i]} would both be calibrated into {f} (each set's "
                             f"file is named after its folder, {Path(data_dirs[i]).resolve().name}): rename one of "
                             "the folders, or calibrate them in separate commands, each with its own -o FILE")
    return files


@checked
def calibrate_each(data_dirs: Sequence[str | os.PathLike[str]], folder: str | os.PathLike[str], *,
                   options: CalibrateOptions | None = None, scheduler: str | None = None,
                   progress: Any = None) -> list[Calibrated]:
    """Calibrate every set of `data_dirs` (as `simucal.calibrate` with `options`) and write each one's file as
    FOLDER/<set's folder name>.json, on a scheduler where given (local, processes or a Dask address).

    Parameters
    ----------
    data_dirs : sequence of str or os.PathLike
        The sets, one calibration each.
    folder : str or os.PathLike
        Where each calibration file is written.
    options : CalibrateOptions, optional
        `simucal.calibrate`'s options as one object, e.g. ``simucal.CalibrateOptions(method="exact")``.
    scheduler : str, optional
        "local" (threads, the default), "processes", or a Dask scheduler's address.
    progress : callable, optional
        A callable wrapping the iterable of sets (e.g. simucal.progress.bar("calibrating", "set")).

    Returns
    -------
    list of Calibrated
        Per set, in order: the files, and the calibration or why it was refused.

    Examples
    --------
    >>> done = simucal.calibrate_each(["unit1", "unit2"], "cals")  # doctest: +SKIP
    >>> [d.error for d in done]  # doctest: +SKIP
    [None, None]
    """
    from simucal.api.calibrating import calibrate_to_file
    from simucal.sweeps import map_tasks
    if options is not None and options.thermal:
        raise InputError("calibrate_each: options with thermal: each set is calibrated on its own; a unit over "
                         "temperature is one calibrate(sets, thermal=True) (or calibrate_instances, an IMU each)")
    out = Path(folder)
    if out.suffix == ".json" or (out.exists() and not out.is_dir()):
        raise InputError(f"-o {folder}: with {len(data_dirs)} sets, -o names a folder (one <set>.json each)")
    tasks = [(Path(d), f, options or CalibrateOptions()) for d, f in zip(data_dirs, output_files(data_dirs, out))]
    made = not out.exists()
    out.mkdir(exist_ok=True)
    try:
        done = map_tasks(calibrate_to_file, tasks, scheduler, progress=progress)
    except BaseException:  # no scheduler, or interrupted: leave no empty folder behind
        if made and not any(out.iterdir()):
            out.rmdir()
        raise
    return [Calibrated(d, path, result, error)
            for (d, path, _), (result, error) in zip(tasks, done)]
