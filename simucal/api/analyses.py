"""`simucal.diagnose` -> Diagnosis and `simucal.noise` -> Noise: the reports of `simucal diagnose` and
`simucal noise` with their verdicts and tables as attributes (tables: simucal/api/tables.py)."""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple, Sequence, Union

from simucal.errors import InputError
from simucal import io
from simucal.io import records
from simucal.api.arguments import checked
from simucal.api.sets import as_set, effect_ids, folder_of
from simucal.api.tables import TableOf

Data = Union[str, os.PathLike, io.MeasurementSet]


class Candidate(NamedTuple):
    """One row of `Diagnosis.candidates`: an effect the model lacks, tested by adding it (a
    likelihood-ratio test, gated as part of the model test's family: fit/family.py)."""
    sensor: str
    id: str               # the effect id calibrate --add takes
    estimate: float | None  # its value fitted beside the model, in `unit`
    std: float | None
    unit: str
    statistic: float | None  # the likelihood ratio (or F) of adding it
    p_value: float | None
    significant: bool     # beats the gate where the model fails: the one to add
    separable: bool       # False: these data cannot see it (note says which data can)
    note: str


class Suggestion(NamedTuple):
    """One effect the diagnosis's verdicts lead to (`Diagnosis.suggested`): its statistics, the twins the data
    could not tell from it and how the choice between them was made."""
    sensor: str
    id: str                 # the effect id calibrate's add takes
    estimate: float | None  # its value fitted beside the model, in `unit`
    std: float | None
    unit: str
    statistic: float | None
    p_value: float | None
    twins: tuple[str, ...]  # candidates these data cannot tell from it by their likelihood ratio
    decided_by: str         # which rows chose it over its twins (in words), "" where it has none
    add: bool               # False: its twins are undecided, so neither is added (the plan that would tell in note)
    note: str


class NextStep(NamedTuple):
    """The step after a diagnosis (`Diagnosis.next`), as data: the API's function and its keywords, with the
    same step as a Python call and as a command. function is "" where calibrate would refuse the data and the
    step is another command (its `command`, and why in `notes`)."""
    function: str
    options: dict[str, list[str]]
    call: str
    command: str
    notes: tuple[str, ...]


@dataclass
class Diagnosis:
    """Where a model fails on a set and which missing effect explains it.

    Attributes
    ----------
    verdict : dict
        Per sensor, the verdict sentence (the model passes, or fails and what to add).
    candidates : DataFrame or list of Candidate
        Every candidate effect, the separable ones by p-value first (a table: simucal/api/tables.py).
    candidate_rows : list of Candidate
        The same rows as a list.
    next_command : str
        The calibration to run next: a `simucal calibrate` command on the set's folder, or for a set
        in memory the `simucal.calibrate` call; with the effects the verdicts lead to.
    next_notes : list of str
        What the next command leaves open (e.g. a failing model with nothing in the library to add).
    notes : list of str
        The data's own (a reflected triad, irregular time stamps).
    model_files : dict
        Per sensor, a found term that is no library effect, as a model file's text (``--add FILE``).
    suggested : list of Suggestion
        The effects the verdicts lead to, with their statistics and twins, as data (the sentences are made from
        them): ``simucal.calibrate(data, add=[s.id for s in d.suggested if s.add])``.
    next : NextStep
        The next step as data: ``getattr(simucal, d.next.function)(data, **d.next.options)``.
    report : dict
        What `simucal diagnose -o` writes (``simucal.diagnosis/1``).
    """
    verdict: dict[str, str]
    candidate_rows: list[Candidate]
    next_command: str
    next_notes: list[str]
    notes: list[str]
    model_files: dict[str, str]
    report: records.JSONObject  # diagnosis.json as written
    suggested: list[Suggestion] = field(default_factory=list)
    next: NextStep = NextStep("calibrate", {"add": []}, "simucal.calibrate(data)", "", ())
    candidates = TableOf("candidate_rows", Candidate._fields)

    def __repr__(self) -> str:  # the verdicts are sentences: the first clause of each, the rest in .verdict
        return ("<simucal.Diagnosis: " + "; ".join(v.split(" (")[0].split(". ")[0] for v in self.verdict.values())
                + f"; next: {self.next_command}>")

    def _repr_html_(self) -> str:
        from simucal.api.tables import html_card
        return html_card("simucal.Diagnosis", [*self.verdict.items(), ("next", self.next_command),
                                               *[("note", n) for n in self.notes + self.next_notes]])


@checked
def diagnose(data: Data, *, add: str | Sequence[str] = (), acc_model: str = "acc_baseline", gyro_model: str = "gyro_baseline",
             acc_noise_g: float | None = None, gyro_noise_dph: float | None = None,
             timestamps: str = "auto", units: str = "spec") -> Diagnosis:
    """Test the model on a set and rank the candidate missing effects.

    Parameters
    ----------
    data : str, os.PathLike or MeasurementSet
        A turntable test, a field set or a hand-placed session.
    add : list of str
        Effect ids or model files already in the model (as `calibrate`'s `add`; not "auto").
    acc_model, gyro_model : str
        The models tested (default the baselines).
    acc_noise_g, gyro_noise_dph : float, optional
        The noise of one row (g, deg/h) where the data's meta.json states none.
    timestamps : {"auto", "nominal", "recorded"}
        A stream's time stamps, as `calibrate` takes them.
    units : {"spec", "si"}
        The unit system of ``.verdict`` and ``.candidates`` (si: m/s^2, rad/s, 1/(m/s^2), ..., as `simucal diagnose
        --units si` prints them); ``.report``, the file, is always in the spec's.

    Returns
    -------
    Diagnosis

    Examples
    --------
    >>> import simucal
    >>> d = simucal.diagnose(simucal.simulate(seed=1, effects={"acc.quadratic.z": 2e-4}))  # doctest: +SKIP
    >>> d.next_command  # doctest: +SKIP
    'simucal calibrate ... --add acc.quadratic.z -o calibration.json'
    """
    from simucal.diagnose import diagnose as run
    from simucal.report.console import calibrate_refusal, next_adds, next_command
    from simucal.report.units import diagnosis_in
    io.units.check_unit_system(units)
    add = effect_ids(add)
    if "auto" in add:
        raise InputError("add 'auto' is calibrate's: diagnose already ranks every candidate")
    report = run(as_set(data), add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph, timestamps)
    sensors = [s for s in ("acc", "gyro") if s in report]
    shown = diagnosis_in(report, units)  # the verdicts and the table in the units asked; the report as written
    rows = [Candidate(c["id"].split(".")[0], c["id"], c.get("estimate"), c.get("std"), c.get("unit", ""),
                      c.get("statistic"), c.get("p_value"), bool(c.get("significant")), bool(c["separable"]),
                      c.get("note") or "") for c in shown["candidates"]]
    files = {s: report[s]["shape"]["model_file"] for s in sensors
             if report[s].get("shape") and not report[s]["shape"].get("catalog_id")}
    refused = calibrate_refusal(report)
    adds, notes = next_adds(report)
    call = f"simucal.calibrate(data, add={adds!r})" + (
        " (a found term: write Diagnosis.model_files[sensor] to a file and add its path)" if files else "")
    if refused is not None:
        cmd, notes = refused
        step = NextStep("", {}, "", cmd, tuple(notes))
    else:
        in_memory = isinstance(data, io.MeasurementSet) and not (Path(data.path) / "meta.json").is_file()
        command = next_command(report)[0]
        cmd = call if in_memory else command  # a set in memory: the next step is a call, not a command on a folder
        step = NextStep("calibrate", {"add": adds}, call, command, tuple(notes))
    return Diagnosis({s: shown[s]["verdict"] for s in sensors}, rows, cmd, notes,
                     list(report.get("notes", [])), files, report, suggestions(shown), step)


def suggestions(report: dict) -> list[Suggestion]:
    """Each sensor's effects its verdict adds (report/console.to_add) and a lead whose twins no rows could
    choose between (added by neither), with the candidate's statistics."""
    from simucal.report.console import to_add
    out = []
    for s in ("acc", "gyro"):
        if s not in report:
            continue
        found, why = to_add(report, s)
        block = report[s]
        cands = {c["id"]: c for c in block["candidates"]}
        lead = next((c for c in block["candidates"] if c.get("significant")), None)
        undecided = [lead["id"]] if lead and lead.get("twins_undecided") and not found else []
        for eid in [e for e in found or [] if e in cands] + undecided:
            c = cands[eid]
            number = lambda k: None if c.get(k) is None else float(c[k])  # noqa: E731 (numpy's scalars as floats)
            out.append(Suggestion(s, eid, number("estimate"), number("std"), c.get("unit", ""), number("statistic"),
                                  number("p_value"), tuple(c.get("twins") or ()),
                                  str(c.get("twin_choice") or "") if not undecided else "",
                                  not undecided, why if undecided else str(c.get("note") or "")))
    return out


def shape_model_path(output: str | os.PathLike, sensor: str) -> Path:
    """Where a diagnosis written to `output` puts a sensor's found term (<stem>_<sensor>_model.py)."""
    return Path(output).with_name(f"{Path(output).stem}_{sensor}_model.py")


def save_diagnosis(path: str | os.PathLike, d: Diagnosis) -> list[Path]:
    """The diagnosis file and, beside it, each found term's model file (named in the file); returns those."""
    from simucal.io import outputs
    written = []
    for s, text in d.model_files.items():
        written.append(shape_model_path(path, s))
        outputs.write_text(written[-1], text)
        block = d.report[s]
        shape = block.get("shape") if isinstance(block, dict) else None
        if isinstance(shape, dict):  # a model file is written for a shape found
            shape["model_file_path"] = str(written[-1])
    outputs.write_text(path, json.dumps(d.report, indent=1, default=float) + "\n")
    return written


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
    report: records.JSONObject  # noise.json as written
    curve_rows: list[AllanPoint] = field(default_factory=list)
    terms = TableOf("term_rows", Term._fields)
    curve = TableOf("curve_rows", AllanPoint._fields)

    def __repr__(self) -> str:
        seen = [f"{t.sensor} {t.axis} {t.term} {t.value:.3g} {t.unit}" for t in self.term_rows if t.status == "seen"
                and t.value is not None]
        return f"<simucal.Noise: {len(seen)} terms seen" + (f": {'; '.join(seen[:6])}" if seen else "") + ">"

    def _repr_html_(self) -> str:
        from simucal.api.tables import html_card
        return html_card("simucal.Noise", [(f"{t.sensor} {t.axis} {t.name}",
                                            f"{t.value:.4g} +- {t.std:.2g} {t.unit}" if t.status == "seen" and t.value
                                            is not None and t.std is not None else
                                            f"{t.status}" + (f" (< {t.bound_95:.3g} {t.unit})" if t.bound_95 else ""))
                                           for t in self.term_rows])

    @checked
    def lines(self, written: dict | None = None, units: str = "spec") -> list[str]:
        """What `simucal noise` prints: each axis's terms in a data sheet's units (``units="si"``: in SI, as
        `simucal noise --units si`), the verdicts and the next step (written: the files the command wrote,
        {"-o": ..., "--kalibr": ...}, which the next step names)."""
        from simucal import allan
        return list(allan.lines(self.report, written, units))

    @checked
    def kalibr_yaml(self) -> str:
        """Kalibr's imu.yaml (noise densities and random walks, SI), as `simucal noise --kalibr` writes it;
        refused (CalibrationError) unless both sensors give them.

        Examples
        --------
        >>> open("imu.yaml", "w").write(simucal.noise("still").kalibr_yaml())  # doctest: +SKIP
        """
        from simucal import allan
        return allan.kalibr_yaml(self.report)


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
    from simucal import allan
    from simucal.io import logs, rosbag
    from simucal.report.units import noise_in
    io.units.check_unit_system(units)
    if not isinstance(data, io.MeasurementSet) and (topic or rosbag.is_rosbag(folder_of(data))):
        data = logs.bag_as_set(folder_of(data), topic)  # read as `simucal import rosbag` reads it
    report = (allan.characterise(data, tau_max_s) if isinstance(data, io.MeasurementSet)
              else allan.characterise_folder(folder_of(data), tau_max_s, scheduler))
    shown = noise_in(report, units)  # the tables in the units asked; the report as written
    rows = [Term(s, a, k, t["name"], t["status"], t["value"] if t["status"] == "seen" else None, t.get("std"), t.get("bound_95"), t.get("needs_s"),
                 t["unit"])
            for s in ("acc", "gyro") if s in shown for a, axis in shown[s]["axes"].items()
            for k, t in axis.get("sheet", {}).items()]
    return Noise(rows, report, allan_points(shown))


def allan_points(report: dict) -> list[AllanPoint]:
    """The report's Allan deviation curves as rows (Noise.curve)."""
    out = []
    for s in ("acc", "gyro"):
        if s not in report:
            continue
        for a, axis in report[s]["axes"].items():
            taus, errs = axis.get("tau_s", report[s]["tau_s"]), axis.get("rel_err") or [None] * len(axis["adev"])
            out += [AllanPoint(s, a, float(t), float(d), None if e is None else float(e), report[s]["unit"])
                    for t, d, e in zip(taus, axis["adev"], errs) if d is not None]
    return out
