"""`simucal noise`'s report of a still recording (simucal.fit.allan_terms says what it holds): a set in memory,
its still stretches pooled, or a stream read a chunk at a time (simucal.fit.allan_sums), and the warning of a
temperature that changes."""
from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path
from typing import TypedDict

import numpy as np

from simucal import io
from simucal.errors import CalibrationError
from simucal.fit import allan_cov, allan_sums
from simucal.fit.allan_terms import (UNIT, SensorNoise, axis_from_avar, axis_report, cluster_sizes, sensor_report,
                                     stuck)
from simucal.fit.stillness import check_still, check_still_stream, sample_step, still_stretches
from simucal.io import MeasurementSetError, columnar


def characterise(ms, kind, tau_max_s=None) -> NoiseReport:
    """The report of `simucal noise` (simucal.fit.allan_terms) of a set of this kind (simucal.methods.Kind: its
    still rows, whether it must be still throughout): per sensor and axis, the Allan deviation with its
    68 % interval and the terms seen (value, std) or not (95 % bound) in the sensor's units and a
    data sheet's; tau up to tau_max_s (default a ninth of the longest still stretch)."""
    out: NoiseReport = {"format": "simucal.noise/1", "data": str(ms.path)}
    for sensor, has in (("acc", ms.has_acc), ("gyro", ms.has_gyro)):
        if not has:
            continue
        stretches, dt, where = still_stretches(ms, sensor, kind)
        check_still(ms, dt, kind)
        lengths = [len(s) for s in stretches]
        m = cluster_sizes(lengths, dt, tau_max_s, ms.path / "samples.csv")
        mats = allan_cov.basis(m, dt, lengths)
        axes = {a: axis_report(sensor, [s[:, j] for s in stretches], dt, m, mats, UNIT[sensor])
                for j, a in enumerate("xyz")}
        out[sensor] = sensor_report(sensor, dt, m, where, axes)  # type: ignore[literal-required]  # acc or gyro
    if "acc" not in out and "gyro" not in out:
        raise CalibrationError(f"{ms.path}: no sensor columns to characterise")
    if "temp_c" in ms.samples:
        T = np.asarray(ms.samples["temp_c"], float)
        out.update(temperature_block(float(T.min()), float(T.max()), ms.path))
    return out


TEMP_CHANGE_C = 3.0  # a MEMS bias moves by its instability's size over a few degC


class TemperatureRange(TypedDict, total=False):
    """The record's temperature in the noise report (temperature_block)."""
    range_c: list[float]              # the lowest and the highest temp_c, degC
    warning: str                      # where it changes by over TEMP_CHANGE_C: why the long-tau terms may be thermal


TemperatureBlock = TypedDict("TemperatureBlock", {"temperature": TemperatureRange})  # the report's temperature key


class NoiseReport(TypedDict, total=False):
    """What `simucal noise -o` writes (simucal.noise/1; characterise)."""
    format: str                       # simucal.noise/1
    data: str                         # the set's folder
    acc: SensorNoise                  # each sensor's block, where the set has it
    gyro: SensorNoise
    temperature: TemperatureRange     # where the set has temp_c (temperature_block)


def noise_blocks(report: NoiseReport) -> dict[str, SensorNoise]:
    """The report's sensor blocks by name, those it has."""
    return {s: b for s, b in (("acc", report.get("acc")), ("gyro", report.get("gyro"))) if b is not None}


def temperature_block(lo, hi, data) -> TemperatureBlock:
    """{"temperature": its range and, where it changes by over TEMP_CHANGE_C, the warning}: a warming board's
    bias follows its temperature, which the Allan variance reads as rate ramp, random walk and instability."""
    block: TemperatureRange = {"range_c": [lo, hi]}
    if hi - lo > TEMP_CHANGE_C:
        block["warning"] = (f"the temperature changes by {hi - lo:.3g} degC over the record "
                            f"({lo:.4g} to {hi:.4g} degC): the bias's thermal drift reads as bias instability, "
                            "random walk and rate ramp, so the long-tau terms (and Kalibr's random walks) "
                            "may be thermal, not noise; record at a steady temperature, or take the thermal model out "
                            f"first: simucal calibrate {data} --thermal -o warm.json, simucal apply warm.json {data} "
                            f"-o {Path(str(data)).name}_flat, simucal noise {Path(str(data)).name}_flat")
    return {"temperature": block}


def characterise_folder(folder, kind_of, tau_max_s=None, scheduler=None, size=allan_sums.CHUNK) -> NoiseReport:
    """characterise() of the set in `folder` (kind_of(set): its kind, simucal.methods.kind_of), a still stream read a
    chunk at a time (simucal.fit.allan_sums: theta in parts of `size` values, the rows of one task, here or on Dask with
    `scheduler`); a segmented set (a turntable test's static segments, short) is read whole."""
    folder = Path(folder)
    meta = io.read_meta(folder)
    if io.read_segments(folder) is not None:
        ms = io.read_set(folder)
        return characterise(ms, kind_of(ms), tau_max_s)
    path = io.samples_path(folder)
    cols, _ = columnar.columns_of(path, None)
    sensors = [s for s, c in (("acc", "ax"), ("gyro", "gx")) if c in cols]
    if "gyro" in sensors and "latitude_deg" not in meta:
        raise MeasurementSetError(folder / "meta.json", None, "latitude_deg is required when gyro data are present")
    scratch: contextlib.AbstractContextManager[str | None] = contextlib.nullcontext()
    if scheduler not in (None, "local"):  # spilled: theta's parts in files the workers read
        scratch = tempfile.TemporaryDirectory(prefix="simucal-noise-")
    with scratch as spill:
        kept, steps = allan_sums.read_pass(folder, meta, sensors, Path(spill) if spill else None, size,
                                           temperature="temp_c" in cols)
        dt = sample_step(steps, path)
        del steps
        n = kept.theta[next(iter(kept.theta))].n - 1
        check_still_stream(kept, dt, folder, sensors[0])  # acc where it has them
        out: NoiseReport = {"format": "simucal.noise/1", "data": str(folder)}
        for sensor in sensors:
            m = cluster_sizes([n], dt, tau_max_s, path)
            mats = allan_cov.basis(m, dt, [n])
            triad = io.SAMPLE_COLS[:3] if sensor == "acc" else io.SAMPLE_COLS[3:]
            avars = allan_sums.allan_variances([kept.theta[c] for c in triad], m, scheduler)
            axes = {a: axis_from_avar(sensor, avar, stuck(kept.lo[c], kept.hi[c], kept.first[c], n, UNIT[sensor]),
                                      dt, m, mats) for a, c, avar in zip("xyz", triad, avars)}
            out[sensor] = sensor_report(sensor, dt, m, "the whole stream", axes)  # type: ignore[literal-required]
    if "temp_c" in cols:
        out.update(temperature_block(kept.temp_c[0], kept.temp_c[1], folder))
    return out


