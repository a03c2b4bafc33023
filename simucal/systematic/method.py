"""The method `systematic` (methods.py): the filter's estimates as a calibration file, the model test
on its innovations, and the refusal of a sequence that leaves a parameter unseen."""
from __future__ import annotations

from typing import Any, Mapping, NamedTuple, cast

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.distributions import chi2_sf
from simucal.fit.results import ALPHA
from simucal.fit.norm_fit import Fit
from simucal.generated import table
from simucal.io import blocks, calibration, records, units
from simucal.io.details import as_details
from simucal.systematic.auto import select
from simucal.systematic.calibrate import STEP_STD, run_filter
from simucal.fit.candidates import advice_text
from simucal.systematic.innovations import family_test, ranked
from simucal.systematic.observability import INFLATION, unobserved, verdict


class Refusal(NamedTuple):
    """Why calibrate refuses a sequence, and the step that helps instead (diagnose's next)."""
    why: str
    next: str
    note: str


SHOWN = 4  # the unobserved parameters a refusal names (plan --sequence names every one)
FIX = ("turn 90 or 180 deg about each of the unit's axes so that the rests hold each axis up and down (the "
       "built-in psins19 does)")


def seen_text(result, cov=None) -> str:
    """The observability check's verdict (observability.unobserved) in words, or "" where every state is seen."""
    poor = unobserved(result, cov)
    if not poor:
        return ""
    shown = [f"{k} (std {q:.2g} of its prior" + (f", {f:.2g} times its own)" if f > INFLATION else ")")
             for k, (q, f) in list(poor.items())[:SHOWN]]
    more = f" and {len(poor) - SHOWN} more" if len(poor) > SHOWN else ""
    why = ([f"its own: its std were the other states known, over {INFLATION:g} times smaller where the data see it "
            "only with them"] * any(f > INFLATION for _, f in poor.values())
           + ["simucal plan --sequence names each"] * bool(more))
    one = ("; its rests all hold the unit at one attitude (a move of whole turns returns it where it was)"
           if result.positions == 1 else "")
    return f"the sequence leaves {', '.join(shown)}{more} unobserved{' (' + '; '.join(why) + ')' if why else ''}{one}"


def refusal(result, where) -> Refusal | None:
    """Why calibrate refuses the sequence (a pass that diverged, a parameter left unobserved, or passes that did not
    converge) and what to do instead, or None: calibrate and diagnose's next line both ask here, so that the loop
    never sends a user to a refusal."""
    plan = ("simucal plan --sequence psins19 -o plan.json", "plan --sequence scores a sequence before it is recorded")
    if result.diverged:  # its estimates and stds are NaN: the verdict is the first pass's, the observability check's
        seen = seen_text(result, result.first_cov)
        return Refusal(f"{where}: the filter diverged (a state or variance not finite, or negative) in "
                       f"{result.diverged}: " + (f"{seen}: {FIX}" if seen else
                                                 "the first pass saw every parameter, but the linearisation did not "
                                                 "hold: record slower turns and longer rests (the built-in psins19)"),
                       *plan)
    seen = seen_text(result)  # first: a parameter the data do not hold also keeps the passes from converging
    if not seen and not result.converged:
        return Refusal(
            f"{where}: the filter's passes did not converge: the last of {result.passes} still moved an estimate "
            f"by {result.step_std:.2g} of its std (they end below {STEP_STD:g}), so the estimates are not the "
            "fixed point the stds describe: the linearisation about them does not hold on this sequence; a unit "
            "far from nominal (a MEMS unit) converges on slower turns and longer rests (the built-in psins19)",
            "record the sequence again with slower turns and longer rests (simucal simulate --sequence psins19 "
            "shows one)", "no plan shows convergence: the sequence itself must change")
    return Refusal(f"{where}: {seen}: {FIX}", *plan) if seen else None


def returns_advice(test) -> str | None:
    """Where the zero-position returns fail on their own (their NIS at ALPHA), what to do: the table returned
    less accurately than meta.json states, which no library effect describes; else None."""
    if not test.get("returns") or chi2_sf(test["nis_returns"], 3 * test["returns"]) >= ALPHA:
        return None
    return (f"the table's {test['returns']} returns to a position disagree with meta.json's table_accuracy_arcsec "
            f"(their NIS {test['nis_returns']:.4g} on {3 * test['returns']} dof): state the table's repeatability "
            "there, or leave it out to calibrate without zero-position updates")


def _fit(model, p, cov, test) -> Fit:
    std = np.sqrt(np.diag(cov))
    nu = test["innovations_whitened"]
    return Fit(model.name, "systematic", dict(zip(model.params, p.tolist())), dict(zip(model.params, std.tolist())),
               cov, nu, float(np.sqrt((nu ** 2).mean())), test["nis"], test["dof"], test["p_value"])


def calibrate_systematic(ms, acc_model="acc_baseline", gyro_model="gyro_baseline", ids=(),
                         auto=False) -> calibration.Calibration:
    """The calibration of a rotation sequence by the filter (calibrate.py), every parameter with its
    std; refused where the sequence leaves a parameter unobserved. auto: and the library effects the
    failing innovations need (auto.select)."""
    if auto:
        r, ids, chosen, stopped = select(ms, acc_model, gyro_model, ids)
    else:  # the first pass is the observability check: an unobservable sequence is refused there
        r = run_filter(ms, acc_model, gyro_model, ids,
                       stop_if=lambda cov, prior_var: not verdict(cov, prior_var)[2].all())
    refused = refusal(r, ms.path)
    if refused:
        raise CalibrationError(refused.why)
    (test, sig), s = family_test(r), r.sensors
    na, ng = len(s.p_acc), len(s.p_gyro)
    cal = calibration.header("systematic", ms)
    M_a, b_a = s.acc.matrix_and_bias(s.p_acc)
    cal.acc = blocks.sensor_block(s.acc, _fit(s.acc, s.p_acc, r.cov[:na, :na], test), M_a, b_a)
    C_b_d = table.mounting(s.eta)
    M_g, b_g = s.gyro.matrix_and_bias(s.p_gyro)
    cal.gyro = blocks.sensor_block(s.gyro, _fit(s.gyro, s.p_gyro, r.cov[na:na + ng, na:na + ng], test),
                                        M_g @ C_b_d, b_g, C_b_model=C_b_d)
    for block in (cal.acc, cal.gyro):
        block.residual_unit = "innovation std (whitened)"
        block.details.update(as_details({k: cast("Mapping[str, Any]", test)[k] for k in (
            "test", "omnibus_p_value", "omnibus_test", "targeted") if k in test}))
    cal.gyro.details["eta_rad"] = {"value": s.eta.tolist(), "std": np.sqrt(np.diag(r.cov)[na + ng:]).tolist(),
                                   "meaning": "C_b^d = mounting(eta) (derive/systematic.py)"}
    cal.details["systematic"] = {
        "passes": r.passes, "last_step_std": r.step_std, "white_noise_per_sample": {
            "gyro_dph": r.sigma[:3].tolist(), "acc_g": r.sigma[3:].tolist(), "rate_hz": r.rate_hz},
        "test": cast(records.InnovationTest, {k: v for k, v in test.items() if k != "innovations_whitened"})}
    if r.returns is not None:
        cal.details["systematic"]["zero_position"] = {
            "updates": len(r.returns.update_at), "positions": r.returns.slots,
            "accuracy_arcsec": r.returns.sigma_rad / units.ARCSEC_RAD,
            "text": (f"{len(r.returns.update_at)} zero-position updates: the table returned to {r.returns.slots} "
                     f"positions, each visit's table angles to {r.returns.sigma_rad / units.ARCSEC_RAD:.3g} arcsec "
                     "each (meta.json's table_accuracy_arcsec), about its gimbal axis")}
    if cal.acc.verdict == "fails":  # one test for both sensors: the one effect to add, as diagnose names it
        cands = [c.to_dict() for c in ranked(test, sig)]
        advice = returns_advice(test) or advice_text(
            cands, None, {"chi2": test["nis"], "dof": test["dof"], "omnibus_test": test["omnibus_test"]})
        for block in (cal.acc, cal.gyro):
            block.details["advice"] = advice or "no library effect passes its targeted test: see simucal diagnose"
    if auto:  # one selection for both sensors (one test): each block lists its own effects, the reason in both
        for sensor, block in (("acc", cal.acc), ("gyro", cal.gyro)):
            block.details.update({"auto": [x for x in chosen if x["id"].startswith(sensor + ".")],
                                  "auto_stopped": stopped})
    return cal
