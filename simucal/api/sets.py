"""`simucal.MeasurementSet`: the measurement set (simucal.io) with constructors from arrays and
DataFrames, so data held in Python need no folder."""
from __future__ import annotations

import os
from dataclasses import fields
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from simucal import io
from simucal.api.arguments import checked, refusal
from simucal.api.tables import DataFrame
from simucal.io import results
from simucal.errors import InputError
from simucal.io import arrays


class MeasurementSet(io.MeasurementSet):
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

    truth: results.Truth | None = None  # a simulated set's truth (truth.json), else None

    def __repr__(self) -> str:
        """One line (the dataclass's printed every array, 8 kB): where, what kind of data, how many
        rows over how long, the sensors' units and the other columns; the arrays are in `samples`."""
        from simucal import methods
        t = self.samples["t_s"]
        sensors = [f"{s} in {self.meta.get(f'{s}_unit')}" for s, has in (("acc", self.has_acc), ("gyro", self.has_gyro))
                   if has]
        other = [c for c in self.samples if c not in ("t_s", "segment", "ax", "ay", "az", "gx", "gy", "gz")]
        return (f"MeasurementSet({str(self.path)!r}: {methods.data_kind(self)}, {len(t):,} rows over "
                f"{float(t[-1] - t[0]) if len(t) else 0.0:.1f} s"
                + (f", {len(self.segments)} segments" if self.segments else "")
                + "".join(f", {x}" for x in sensors + other) + ")")

    def _repr_html_(self) -> str:
        """A notebook's view: where, what kind, how many rows over how long, the sensors' units, the columns."""
        from simucal import methods
        from simucal.api.tables import html_card
        t = self.samples["t_s"]
        return html_card(f"MeasurementSet {self.path}", [
            ("kind of data", methods.data_kind(self)), ("rows", f"{len(t):,}"),
            ("duration", f"{float(t[-1] - t[0]) if len(t) else 0.0:.1f} s"),
            ("segments", len(self.segments) if self.segments else "none (a stream)"),
            *[(s, self.meta.get(f"{s}_unit")) for s, has in (("acc", self.has_acc), ("gyro", self.has_gyro)) if has],
            ("columns", ", ".join(self.samples))])

    @classmethod
    @checked
    def of(cls, ms: io.MeasurementSet) -> MeasurementSet:
        """The same set as this class (its arrays shared, not copied)."""
        return ms if isinstance(ms, cls) else cls(**{f.name: getattr(ms, f.name) for f in fields(ms)})

    @classmethod
    @checked
    def from_arrays(cls, acc: Any = None, gyro: Any = None, *, acc_unit: str, gyro_unit: str,
                    rate_hz: float | None = None, t_s: Any = None, temp_c: Any = None, segment: Any = None,
                    segments: Sequence[io.Segment | Mapping[str, Any]] | DataFrame | None = None,
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
            segments.csv (`simucal.io.Segment` or mappings with its columns: segment, kind,
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
        return cls.of(arrays.from_arrays(acc, gyro, acc_unit=acc_unit, gyro_unit=gyro_unit, rate_hz=rate_hz, t_s=t_s,
                                  temp_c=temp_c, segment=segment, segments=segments, columns=columns, meta=meta,
                                  name=name, cls=cls))

    @classmethod
    @checked
    def from_dataframe(cls, df: Any, *, acc_unit: str, gyro_unit: str, columns: Mapping[str, str] | None = None,
                       rate_hz: float | None = None, t_s: Any = None,
                       segments: Sequence[io.Segment | Mapping[str, Any]] | DataFrame | None = None,
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
        return cls.of(arrays.from_dataframe(df, acc_unit=acc_unit, gyro_unit=gyro_unit, columns=columns,
                                     rate_hz=rate_hz, t_s=t_s, segments=segments, meta=meta, name=name, cls=cls))

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
        first = [c for c in ("t_s", "segment", *io.SAMPLE_COLS, "temp_c") if c in self.samples]
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
        from simucal.io import outputs
        outputs.check(sets=[folder], force=force)
        io.write_set(Path(folder), {k: v for k, v in self.meta.items() if k != "format"}, self.samples, self.segments,
                     {"truth.json": self.truth} if self.truth is not None else None)


def folder_of(data: Any) -> str | os.PathLike[str]:
    """data as a set's folder, or refused in one line naming the constructor it needs (an item of a list the door
    let through, arguments.refusal)."""
    if isinstance(data, (str, os.PathLike)):
        return data
    raise refusal("a measurement set", "data", data, "a path or a MeasurementSet")


def as_set(data: Any) -> io.MeasurementSet:
    """A folder read, or a copy of the caller's set (a calibration records the user's T_ref on the
    set it is given, which stays the caller's)."""
    return data.copy() if isinstance(data, io.MeasurementSet) else io.read_set(folder_of(data))


def effect_ids(add: str | Sequence[str]) -> tuple[str, ...]:
    """add as the commands take it, one id or model file per item: a string is one (not its letters)."""
    return (add,) if isinstance(add, str) else tuple(add)
