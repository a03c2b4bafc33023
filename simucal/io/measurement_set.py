"""The measurement set in memory (spec: docs/spec/measurement-set.md): meta.json's keys, the samples by column and
the segments, with the constructors from arrays and DataFrames (io/arrays.py) and the writer's and a notebook's
views; the package (simucal.io) reads and writes its folder."""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from simucal.arguments import DataFrame, checked
from simucal.errors import InputError
from simucal.io import meta as meta_keys
from simucal.io import arrays, outputs, results, set_writer, units
from simucal.io.csv_columns import triad_block
from simucal.io.segments import Segment
from simucal.io.set_rules import SAMPLE_COLS, SENSOR_COLS, group_rows, run_or_rows
from simucal.kinds import data_kind
from simucal.notebook import html_card


@dataclass
class MeasurementSet:
    """One recording of one unit (spec: docs/spec/measurement-set.md): meta.json's keys, the
    samples by column, and the segments (None: one continuous stream, a hand-placed session).

    Build one with `simucal.read_set` (a folder), `MeasurementSet.from_arrays` or
    `MeasurementSet.from_dataframe`; every function of the API takes it where it takes a folder.

    Examples
    --------
    >>> import numpy as np, simucal
    >>> acc = np.tile([0.0, 0.0, 1.0], (100, 1))
    >>> ms = simucal.MeasurementSet.from_arrays(acc, None, acc_unit="g", gyro_unit="deg/h", rate_hz=100.0)
    >>> ms.acc_g().shape
    (100, 3)
    """

    path: Path
    meta: meta_keys.Meta
    samples: dict[str, np.ndarray]    # column -> float array (segment as int array)
    segments: list[Segment] | None    # None: one continuous stream
    temperature_ref_c: float | None = None  # T_ref chosen by the user (calibrate --t-ref-c); None: t_ref_c's default
    sha256: str | None = None         # of the files as read (files_sha256): a calibration's input_sha256
    truth: results.Truth | None = None  # a simulated set's truth (truth.json), else None

    def __repr__(self) -> str:
        """One line (the dataclass's printed every array, 8 kB): where, what kind of data, how many
        rows over how long, the sensors' units and the other columns; the arrays are in `samples`."""
        t = self.samples["t_s"]
        sensors = [f"{s} in {self.meta.get(f'{s}_unit')}" for s, has in (("acc", self.has_acc), ("gyro", self.has_gyro))
                   if has]
        other = [c for c in self.samples if c not in ("t_s", "segment", "ax", "ay", "az", "gx", "gy", "gz")]
        return (f"MeasurementSet({str(self.path)!r}: {data_kind(self)}, {len(t):,} rows over "
                f"{float(t[-1] - t[0]) if len(t) else 0.0:.1f} s"
                + (f", {len(self.segments)} segments" if self.segments else "")
                + "".join(f", {x}" for x in sensors + other) + ")")

    def _repr_html_(self) -> str:
        """A notebook's view: where, what kind, how many rows over how long, the sensors' units, the columns."""
        t = self.samples["t_s"]
        return html_card(f"MeasurementSet {self.path}", [
            ("kind of data", data_kind(self)), ("rows", f"{len(t):,}"),
            ("duration", f"{float(t[-1] - t[0]) if len(t) else 0.0:.1f} s"),
            ("segments", len(self.segments) if self.segments else "none (a stream)"),
            *[(s, self.meta.get(f"{s}_unit")) for s, has in (("acc", self.has_acc), ("gyro", self.has_gyro)) if has],
            ("columns", ", ".join(self.samples))])

    @classmethod
    @checked
    def from_arrays(cls, acc: Any = None, gyro: Any = None, *, acc_unit: str, gyro_unit: str,
                    rate_hz: float | None = None, t_s: Any = None, temp_c: Any = None, segment: Any = None,
                    segments: Sequence[Segment | Mapping[str, Any]] | DataFrame | None = None,
                    columns: Mapping[str, Any] | None = None, meta: Mapping[str, Any] | None = None,
                    name: str = "arrays") -> MeasurementSet:
        """A set from numpy arrays of raw outputs, checked by the spec's rules.

        Parameters
        ----------
        acc, gyro : array_like of shape (n, 3), optional
            The accelerometer and gyro outputs as recorded, columns x y z; at least one.
        acc_unit, gyro_unit : str
            Their units: acc ``g``, ``m/s^2``, ``pulse/s`` or ``counts``; gyro ``deg/h``, ``deg/s``,
            ``rad/s``, ``pulse/s`` or ``counts`` (pulse/s and counts need their nominal scale
            factors in `meta`, e.g. ``acc_counts_per_g``).
        rate_hz : float, optional
            Evenly sampled from 0 s at this rate (Hz); or give `t_s`.
        t_s : array_like of shape (n,), optional
            Each row's time (s), increasing through a stream.
        temp_c : array_like of shape (n,), optional
            Each row's temperature (degC), for temperature terms and thermal calibrations.
        segment, segments : optional
            A turntable test or field set: each row's segment id (n,) and the table of
            segments.csv (`simucal.Segment` or mappings with its columns: segment, kind,
            outer_deg, middle_deg, inner_deg, outer_rate_dps, heading_ref_deg). Without them the
            rows are one stream (a hand-placed session).
        columns : mapping, optional
            Further per-row inputs a user's model reads (e.g. ``{"supply_v": v}``).
        meta : mapping, optional
            meta.json's other keys: ``latitude_deg`` (required with gyro data), scale factors,
            ``acc_noise_g``, ``gyro_noise_dph``, ``unit_serial``, ``description``.
        name : str
            What errors and the calibration's ``input`` call the set.

        Returns
        -------
        MeasurementSet

        Raises
        ------
        simucal.io.MeasurementSetError
            A rule broken, naming the argument, the row and the fix.

        Examples
        --------
        >>> import numpy as np, simucal
        >>> gyro = np.zeros((50, 3))
        >>> ms = simucal.MeasurementSet.from_arrays(None, gyro, acc_unit="g", gyro_unit="deg/s", t_s=np.arange(50) / 10,
        ...                                         meta={"latitude_deg": 45.0})
        >>> ms.has_gyro, ms.has_acc
        (True, False)
        """
        return arrays.from_arrays(acc, gyro, acc_unit=acc_unit, gyro_unit=gyro_unit, rate_hz=rate_hz, t_s=t_s,
                                  temp_c=temp_c, segment=segment, segments=segments, columns=columns, meta=meta,
                                  name=name, cls=cls)

    @classmethod
    @checked
    def from_dataframe(cls, df: Any, *, acc_unit: str, gyro_unit: str, columns: Mapping[str, str] | None = None,
                       rate_hz: float | None = None, t_s: Any = None,
                       segments: Sequence[Segment | Mapping[str, Any]] | DataFrame | None = None,
                       meta: Mapping[str, Any] | None = None, name: str = "dataframe") -> MeasurementSet:
        """A set from a pandas DataFrame (pandas: ``pip install simucal[pandas]``).

        Parameters
        ----------
        df : pandas.DataFrame
            One row per sample.
        acc_unit, gyro_unit : str
            As in `from_arrays`.
        columns : mapping, optional
            ``{spec name: the frame's column}`` for columns not named as the spec names them
            (ax ay az gx gy gz, t_s, temp_c, segment), e.g. ``{"ax": "acc_x"}``.
        rate_hz, t_s : optional
            The times, where the frame has no t_s column (or to override it).
        segments : optional
            The segments' table (as in `from_arrays`); each row's id from the segment column.
        meta, name :
            As in `from_arrays`.

        Returns
        -------
        MeasurementSet

        Examples
        --------
        >>> import pandas as pd, simucal
        >>> df = pd.DataFrame({"acc_x": [0.0] * 10, "acc_y": [0.0] * 10, "acc_z": [1.0] * 10})
        >>> ms = simucal.MeasurementSet.from_dataframe(df, columns={"ax": "acc_x", "ay": "acc_y", "az": "acc_z"},
        ...                                            acc_unit="g", gyro_unit="deg/h", rate_hz=100.0)
        >>> len(ms.samples["t_s"])
        10
        """
        return arrays.from_dataframe(df, acc_unit=acc_unit, gyro_unit=gyro_unit, columns=columns,
                                     rate_hz=rate_hz, t_s=t_s, segments=segments, meta=meta, name=name, cls=cls)

    @checked
    def to_arrays(self) -> dict[str, NDArray[Any]]:
        """The samples by column as recorded, as arrays, in one order whatever made the set: t_s,
        segment, ax ay az gx gy gz, temp_c, then any other column.

        Examples
        --------
        >>> import numpy as np, simucal
        >>> ms = simucal.MeasurementSet.from_arrays(np.tile([0, 0, 1.0], (5, 1)), None, acc_unit="g",
        ...                                         gyro_unit="deg/h", rate_hz=1.0)
        >>> list(ms.to_arrays())
        ['t_s', 'ax', 'ay', 'az']
        """
        first = [c for c in ("t_s", "segment", *SAMPLE_COLS, "temp_c") if c in self.samples]
        return {k: np.asarray(self.samples[k]) for k in first + [c for c in self.samples if c not in first]}

    @checked
    def to_dataframe(self) -> Any:
        """The samples as a pandas DataFrame, `to_arrays`'s columns in its order, as recorded; the units in its
        ``attrs`` (acc_unit, gyro_unit: attrs stay small, as pandas copies them along); the segments' table is
        `segments_frame()`.

        Examples
        --------
        >>> import simucal
        >>> df = simucal.simulate(seed=1).to_dataframe()
        >>> df.attrs["acc_unit"], list(df.columns[:3])
        ('pulse/s', ['t_s', 'segment', 'ax'])
        """
        try:
            import pandas as pd
        except ImportError:
            raise InputError("to_dataframe needs pandas: pip install simucal[pandas] "
                             "(to_arrays needs nothing)") from None
        df = pd.DataFrame(self.to_arrays())
        df.attrs.update(acc_unit=self.meta.get("acc_unit"), gyro_unit=self.meta.get("gyro_unit"))
        return df

    @checked
    def segments_frame(self) -> Any:
        """segments.csv's rows as a pandas DataFrame (what `from_dataframe`'s segments= takes back), None for a
        stream (a set without segments)."""
        if not self.segments:
            return None
        import pandas as pd
        return pd.DataFrame([dict(vars(s)) for s in self.segments])

    @checked
    def write(self, folder: str | os.PathLike[str], *, force: bool = False) -> None:
        """Write the set as a folder (meta.json, samples.csv, segments.csv; a simulated set's truth.json),
        as `simucal simulate` and `simucal import` write one.

        Parameters
        ----------
        folder : str or os.PathLike
            Created where absent; one that already holds a measurement set is refused unless `force`.
        force : bool
            Replace a measurement set already in `folder`.

        Examples
        --------
        >>> import simucal
        >>> simucal.simulate(seed=1).write("set")  # doctest: +SKIP
        """
        outputs.check(sets=[folder], force=force)
        set_writer.write_set(Path(folder), {k: v for k, v in self.meta.items() if k != "format"}, self.samples,
                             self.segments, {"truth.json": self.truth} if self.truth is not None else None)

    @property
    def t_ref_c(self) -> float | None:
        """T_ref of temperature terms (degC): the user's, else the mean of temp_c over every row; None
        without a temp_c column. Calibrations write it (t_ref_c) and apply reads it back."""
        if "temp_c" not in self.samples:
            return None
        if self.temperature_ref_c is not None:
            return float(self.temperature_ref_c)
        return float(np.mean(self.samples["temp_c"]))

    def copy(self, **changes) -> MeasurementSet:
        """dataclasses.replace, keeping what _once found where only T_ref changes (an entry that depends on
        T_ref has it in its key): a copy for its own T_ref keeps the reader's column extremes and row groups."""
        out = dataclasses.replace(self, **changes)
        if set(changes) <= {"temperature_ref_c"}:
            out.__dict__["_cache"] = dict(self.__dict__.get("_cache", {}))
        return out

    @property
    def has_acc(self):
        return "ax" in self.samples

    @property
    def has_gyro(self):
        return "gx" in self.samples

    @property
    def sensors(self) -> list[str]:
        """The sensors the set records: acc, gyro or both."""
        return [s for s, cols in SENSOR_COLS.items() if cols[0] in self.samples]

    def raw(self, sensor: str) -> np.ndarray:
        """The outputs of 'acc' (ax ay az) or 'gyro' (gx gy gz) as recorded, in their own unit (n, 3),
        read-only."""
        cols = SAMPLE_COLS[:3] if sensor == "acc" else SAMPLE_COLS[3:]
        return self._once(("raw", sensor), cols, lambda: _block_or_stack(self.samples, cols))

    def acc_g(self) -> np.ndarray:
        """Accelerometer outputs in g (n, 3), read-only."""
        return self._once(("g", "acc"), SAMPLE_COLS[:3], lambda: self.in_units("acc", slice(None)))

    def gyro_dph(self) -> np.ndarray:
        """Gyro outputs in deg/h (n, 3), read-only."""
        return self._once(("g", "gyro"), SAMPLE_COLS[3:], lambda: self.in_units("gyro", slice(None)))

    def in_units(self, sensor: str, rows) -> np.ndarray:
        """acc_g() or gyro_dph() of some rows alone (a slice or indices): the same numbers, without the whole
        set converted (38 MB a sensor at 1.6 million rows, and as many page faults): elementwise, the same bits."""
        return (units.acc_to_g if sensor == "acc" else units.gyro_to_dph)(self.raw(sensor)[rows], self.meta)

    def rows(self, segment: int) -> np.ndarray:
        """The indices (ascending) of one segment's rows; empty if it has none."""
        groups = self._once("rows", ("segment",), lambda: group_rows(self.samples["segment"]), meta=False)
        return groups.get(segment, np.zeros(0, int))

    def sample_digests(self) -> list[str]:
        """Per segment (a stream: one for the whole), the first 16 hex digits of the SHA-256 of its sensor
        outputs' numbers (float64, the columns of ax..gz present, one after the other): the samples themselves,
        whatever meta.json, segments.csv, t_s or the number format say. A calibration records them
        (samples_sha256) and validate finds its own rows by them. Found once per set (on a thread of
        its own while a turntable method averages the segments: hashlib frees the GIL)."""
        names = tuple(c for c in ("segment", *SAMPLE_COLS) if c in self.samples)
        return list(self._once("digests", names, self._digests, meta=False))

    def _digests(self) -> list[str]:
        cols = [np.asarray(self.samples[c], "<f8") for c in SAMPLE_COLS if c in self.samples]
        out = []
        for rows in [slice(None)] if self.segments is None else [run_or_rows(self.rows(s.segment))
                                                                 for s in self.segments]:
            h = hashlib.sha256()
            for c in cols:  # column by column
                h.update(np.ascontiguousarray(c[rows]).data)
            if len(cols[0][rows]):
                out.append(h.hexdigest()[:16])
        return out

    def _once(self, name, cols, make, meta=True):
        """make(), formed once per set of columns and (meta=True: it reads it) meta.json (the methods ask
        many times; at 300,000 rows each costs milliseconds). Arrays are made read-only: callers share them."""
        key = (tuple(id(self.samples[c]) for c in cols), json.dumps(self.meta, sort_keys=True, default=str) if meta
               else None)
        cache = self.__dict__.setdefault("_cache", {})
        if cache.get(name, (None,))[0] != key:
            out = make()
            for a in (out.values() if isinstance(out, dict) else out if isinstance(out, tuple) else [out]):
                if isinstance(a, np.ndarray):
                    a.flags.writeable = False
            cache[name] = (key, out)
        return cache[name][1]


def _block_or_stack(samples, cols) -> np.ndarray:
    """The (n, 3) outputs of one triad: the block read_samples formed its columns in (no copy), else
    the columns stacked."""
    block = triad_block(samples, cols)
    return block if block is not None else np.column_stack([samples[c] for c in cols])
