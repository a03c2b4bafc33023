"""Several IMUs of one log, each calibrated over temperature apart and exported into its own slot: the sets
`simucal import ulog|dataflash LOG --instance all` writes, grouped by the IMU meta.json's `log` names
(instance, device ids; io/meta.log_imu), one thermal calibration per IMU, and one PX4 .params file (every
TC_A{n}_*, TC_G{n}_* with its device id, as PX4's own script writes them) and one ArduPilot .param file
(every INS_TCAL{n+1}_*) for all of them."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, NamedTuple, Sequence, Union

from simucal import io
from simucal.arguments import checked
from simucal.io.autopilot import AutopilotFile
from simucal.io.calibration import Calibration
from simucal.api.calibrating import calibrate
from simucal.api.sets import as_set
from simucal.errors import InputError
from simucal.io.meta import Meta, log_imu
from simucal.options import CalibrateOptions

Data = Union[str, os.PathLike[str], io.MeasurementSet]

class ImuCalibration(NamedTuple):
    """One IMU's thermal calibration: its log's instance (None: a set from elsewhere), the sets it was made
    from, the calibration, and its data's meta.json (the device ids the export writes)."""
    instance: int | None
    sets: list[str]
    calibration: Calibration
    meta: Meta


def imus_of(data: Sequence[Data]) -> list[tuple[Any, ...] | None]:
    """The IMUs (io/meta.log_imu) the sets are of, each once, in the order first given; only meta.json read."""
    metas = [d.meta if isinstance(d, io.MeasurementSet) else io.read_meta(Path(d)) for d in data]
    return list(dict.fromkeys(log_imu(m) for m in metas))


def by_imu(sets: Sequence[io.MeasurementSet]) -> list[list[io.MeasurementSet]]:
    """The sets grouped by their IMU (io/meta.log_imu), in the order first given."""
    groups: dict[Any, list[io.MeasurementSet]] = {}
    for ms in sets:
        groups.setdefault(log_imu(ms.meta), []).append(ms)
    return list(groups.values())


@checked
def calibrate_instances(data: Sequence[Data], options: CalibrateOptions | None = None) -> list[ImuCalibration]:
    """Calibrate each IMU of the sets over temperature apart (`simucal calibrate SETS --thermal` where the
    sets are of several instances): its plateaus, or its warm-up.

    Parameters
    ----------
    data : sequence of paths or MeasurementSets
        Every IMU's sets, e.g. those `import_instances` wrote; the sets of one IMU are one unit's plateaus.
    options : CalibrateOptions, optional
        `calibrate`'s options as one object (``thermal_degree``, ``t_ref_c``, ...); every IMU is calibrated over
        temperature.

    Returns
    -------
    list of ImuCalibration
        One per IMU, in the order its first set was given.

    Examples
    --------
    >>> imus = simucal.calibrate_instances(["imus/instance0", "imus/instance1"])  # doctest: +SKIP
    >>> files = simucal.autopilot_files(imus, px4="tc.params")  # doctest: +SKIP
    """
    if isinstance(data, (str, os.PathLike, io.MeasurementSet)):
        raise InputError(f"calibrate_instances: data={data!r}: a list of sets ([{data!r}] for one)")
    return [ImuCalibration(None if (key := log_imu(group[0].meta)) is None else key[0], [str(ms.path) for ms in group],
                           calibrate(group, options), group[0].meta)
            for group in by_imu([as_set(d) for d in data])]


@checked
def autopilot_files(imus: Sequence[ImuCalibration], *, px4: str | None = None,
                    ardupilot: str | None = None) -> list[AutopilotFile]:
    """Every IMU's bias polynomials in one PX4 file and one ArduPilot file, each IMU in its own slot (the
    log's instance): their texts, made before anything is written (`Calibration.autopilot_files` of one).

    Parameters
    ----------
    imus : sequence of ImuCalibration
        `calibrate_instances`' result: each IMU's thermal calibration with its log instance.
    px4, ardupilot : str, optional
        The paths of PX4's parameter file and ArduPilot's (each written only where given).

    Examples
    --------
    >>> for f in simucal.autopilot_files(imus, px4="tc.params", ardupilot="tc.param"):  # doctest: +SKIP
    ...     open(f.path, "w").write(f.text)
    """
    from simucal.io import autopilot
    pairs = [(u.calibration, u.meta) for u in imus]
    return autopilot.files(pairs, px4, ardupilot)
