"""Monte Carlo of a turntable scenario: simulation, exact fits and frame unification, batched.

Trials are simulated as arrays with a trial axis (simulate.Scenario's settings, one
averaged row per position): random angular position errors per trial and position,
exact rotations (kinematics.py, compiled from generated/table.c), white noise on each
mean output. A rate run's mean over one whole revolution is the mean of K equally
spaced outer angles, exact for every model term of degree below K in the input (a
trigonometric polynomial in gamma of that degree averages exactly): the fewest of 3 and 4 whose
means equal 24 samples' (terms up to quadratic or cubic), else 12, where simulate() samples 720;
for affine models it is the outer axis in k, in closed form. The K verticals are one evaluation of
the kinematics turned about the outer axis (kinematics.specific_force_turning_k).

Each batch of trials is fitted by one call of the compiled whole fit per sensor
(derive/templates/exact_fit.c, the paper's linear start (eq. 8/12) included; with effects
added, of the augmented model derived into the cache once, augmented.compiled_form, started
from the base model's linear fit), or without a compiler by the same Levenberg-Marquardt in
numpy vectorised over the trials (gauss_newton.fit_batch) from the same start. C_b^d follows from the rate
runs' means (unification.py; Wahba by rotations.nearest_rotation, batched). Batches run
on one thread per core, each with its own random stream.

The Cramer-Rao bound is the covariance of the exact fit of a noise-free trial with the
stated noise: the inverse Fisher information from the generated Jacobian, directions
profiled out. A trial whose fit does not converge is counted in `failed` and listed.
"""
from __future__ import annotations

import os
import time
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from simucal.errors import InputError
from simucal.io import results
from simucal.fit.augmented import AugmentedModel, compiled_form
from simucal.fit.aux_inputs import FORCE, AuxInputs, specific_force
from simucal.fit.norm_fit import fit_batch
from simucal.fit.rotations import adjugate3, det3, wahba
from simucal.generated import table
from simucal.generated.effects import AUX as SENSOR_AUX, SEPARATE
from simucal.io import units
from simucal.turntable import kinematics, plans
from simucal.turntable.simulate import Scenario

K_REV = (3, 4, 12)  # outer-angle samples per revolution: the fewest where exact, else the most (module doc)


class TrialChunk(TypedDict):
    """One batch of trials (chunk_of_trials): the estimates of those whose fits converged, in the models' units."""
    acc: NDArray[np.float64]          # (converged, acc parameters)
    gyro: NDArray[np.float64]         # (converged, gyro parameters and effects)
    phi: NDArray[np.float64]          # (converged, 3): the error rotation of C_b^d, rad
    failed: list[int]                 # the others, by their index within the batch


def _plan(sc):
    plan = plans.PLANS[sc.plan]() if sc.plan in plans.PLANS else plans.read_csv(sc.plan)
    static = list(plan) + (plans.TABLE2 if sc.unify_positions else [])
    rates = [(a, b, r) for r in sc.outer_rate_dps for (_, a, b) in plan]
    if sc.unify_positions:
        rates += [(a, 0.0, r) for r in sc.outer_rate_dps for a in (0.0, 90.0)]
    return np.radians(np.array(static, float)), np.array(rates, float)


def _affine(model, p):
    """Is the model's output affine in its input (dN/du the same at two inputs)?"""
    u = np.array([[[0.3, -0.5, 0.8], [-0.9, 0.2, 0.1]]]) * 1e3
    Ju = model.jacobians(u, p[None])[1][0]  # as a batch of one set: the numpy module, no CasADi to import
    return bool(np.allclose(Ju[0], Ju[1], rtol=0, atol=1e-12 * max(np.abs(Ju).max(), 1.0)))


def _times(X, C):
    """X (..., 3) @ C as one matrix product: numpy's batched @ loops over tiny products, ten times slower."""
    return (X.reshape(-1, 3) @ C).reshape(X.shape)


class BatchTruth(TypedDict):
    """The simulated unit's parameters, every trial's (simulate_batch)."""
    acc: np.ndarray            # the acc model's parameters, in its order
    gyro: np.ndarray           # the gyro model's
    C_b_d: np.ndarray          # (3, 3)


class Batch(TypedDict):
    """`trials` simulated tests' mean outputs (simulate_batch)."""
    acc: np.ndarray            # (T, Ps, 3), g: at the static positions
    acc_rate: np.ndarray       # (T, Pr, 3), g: over the rate runs
    gyro: np.ndarray           # (T, Pr, 3), deg/h
    rho_gyro: np.ndarray       # (Pr,): each rate run's rate magnitude, deg/h
    rate_sign: np.ndarray      # (Pr,)
    f_gyro: np.ndarray         # (Pr, 3): the rate runs' mean specific force in d
    truth: BatchTruth
    models: tuple[AugmentedModel, AugmentedModel]  # acc, gyro


def simulate_batch(sc: Scenario, trials: int, rng, noise=True, k_rev=K_REV[-1]) -> Batch:
    """Mean outputs of `trials` simulated tests: acc at the static positions (T, Ps, 3) in g,
    gyro (T, Pr, 3) in deg/h and acc (T, Pr, 3) over the rate runs, with the plan's rates and the
    rate runs' mean specific force in the gyro frame (Pr, 3), the g-sensitivity terms' input (Batch)."""
    static, rates = _plan(sc)
    am, gm = AugmentedModel(sc.acc_model, tuple(sc.acc_effects)), AugmentedModel(sc.gyro_model, tuple(sc.gyro_effects))
    p_a = np.array([{**sc.acc_params, **sc.acc_effects}.get(k, 0.0) for k in am.params])
    p_g = np.array([{**sc.gyro_params, **sc.gyro_effects}.get(k, 0.0) for k in gm.params])
    C_b_k, C_d_k = table.mounting(np.array(sc.theta4_rad)), table.mounting(np.array(sc.lambda4_rad))
    lat = np.radians(sc.latitude_deg)
    w_e = units.DEFAULT_EARTH_RATE_DPH
    w_ie_n = table.earth_rate_n(w_e, lat)
    T, Ps, Pr = trials, len(static), len(rates)
    table_err = sc.table_errors_rad()  # shared by every row; the angle errors per row
    f_s = _times(kinematics.specific_force_k(static[:, 0], static[:, 1], static[:, 2], table_err,
                                             sc.angle_errors_rad(rng, (T, Ps), noise)), C_b_k)
    tilt = table.C_k_n(0.0, 0.0, 0.0, np.r_[sc.tilt_rad, np.zeros(5)])
    w_n = w_ie_n + (rates[:, 2] * units.DPH_PER_DPS)[:, None] * tilt[:, 2]  # (Pr, 3)
    err_r = sc.angle_errors_rad(rng, (T, Pr), noise)
    w2 = (np.radians(rates[:, 2]) ** 2 / units.DEFAULT_GRAVITY)[None, :]
    # over a revolution a vector v fixed in n averages, in k, to the outer axis times v's component
    # along the tilted outer axis (derive/table.py outer_axis_k): the means an affine model needs
    axis_k = kinematics.outer_axis_k(np.radians(rates[:, 0]), np.radians(rates[:, 1]), table_err, err_r)
    f_k = axis_k * tilt[2, 2]
    f_r, f_d = _times(f_k, C_b_k), _times(f_k, C_d_k)
    w_d = _times(axis_k * (w_n @ tilt)[:, 2][:, None], C_d_k)
    nonlinear_a, nonlinear_g = not _affine(am, p_a), not _affine(gm, p_g)
    if nonlinear_a or nonlinear_g:  # a nonlinear model's mean: of K samples, exact below degree K
        # the K samples lead (K, T, Pr, ...): a mean over the leading axis adds contiguous blocks
        up_k = kinematics.specific_force_turning_k(k_rev, np.radians(rates[:, 0]), np.radians(rates[:, 1]),
                                                   table_err, err_r, axis_k)  # (K, T, Pr, 3): the vertical in k
    if nonlinear_g:  # the Earth rate and the table's rate turn in k too: the whole rotation
        gam = np.arange(k_rev) * 2 * np.pi / k_rev
        Cr = table.C_k_n(gam[:, None, None], np.radians(rates[:, 0]), np.radians(rates[:, 1]),
                         kinematics.errors(table_err, np.broadcast_to(err_r, (k_rev, T, Pr, 3))))  # (K, T, Pr, 3, 3)
    N_ar = (am.output(_times(up_k, C_b_k), p_a, AuxInputs({"w2": w2})).mean(0) if nonlinear_a else
            am.output(f_r, p_a, AuxInputs({"w2": w2})))
    N_g = (gm.output(_times(np.einsum("pi,ktpij->ktpj", w_n, Cr), C_d_k), p_g,
                     AuxInputs(specific_force(_times(up_k, C_d_k)))).mean(0) if nonlinear_g else
           gm.output(w_d, p_g, AuxInputs(specific_force(f_d))))
    N_as = am.output(f_s, p_a)
    if noise:
        N_as = N_as + rng.normal(0, sc.acc_noise_g, N_as.shape)
        N_ar = N_ar + rng.normal(0, sc.acc_noise_g, N_ar.shape)
        N_g = N_g + rng.normal(0, sc.gyro_noise_dph, N_g.shape)
    rho_g = np.abs(rates[:, 2] * units.DPH_PER_DPS + w_e * np.sin(lat))
    return {"acc": N_as, "acc_rate": N_ar, "gyro": N_g, "rho_gyro": rho_g, "rate_sign": np.sign(rates[:, 2]),
            "f_gyro": f_d.mean(0),  # (Pr, 3): the trials' angle errors move it by arcseconds
            "truth": {"acc": p_a, "gyro": p_g, "C_b_d": C_d_k.T @ C_b_k}, "models": (am, gm)}


def _base_start(model, N, rho_b):
    """The start of every trial: the paper's linear fit of the base model (vectorised), effects at 0;
    0 where it is not finite (a hopeless start fails its trial, counted)."""
    base = model.base
    Psi = base.norm_regressors(N)
    PsiT = Psi.swapaxes(1, 2)
    K = np.linalg.solve(PsiT @ Psi, PsiT @ (rho_b ** 2)[..., None])[..., 0]  # matmul: einsum does not use BLAS here
    with np.errstate(invalid="ignore", divide="ignore"):
        p0 = np.c_[base.params_of_K(K), np.zeros((len(N), len(model.params) - len(base.params)))]
    p0[~np.all(np.isfinite(p0), axis=1)] = 0.0
    return p0


def fit_trials(model, N, rho, sigma, aux=None, covariance=True, threads=0):
    """Exact fits of a batch (T, n, 3): (p (T, m), cov (T, m, m) or None, u (T, n, 3), ok (T,)). One compiled
    call where there is one (the base model's, or with effects the augmented model derived into the cache,
    augmented.compiled_form; `threads` its OpenMP team), else gauss_newton.fit_batch (numpy, vectorised over
    the trials). aux: the rows' auxiliary inputs, shared by the trials (the rate runs' specific force, a
    g-sensitivity's input). The start: the paper's linear fit of the base model (in the compiled call for a
    base model, else _base_start), effects at 0."""
    T, n, _ = N.shape
    m = len(model.params)
    base = model.base
    rho_b = np.broadcast_to(rho, (T, n))
    sig = np.full((T, n, 3), float(sigma))
    compiled = compiled_form(model) if model.effects else base
    p0 = _base_start(model, N, rho_b) if model.effects or compiled is None or compiled._fit is None else None
    out = None if compiled is None else compiled.fit_compiled(N, rho_b, sig, compiled.aux_array(aux, (T, n)), p0,
                                                              covariance=covariance, threads=threads)
    if out is not None:
        p, cov, u, _, _, status = out
        return p, cov, u, status == 0
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        p, u, _, H, _, status = fit_batch(model, N, rho_b, sig, p0, aux)
    ok = status == 0
    cov = np.full((T, m, m), np.nan) if covariance else None
    if cov is not None and ok.any():
        cov[ok] = np.linalg.inv(H[ok])
    return p, cov, u, ok


def _unify_batch(am, p_a, N_ar, u_g, sign):
    """C_b^d per trial from the rate runs' mean specific force (b) and rate (d): Wahba, batched."""
    M, b = am.matrix_and_bias(p_a)  # (T, 3, 3), (T, 3): the affine inverse, exact for affine models
    inv_T = np.ascontiguousarray((adjugate3(M) / det3(M)[:, None, None]).swapaxes(1, 2))  # M^-1 = adj(M) / det(M)
    f = (N_ar - b[:, None]) @ inv_T
    if len(p_a) and not _affine(am, p_a[0]):
        # effects nonlinear in f: the whole model inverted (as fit/apply.solve_inputs and the unification of a
        # calibration; M^-1 (N - b) alone is off by them), by the chord method: Newton's step with the affine
        # part's M in place of the whole Jacobian, each pass gaining the effects' share of the slope (1e-4 for
        # a quadratic of 1e-4 g/g^2). A Newton step's batched 3x3 solves and Jacobians cost 8x as much. Where the
        # base is affine (M f + b exactly) the step is f0 - M^-1 E(f) - f, the effects' share E alone evaluated.
        f0, affine_base = f, _affine(am.base, p_a[0][:len(am.base.params)])
        for _ in range(50):
            step = (f0 - am.effects_output(f, p_a) @ inv_T - f) if affine_base else (N_ar - am.output(f, p_a)) @ inv_T
            f = f + step
            if np.abs(step).max() <= 1e-13:
                break
    u_b = f / np.sqrt(np.sum(f * f, axis=2, keepdims=True))
    return wahba(u_b, u_g * sign[None, :, None], np.ones(u_b.shape[:2]))


def revolution_samples(sc: Scenario) -> int:
    """The fewest of K_REV where the rate-run means of 8 trials, with their angle errors, equal those of
    24 samples (every term of degree below it in the input: 3 for the library's quadratic and
    cross-coupling terms, 4 for cubic ones; not a sign-dependent scale, whose kink the angle errors
    move), else the most. The same random draws for each, so the noise cancels in the comparison."""
    exact = simulate_batch(sc, 8, np.random.default_rng(0), k_rev=24)
    for k_rev in K_REV[:-1]:
        few = simulate_batch(sc, 8, np.random.default_rng(0), k_rev=k_rev)
        if all(np.abs(a - b).max() <= 1e-12 * max(np.abs(b).max(), 1.0)
               for a, b in ((few["acc_rate"], exact["acc_rate"]), (few["gyro"], exact["gyro"]))):
            return k_rev
    return K_REV[-1]


def chunk_of_trials(sc: Scenario, size: int, seed: int, k: int, k_rev: int = K_REV[-1]) -> TrialChunk:
    """One batch of trials with its own random stream (seed, k): the estimates of the trials whose
    fits converged, the error rotation of C_b^d, and the indices (within the batch) of the others."""
    rng = np.random.default_rng([seed, k])
    am, gm = AugmentedModel(sc.acc_model, tuple(sc.acc_effects)), AugmentedModel(sc.gyro_model, tuple(sc.gyro_effects))
    sim = simulate_batch(sc, size, rng, k_rev=k_rev)
    # one thread per batch: batches run side by side (run's thread pool, or Dask's workers)
    pa, _, _, ok_a = fit_trials(am, sim["acc"], 1.0, sc.acc_noise_g, covariance=False, threads=1)
    pg, _, ug, ok_g = fit_trials(gm, sim["gyro"], sim["rho_gyro"], sc.gyro_noise_dph,
                                 AuxInputs(specific_force(sim["f_gyro"])), covariance=False, threads=1)
    ok = ok_a & ok_g
    C = _unify_batch(am, pa[ok], sim["acc_rate"][ok], ug[ok], sim["rate_sign"])
    R = C.swapaxes(1, 2) @ sim["truth"]["C_b_d"]  # C^T C_true: the error rotation
    phi = 0.5 * np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], 1)
    return {"acc": pa[ok], "gyro": pg[ok], "phi": phi, "failed": np.nonzero(~ok)[0].tolist()}


UNSEEN = ("the Monte Carlo's averaged positions never vary (no time, temperature, lever-arm or column rows are "
          "fitted), so no fit can see it; simulate a set")


def _reads_beyond_input(model) -> list[str]:
    """The auxiliary inputs a model's output (its effects' included) changes with, beyond the specific
    force that gyro terms read: each changed in turn from a random point where every input is non-zero
    (a product of two inputs shows too), every parameter at 1."""
    rng = np.random.default_rng(0)
    u, p = rng.normal(size=(1, 3)), np.ones(len(model.params))
    names = list(dict.fromkeys(model.aux + SENSOR_AUX[model.sensor]))
    at = dict(zip(names, rng.uniform(0.5, 1.5, len(names))))  # dtemp_c given: no T_ref needed
    N = model.output(u, p, AuxInputs(at))
    return [a for a in names if a not in FORCE and not np.allclose(
        model.output(u, p, AuxInputs({**at, a: at[a] + 1.0})), N, rtol=0, atol=1e-12)]


def _simulate_instead(model, read) -> str:
    """The simulate command that gives the inputs the Monte Carlo cannot: the model's effects and
    file, a user's column and the temperature by --column; time and the centripetal w2 come with
    every simulated set."""
    columns = sorted({"temp_c" if a == "dtemp_c" else a for a in read} - {"t_s", "w2"})
    return " ".join(["simucal simulate"] + ([f"--effect-file {model.base.source}"] if model.base.source != "built-in"
                                            else []) + [f"--effect {e}=VALUE" for e in model.effects]
                    + [f"--column {c}=LOW:HIGH" for c in columns])


def _reference(sc: Scenario, am, gm):
    """(the noise-free trial, {sensor: the CRLB of each parameter}): the exact fit of a noise-free
    trial with the stated noise. Effects no trial can determine are refused before any trial: those
    whose regressor reads what the averaged positions never vary, and those the plan leaves
    unobservable (that trial's fit fails)."""
    for m in (am, gm):
        read = _reads_beyond_input(m)
        if read:
            raise InputError(f"model {m.name} reads {', '.join(read)}, which {UNSEEN} ({_simulate_instead(m, read)}) "
                             "and calibrate it instead")
    ref = simulate_batch(sc, 1, np.random.default_rng(0), noise=False)
    crlb = {}
    for sensor, model, N, rho, sig, aux in (
            ("acc", am, ref["acc"], 1.0, sc.acc_noise_g, None),
            ("gyro", gm, ref["gyro"], ref["rho_gyro"], sc.gyro_noise_dph, AuxInputs(specific_force(ref["f_gyro"])))):
        _, cov0, _, ok0 = fit_trials(model, N, rho, sig, aux)
        if not ok0[0]:
            raise InputError(f"plan {sc.plan}: a noise-free trial's {sensor} fit of {model.name} fails, so the plan "
                             f"leaves a combination of its parameters unobservable (simucal plan --score {sc.plan} "
                             f"--model {model.base.name}" + "".join(f" --add {e}" for e in model.effects)
                             + " names it)"
                             + "".join(f"; to see {e}: {SEPARATE[e.split('.')[1]]}" for e in model.effects)
                             + f" (this scenario's rate runs: {', '.join(f'{r:g}' for r in sc.outer_rate_dps)} deg/s; "
                             "montecarlo --plan and --rates-dps, e.g. 10,-10, change them)")
        crlb[sensor] = np.sqrt(np.diag(cov0[0]))
    return ref, crlb


def run(sc: Scenario, trials: int, seed: int = 0, chunk: int = 2500, progress=None,
        scheduler=None) -> results.MonteCarlo:
    """The Monte Carlo result (module doc) as a dict ready for JSON. Batches of `chunk` trials
    run on the scheduler (sweeps.map_tasks; here on one thread per core), each with its own seed:
    the same numbers on any."""
    from simucal.sweeps import map_tasks
    am, gm = AugmentedModel(sc.acc_model, tuple(sc.acc_effects)), AugmentedModel(sc.gyro_model, tuple(sc.gyro_effects))
    compiled = {s: compiled_form(m) if m.effects else m.base for s, m in (("acc", am), ("gyro", gm))}  # derived once
    ref, crlb = _reference(sc, am, gm)
    kinematics.compiled()  # built (or found) once, before the threads
    k_rev = revolution_samples(sc)
    t0 = time.perf_counter()
    tasks = [(sc, min(chunk, trials - k0), seed, k, k_rev) for k, k0 in enumerate(range(0, trials, chunk))]
    parts = map_tasks(chunk_of_trials, tasks, scheduler, progress, threads=os.cpu_count() or 1)
    failed = [k * chunk + i for k, p in enumerate(parts) for i in p["failed"]]
    secs = time.perf_counter() - t0
    out: results.MonteCarlo = {
        "format": "simucal.montecarlo/1", "scenario": "paper", "trials": trials, "failed": len(failed),
        "failed_trials": failed[:1000], "seed": seed, "seconds": secs, "trials_per_s": trials / secs,
        "scheduler": scheduler or "local",
        "backend": {s: f"compiled {m.name} (one call per batch)" if m is not None and m._fit is not None else
                    "numpy (gauss_newton.fit_batch, vectorised over the trials)" for s, m in compiled.items()},
        "parameters": {}}
    for sensor, model in (("acc", am), ("gyro", gm)):
        e = np.concatenate([p[sensor] for p in parts])
        mean = e.mean(axis=0)
        std = e.std(axis=0, ddof=1) if len(e) > 1 else np.full(len(model.params), np.nan)
        for j, name in enumerate(model.params):
            out["parameters"][name if name.startswith(f"{sensor}.") else f"{sensor}.{name}"] = {  # effects: their id
                "unit": model.param_units[j], "truth": float(ref["truth"][sensor][j]), "mean": float(mean[j]),
                "std": float(std[j]),
                "crlb": float(crlb[sensor][j]), "std_over_crlb": float(std[j] / crlb[sensor][j])}
    phi = np.concatenate([p["phi"] for p in parts])
    out["unification"] = {"C_b_d_error_rms_rad": np.sqrt(np.mean(phi ** 2, axis=0)).tolist(),
                          "method": "rate-run means (Wahba)"}
    return out
