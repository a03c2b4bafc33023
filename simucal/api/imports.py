"""Other tools' recordings and logs into measurement sets, from Python:
`simucal import` and `simucal convert` are one call of these plus printing."""
from __future__ import annotations

import os
from pathlib import Path
import typing
from typing import Literal, Sequence

from simucal.arguments import checked
from simucal.io.measurement_set import MeasurementSet
from simucal.errors import InputError

Format = Literal["imu_tk", "imucal-ferraris", "imucal-annotated", "csv", "ulog", "dataflash",
                 "rosbag"]  # an editor's check
FORMATS: tuple[str, ...] = typing.get_args(Format)
FERRARIS_HZ = 102.4  # imucal's Ferraris recordings' rate, where the file has no time column
# imucal's annotated sessions: Hz, counts/g, counts/(deg/s)
ANNOTATED_HZ, ANNOTATED_ACC, ANNOTATED_GYRO = 204.8, 2048.0, 16.4

Path_ = str | os.PathLike[str]


@checked
def import_recording(fmt: Format, sources: Sequence[Path_], out: Path_, *, latitude_deg: float | None = None,
                     acc_counts_per_g: float | None = None, gyro_counts_per_dps: float | None = None,
                     gravity_mps2: float | None = None, rate_hz: float | None = None, columns: str | None = None,
                     acc_unit: str | None = None, gyro_unit: str | None = None, turn_deg: float = -360.0,
                     instance: int | None = None, topic: str | None = None, force: bool = False,
                     read_back: bool = True) -> MeasurementSet | None:
    """Write a measurement set from another tool's recording or an autopilot's or ROS log, and return it.

    Parameters
    ----------
    fmt : {"imu_tk", "imucal-ferraris", "imucal-annotated", "csv", "ulog", "dataflash", "rosbag"}
        One of FORMATS: imu_tk (two .mat or text files, acc and gyro), imucal-ferraris (its CSV, and
        optionally its section list .json), imucal-annotated, csv (any CSV with `columns`), ulog (PX4),
        dataflash (ArduPilot), rosbag (ROS 1 file or ROS 2 folder).
    sources : sequence of paths
        The recording's files.
    out : path
        The new set's folder (`simucal import -o`); refused where it holds a set already, unless `force`.
    latitude_deg, acc_counts_per_g, gyro_counts_per_dps, gravity_mps2, rate_hz, columns, acc_unit, gyro_unit,
    turn_deg, instance, topic :
        `simucal import`'s options of the same names (``simucal import --help``).
    force : bool
        Replace a set already in `out`.
    read_back : bool
        Return the set read from `out` (False: None; the command line, whose outputs are renamed into place
        only when it ends, reads nothing back).

    Returns
    -------
    MeasurementSet or None
        The set as written, read back.

    Examples
    --------
    >>> ms = simucal.import_recording("imucal-ferraris", ["session.csv"], "set", latitude_deg=49.6)  # doctest: +SKIP
    """
    from simucal.io import importers as im
    from simucal.io import outputs
    if fmt not in FORMATS:
        raise InputError(f"format {fmt!r}: one of {', '.join(FORMATS)}")
    paths = [Path(s) for s in sources]
    outputs.check(paths, sets=[out], force=force)
    folders = [s for s in paths if s.is_dir()]
    if folders and fmt != "rosbag":
        raise im.ImportError_(f"{folders[0]}: is a folder; {fmt} reads files (a ROS 2 bag is a folder: import rosbag)")
    if fmt in ("ulog", "dataflash", "rosbag"):
        from simucal.io.logs import import_log
        if len(paths) != 1:
            raise im.ImportError_(f"{fmt} reads one log: give one file (a ROS 2 bag: its folder)")
        import warnings
        from simucal.errors import LogWarning
        meta = import_log(fmt, paths[0], out, latitude_deg, None if instance is None else int(instance), topic)
        for line in meta.get("warnings", []):
            warnings.warn(line, LogWarning, stacklevel=3)  # the caller's line, past arguments.checked
    elif fmt == "imu_tk":
        if len(paths) != 2 or not acc_counts_per_g or not gyro_counts_per_dps:
            raise im.ImportError_("imu_tk needs ACC_FILE GYRO_FILE, --acc-counts-per-g and --gyro-counts-per-dps")
        im.import_imu_tk(paths[0], paths[1], out, acc_counts_per_g, gyro_counts_per_dps, latitude_deg, gravity_mps2)
    elif fmt == "imucal-ferraris":
        if len(paths) == 2:  # with the section list: poses and turns as segments
            im.import_ferraris_sections(paths[0], paths[1], out, rate_hz or FERRARIS_HZ, latitude_deg, turn_deg)
        else:  # a continuous stream: poses found by static detection
            im.import_ferraris(paths[0], out, rate_hz or FERRARIS_HZ, latitude_deg)
    elif fmt == "imucal-annotated":
        im.import_imucal_annotated(paths[0], out, rate_hz or ANNOTATED_HZ, acc_counts_per_g or ANNOTATED_ACC,
                                   gyro_counts_per_dps or ANNOTATED_GYRO, latitude_deg, turn_deg)
    else:
        _import_csv(paths[0], out, columns, acc_unit, gyro_unit, rate_hz, latitude_deg)
    from simucal import io
    return io.read_set(out) if read_back else None


@checked
def import_instances(fmt: Literal["ulog", "dataflash"], source: Path_, out: Path_, *,
                     instances: Sequence[int] | None = None, latitude_deg: float | None = None, force: bool = False,
                     read_back: bool = True) -> list[MeasurementSet]:
    """Write one measurement set per IMU instance of an autopilot's log, OUT/instance<n> (`simucal import
    ulog|dataflash LOG --instance all -o OUT`, or `--instance 0,1`), the log read once; return them.

    Parameters
    ----------
    fmt : {"ulog", "dataflash"}
        ulog (PX4: each instance's sensor_accel/sensor_gyro or vehicle_imu) or dataflash (ArduPilot: IMU's
        instance field, or IMU2, IMU3).
    source : path
        The log.
    out : path
        The folder that gets instance<n> for each instance.
    instances : sequence of int, optional
        The instances to import (default: every instance holding both sensors).
    latitude_deg, force :
        As `import_recording`.
    read_back : bool
        Return the sets read from `out` (False: as written, in memory; the command line's outputs are renamed
        into place only when it ends).

    Examples
    --------
    >>> sets = simucal.import_instances("ulog", "warmup.ulg", "imus")  # doctest: +SKIP
    >>> [s.meta["log"]["instance"] for s in sets]  # doctest: +SKIP
    [0, 1]
    """
    from simucal import io
    from simucal.io.logs import import_instances as write_instances
    from simucal.io import outputs
    if isinstance(source, (list, tuple)):
        raise InputError(f"import_instances: source={source!r}: one log (a path), not a list")
    outputs.check([source], folders=[out])
    done = write_instances(fmt, Path(source), out, latitude_deg, None if instances is None else
                           [int(i) for i in instances], force)
    import warnings
    from simucal.errors import LogWarning
    for line in dict.fromkeys(w for ms in done for w in ms.meta.get("warnings", [])):  # a log's once
        warnings.warn(line, LogWarning, stacklevel=3)
    return [io.read_set(ms.path) if read_back else ms for ms in done]


def _import_csv(path: Path, out: Path_, columns: str | None, acc_unit: str | None, gyro_unit: str | None,
                rate_hz: float | None, latitude_deg: float | None) -> None:
    """Any CSV by its columns' map (--columns), each mapped triad's unit given."""
    from simucal.io import importers as im
    if not columns:
        raise im.ImportError_("csv needs --columns (and --acc-unit, --gyro-unit for the triads it maps)")
    cmap = im.parse_columns(columns)
    for triad, unit, option in (("ax", acc_unit, "--acc-unit"), ("gx", gyro_unit, "--gyro-unit")):
        if triad in cmap and not unit:
            raise im.ImportError_(f"csv: --columns maps {triad}, so give {option}")
    im.import_csv(path, out, cmap, acc_unit, gyro_unit, rate_hz, latitude_deg)


@checked
def convert(data: Path_, out: Path_, to: str, *, force: bool = False) -> tuple[Path, int]:
    """Copy a measurement set with its samples as samples.parquet or samples.csv (`to`), read and written a
    chunk at a time, every row checked; the input is never changed (a set already in `out` is refused
    unless `force`). Returns (the samples file written, its rows).

    Parameters
    ----------
    data : str or os.PathLike
        The set read.
    out : str or os.PathLike
        The set written (a folder).
    to : {"parquet", "csv"}
        The samples' format.
    force : bool
        Replace a set already in `out`.

    Examples
    --------
    >>> simucal.convert("set", "set_parquet", "parquet")  # doctest: +SKIP
    (PosixPath('set_parquet/samples.parquet'), 3600)
    """
    from simucal.io import columnar, outputs
    if to not in ("parquet", "csv"):
        raise InputError(f"to {to!r}: parquet or csv")
    outputs.check([data], sets=[out], force=force)
    return columnar.convert(data, out, to)
