"""`simucal.noise` -> Noise: the report of `simucal noise` with its tables as attributes (tables:
simucal/api/tables.py)."""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple, Union

from simucal import io
from simucal.arguments import checked
from simucal.api.sets import folder_of
from simucal.api.tables import TableOf

if TYPE_CHECKING:  # the report's type only: fit/ loads when noise() runs
    from simucal.fit.allan_noise import NoiseReport

Data = Union[str, os.PathLike[str], io.MeasurementSet]


class Term(NamedTuple):
    """One row of `Noise.terms`: an IEEE 952 term of one axis, in a data sheet's unit."""
    sensor: str
    axis: str
    term: str             # Q, N, B, K, R (the fit's letters)
    name: str             # what a data sheet calls it (angle random walk, bias instability, ...)
    status: str           # "seen", "not seen" (bound_95 holds its bound), "too short" (needs_s)
    value: float | None
    std: float | None
    bound_95: float | None
    needs_s: float | None  # the recording length that would show it (s)
    unit: str


class AllanPoint(NamedTuple):
    """One row of `Noise.curve`: an axis's overlapping Allan deviation at one averaging time."""
    sensor: str
    axis: str
    tau_s: float
    adev: float            # in unit
    rel_err: float | None  # its relative standard error (the estimates' own scatter)
    unit: str              # the sensor's output unit per axis (g or deg/h in the recording's terms)


@dataclass
class Noise:
    """The noise of a still recording: Allan deviation and its IEEE 952 terms.

    Attributes
    ----------
    terms : DataFrame or list of Term
        Every sensor's, axis's and term's value (seen) or bound (not seen), in a data sheet's units.
    term_rows : list of Term
        The same rows as a list.
    curve : DataFrame or list of AllanPoint
        Every sensor's and axis's Allan deviation by averaging time (``curve.pivot(index="tau_s",
        columns=["sensor", "axis"], values="adev")`` for a plot).
    curve_rows : list of AllanPoint
        The same rows as a list.
    report : dict
        What `simucal noise -o` writes (``simucal.noise/1``), the same numbers.
    """
    term_rows: list[Term]
    report: NoiseReport  # noise.json as written
    curve_rows: list[AllanPoint] = field(default_factory=list)
    terms = TableOf("term_rows", Term._fields)
    curve = TableOf("curve_rows", AllanPoint._fields)

    def __repr__(self) -> str:
        seen = [f"{t.sensor} {t.axis} {t.term} {t.value:.3g} {t.unit}" for t in self.term_rows if t.status == "seen"
                and t.value is not None]
        return f"<simucal.Noise: {len(seen)} terms seen" + (f": {'; '.join(seen[:6])}" if seen else "") + ">"

    def _repr_html_(self) -> str:
        from simucal.notebook import html_card
        return html_card("simucal.Noise", [(f"{t.sensor} {t.axis} {t.name}",
                                            f"{t.value:.4g} +- {t.std:.2g} {t.unit}" if t.status == "seen" and t.value
                                            is not None and t.std is not None else
                                            f"{t.status}" + (f" (< {t.bound_95:.3g} {t.unit})" if t.bound_95 else ""))
                                           for t in self.term_rows])

    @checked
    def lines(self, written: dict[str, Any] | None = None, units: str = "spec") -> list[str]:
        """What `simucal noise` prints: each axis's terms in a data sheet's units (``units="si"``: in SI, as
        `simucal noise --units si`), the verdicts and the next step (written: the files the command wrote,
        {"-o": ..., "--kalibr": ...}, which the next step names)."""
        from simucal.report.console import noise_lines
        return list(noise_lines(self.report, written, units))

    @checked
    def kalibr_yaml(self) -> str:
        """Kalibr's imu.yaml (noise densities and random walks, SI), as `simucal noise --kalibr` writes it;
        refused (CalibrationError) unless both sensors give them.

        Examples
        --------
        >>> open("imu.yaml", "w").write(simucal.noise("still").kalibr_yaml())  # doctest: +SKIP
        """
        from simucal.report.kalibr import kalibr_yaml
        return kalibr_yaml(self.report)


@checked
def noise(data: Data, *, tau_max_s: float | None = None, scheduler: str | None = None,
          topic: str | None = None, units: str = "spec") -> Noise:
    """Allan deviation of a still recording and its IEEE 952 terms (quantisation, white noise, bias
    instability, random walk, ramp).

    Parameters
    ----------
    data : str, os.PathLike or MeasurementSet
        A still stream, or a set whose static segments are pooled.
    tau_max_s : float, optional
        The longest tau (s); default a ninth of the longest still stretch.
    scheduler : str, optional
        For a folder holding a stream, which is read a chunk at a time: where the sums over its rows run
        (None or "local": here; "processes": a Dask LocalCluster; or a Dask scheduler's address), as
        `simucal noise --scheduler`.
    topic : str, optional
        Where `data` is a ROS 1 bag or a ROS 2 bag's folder: its sensor_msgs/Imu topic (default: the bag's only
        one); a bag is read as `simucal import rosbag` reads it.
    units : {"spec", "si"}
        The unit system of ``.terms`` and ``.curve`` (si: rad/sqrt(s), m/s^2/sqrt(Hz), rad/s, ...; ``.lines(units=)``
        prints either); ``.report``, the file, is always in the spec's.

    Returns
    -------
    Noise

    Examples
    --------
    >>> import simucal
    >>> n = simucal.noise("still")  # doctest: +SKIP
    >>> n.terms[n.terms.name == "angle random walk"]  # doctest: +SKIP
    """
    from simucal import methods
    from simucal.fit.allan_noise import characterise, characterise_folder, noise_blocks
    from simucal.io import logs, rosbag
    from simucal.report.units import noise_in
    io.units.check_unit_system(units)
    if not isinstance(data, io.MeasurementSet) and (topic or rosbag.is_rosbag(folder_of(data))):
        data = logs.bag_as_set(folder_of(data), topic)  # read as `simucal import rosbag` reads it
    report = (characterise(data, methods.kind_of(data), tau_max_s) if isinstance(data, io.MeasurementSet)
              else characterise_folder(folder_of(data), methods.kind_of, tau_max_s, scheduler))
    shown = noise_in(report, units)  # the tables in the units asked; the report as written
    rows = [Term(s, a, k, t["name"], t["status"], t["value"] if t["status"] == "seen" else None, t.get("std"),
                 t.get("bound_95"), t.get("needs_s"), t["unit"])
            for s, block in noise_blocks(shown).items() for a, axis in block["axes"].items()
            for k, t in axis.get("sheet", {}).items()]
    return Noise(rows, report, allan_points(shown))


def allan_points(report: NoiseReport) -> list[AllanPoint]:
    """The report's Allan deviation curves as rows (Noise.curve)."""
    from simucal.fit.allan_noise import noise_blocks
    out = []
    for s, block in noise_blocks(report).items():
        for a, axis in block["axes"].items():
            taus = axis.get("tau_s", block["tau_s"])
            errs: list[float | None] = [*axis["rel_err"]] if axis.get("rel_err") else [None] * len(axis["adev"])
            out += [AllanPoint(s, a, float(t), float(d), None if e is None else float(e), block["unit"])
                    for t, d, e in zip(taus, axis["adev"], errs) if d is not None]
    return out
