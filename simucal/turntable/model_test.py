"""One model test per sensor on a turntable set, shared by calibrate and diagnose.

The rows: for accelerometers the static positions and the rate runs (a rate run's mean
specific force is gravity's component along the outer axis plus, with lever arms, a
centripetal term: the rows where size effects show); for gyros the rate runs. The statistic:
fit.candidates.test_model (chi-square where the noise is known, the lack-of-fit F where it is
not). The ranking: the library's candidates, with the positions that would reveal the ones
this plan cannot see (plan_design.TableAdvice), and for accelerometers the table's own error
terms fitted to the static directions (table_fit), ordered by p-value. calibrate's advice and
diagnose's verdict are read from the same list, so they name the same effect.
"""
from __future__ import annotations

from collections import Counter
from typing import Any, NamedTuple, cast

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.apply import model_inputs
from simucal.fit.augmented import AugmentedModel
from simucal.fit.aux_inputs import specific_force
from simucal.fit import family
from simucal.fit.candidates import positions_that_separate, rank_candidates, shape_if_unexplained, test_model
from simucal.fit.results import ALPHA, CandidateRecord, ModelTest
from simucal.fit.twins import CANNOT_TELL
from simucal.fit.distributions import chi2_sf
from simucal.fit.norm_fit import Fit, Observations, fit_exact
from simucal.io import records, units
from simucal.io.details import ModelTestBlock
from simucal.turntable.plan_design import TableAdvice

ROWS = {"acc": {"static", "rate"}, "gyro": {"rate"}}  # the segment kinds each sensor's test fits
MIN_TABLE_POSITIONS = 6  # static positions with middle/inner angles for the table's own terms


def rows_text(segs) -> str:
    """Which rows a test used, in words: '16 static positions and 14 rate runs'."""
    n = Counter(s.kind for s in segs)
    return " and ".join(f"{n[k]} {name}" for k, name in (("static", "static positions"), ("rate", "rate runs")) if n[k])


class Tested(NamedTuple):
    """A model tested and its candidates ranked (test_and_rank)."""
    fit: Fit
    obs: Observations       # with the noise the test used
    base: ModelTestBlock    # the test block (fit.candidates.test_model, with `rows`)
    candidates: list[CandidateRecord]  # ranked (results.Candidate.to_dict), [] where not ranked
    shape: dict | None      # the generic term that explains the misfit better than any candidate
    table: dict | None      # the table's own terms fitted (turntable/table_fit.py)


def test_and_rank(model, obs, segs=None, only_if_failing=False, ranked=True, at_rest=None) -> Tested:
    """The model tested and, unless only_if_failing and it passes or ranked is False, its candidates
    ranked (rank). segs: the turntable segments of obs's rows; None for a stream's static poses (no plan
    to grow, no table angles); at_rest: rank's."""
    fit, obs, base = test_model(model, obs)
    if segs is not None:
        base["rows"] = rows_text(segs)
    if (only_if_failing and not ModelTest.of(base).fails) or not ranked:
        return Tested(fit, obs, base, [], None, None)
    return Tested(fit, obs, base, *rank(model, obs, fit, base, segs, at_rest))


def rank(model, obs, fit, base, segs=None, at_rest=None):
    """The ranked candidates, the generic shape where it explains more than they do (or None),
    and the table's fit (or None). at_rest(model, obs, fit, base) -> AtRest or None: a gyro's static
    rows, which choose among twins the rate runs cannot tell apart (choose_twin)."""
    cands = rank_candidates(model, obs, fit, ModelTest.of(base).fails,
                            advisor=TableAdvice() if segs is not None else None)
    if at_rest is not None:
        choose_twin(cands, lambda: at_rest(model, obs, fit, base))
    table_info = None
    if segs is not None:
        idx = [i for i, s in enumerate(segs) if s.kind == "static" and s.middle_deg is not None
               and s.inner_deg is not None]
        if model.sensor == "acc" and len(idx) >= MIN_TABLE_POSITIONS:
            from simucal.turntable.table_fit import table_candidates
            ang = [[segs[i].outer_deg or 0.0, segs[i].middle_deg, segs[i].inner_deg] for i in idx]
            tc, table_info = table_candidates(fit.directions[idx], ang)
            both = cands + tc
            cands = sorted([c for c in both if c["separable"]],
                           key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0, -c["statistic"])) + \
                [c for c in both if not c["separable"]]
    return cands, shape_if_unexplained(model, obs, fit, base, cands), table_info


def static_gyro_test(ms, gm, fg, u_b, C_b_d, static_gyro, term=None) -> records.StaticRows:
    """The gyro's static rows as part of its model test. At rest a gyro reads the
    Earth rate plus its bias: the fitted model (rate runs only) inverted whole at each static
    position, w = h^-1(N), must show the Earth rate's vertical component w_e sin L along the
    accelerometers' up (u_b in d through C_b^d) and its horizontal magnitude w_e cos L (the
    azimuth needs a heading the table does not give). Each residual's variance: the row's own noise
    through M^-1, plus the rate-run fit's parameter covariance (shared by all rows, numerical
    Jacobian). chi2 = e^T S^-1 e on len(e) dof (the rows are predictions: no parameter is fitted to
    them). A bias that follows a fixed direction in the local frame (the magnetic field's) shows in
    rate-run means only as its vertical part, which a g-sensitivity absorbs; the static rows see
    the rest. term: a generic term the rate runs were fitted with (lack_of_fit.twin_fits: its column,
    the parameters with its coefficient last, their covariance), added to the model here."""
    N, sig, aux = static_gyro
    if sig is None:
        return {"verdict": "not tested: no noise for the static gyro rows (raw rows or a stated gyro_noise_dph)"}
    w_e, L = units.earth_rate_dph(ms.meta), np.radians(float(ms.meta["latitude_deg"]))
    up_d = u_b @ C_b_d.T
    aux_f = aux.with_values(**specific_force(up_d))
    p, cov = (fg.vector(gm.params), fg.cov) if term is None else (term["params"], term["cov"])
    m = len(gm.params)
    A = np.linalg.inv(gm.matrix_and_bias(p[:m])[0])
    if term is not None:  # the term's values at the rates the model alone reads (at rest they hardly differ)
        col = term["column"](model_inputs(gm, p[:m], N, aux_f, ms.path / "samples.csv"), aux_f)
    horizontal = w_e * np.cos(L) > 20 * float(np.median(sig))  # its magnitude is Gaussian only well above noise

    def residuals(q):
        w = model_inputs(gm, q[:m], N - (q[m] * col if term is not None else 0.0), aux_f, ms.path / "samples.csv")
        v = np.sum(w * up_d, axis=1)
        h = w - v[:, None] * up_d
        e = [v - w_e * np.sin(L)] + ([np.linalg.norm(h, axis=1) - w_e * np.cos(L)] if horizontal else [])
        return np.concatenate(e), [up_d] + ([h / np.linalg.norm(h, axis=1, keepdims=True)] if horizontal else [])

    e, dirs = residuals(p)
    var = np.concatenate([np.sum((d @ A) ** 2 * sig ** 2, axis=1) for d in dirs])  # (d^T M^-1) diag(sig^2) (.)^T
    step = np.maximum(np.sqrt(np.diag(cov)), 1e-12) * 1e-3
    J = np.column_stack([(residuals(p + s * k)[0] - residuals(p - s * k)[0]) / (2 * s)
                         for s, k in zip(step, np.eye(len(p)))])
    S = np.diag(var) + J @ cov @ J.T
    chi2 = float(e @ np.linalg.solve(S, e))
    n, dof = len(N), len(e)
    p_value = float(chi2_sf(chi2, dof))
    what = "the Earth rate's vertical component" + (" and horizontal magnitude" if horizontal else "")
    out: dict[str, Any] = {"chi2": chi2, "dof": dof, "p_value": p_value, "positions": n, "what": what,
                           "residual_rms_dph": float(np.sqrt(np.mean(e ** 2))),
                           "noise_rms_dph": float(np.sqrt(np.mean(var)))}
    return cast(records.StaticRows, {**out, "verdict": static_rows_verdict(out)})


def static_rows_verdict(st: dict, unit: str = "deg/h", per_dph: float = 1.0) -> str:
    """The static rows' test in words, their residual and noise in unit (per_dph of it per deg/h)."""
    return (f"{st['positions']} static positions ({st['what']} at rest, predicted by the rate runs' fit): chi2 "
            f"{st['chi2']:.1f} on {st['dof']} dof, p = {st['p_value']:.2g}; residual rms "
            f"{st['residual_rms_dph'] * per_dph:.3g} {unit} against {st['noise_rms_dph'] * per_dph:.3g} noise"
            + ("" if st["p_value"] >= ALPHA else ": the model misfits at rest what the rate runs cannot see "
               "(e.g. a bias that follows a fixed direction in the local frame, as a magnetic field, "
               "shows in rate-run means only as its vertical part, which a g-sensitivity absorbs)"))


class AtRest:
    """A gyro model fitted on the rate runs, judged on the rows that fit does not use:
    the static rows (static_gyro_test) and, where tie is given, the unification pairs, which tell apart
    the effects the rate runs cannot. A g-sensitivity and its twin in the rate-run means (another
    g-sensitivity, a scale asymmetry) read the same there; at rest only the g-sensitivity reads G f, and
    in the pairs each twin turns the rate runs' directions its own way (a turn that flips with the rate's
    sign, which C_b^d cannot take up). u_b: the accelerometers' up at the static rows (b), C_b_d: the
    frames' tie, static_gyro: consistency.static_gyro_rows's (N, sigma, aux); tie(model, fit): the
    frames tied by that gyro fit (unification.unify's answer), raising CalibrationError where they cannot be."""

    def __init__(self, ms, u_b, C_b_d, static_gyro, model, obs, fit, tie=None):
        self.ms, self.u_b, self.C_b_d, self.static_gyro = ms, u_b, C_b_d, static_gyro
        self.model, self.obs, self.fit, self.tie = model, obs, fit, tie

    def test(self, term=None) -> records.StaticRows:
        """The static rows' test of the model, or of it with a generic term (twin_fits's)."""
        return static_gyro_test(self.ms, self.model, self.fit, self.u_b, self.C_b_d, self.static_gyro, term)

    def with_effect(self, eid) -> records.StaticRows:
        """The static rows' test of the model with library effect eid added, refitted on the rate runs, with
        the frames tied by that fit and, where their noise is known, the pairs' chi-square (`pairs`)."""
        model = AugmentedModel(self.model.base, self.model.effects + (eid,))
        try:
            fit = fit_exact(model, self.obs, p0=np.r_[self.fit.vector(self.model.params), 0.0])
        except CalibrationError as e:
            return {"verdict": f"not tested: the fit with {eid} failed: {e}"}
        C_b_d, pairs = self.C_b_d, None
        if self.tie is not None:
            try:
                C_b_d, _, _, info = self.tie(model, fit)
                pairs = pairs_evidence(info)
            except CalibrationError:
                pass
        st = static_gyro_test(self.ms, model, fit, self.u_b, C_b_d, self.static_gyro)
        return {**st, "pairs": pairs} if pairs and "chi2" in st else st


def pairs_evidence(info) -> records.PairsChi2 | None:
    """The unification pairs' chi-square as evidence between twins (unification.unify's record), or None
    where their noise is estimated from their own scatter (which brings every fit's pairs to their dof)."""
    noise = info.get("noise") or {}
    estimated = ("acc_rate_run_means" in noise if info["method"] == "rate_run_means" else
                 (noise.get("table_angles") or {}).get("dof") is not None)
    if estimated or not info["dof"] > 0:
        return None
    return {"pairs": info["pairs"], "chi2": info["chi2"], "dof": info["dof"],
            "p_value": float(chi2_sf(info["chi2"], info["dof"]))}


def _evidence(tested: dict) -> tuple[dict, bool, str]:
    """({twin: chi-square over the rows that judge}, whether the pairs are among them, those rows in words):
    the static rows, and the pairs where every twin has them (the sum is the evidence)."""
    pairs = all("pairs" in v for v in tested.values())
    total = {k: v["chi2"] + (v["pairs"]["chi2"] if pairs else 0.0) for k, v in tested.items()}
    st = next(iter(tested.values()))
    return total, pairs, f"{st['positions']} static positions" + (f" and {st['pairs']['pairs']} unification pairs"
                                                                   if pairs else "")


def _chi2s(tested: dict, ids, pairs: bool) -> str:
    """Each twin's chi-squares at rest and, where they judge, in the pairs."""
    return ", ".join(f"{k} {tested[k]['chi2']:.1f}" + (f" + {tested[k]['pairs']['chi2']:.1f}" if pairs else "")
                     for k in ids)


def choose_twin(cands: list[CandidateRecord], at_rest) -> None:
    """Where the strongest significant candidate has twins that the rate runs cannot tell from it
    (fit/twins.py), the one whose fit predicts the rows the rate-run fit does not use best (the static rows'
    chi-square, plus the unification pairs' where their noise is known: AtRest.with_effect; lowest, all
    on the same rows), by at least the twins' level CANNOT_TELL, leads the ranking, with its `at_rest`
    statistics and its `twin_choice` in words (which rows decided): the ranking, calibrate's advice,
    diagnose's verdict and `--add auto` then take it. Closer, no twin is chosen: the lead keeps its place
    marked `twins_undecided` (so `--add auto` adds neither and the advice names the plan that would tell).
    at_rest() -> AtRest or None (built only here: it ties the frames)."""
    lead = next((c for c in cands if c.get("significant")), None)
    group = [lead] + [c for c in cands if c.get("significant") and c["id"] in lead.get("twins", ())] if lead else []
    if len(group) < 2 or (judge := at_rest()) is None:
        return
    tested = {c["id"]: judge.with_effect(c["id"]) for c in group}
    tested = {k: v for k, v in tested.items() if "chi2" in v}
    if len(tested) < 2:
        return
    assert lead is not None  # group holds it
    total, with_pairs, rows = _evidence(tested)
    best = min(total, key=lambda k: total[k])
    chosen = next(c for c in group if c["id"] == best)
    st = tested[best]
    rate = ", ".join(f"{c['statistic']:.1f}" for c in group)
    at_rest_chi2: dict[str, records.StaticRows] = {}
    for k, v in tested.items():
        at_rest_chi2[k] = {"chi2": v["chi2"], "dof": v["dof"], "p_value": v["p_value"]}
        if "pairs" in v:
            at_rest_chi2[k]["pairs"] = v["pairs"]
    gap = min(v for k, v in total.items() if k != best) - total[best]
    if gap < CANNOT_TELL:  # the rows that judge cannot choose either: no twin is claimed, the ranking stands
        twin = next(c for c in group if c is not lead and c["id"] in tested)
        lead.update({"at_rest": at_rest_chi2, "twins_undecided": True, "twin_choice": (
            f"cannot tell {lead['id']} from {', '.join(k for k in tested if k != lead['id'])} with these data: "
            f"neither the rate runs (likelihood ratios {rate}) nor the {rows} (chi2 "
            f"{_chi2s(tested, tested, with_pairs)}, {gap:.1f} apart, under the twins' level {CANNOT_TELL:.2f}) choose: "
            "either may be the unit's; " + positions_that_separate(lead, twin))})
        return
    others = "; ".join(_chi2s(tested, [k], with_pairs) for k in tested if k != best)
    pairs = f", and {st['pairs']['chi2']:.1f} on {st['pairs']['dof']} dof in the pairs" if with_pairs else ""
    chosen["at_rest"] = at_rest_chi2
    chosen["twin_choice"] = (
        f"{best}, not its twin{'s' if len(tested) > 2 else ''} {', '.join(k for k in tested if k != best)}: the rate "
        f"runs cannot tell them apart (likelihood ratios {rate}); the {st['positions']} static positions chose it"
        + (f" with the {st['pairs']['pairs']} unification pairs" if pairs else "")
        + f" (chi2 {st['chi2']:.1f} on {st['dof']} dof at rest, p = {st['p_value']:.2g}{pairs}; against {others})"
        + ("" if st["p_value"] >= ALPHA else ", though none of them passes at rest"))
    at = cands.index(lead)
    cands.remove(chosen)
    cands.insert(at, chosen)


def with_static_rows(base: ModelTestBlock, st: records.StaticRows) -> None:
    """A gyro's test block (test_model's) over its rate runs and its static rows together: one chi-square
    where the rate runs' noise is known (test 'chi-square'), else the smaller of the two p-values doubled.
    calibrate and diagnose both call it, so they report the same test."""
    base["static_rows"] = st
    if "chi2" not in st:
        return
    base["rows"] = f"{base.get('rows') or 'the rate runs'} and {st['positions']} static positions ({st['what']})"
    p0, test0 = base["omnibus_p_value"], base["omnibus_test"]
    if base["chi2"] is not None and test0 == "chi-square":
        base["chi2"], base["dof"] = base["chi2"] + st["chi2"], base["dof"] + st["dof"]
        base.update({"p_value": float(chi2_sf(base["chi2"], base["dof"])),
                     "test": "chi-square over the rate runs and the static rows"})
    elif p0 is not None:
        base.update({"p_value": min(1.0, 2 * min(p0, st["p_value"])),
                     "test": f"{test0} (rate runs) and the static rows' chi-square, the smaller p doubled"})
    else:
        return
    family.fold(base, base.get("targeted"))
