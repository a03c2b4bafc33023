"""`simucal.diagnose` -> Diagnosis (`simucal diagnose`): where the model fails and which effect is missing.

For each sensor triad: the exact norm fit with the noise the data give,
residuals per segment and axis against the noise floor, the tests and the
candidate ranking of simucal.fit.candidates (one test for every diagnosis), the
shape of a misfit no candidate explains (with a model file for it), and with
--add the parameters and the residual before and after; its verdicts and tables as a Diagnosis's
attributes (tables: simucal/api/tables.py).
"""
from __future__ import annotations

import heapq
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, NamedTuple, Sequence, cast

import numpy as np

from simucal import io, methods
from simucal.arguments import checked
from simucal.api.calibrating import Data
from simucal.api.sets import as_set, effect_ids
from simucal.api.tables import TableOf
from simucal.errors import InputError
from simucal.fit.results import Candidate as Candidate  # the API's (simucal.Candidate)
from simucal.io import records
from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel
from simucal.fit.candidates import test_model
from simucal.io.results import SensorTruth
from simucal.io.text_files import json_object_or_none
from simucal.report.console import skipped_sensors
from simucal.report.verdicts import sensor_verdict
from simucal.fit.norm_fit import Fit, Observations
from simucal.fit.results import (ALPHA, Added, DiagnosisReport, SensorDiagnosis, added_params, model_test_keys,
                                 diagnosis_blocks)
from simucal.io.timestamps import with_timestamps
from simucal.report.model_files import model_file_text
from simucal.turntable.model_test import test_and_rank


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
    report: DiagnosisReport  # diagnosis.json as written
    suggested: list[Suggestion] = field(default_factory=list)
    next: NextStep = NextStep("calibrate", {"add": []}, "simucal.calibrate(data)", "", ())
    candidates = TableOf("candidate_rows", ("sensor", "id", "estimate", "std", "unit", "statistic", "p_value",
                                            "significant", "separable", "note"))

    def __repr__(self) -> str:  # the verdicts are sentences: the first clause of each, the rest in .verdict
        return ("<simucal.Diagnosis: " + "; ".join(v.split(" (")[0].split(". ")[0] for v in self.verdict.values())
                + f"; next: {self.next_command}>")

    def _repr_html_(self) -> str:
        from simucal.notebook import html_card
        return html_card("simucal.Diagnosis", [*self.verdict.items(), ("next", self.next_command),
                                               *[("note", n) for n in self.notes + self.next_notes]])


@checked
def diagnose(data: Data, *, add: str | Sequence[str] = (), acc_model: str = "acc_baseline",
             gyro_model: str = "gyro_baseline", acc_noise_g: float | None = None, gyro_noise_dph: float | None = None,
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
    from simucal.report.console import calibrate_refusal, next_adds, next_command
    from simucal.report.units import diagnosis_in
    io.units.check_unit_system(units)
    add = effect_ids(add)
    if "auto" in add:
        raise InputError("add 'auto' is calibrate's: diagnose already ranks every candidate")
    report = diagnosis_report(as_set(data), add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph, timestamps)
    blocks = diagnosis_blocks(report)
    shown = diagnosis_in(report, units)  # the verdicts and the table in the units asked; the report as written
    rows = [Candidate.of(c) for c in shown["candidates"]]
    files: dict[str, str] = {s: str(b["shape"]["model_file"]) for s, b in blocks.items()
                             if b.get("shape") and not b["shape"].get("catalog_id")}
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
    return Diagnosis({s: b["verdict"] for s, b in diagnosis_blocks(shown).items()}, rows, cmd, notes,
                     list(report.get("notes", [])), files, report, suggestions(shown), step)


def suggestions(report: DiagnosisReport) -> list[Suggestion]:
    """Each sensor's effects its verdict adds (report/console.to_add) and a lead whose twins no rows could
    choose between (added by neither), with the candidate's statistics."""
    from simucal.report.console import to_add
    out = []
    for s, block in diagnosis_blocks(report).items():
        found, why = to_add(report, s)
        cands = {c["id"]: c for c in block["candidates"]}
        lead = next((c for c in block["candidates"] if c.get("significant")), None)
        undecided = [lead["id"]] if lead and lead.get("twins_undecided") and not found else []
        for eid in [e for e in found or [] if e in cands] + undecided:
            c: Mapping[str, Any] = cands[eid]  # its numbers read by name (number, below)
            number: Callable[[str], float | None] = lambda k: None if c.get(k) is None else float(c[k])  # noqa: E731 (numpy's scalars as floats)
            out.append(Suggestion(s, eid, number("estimate"), number("std"), c.get("unit", ""), number("statistic"),
                                  number("p_value"), tuple(c.get("twins") or ()),
                                  str(c.get("twin_choice") or "") if not undecided else "",
                                  not undecided, why if undecided else str(c.get("note") or "")))
    return out


def shape_model_path(output: str | os.PathLike[str], sensor: str) -> Path:
    """Where a diagnosis written to `output` puts a sensor's found term (<stem>_<sensor>_model.py)."""
    return Path(output).with_name(f"{Path(output).stem}_{sensor}_model.py")


def save_diagnosis(path: str | os.PathLike[str], d: Diagnosis) -> list[Path]:
    """The diagnosis file and, beside it, each found term's model file (named in the file); returns those."""
    from simucal.io import outputs
    written = []
    for s, text in d.model_files.items():
        written.append(shape_model_path(path, s))
        outputs.write_text(written[-1], text)
        shape = diagnosis_blocks(d.report).get(s, {}).get("shape")
        if isinstance(shape, dict):  # a model file is written for a shape found
            shape["model_file_path"] = str(written[-1])
    outputs.write_text(path, json.dumps(d.report, indent=1, default=float) + "\n")
    return written


def residual_table(fit: Fit, obs: Observations, segs: Sequence[io.Segment]) -> list[records.JSONObject]:
    """Each row's residual, its sigma and its inputs (the rows of a diagnosis's `residuals`)."""
    assert fit.directions is not None  # an exact fit's (test_model)
    rows: list[records.JSONObject] = []
    for i, s in enumerate(segs):
        r = fit.residuals[i]
        sd = obs.sigma[i] if obs.sigma is not None else None
        rows.append({"segment": s.segment, "kind": s.kind, "outer_rate_dps": s.outer_rate_dps,
                     **{k: float(np.broadcast_to(v, len(segs))[i]) for k, v in obs.aux.values.items()},
                     "direction": fit.directions[i].tolist(), "residual": r.tolist(),
                     "sigma": None if sd is None else sd.tolist(),
                     "normalized": None if sd is None else (r / sd).tolist()})
    return rows


def diagnose_sensor(ms: io.MeasurementSet, sensor: str, base_model: str, add: Sequence[str] = (),
                    stated: float | None = None, truth: dict[str, SensorTruth] | None = None,
                    before_model: str | None = None,
                    added: Sequence[str] = (), acc_model: str | AugmentedModel = "acc_baseline",
                    kind: methods.Kind | None = None) -> SensorDiagnosis | None:
    """One sensor's block. add: effect ids; before_model: the model to compare with when
    something was added (default base_model without the ids); added: what the user added
    (ids and model files), for the report; acc_model: on a stream, the accelerometer model (its
    effects too) whose pose directions the gyro's moves are judged against; kind: the set's entry
    in methods.KINDS (default its own), which gives the rows and what else its data judge."""
    kind = kind or methods.kind_of(ms)
    if sensor == "gyro" and kind.diagnose_gyro is not None:  # judged its own way (a stream: against its moves)
        return kind.diagnose_gyro(ms, base_model, tuple(add), truth, acc_model)
    found = kind.observations(ms, sensor, stated)
    if found is None:
        return None
    obs, segs, rows = found
    model = AugmentedModel(base_model, tuple(add))
    fit, obs, base, cands, shape, table_info = test_and_rank(model, obs, segs)
    out: dict[str, Any] = {**model_test_keys(base), "candidates": cands,
           "params": fit.params, "std": fit.std, "param_units": dict(zip(model.params, model.param_units)),
           "residuals": residual_table(fit, obs, rows)}
    if shape:
        out["shape"] = {**shape, "model_file": model_file_text(base_model, add, shape, sensor)}
    if table_info is not None:
        out["table"] = table_info
    out.update(kind.sensor_extras(ms, sensor, model, obs, fit, segs, shape))
    if "twin_fits" in out:  # the found term's twins, each with its model file (judged at rest by kind.finish_diagnosis)
        out["twin_fits"] = [{**tf, "shape": {**tf["shape"], "model_file": model_file_text(
            base_model, add, tf["shape"], sensor)}} for tf in out["twin_fits"]]
    before_model = before_model or model.base.name
    if add or before_model != base_model:
        f0, _, b0 = test_model(AugmentedModel(before_model), obs)
        comp = added_params({k: fit.params[k] for k in model.params}, fit.std, f0.params, f0.std,
                            (truth or {}).get(sensor, {}).get("params"))
        before_after: Added = {"effects": list(added or add), "residual_rms_before": f0.residual_rms,
                               "residual_rms_after": fit.residual_rms, "residual_unit": model.unit,
                               "p_value_before": b0["p_value"], "p_value_after": base["p_value"], "params": comp,
                               "residuals_before": residual_table(f0, obs, segs)}
        out["added"] = before_after
    return cast(SensorDiagnosis, out)  # its kind's extras: finish takes the transient ones (mirror, twin_fits) out


def scoring_truth(path: Path) -> dict[str, SensorTruth]:
    """A simulator's truth.json beside the set, read for scoring only (the errors of --add's parameters):
    {sensor: {params: {name: number}, T: 3x3, bias_dps: 3}} with whatever is not of that shape left
    out, and empty where it is missing or unreadable (deep, damaged, not JSON): it is never an input."""
    d = json_object_or_none(path)
    number: Callable[[Any], bool] = lambda x: isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x)
    out: dict[str, dict[str, Any]] = {}
    for sensor, block in (d.items() if isinstance(d, dict) else ()):
        if sensor not in ("acc", "gyro") or not isinstance(block, dict):
            continue
        params = block.get("params")
        out[sensor] = {"params": {k: v for k, v in params.items() if number(v)} if isinstance(params, dict) else {}}
        for key, shape in (("T", (3, 3)), ("bias_dps", (3,))):
            try:
                a = np.asarray(block[key], float)
                if a.shape == shape and np.all(np.isfinite(a)):
                    out[sensor][key] = a.tolist()
            except (KeyError, TypeError, ValueError):
                continue
    return cast("dict[str, SensorTruth]", out)


def diagnosis_report(folder: Data, add: Sequence[str] = (), acc_model: str = "acc_baseline",
                     gyro_model: str = "gyro_baseline", acc_noise_g: float | None = None,
                     gyro_noise_dph: float | None = None, timestamps: str = "auto") -> DiagnosisReport:
    """folder: a set's folder, or the set (io.MeasurementSet: its truth.json beside it, if any, scores);
    add: effect ids and model files (fit/augmented.resolve_add); timestamps: a stream's time
    stamps as calibrate takes them (io/timestamps.py)."""
    ms = folder if isinstance(folder, io.MeasurementSet) else io.read_set(folder)
    folder = Path(ms.path)
    try:
        ms, stamps = with_timestamps(ms, timestamps)
        result = _diagnose(ms, folder, add, acc_model, gyro_model, acc_noise_g, gyro_noise_dph)
        if stamps:
            result["timestamps"] = stamps
            if stamps["irregular"] or stamps.get("gaps") or timestamps != "auto":
                result["notes"] = [stamps["text"]] + result.get("notes", [])
        return result
    except CalibrationError as e:
        raise e.naming(ms.path) from None


def _diagnose(ms: io.MeasurementSet, folder: Path, add: Sequence[str], acc_model: str, gyro_model: str,
              acc_noise_g: float | None, gyro_noise_dph: float | None) -> DiagnosisReport:
    from simucal.fit.augmented import resolve_add
    from simucal.io.sensor_checks import stuck_channels
    stuck_channels(ms)
    before = {"acc": acc_model, "gyro": gyro_model}
    acc_model, gyro_model, ids = resolve_add(add, acc_model, gyro_model)
    truth = scoring_truth(folder / "truth.json")
    kind = methods.kind_of(ms)
    result: dict[str, Any] = {"format": "simucal.diagnosis/1", "input": str(folder), "alpha": ALPHA}
    if kind.diagnose_both is not None:  # both sensors in one (a sequence's filter)
        added = tuple(add) if add else ()
        result.update(kind.diagnose_both(ms, acc_model, gyro_model, ids, truth, (before["acc"], before["gyro"]), added))
    for sensor, model, stated, has in (("acc", acc_model, acc_noise_g, ms.has_acc),
                                       ("gyro", gyro_model, gyro_noise_dph, ms.has_gyro)):
        if not has or kind.diagnose_both is not None:
            continue
        mine = tuple(a for a in ids if a.startswith(sensor + "."))
        files = tuple(a for a in add if a.endswith(".py")) if model != before[sensor] else ()
        block = diagnose_sensor(ms, sensor, model, mine, stated, truth, before[sensor], mine + files,
                                AugmentedModel(acc_model, tuple(a for a in ids if a.startswith("acc."))), kind)
        if block is not None:
            result[sensor] = block
    kind.finish_diagnosis(ms, result, (acc_model, gyro_model, ids, acc_noise_g, gyro_noise_dph))
    sensors = [s for s in ("acc", "gyro") if s in result]
    for s in sensors:
        result[s]["verdict"] = sensor_verdict(result[s], s)
    if not sensors:
        raise CalibrationError(f"{folder}: nothing to diagnose: segments.csv holds no rows the "
                               f"{' or '.join(ms.sensors)} model is tested on (the accelerometers' static positions, "
                               "the gyro's rate runs)")
    worst = min(sensors,
                key=lambda s: result[s]["model_test"]["p_value"] if result[s]["model_test"]["p_value"] is not None
                else 1.0)
    result["sensor"] = worst
    result.update(model_test_keys(result[worst]["model_test"]))
    # merged in each sensor's own order (a twin chosen by rows beyond the likelihood ratio keeps its place)
    result["candidates"] = list(heapq.merge(*[[c for c in result[s]["candidates"] if c["separable"]] for s in sensors],
                                            key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0,
                                                           -c["statistic"]))) + \
        [c for s in sensors for c in result[s]["candidates"] if not c["separable"]]
    result["verdict"] = " | ".join(result[s]["verdict"] for s in sensors)
    result["notes"] = skipped_sensors(ms.sensors) + result.get("notes", [])
    return cast(DiagnosisReport, result)  # with the kind's keys (tests/test_calibration_file.py checks them)
