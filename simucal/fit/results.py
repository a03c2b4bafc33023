"""The typed results of the model test, the candidate ranking and forward selection.

- ModelTest: a model's test (chi2, dof, p) and the one level at which a model fails, ALPHA
  (io.calibration: the calibration file's `verdict` is defined by it). The advice, `--add auto`,
  diagnose's verdict, the console's THE MODEL FAILS and the std inflation all ask ModelTest.fails.
- Candidate: one effect tried beside the model, written once for every ranking (the library's on
  the norm fit, the gyro's over a stream's moves, a table's own terms); to_dict() gives the keys the
  diagnosis file has always held (spec/measurement-set.md).
- Selection: what `--add auto`'s forward selection chose and why it stopped.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping, TypedDict, TypeVar, cast

from simucal.io.calibration import ALPHA
from simucal.io.details import ModelTestBlock
from simucal.io.records import AutoStep, JSONObject, Saturation, SkippedMove, StaticRows
from simucal.io.stream_records import Timestamps

__all__ = ["ALPHA", "Candidate", "ModelTest", "Selection", "added_params", "model_test_keys"]
Test = TypeVar("Test")  # a model test's block, whatever its type


class CandidateRecord(TypedDict, total=False):
    """A candidate as the diagnosis file writes it (Candidate.to_dict; units: the candidate's unit)."""
    effect: str                       # the library effect, without its axis
    axis: str                         # x, y or z
    id: str                           # effect.axis
    parameter: str                    # its parameter's name in the model
    unit: str                         # the parameter's
    meaning: str                      # what it is, in words
    test: str                         # a ranking other than the likelihood ratio: its test
    separable: bool                   # the data can tell it from the model
    estimate: float | None            # where separable: its estimate and std, in unit
    std: float | None                 # its estimate's std
    statistic: float | None           # the likelihood-ratio (or F) statistic, and its p
    p_value: float | None             # the statistic's p-value
    delta_aic: float | None           # the AIC's change with it, where the noise is known
    residual_rms_after: float | None  # the model's residual rms with it
    significant: bool                 # it passes the gate: the one to add
    note: str                         # why it is not separable, what would show it
    twins: list[str]                  # the candidates the data cannot tell it from
    at_rest: dict[str, StaticRows]    # a lead with twins: each twin's static rows' (and pairs') test
    twin_choice: str                  # which twin the rows at rest chose, or why none, in words
    twins_undecided: bool             # no rows chose between its twins: --add auto adds neither


class MisfitShares(TypedDict):
    """`--add auto` over the moves as the diagnosis file's `misfit_shares` (select_effects)."""
    chi2: float                       # the fit without effects, on dof
    dof: int                          # its degrees of freedom
    residual_rms: float               # its gravity-direction residuals' rms (unit vector components)
    steps: list[AutoStep]             # each effect chosen, with its share of that fit's excess (chi2 - dof)
    effects: list[str]                # the model chosen's effects
    stopped: str                      # why the selection stopped
    unexplained: float                # the share of the excess the chosen effects leave


class ShapePoints(TypedDict):
    """The rows of a shape block's plot, in the model's residual unit."""
    regressor: list[float]            # the term's regressor at each row
    residual: list[float]             # the row's residual on the term's axis
    term_visible: list[float]         # the part of the term the model cannot absorb: what the residual should show


class Shape(TypedDict):
    """The generic term that explains most of a model's misfit (describe_shape): diagnose's `shape`."""
    axis: str                         # x, y or z
    regressor: str                    # the term, in words
    catalog_id: str | None            # the library effect with this very regressor, if there is one
    degree: int                       # the regressor's degree in the input
    parity: str                       # even or odd in the input, in words
    estimate: float                   # its coefficient, in unit
    unit: str                         # the coefficient's
    parameter: str                    # its name as a model file's parameter
    sympy: str                        # its regressor as a SymPy expression
    share_of_misfit: float            # of the residuals' sum of squares it explains, 0 to 1
    residual_rms_after: float         # with it, in g or deg/h
    indistinguishable_here: list[str]  # the generic terms these rows cannot tell from it (6 at most)
    points: ShapePoints               # the plot's rows
    text: str                         # the console's words


class DiagnosedShape(Shape, total=False):
    """A diagnosis's `shape`: the term found in the residuals (fit/lack_of_fit.describe_shape) with its model file."""
    model_file: str                   # the term as a model file's text (report/model_files.py)
    model_file_path: str              # where diagnose wrote it, where it did


class Added(TypedDict):
    """diagnose --add: the model without the effects beside the model with them (every kind of data)."""
    effects: list[str]                # what was added: ids and model files
    residual_rms_before: float
    residual_rms_after: float
    residual_unit: str
    p_value_before: float | None      # the model test's, without and with the effects
    p_value_after: float | None
    params: dict[str, AddedParam]     # each parameter before and after (added_params)
    residuals_before: list[JSONObject]  # each row's residual without the effects


class SensorDiagnosis(TypedDict, total=False):
    """One sensor's block of a diagnosis (api/diagnosing.py, and the kinds' own: handheld/, systematic/); its
    free-form parts are documents (docs/spec/measurement-set.md). tests/test_calibration_file.py checks that
    every key a diagnosis writes is declared here."""
    model_test: ModelTestBlock        # the model diagnosed's test (model_test_keys), also under `baseline`
    baseline: ModelTestBlock
    candidates: list[CandidateRecord]  # ranked
    params: dict[str, float]          # the model's estimates and stds, in param_units
    std: dict[str, float]
    param_units: dict[str, str]
    residual_unit: str
    residuals: list[JSONObject]       # each row's residual, sigma and inputs
    shape: DiagnosedShape             # a term found in the residuals, with its model file
    table: JSONObject                 # a turntable's own terms
    added: Added                      # --add: the residuals and parameters before and after
    misfit_shares: MisfitShares | None  # a stream's: the effects chosen over its moves
    twin_choice: str                  # which twin the rows at rest chose, in words
    moves_opposite_sense: list[int]
    moves_skipped: list[SkippedMove]
    saturation: list[Saturation]
    explained_by: dict[str, str]      # the other sensor's effect explains the misfit (id, sensor)
    calibrate_refuses: str            # why calibrate would refuse these data, and what to run instead
    next_instead: dict[str, str]
    verdict: str
    unit: str                         # the residuals' unit in the system shown (report/units.diagnosis_in)


class DiagnosisReport(TypedDict, total=False):
    """What `simucal diagnose -o` writes (simucal.diagnosis/1): the top level; each sensor's a SensorDiagnosis."""
    format: str
    input: str                        # the set's folder
    alpha: float                      # the model test's level
    acc: SensorDiagnosis
    gyro: SensorDiagnosis
    sensor: str                       # the sensor whose model test has the lowest p (its test below)
    model_test: ModelTestBlock
    baseline: ModelTestBlock
    candidates: list[CandidateRecord]  # both sensors', merged in each one's order
    stream: JSONObject                # a stream's stillness and norms
    timestamps: Timestamps
    verdict: str                      # each sensor's, joined by " | "
    notes: list[str]


def diagnosis_blocks(report: DiagnosisReport) -> dict[str, SensorDiagnosis]:
    """The report's sensor blocks by name, those it has."""
    return {s: b for s, b in (("acc", report.get("acc")), ("gyro", report.get("gyro"))) if b is not None}


class AddedParam(TypedDict, total=False):
    """One parameter of the diagnosis file's `added.params` (added_params), in the parameter's unit."""
    before: float | None              # without the effects (None: an effect's own)
    std_before: float | None          # its std without them
    after: float                      # with them
    std_after: float                  # its std with them
    truth: float                      # a simulator's truth, and each fit's error against it
    error_before: float | None        # before less truth (None: an effect's own)
    error_after: float                # after less truth


@dataclass(frozen=True)
class ModelTest:
    """A model's test: chi2 on dof where the noise is known (None where only the lack-of-fit F
    tests it), p its p-value (None: too few dof for any test), test in words."""
    chi2: float | None
    dof: int
    p_value: float | None
    test: str = ""

    @property
    def fails(self) -> bool:
        """The model fails its test: p below ALPHA (no test, no failure)."""
        return self.p_value is not None and self.p_value < ALPHA

    @classmethod
    def of(cls, block: Mapping[str, Any]) -> ModelTest:
        """The test a block holds (fit.candidates.test_model's, the diagnosis file's `baseline`)."""
        return cls(block.get("chi2"), int(block.get("dof") or 0), block.get("p_value"), block.get("test", ""))


@dataclass(frozen=True)
class Candidate:
    """One effect tried beside the model: a ranking's, and a row of `simucal.Diagnosis.candidates` (read back
    from the diagnosis file by `of`, in the units asked). Not separable: note says why (no input for it in these
    data, collinear with the model, its fit failed) and what would show it. Separable: its estimate
    and std, the likelihood-ratio (or F) statistic and p-value, delta AIC where the noise is known,
    the residual rms with it, whether it passes the gate (ranking.gate; significant: the one to add) and
    the candidates the data cannot tell it from (fit/twins.py)."""
    id: str
    parameter: str
    unit: str
    meaning: str
    separable: bool
    note: str | None = None
    estimate: float | None = None
    std: float | None = None
    statistic: float | None = None
    p_value: float | None = None
    delta_aic: float | None = None
    residual_rms_after: float | None = None
    significant: bool = False
    twins: tuple[str, ...] = ()
    test: str | None = None  # a ranking other than the model's likelihood ratio names its test

    @classmethod
    def of(cls, d: Mapping[str, Any]) -> Candidate:
        """The candidate a diagnosis file holds (to_dict's keys)."""
        number = lambda k: None if d.get(k) is None else float(d[k])  # noqa: E731 (numpy's scalars as floats)
        return cls(str(d["id"]), str(d.get("parameter", "")), str(d.get("unit", "")), str(d.get("meaning", "")),
                   bool(d["separable"]), d.get("note"), number("estimate"), number("std"), number("statistic"),
                   number("p_value"), number("delta_aic"), number("residual_rms_after"), bool(d.get("significant")),
                   tuple(d.get("twins") or ()), d.get("test"))

    @property
    def sensor(self) -> str:
        return self.id.split(".")[0]

    @property
    def effect(self) -> str:
        return ".".join(self.id.split(".")[:2])

    @property
    def axis(self) -> str:
        return self.id.split(".")[2]

    def with_note(self, text: str) -> Candidate:
        """This candidate with text appended to its note (itself where text is empty)."""
        if not text:
            return self
        return replace(self, note=(self.note + "; " if self.note else "") + text)

    def to_dict(self) -> CandidateRecord:
        """The diagnosis file's candidate (spec/measurement-set.md): the keys a candidate of its kind
        has always had."""
        d = {"effect": self.effect, "axis": self.axis, "id": self.id, "parameter": self.parameter, "unit": self.unit,
             "meaning": self.meaning, **({"test": self.test} if self.test else {}), "separable": self.separable}
        if self.separable:
            d.update(estimate=self.estimate, std=self.std, statistic=self.statistic, p_value=self.p_value,
                     delta_aic=self.delta_aic, residual_rms_after=self.residual_rms_after, significant=self.significant)
        if self.note is not None:
            d["note"] = self.note
        if self.twins:
            d["twins"] = list(self.twins)
        return cast(CandidateRecord, d)


@dataclass(frozen=True)
class Selection:
    """`--add auto`: the model chosen, the steps (id, estimate, std, unit, the test's p, the residual and
    held-out rms after, the held-out test's p) and why it stopped."""
    model: Any
    steps: list = field(default_factory=list)
    stopped: str = ""



def model_test_keys(test: Test) -> dict[str, Test]:
    """A diagnosis block's model test under its name, `model_test` (the model diagnosed, --add's effects
    included), and under `baseline`, the name the diagnosis file has always given it (kept for its readers)."""
    return {"model_test": test, "baseline": test}


def added_params(after: Mapping[str, float], std_after: Mapping[str, float], before: Mapping[str, float],
                 std_before: Mapping[str, float], truth: Mapping[str, float] | None = None) -> dict[str, AddedParam]:
    """The diagnosis file's `added.params` (diagnose --add, every kind of data): each parameter of the
    model with the effects, its value and std without them (None for the effects' own) and, where a
    simulator's truth knows it, the error of each."""
    out: dict[str, AddedParam] = {}
    for k, v in after.items():
        row = {"before": before.get(k), "std_before": std_before.get(k), "after": v, "std_after": std_after[k]}
        if truth and k in truth:
            t = truth[k]
            row.update(truth=t, error_before=None if row["before"] is None else row["before"] - t, error_after=v - t)
        out[k] = cast(AddedParam, row)
    return out
