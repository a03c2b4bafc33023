"""The accelerometer of a hand-placed session from its static poses (Tedaldi et al. 2014): the
poses found (static_detect), their means checked (swapped axes, a still unit, poses at the
rails), the exact norm fit of any model started from the closed-form quadric, and an extra
per-pose variance where the model does not explain the poses to their own noise."""
from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from simucal.errors import CalibrationError
from simucal.fit.augmented import AugmentedModel
from simucal.fit.aux_inputs import AuxInputs, column_means
from simucal.fit.norm_fit import Fit, Observations, check_not_coplanar, fit_exact
from simucal.handheld.static_detect import (DetectSettings, Detection, detect_static, dropped_text,
                                            two_digits)
from simucal.io import units



PRIOR_MISALIGNMENT_RAD = 0.01  # accelerometer misalignments the poses cannot see: held at 0 with this std


def with_model_error(model, obs: Observations, fit, prior=None, alpha=0.01):
    """When chi2 rejects the model, give every pose an extra variance tau^2 (the
    same on all axes) with chi2/dof = 1 and refit: the weights then reflect what
    the model misses, not only the noise within a pose, and the stds grow to match."""
    if fit.p_value is None or fit.p_value >= alpha or fit.dof <= 0:
        return fit, 0.0
    assert obs.sigma is not None  # a p-value: the fit knew the poses' noise
    r2, s2 = fit.residuals ** 2, obs.sigma ** 2
    lo, hi = 0.0, float(np.max(r2)) * 10
    for _ in range(60):  # bisection on tau^2: sum r^2 / (s^2 + tau^2) = dof
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if np.sum(r2 / (s2 + mid)) > fit.dof else (lo, mid)
    tau2 = (lo + hi) / 2
    obs2 = replace(obs, sigma=np.sqrt(s2 + tau2))
    refit = fit_exact(model, obs2, p0=fit.vector(model.params), prior=prior)
    refit.chi2, refit.p_value = fit.chi2, fit.p_value  # the test is the one without the extra variance
    return refit, float(np.sqrt(tau2))


def swapped_or_still(ms, obs, poses):
    """Refuse poses whose gravity directions barely differ: accelerometer and gyro columns
    swapped (the gyro's pose means then spread instead), or a session that never turned."""
    spread = float(np.sqrt(np.trace(np.atleast_2d(np.cov(obs.N.T)))))  # g
    if spread > 0.2:
        return
    detail = (f"the {len(obs.N)} poses' accelerometer means differ by {spread:.2g} g rms, where turning the unit "
              "moves gravity by about 1 g")
    if ms.has_gyro:
        w = ms.gyro_dph()
        means = np.array([w[a:b].mean(0) for a, b in poses])
        noise = np.sqrt(np.mean([w[a:b].var(0).sum() / (b - a) for a, b in poses]))  # std of a pose mean
        if np.sqrt(np.trace(np.atleast_2d(np.cov(means.T)))) > 100 * noise:
            raise CalibrationError(f"{ms.path / 'samples.csv'}: {detail}, while the gyro's pose means differ by far "
                                   "more than their noise: the accelerometer and gyro columns look swapped (ax ay az "
                                   "hold the gyro); check the column names")
    raise CalibrationError(f"{ms.path / 'samples.csv'}: {detail}: the unit was not turned between poses")


def rail_poses(ms, poses):
    """Refuse poses whose accelerometer sits at a rail: meta's full scale where given, else a column's
    extreme value held by nearly every sample of a pose (an unclipped pose's quantised noise does not)."""
    raw = ms.raw("acc")
    fs = ms.meta.get("full_scale", {}).get("acc")
    hits = []
    for j, c in enumerate(("ax", "ay", "az")):
        rails = fs if fs is not None else (raw[:, j].min(), raw[:, j].max())
        for i, (a, b) in enumerate(poses):
            x = raw[a:b, j]
            at = (x <= rails[0]) | (x >= rails[1]) if fs is not None else np.isin(x, rails)
            if np.mean(at) > (0.0 if fs is not None else 0.9):
                hits.append((i, c, float(x[at][0])))
    if hits:
        named = ", ".join(f"pose {i + 1} ({c} at {v:g})" for i, c, v in hits[:6]) + (" ..." if len(hits) > 6 else "")
        raise CalibrationError(f"{ms.path / 'samples.csv'}: {len({h[0] for h in hits})} of {len(poses)} poses hold "
                               f"accelerometer samples at a rail ({named}): the accelerometer saturates there; use a "
                               "larger range (or give full_scale in meta.json), or record those poses again")


def too_few_poses(ms, det: Detection, settings: DetectSettings, am: AugmentedModel):
    """Refuse fewer poses than the model has parameters, naming each interval a rule dropped (with the rule and
    its numbers) and the option that relaxes it."""
    n, m = len(det.starts), len(am.params)
    if n >= m:
        return
    relax = []
    gyro = [x for x in det.dropped if x["rule"] == "gyro"]
    short = [x for x in det.dropped if x["rule"] == "min_static_s" and x["length_s"] >= settings.min_static_s / 2]
    if gyro:
        limits, more = sorted(x["kept_from_limit_dps"] for x in gyro), min(m - n, len(gyro))
        relax.append(f"--gyro-limit-dps {two_digits(limits[more - 1], True):g} keeps {more} more of the intervals the "
                     f"gyro dropped (now {det.gyro_threshold_dps:.3g} deg/s, set by "
                     f"{(det.gyro_limit or {}).get('set_by', '')}); a hand that holds its poses stiller keeps them too")
    if short:
        lengths = sorted((x["length_s"] for x in short), reverse=True)
        keep = min(m - n, len(lengths))
        relax.append(f"--min-static-s {two_digits(lengths[keep - 1], False):g} keeps {keep} more of the short ones")
    relax.append(f"a larger --threshold-factor (now {det.factor:g}) lets more through the accelerometers' test; "
                 "or record more poses, each held still for a few seconds")
    raise CalibrationError(
        f"{ms.path}: {n} acc positions for {m} parameters of {am.name}: {n} static poses found (the norm gives one "
        f"equation per pose, so at least {m} are needed)"
        + (f"; {len(det.dropped)} still interval{'s' * (len(det.dropped) != 1)} dropped: "
           + dropped_text(det.dropped, "; ") if det.dropped else "; no still interval was dropped")
        + ". To relax: " + "; ".join(relax))


def pose_observations(ms, detect=None, pose_window_s=1.0, am=None):
    """Accelerometer observations of a stream's static poses: (Observations, Detection, poses).

    Each pose is the mean of its first pose_window_s (None: the whole interval),
    with the std of that mean from the scatter of its samples. am: the model to fit, whose parameters the
    poses must outnumber (too_few_poses)."""
    t = ms.samples["t_s"]
    acc = ms.acc_g()
    settings = detect or DetectSettings()
    det = detect_static(acc, t, settings, gyro_dps=ms.gyro_dph() / units.DPH_PER_DPS if ms.has_gyro else None)
    if am is not None:
        too_few_poses(ms, det, settings, am)
    dt = float(np.median(np.diff(t)))
    win = None if pose_window_s is None else max(int(round(pose_window_s / dt)), 2)
    poses = [(a, b if win is None else min(a + win, b)) for a, b in zip(det.starts, det.ends)]
    rail_poses(ms, poses)
    N = np.array([acc[a:b].mean(0) for a, b in poses])
    sig = np.array([acc[a:b].std(0, ddof=1) / np.sqrt(b - a) for a, b in poses])
    aux = AuxInputs(column_means(ms.samples, [slice(a, b) for a, b in poses], t_ref_c=ms.t_ref_c))
    obs = Observations(N, np.ones(len(N)), np.maximum(sig, 1e-12), aux, list(range(len(poses))))
    return obs, det, poses


class Poses(NamedTuple):
    """The accelerometer from a stream's poses (acc_from_poses)."""
    obs: Observations      # one row per pose
    det: Detection         # the static intervals found
    model: AugmentedModel
    fit: Fit
    tau: float             # the poses' extra std (g) where the model does not explain them, else 0
    std_noise: dict | None  # where tau > 0: the stds from the poses' own noise alone (the fit before tau)


def acc_from_poses(ms, acc_model="acc_baseline", detect=None, pose_window_s=1.0) -> Poses:
    """The accelerometer from a stream's poses."""
    if not ms.has_acc:
        raise CalibrationError(f"{ms.path}: a hand-placed session needs accelerometer data")
    am = acc_model if isinstance(acc_model, AugmentedModel) else AugmentedModel(acc_model)
    obs, det, poses = pose_observations(ms, detect, pose_window_s, am)
    swapped_or_still(ms, obs, poses)
    units.check_magnitude("acc", np.linalg.norm(obs.N, axis=1), obs.rho, ms.path / "samples.csv", ms.meta)
    check_not_coplanar(obs.N, "accelerometer", f"{ms.path}: ")
    prior = None
    if np.all(np.max(np.abs(obs.N / np.linalg.norm(obs.N, axis=1, keepdims=True)), axis=1) > np.cos(np.radians(10))):
        # every pose along a sensor axis (the Ferraris design): the norm sees each axis's scale and bias,
        # not the misalignments (second order there): hold them at 0 by a stated prior, named undetermined
        prior = {k: (0.0, PRIOR_MISALIGNMENT_RAD) for k, unit in zip(am.params, am.param_units) if unit == "rad"}
    noise_only = fit_exact(am, obs, prior=prior)
    fa, tau = with_model_error(am, obs, noise_only, prior)
    fa.undetermined = {k: {"determined": False, "held_at": v, "prior_std": sd,
                           "to_determine": "add poses tilted between the sensor axes (e.g. 45 deg about each axis)"}
                       for k, (v, sd) in (prior or {}).items()}
    return Poses(obs, det, am, fa, tau, dict(noise_only.std) if tau else None)


