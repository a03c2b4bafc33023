"""Model versus measurement: where the model fails and which effect is missing.

For each sensor triad: the exact norm fit (norm_fit.fit_exact), residuals per
segment and axis against a noise floor from the data (scatter of raw samples
within segments, autocorrelation counted) or a stated noise, and a
chi-square test of "the model explains the data down to the noise".
Then every candidate effect of generated/effects.py is fit as baseline +
candidate with the same exact solver and ranked by the likelihood-ratio
statistic (with its p-value and the change in AIC). A candidate is declared
significant only if the baseline fails and its p-value beats alpha divided by
the number of candidates tested (Bonferroni), so on data the model explains
no effect is declared more often than alpha. Candidates whose Jacobian column
lies in the span of the baseline's (or of another candidate's) are reported
as not separable by this plan, with what would separate them.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from scipy import stats

from . import io
from .augmented import AugmentedModel, effect_ids
from .calibrate import segment_observations
from .generated.effects import EFFECTS
from .models import aux_args
from .norm_fit import CalibrationError, Fit, Observations, fit_exact, jacobian_blocks

ALPHA = 0.01
SEPARATE = {  # what a plan needs for each family to be told apart from the baseline
    "quadratic": "static positions at several levels and both signs of the input on that axis "
                 "(e.g. --plan fibonacci48); for gyros rate runs at several rates (e.g. 5, 10, 20 deg/s)",
    "scale_asymmetry": "inputs of both signs on that axis (for gyros, rate runs of both signs)",
    "cross_coupling": "static positions where both axes carry input at once (e.g. --plan fibonacci48)",
    "bias_drift_time": "positions revisited at the start and the end of the test",
    "bias_temperature": "a temperature sweep across the positions (a temp_c column)",
    "size_effect": "rate runs with the accelerometers recorded during them, at several attitudes and rates",
    "g_sensitivity": "rate runs of both signs at each attitude: the specific force keeps its direction while the "
                     "rate flips, which separates G f from the scale and misalignment",
}


def _stated(obs_sigma, n_rows, stated):
    return None if stated is None else np.broadcast_to(stated / np.sqrt(n_rows)[:, None], obs_sigma.shape)


def baseline_block(fit: Fit, obs: Observations) -> dict:
    n, m = len(obs.N), len(fit.params)
    block = {"residual_rms": fit.residual_rms, "dof": fit.dof, "model": fit.model}
    if obs.sigma is not None:
        noise_std = float(np.sqrt(np.mean(obs.sigma ** 2)))
        # expected residual rms if the model is right: chi2 has n - m dof over 3n components
        block.update(noise_floor=noise_std * float(np.sqrt(max(n - m, 0) / (3 * n))), noise_std_of_mean=noise_std,
                     chi2=fit.chi2, p_value=fit.p_value, test="chi-square")
    else:
        block.update(noise_floor=None, p_value=None, test="none: no noise estimate (one row per segment and no "
                     "stated noise); give --acc-noise-g / --gyro-noise-dph")
    return block


def _weighted_jacobian(model, obs, fit):
    """Dense weighted Jacobian of the exact problem at the solution: [dr/dp | dr/dd]."""
    n, m = len(obs.N), len(model.params)
    sig = np.broadcast_to(obs.sigma if obs.sigma is not None else 1.0, (n, 3))
    _, Jq, Jd, _ = jacobian_blocks(model, obs, fit.vector(model.params), fit.directions, sig)
    J = np.zeros((3 * n, m + 2 * n))
    J[:, :m] = Jq.reshape(3 * n, m)
    for i in range(n):
        J[3 * i:3 * i + 3, m + 2 * i:m + 2 * i + 2] = Jd[i]
    return J, sig


def rank_candidates(model: AugmentedModel, obs: Observations, fit: Fit, base_fails: bool) -> list[dict]:
    J, sig = _weighted_jacobian(model, obs, fit)
    Q, _ = np.linalg.qr(J)
    u = fit.directions * obs.rho[:, None]
    ids = [e for e in effect_ids(model.sensor) if e not in model.effects]
    cols, out = {}, []
    for eid in ids:
        _, axis, pname, unit, meaning, f = EFFECTS[eid]
        aux = aux_args(model.sensor, obs.temp_c, obs.t_s, obs.extra)
        phi = np.broadcast_to(f(u, *aux)[0][..., 0], (len(u),))
        col = np.zeros((len(u), 3))
        col[:, axis] = phi
        col = (col / sig).ravel()
        perp = col - Q @ (Q.T @ col)
        family, ax = eid.split(".")[1], eid.split(".")[2]
        entry = {"effect": ".".join(eid.split(".")[:2]), "axis": ax, "id": eid, "parameter": pname,
                 "unit": unit, "meaning": meaning}
        norm_col = np.linalg.norm(col)
        if norm_col == 0 or np.linalg.norm(perp) < 1e-3 * norm_col:
            why = ("no input for it in these data" if norm_col == 0 else
                   f"collinear with the baseline model ({100 * np.linalg.norm(perp) / norm_col:.2g} % of its "
                   "signature is separable)")
            entry.update(separable=False, note=f"{why}; to see it: {SEPARATE[family]}")
            out.append(entry)
            continue
        cols[eid] = perp / np.linalg.norm(perp)
        aug = AugmentedModel(model.base, model.effects + (eid,))
        try:
            f1 = fit_exact(aug, obs, p0=np.r_[fit.vector(model.params), 0.0])
        except CalibrationError as e:
            entry.update(separable=False, note=f"augmented fit failed: {e}")
            out.append(entry)
            continue
        if f1.chi2 is not None:
            stat = max(fit.chi2 - f1.chi2, 0.0)
            p = float(stats.chi2.sf(stat, 1))
            daic = stat - 2.0
        else:  # unknown noise: F test on the residual sums of squares
            rss0, rss1 = fit.residual_rms ** 2, f1.residual_rms ** 2
            stat = max((rss0 - rss1) / max(rss1 / max(f1.dof, 1), 1e-300), 0.0) if f1.dof > 0 else 0.0
            p = float(stats.f.sf(stat, 1, f1.dof)) if f1.dof > 0 else None
            daic = None
        entry.update(separable=True, estimate=f1.params[eid], std=f1.std[eid], statistic=float(stat),
                     p_value=p, delta_aic=daic, residual_rms_after=f1.residual_rms)
        visible = float(np.linalg.norm(perp) / norm_col)
        if visible < 0.05:
            entry["note"] = (f"nearly collinear with the baseline: {100 * visible:.2g} % of its signature is separable, "
                             f"so it is weakly seen; to see it: {SEPARATE[family]}")
        out.append(entry)
    for e in out:
        twins = [o for o in cols if o != e["id"] and abs(cols[o] @ cols[e["id"]]) > 0.99] if e["separable"] else []
        if twins:
            e["note"] = "cannot be told apart from " + ", ".join(twins) + " by this plan"
    return gate_candidates(out, base_fails)


def gate_candidates(out, base_fails, alpha=ALPHA):
    """The Bonferroni gate over one family of tests: a separable candidate is significant only
    when the baseline fails and its p-value beats alpha / (number tested). Returns the
    tested candidates, strongest first, then the ones that could not be tested."""
    tested = [e for e in out if e["separable"]]
    for e in tested:
        e["significant"] = bool(base_fails and e["p_value"] is not None and e["p_value"] < alpha / len(tested))
    return sorted(tested, key=lambda e: -e["statistic"]) + [e for e in out if not e["separable"]]


def residual_table(fit: Fit, obs: Observations, segs) -> list[dict]:
    rows = []
    for i, s in enumerate(segs):
        r = fit.residuals[i]
        sd = obs.sigma[i] if obs.sigma is not None else None
        rows.append({"segment": s.segment, "kind": s.kind, "outer_rate_dps": s.outer_rate_dps,
                     "t_s": float(np.atleast_1d(obs.t_s)[i]) if np.ndim(obs.t_s) else 0.0,
                     "temp_c": float(np.atleast_1d(obs.temp_c)[i]) if np.ndim(obs.temp_c) else None,
                     "direction": fit.directions[i].tolist(), "residual": r.tolist(),
                     "sigma": None if sd is None else sd.tolist(),
                     "normalized": None if sd is None else (r / sd).tolist()})
    return rows


def verdict(sensor, base, cands):
    if base["p_value"] is None:
        return f"{sensor}: no noise estimate, so no test; residual rms {base['residual_rms']:.3g}"
    if base["p_value"] >= ALPHA:
        return (f"{sensor}: the model explains the data down to the noise (chi2 {base['chi2']:.1f} on "
                f"{base['dof']} dof, p = {base['p_value']:.3g})")
    sig = [c for c in cands if c.get("significant")]
    head = (f"{sensor}: the model does not explain the data (chi2 {base['chi2']:.1f} on {base['dof']} dof, "
            f"p = {base['p_value']:.2g}; residual rms {base['residual_rms']:.3g} against a noise floor "
            f"{base['noise_floor']:.3g})")
    if sig:
        c = sig[0]
        after = c.get("residual_rms_after")
        more = (f" With it the residual rms would be {after:.3g}, still above the floor: more is missing "
                "(see the other candidates)." if after and base["noise_floor"] and after > 2 * base["noise_floor"]
                else "")
        return (head + f". Most likely missing: {c['id']} ({c['meaning']}), estimate {c['estimate']:.3g} "
                f"+- {c['std']:.2g} {c['unit']}, LR {c['statistic']:.1f}, p = {c['p_value']:.2g}. "
                f"Add it: simucal diagnose DIR --add {c['id']}.{more}")
    return head + ". No candidate explains it; the missing effect is not in the library (or the plan cannot separate it)."


def diagnose_sensor(ms, sensor, base_model, add=(), stated=None, truth=None):
    if ms.segments is None and sensor == "gyro":  # a stream: the gyro against its moves
        if base_model != "gyro_baseline":
            raise CalibrationError(f"{ms.path}: on a stream the gyro is fit as a full T and a bias over the moves, so "
                                   f"the model {base_model} does not apply; add effects with --add gyro.<effect>.<axis>")
        from .diagnose_moves import diagnose_moves
        from .handheld import acc_from_poses
        obs, det, am, fa, _ = acc_from_poses(ms)
        return diagnose_moves(ms, obs, det, am, fa, tuple(add), truth, ALPHA)
    if ms.segments is None:  # a stream: its static poses, as the hand-placed calibration finds them
        from .handheld import pose_observations
        obs, det, poses = pose_observations(ms)
        segs = [io.Segment(i, "static", None, None, None, 0.0) for i in range(len(poses))]
    else:  # accelerometers: the rate runs too, where lever arms show
        obs, segs = segment_observations(ms, sensor, acc_in_rate_runs=True)
    if not segs:
        return None
    if obs.sigma is None and stated is not None:
        n_rows = np.array([np.sum(ms.samples["segment"] == s.segment) for s in segs], float)
        obs.sigma = np.array(_stated(np.zeros((len(segs), 3)), n_rows, stated))
    model = AugmentedModel(base_model, tuple(add))
    fit = fit_exact(model, obs, p0=None if not add else _p0(base_model, add, obs))
    base = baseline_block(fit, obs)
    cands = rank_candidates(model, obs, fit, base["p_value"] is not None and base["p_value"] < ALPHA)
    table_info = None
    if sensor == "acc" and ms.segments is not None:  # the table, from the static positions' directions
        idx = [i for i, s in enumerate(segs) if s.kind == "static" and s.middle_deg is not None
               and s.inner_deg is not None]
        if len(idx) >= 6:
            from .table_fit import table_candidates
            ang = [[segs[i].outer_deg or 0.0, segs[i].middle_deg, segs[i].inner_deg] for i in idx]
            tc, table_info = table_candidates(fit.directions[idx], ang, ALPHA)
            cands = sorted([c for c in cands + tc if c["separable"]],
                           key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0, -c["statistic"])) + \
                [c for c in cands + tc if not c["separable"]]
    out = {"baseline": base, "candidates": cands, "verdict": verdict(sensor, base, cands),
           "params": fit.params, "std": fit.std, "residuals": residual_table(fit, obs, segs)}
    if table_info is not None:
        out["table"] = table_info
    if add:
        before_model = AugmentedModel(base_model)
        f0 = fit_exact(before_model, obs)
        comp = {}
        for k in model.params:
            row = {"before": f0.params.get(k), "std_before": f0.std.get(k), "after": fit.params[k], "std_after": fit.std[k]}
            if truth and k in truth.get(sensor, {}).get("params", {}):
                t = truth[sensor]["params"][k]
                row.update(truth=t, error_before=None if row["before"] is None else row["before"] - t,
                           error_after=row["after"] - t)
            comp[k] = row
        out["added"] = {"effects": list(add), "residual_rms_before": f0.residual_rms,
                        "residual_rms_after": fit.residual_rms, "p_value_before": f0.p_value,
                        "p_value_after": fit.p_value, "params": comp,
                        "residuals_before": residual_table(f0, obs, segs)}
    return out


def _p0(base_model, add, obs):
    f0 = fit_exact(AugmentedModel(base_model), obs)
    return np.r_[f0.vector(f0.params), np.zeros(len(add))]


def stream_summary(ms, max_points=4000):
    """A continuous stream for the report: |f| over time (decimated), calibrated by the
    hand-placed accelerometer fit, and the static intervals found (the gyro's moves are in
    the gyro block, diagnose_moves)."""
    from .handheld import acc_from_poses
    _, det, am, fa, _ = acc_from_poses(ms)
    t = ms.samples["t_s"]
    step = max(len(t) // max_points, 1)
    M, b = am.matrix_and_bias(fa.vector(am.params))
    f = np.linalg.solve(M, (ms.acc_g()[::step] - b).T).T  # calibrated specific force, g
    return {"t_s": t[::step].tolist(), "acc_norm_g": np.linalg.norm(f, axis=1).tolist(),
            "static_detection": det.as_dict(t)}


def diagnose(folder, add=(), acc_model="acc_baseline", gyro_model="gyro_baseline",
             acc_noise_g=None, gyro_noise_dph=None) -> dict:
    folder = Path(folder)
    ms = io.read(folder)
    truth_path = folder / "truth.json"
    truth = json.loads(truth_path.read_text()) if truth_path.is_file() else None  # scoring only
    result = {"format": "simucal.diagnosis/1", "input": str(folder), "alpha": ALPHA}
    for sensor, model, stated, has in (("acc", acc_model, acc_noise_g, ms.has_acc),
                                       ("gyro", gyro_model, gyro_noise_dph, ms.has_gyro)):
        if not has:
            continue
        mine = [a for a in add if a.startswith(sensor + ".")]
        block = diagnose_sensor(ms, sensor, model, mine, stated, truth)
        if block is not None:
            result[sensor] = block
    if ms.segments is None:
        result["stream"] = stream_summary(ms)
    sensors = [s for s in ("acc", "gyro") if s in result]
    if not sensors:
        raise CalibrationError(f"{folder}: nothing to diagnose (no static or rate segments)")
    worst = min(sensors, key=lambda s: result[s]["baseline"]["p_value"] if result[s]["baseline"]["p_value"] is not None else 1.0)
    result["sensor"] = worst
    result["baseline"] = result[worst]["baseline"]
    result["candidates"] = sorted([c for s in sensors for c in result[s]["candidates"] if c["separable"]],
                                  key=lambda c: (c["p_value"] if c["p_value"] is not None else 2.0,
                                                 -c["statistic"])) + \
        [c for s in sensors for c in result[s]["candidates"] if not c["separable"]]
    result["verdict"] = " | ".join(result[s]["verdict"] for s in sensors)
    return result
