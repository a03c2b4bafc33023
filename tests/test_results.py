"""The typed core: one level at which a model fails, one candidate schema, the
diagnosis's model test under its name and its old one, no write onto the caller's set (a fit that
stops at its limit is told by its type: tests/test_calibrate_and_io.py)."""
import json

import numpy as np
import pytest

from simucal import io
from simucal.api.calibrating import calibrate
from simucal.api.diagnosing import diagnosis_report as diagnose
from simucal.fit.candidates import forward_selection
from simucal.fit.ranking import Trial, gate, rank
from simucal.fit.results import ALPHA, Candidate, ModelTest, Selection
from simucal.io.calibration import SensorBlock
from simucal.io.blocks import inflate_if_failing
from simucal.report.console import calibration_lines
from simucal.turntable.simulate import Scenario, plant, write


@pytest.mark.parametrize("p", [ALPHA / 2, 2 * ALPHA, 5e-3, 0.5])
def test_one_level_decides_fails_for_the_test_the_file_the_console_and_the_stds(p):
    """Between 1e-3 and 0.01 the advice said 'add it' while the console was silent: now every reader asks
    one level."""
    fails = ModelTest(40.0, 20, p).fails
    assert fails == (p < ALPHA)
    block = SensorBlock("affine", np.eye(3), np.zeros(3), "g", std={"b_x": 1.0}, chi2=40.0, dof=20, p_value=p)
    assert (block.verdict == "fails") == fails
    assert inflate_if_failing(block) == fails and ("std_raw" in block.details) == fails
    assert ModelTest.of({"chi2": 40.0, "dof": 20, "p_value": p}).fails == fails


class _Line:
    """A ranking Problem with known columns: the model spans e0, the residual lies along e1, so
    candidate 'a.strong.x' (along e1) explains it, 'a.twin.x' (along e1 and a little e2) nearly as
    well, 'a.none.x' has no input and 'a.span.x' lies in the model's span."""
    span = "the line"
    cols = {"a.strong.x": [0, 1, 0, 0], "a.twin.x": [0, 1, 0.05, 0], "a.none.x": [0, 0, 0, 0], "a.span.x": [2, 0, 0, 0]}

    def info(self, cid):
        return "k", "1", "a test effect"

    def basis(self):
        return np.eye(4)[:, :1]

    def residual(self):
        return np.array([0.0, 30.0, 0.0, 0.0]), 1.0

    def column(self, cid):
        return np.asarray(self.cols[cid], float)

    def fit_with(self, cid):
        stat = 900.0 if cid == "a.strong.x" else 899.0
        return Trial(1.0, 0.1, stat, 1e-12, stat - 2, 0.5)

    def to_see(self, cid):
        return "another line"

    def to_separate(self, cid, twin):
        return "a third axis"


def test_one_ranking_for_every_problem():
    out = rank(_Line(), _Line.cols, True, "test")
    by = {c.id: c for c in out}
    assert [c.id for c in out[:2]] == ["a.strong.x", "a.twin.x"] and by["a.strong.x"].significant
    assert by["a.strong.x"].twins == ("a.twin.x",) and "a third axis" in by["a.strong.x"].note
    assert "significant alone, but a.strong.x explains more" in by["a.twin.x"].note
    assert not by["a.none.x"].separable and by["a.none.x"].note.startswith("no input for it in these data")
    assert not by["a.span.x"].separable and "collinear with the line" in by["a.span.x"].note
    # significant only where the model test's family fails (its targeted tests are part of it: fit/family.py)
    assert not any(c.significant for c in rank(_Line(), _Line.cols, False, "test"))


def test_a_candidate_has_the_diagnosis_files_keys():
    """spec/measurement-set.md's candidate: the same keys for a tested and an untested one as before the
    schema was written once."""
    tested = gate([Candidate("acc.quadratic.x", "k2_x", "1/g", "m", True, estimate=1.0, std=0.1, statistic=100.0,
                             p_value=1e-20, delta_aic=98.0, residual_rms_after=1e-5)], True)[0].to_dict()
    assert set(tested) == {"effect", "axis", "id", "parameter", "unit", "meaning", "separable", "estimate", "std",
                           "statistic", "p_value", "delta_aic", "residual_rms_after", "significant"}
    assert tested["effect"] == "acc.quadratic" and tested["axis"] == "x" and tested["significant"] is True
    untested = Candidate("acc.quadratic.x", "k2_x", "1/g", "m", False, note="no input").to_dict()
    assert set(untested) == {"effect", "axis", "id", "parameter", "unit", "meaning", "separable", "note"}
    json.dumps([tested, untested])


@pytest.fixture(scope="module")
def failing_set(tmp_path_factory):
    root = tmp_path_factory.mktemp("core")
    sc = Scenario(plan="fibonacci48")
    plant(sc, ["acc.quadratic.z=3e-4"])
    write(root / "q", sc, 3)
    return root / "q"


def test_the_diagnosis_names_its_model_test_and_keeps_baseline(failing_set):
    d = diagnose(failing_set)
    assert d["acc"]["model_test"] is d["acc"]["baseline"] and d["model_test"] is d["baseline"]
    assert d["alpha"] == ALPHA and ModelTest.of(d["acc"]["model_test"]).fails
    saved = json.loads(json.dumps(d, default=float))
    assert saved["acc"]["baseline"] == saved["acc"]["model_test"]


def test_auto_and_the_console_agree_on_failing(failing_set):
    """--add auto adds while the model fails; the console says THE MODEL FAILS exactly where the block's
    verdict says fails, at the same level."""
    cal = calibrate(failing_set, add=("auto",))
    assert [s["id"] for s in cal.acc.details["auto"]] == ["acc.quadratic.z"]
    assert cal.acc.verdict == "passes" and "THE MODEL FAILS" not in "\n".join(calibration_lines(cal))
    base = calibrate(failing_set)
    assert base.acc.verdict == "fails" and "acc: THE MODEL FAILS" in "\n".join(calibration_lines(base))
    assert base.acc.details["advice"] == "acc.quadratic.z"


def test_forward_selection_returns_a_selection(failing_set):
    from simucal.fit.augmented import AugmentedModel
    from simucal.turntable.observations import segment_observations
    obs, _ = segment_observations(io.read_set(failing_set), "acc")
    sel = forward_selection(AugmentedModel("acc_baseline"), obs)
    assert isinstance(sel, Selection) and sel.model.effects == ("acc.quadratic.z",)
    assert sel.stopped == "the model passes its test" and sel.steps[0]["p_value_after"] >= ALPHA


def test_calibrate_leaves_the_callers_set_as_it_was(tmp_path):
    write(tmp_path / "t", Scenario(plan="fibonacci48", temp_c=(20.0, 30.0)), 1)
    ms = io.read_set(tmp_path / "t")
    cal = calibrate(ms, t_ref_c=22.0)
    assert ms.temperature_ref_c is None and cal.t_ref_c == 22.0


def test_every_step_of_the_forward_selection_has_the_whole_protocol():
    """fit/selection.forward_selection asks a SelectionStep for each of the Protocol's methods (to_separate only where
    the chosen effect has a twin, so a missing one would fail late, on real data): every kind of data's
    SelectionStep implements them all."""
    from simucal.fit.candidates import NormStep
    from simucal.fit.selection import SelectionStep
    from simucal.handheld.moves_selection import MovesStep
    from simucal.systematic.auto import FilterStep
    wanted = {n for n in vars(SelectionStep) if not n.startswith("_") and callable(getattr(SelectionStep, n))}
    assert {"test", "rank", "add", "held_out", "after", "to_separate"} <= wanted
    for cls in (NormStep, MovesStep, FilterStep):
        assert not wanted - set(dir(cls)), (cls.__name__, wanted - set(dir(cls)))


class _Fake:
    """A SelectionStep of fit/selection.forward_selection with a fixed test, candidates and estimates."""

    def __init__(self, chi2, dof, estimates, effects=(), next_steps=None):
        self.chi2, self.dof, self.est, self.effects, self.next = chi2, dof, estimates, tuple(effects), next_steps or {}
        self.model = self.effects

    def test(self):
        from simucal.fit.distributions import chi2_sf
        return ModelTest(self.chi2, self.dof, float(chi2_sf(self.chi2, self.dof)))

    def rank(self):
        return [{"id": e, "significant": True, "estimate": 1.0, "std": 0.1, "unit": "1", "statistic": 50.0}
                for e in self.next], None

    def add(self, eid):
        return self.next[eid]

    def held_out(self):
        return [1.0] * 20 if not self.effects else [0.5] * 20

    def after(self):
        return {}

    def estimates(self):
        return self.est

    def to_separate(self, chosen, twin):
        return ""


def test_auto_keeps_no_effect_that_leaves_the_model_failing_having_explained_little():
    """An effect that passes the gate and predicts the held-out rows better, but leaves the model
    failing with less than half the misfit explained and moves a baseline parameter by more than its std,
    is not kept; where it explains most of the misfit it is (more may be missing, in the library)."""
    from simucal.fit.selection import forward_selection
    start = lambda after: _Fake(1000.0, 100, {"b_z": (0.0, 1.0)}, next_steps={"gyro.quadratic.z": after})  # noqa
    little = forward_selection(start(_Fake(800.0, 99, {"b_z": (3.0, 1.0)}, ("gyro.quadratic.z",))), max_terms=1)
    assert (little.steps == [] and little.model == () and "not kept" in little.stopped
            and "b_z by 3.0 std" in little.stopped)
    most = forward_selection(start(_Fake(300.0, 99, {"b_z": (3.0, 1.0)}, ("gyro.quadratic.z",))), max_terms=1)
    assert [s["id"] for s in most.steps] == ["gyro.quadratic.z"] and most.model == ("gyro.quadratic.z",)
    still = forward_selection(start(_Fake(800.0, 99, {"b_z": (0.5, 1.0)}, ("gyro.quadratic.z",))), max_terms=1)
    assert [s["id"] for s in still.steps] == ["gyro.quadratic.z"]  # little explained, but nothing moved


def test_several_library_effects_at_once_are_not_called_outside_the_library():
    """Three accelerometer quadratics planted at once each explain under half of the misfit;
    together (family.outside_library's joint test of the strongest three) they explain it, so calibrate and
    diagnose advise one of them, not 'outside the library'."""
    from simucal import api
    ms = api.simulate(plan="fibonacci48", seed=1, effects={f"acc.quadratic.{a}": 1e-4 for a in "xyz"})
    cal = api.calibrate(ms)
    assert cal.acc.verdict == "fails" and cal.acc.details["advice"] in {f"acc.quadratic.{a}" for a in "xyz"}
    assert "add=['acc.quadratic." in api.diagnose(ms).next_command
