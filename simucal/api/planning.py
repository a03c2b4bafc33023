"""Test plans from Python (`simucal plan` is one call of these plus printing): a plan scored or designed for a
model (Fisher information, CRLB, D and A criteria; turntable/plan_design.py), the positions that would tell two
effects apart, and a rotation sequence's observability beside the norm method's CRLB."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

import numpy as np
from numpy.typing import NDArray

from simucal.arguments import checked
from simucal.errors import InputError
from simucal.io import results

if TYPE_CHECKING:  # imported where used: the commands that plan nothing skip them
    from simucal.fit.augmented import AugmentedModel
    from simucal.turntable.sequence import Step

PAPER_RATE_DPS = 10.0  # dong2018 section 4's rate runs
PAPER_NOISE = {"acc": 1e-5, "gyro": 0.01}  # section 4's noise of one position's mean: g, deg/h


def model_sensor(model: str, add: Sequence[str] = ()) -> str:
    """"acc" or "gyro": whose model `model` (a built-in's name or a derived model file's) with `add` is."""
    from simucal.fit.augmented import AugmentedModel
    return str(AugmentedModel(model, tuple(add)).sensor)


@checked
def plan(score: str | None = None, *, positions: int | None = None, model: str = "acc_baseline",
         add: Sequence[str] = (), criterion: str = "D", rates_dps: Sequence[float] | None = None,
         acc_noise_g: float | None = None, gyro_noise_dph: float | None = None, table: str = "three-axis",
         separate: Sequence[str] | None = None, sizes: Sequence[float] | None = None,
         power: float = 0.9) -> results.PlanScore:
    """Score a plan, or design one, for a model.

    Parameters
    ----------
    score : str, optional
        The plan to score: table1, dodecahedron20, fibonacci24, fibonacci48 or a CSV (outer_deg,middle_deg,inner_deg).
    positions : int, optional
        Design a plan of this many positions instead (by `criterion`: D or A optimal).
    model, add :
        The model scored (a built-in's name or a derived model file's) and effect ids added to it.
    rates_dps : sequence of float, optional
        Gyro models: the rate runs' outer-axis rate (a score: one; a design: the rates to choose from); default 10.
    acc_noise_g, gyro_noise_dph : float, optional
        The noise of one position's mean, g or deg/h: the model's sensor's (default section 4's: 1e-5 g, 0.01 deg/h).
    table : str
        A design's table: "three-axis" (angles) or "hand" (poses as gravity directions in the unit).
    separate, sizes, power :
        With `score`: two effect ids, their expected sizes, and the power to reach: the positions to add so that
        the plan tells them apart.

    Returns
    -------
    dict
        ``plan`` (its name), ``D_per_position``, ``A``, ``crlb`` and ``units`` per parameter, correlations, and
        for a design ``rows`` with their ``columns`` (the plan file's), for `separate` ``separation``.

    Examples
    --------
    >>> import simucal
    >>> r = simucal.plan("table1")
    >>> sorted(r["crlb"])[:3]
    ['b_x', 'b_y', 'b_z']
    """
    from simucal.fit.augmented import AugmentedModel
    from simucal.io.units import DPH_PER_DPS
    from simucal.turntable.plan_design import plan_rows, score as score_of
    if (score is None) == (positions is None):
        raise InputError("give --score PLAN to score a plan, or --positions N to design one")
    m = AugmentedModel(model, tuple(add))
    gyro = m.sensor == "gyro"
    sigma = _noise(model, gyro, acc_noise_g, gyro_noise_dph)
    rate_list = list(rates_dps) if rates_dps else [PAPER_RATE_DPS]
    if gyro and score is not None and len(rate_list) > 1:
        raise InputError(f"--rates-dps {','.join(f'{r:g}' for r in rate_list)}: a score takes one rate (its rate "
                         "runs'); a design (--positions N) chooses among several")
    u, rho, name = _directions(m, score, positions, rate_list, sigma, criterion)
    rates = sorted(set(np.round(np.atleast_1d(rho) / DPH_PER_DPS, 6).tolist())) if gyro else None
    result: results.PlanScore = {"plan": name, "model": m.name, "unit": m.unit, "noise": sigma, "rates_dps": rates}
    result.update(score_of(m, u, rho, sigma, f"plan {score}: " if score is not None else ""))
    if positions is not None:
        if table == "hand":  # a pose is where gravity (or the turn axis) points in the unit's own axes
            result["rows"], result["columns"] = [[i + 1, *map(float, d)] for i, d in enumerate(u)], "pose,f_x,f_y,f_z"
        else:
            result["rows"] = [list(r) for r in plan_rows(u, np.asarray(rho) / DPH_PER_DPS if gyro else None)]
            result["columns"] = "outer_deg,middle_deg,inner_deg" + (",outer_rate_dps" if gyro else "")
    if separate:
        result["separation"] = _separation(m, separate, sizes, score, u, rho, sigma, power)
    return result


def _directions(m: Any, score: str | None, positions: int | None, rate_list: list[float], sigma: float,
                criterion: str) -> tuple[NDArray[np.float64], Any, str]:
    """The plan's directions in frame k, its rate runs' rate (deg/h; a design's per position; 1 for an
    accelerometer) and its name: the plan scored, or one designed (D or A optimal)."""
    from simucal.io.units import DPH_PER_DPS
    from simucal.turntable import plans
    from simucal.turntable.plan_design import design, directions_k
    gyro = m.sensor == "gyro"
    if score is not None:
        rows = plans.PLANS[score]() if score in plans.PLANS else plans.read_csv(score)
        return directions_k(rows), abs(rate_list[0]) * DPH_PER_DPS if gyro else 1.0, score
    assert positions is not None  # one of the two, refused by plan otherwise
    u, rho = design(m, positions, np.abs(rate_list) * DPH_PER_DPS if gyro else 1.0, sigma, criterion)
    return u, rho, f"{criterion}-optimal, {positions} positions"


def _noise(model: str, gyro: bool, acc_noise_g: float | None, gyro_noise_dph: float | None) -> float:
    """The noise of one position's mean for the model's sensor (the other sensor's refused), else section 4's."""
    wrong = acc_noise_g if gyro else gyro_noise_dph
    if wrong is not None:
        raise InputError(f"{'--acc-noise-g' if gyro else '--gyro-noise-dph'} {wrong:g}: model {model} is a "
                         f"{'gyro' if gyro else 'acc'} model; give {'--gyro-noise-dph' if gyro else '--acc-noise-g'}")
    return (gyro_noise_dph if gyro else acc_noise_g) or PAPER_NOISE["gyro" if gyro else "acc"]


def _separation(model: AugmentedModel, pair: Sequence[str], sizes: Sequence[float] | None, score: str | None,
                u: NDArray[np.float64], rho: float | NDArray[np.float64], sigma: float,
                target: float) -> results.Separation:
    """The positions to add so that two candidate effects are told apart (turntable/plan_design.separate), with
    the added positions' angles and what a plan must vary where no position does."""
    from simucal.fit.augmented import check_effect
    from simucal.generated.effects import SEPARATE
    from simucal.io.calibration_checks import PARAM_LIMIT
    from simucal.turntable.plan_design import plan_rows, separate
    ids, q = [str(x).strip() for x in pair], [float(x) for x in (sizes or ())]
    if score is None or not q:
        raise InputError("--separate needs --score PLAN (the plan you have) and --sizes Q1,Q2")
    if len(ids) != 2 or len(q) != 2:
        raise InputError("--separate ID1,ID2 and --sizes Q1,Q2: two of each")
    if ids[0] == ids[1]:
        raise InputError(f"--separate {','.join(ids)}: an effect cannot be told from itself; "
                         "name two different effects")
    if not all(np.isfinite(x) and 0 < abs(x) <= PARAM_LIMIT for x in q):
        raise InputError(f"--sizes {','.join(f'{x:g}' for x in q)}: each size must be a finite, non-zero number (the "
                         f"effect's expected value, in its unit) of at most {PARAM_LIMIT:g}")
    for e in ids:
        check_effect(e, model.sensor)
    rates: Sequence[float] | NDArray[np.float64] = (np.array([0.5, 1.0, 2.0]) * rho) if model.sensor == "gyro" else ()
    sep = separate(model.base, ids[0], ids[1], u, rho, sigma, q, rates, target)
    sep["added_rows"] = [list(map(float, x)) for x in plan_rows(np.array([d["direction_k"] for d in sep["added"]]))] \
        if sep["added"] else []
    sep["hints"] = sorted({SEPARATE[e.split(".")[1]] for e in ids})
    return sep


@checked
def sequence_observability(sequence: str, *, model: str = "acc_baseline", add: Sequence[str] = (),
                           score: str | None = None, rates_dps: Sequence[float] | None = None,
                           acc_noise_g: float | None = None,
                           gyro_noise_dph: float | None = None) -> results.SequenceObservability:
    """Each parameter's std over a rotation sequence (one pass of the linearised systematic filter, the default
    unit simulated at seed 0: systematic/observability.py) beside the norm method's CRLB of the same models on a
    plan (`score`, default table1), its positions held as long as the sequence's rests unless the noise is given.

    Parameters
    ----------
    sequence : str
        psins19, sysclbt19, dong2018 or a sequence file.
    model, add :
        The model whose stds are compared (a built-in's name or a model file) and effect ids added to it.
    score : str, optional
        The plan the norm method is scored on (default table1).
    rates_dps : sequence of float, optional
        That plan's rate runs' outer-axis rate, deg/s.
    acc_noise_g, gyro_noise_dph : float, optional
        The noise of one position's mean (g, deg/h; default: the sequence's noise per sample over its rests).

    Returns
    -------
    dict
        ``sequence``, ``models``, ``add``, ``observability`` (per parameter: prior std, std, ratio; the
        unobserved), ``norm`` (per sensor: the plan's scores), ``plan``, ``noise`` (per position) and ``rest_n``.

    Examples
    --------
    >>> r = simucal.sequence_observability("psins19")  # doctest: +SKIP
    >>> r["observability"]["unobserved"]  # doctest: +SKIP
    []
    """
    from simucal.api.simulation import simulate
    from simucal.fit.augmented import AugmentedModel, for_sensor
    from simucal.systematic.observability import observability
    plan_name = score or "table1"
    models = {"acc": "acc_baseline", "gyro": "gyro_baseline", AugmentedModel(model).sensor: model}
    ms = simulate(sequence=sequence, seed=0)
    obs = observability(ms, models["acc"], models["gyro"], tuple(add), truth=ms.truth)
    n = obs["noise_per_sample"]
    # the same unit held as long at each position as at each of the sequence's rests (its median)
    rest_n = float(np.median([len(ms.rows(s.segment)) for s in ms.segments or [] if s.kind == "static"]))
    noise = {"acc": acc_noise_g or max(n["acc_g"]) / rest_n ** 0.5,
             "gyro": gyro_noise_dph or max(n["gyro_dph"]) / rest_n ** 0.5}
    crlb = {s: plan(plan_name, model=models[s], add=for_sensor(tuple(add), s), rates_dps=rates_dps,
                  acc_noise_g=noise["acc"] if s == "acc" else None,
                  gyro_noise_dph=noise["gyro"] if s == "gyro" else None)
            for s in ("acc", "gyro")}
    assert ms.truth is not None  # a simulated set's
    return {"sequence": ms.truth["sequence"], "models": models, "add": list(add), "observability": obs, "norm": crlb,
            "plan": plan_name, "noise": noise, "rest_n": rest_n, "stated": bool(acc_noise_g and gyro_noise_dph)}


@checked
def design_sequence(minutes: float = 10.0, *, reference: str = "psins19", reference_minutes: float | None = None,
                    calibration: str | None = None, acc_noise_g: float | None = None,
                    gyro_noise_dph: float | None = None, table_rate_dps: float = 60.0, evaluations: int = 600,
                    seed: int = 0, progress: Any = None) -> results.SequenceDesign:
    """A rotation sequence designed for a unit and a table time (`simucal plan --sequence REF --design`;
    turntable/sequence_design.py): its moves and rests chosen to minimise the worst parameter std relative to the
    reference sequence's in reference_minutes (default: the same table time).

    Parameters
    ----------
    minutes : float
        The designed sequence's table time, min.
    reference : str
        The sequence whose stds are the targets: psins19, sysclbt19, dong2018 or a sequence file; or "best",
        each parameter's smallest std over the built-ins.
    reference_minutes : float, optional
        The reference's table time (its rests scaled to fit it), min; default `minutes`.
    calibration : str, optional
        A calibration file: the unit's parameters and white noise per sample (default the simulator's unit).
    acc_noise_g, gyro_noise_dph : float, optional
        The unit's noise per sample at 100 Hz (over the file's).
    table_rate_dps : float
        The table's rate for the moves, deg/s (its acceleration is sequence.ACCEL_DPS2).
    evaluations, seed :
        The filter passes the search may spend, and the seed of its random changes.
    progress : callable, optional
        A callable wrapping the iterable of the search's rounds (e.g. simucal.progress.bar("design", "round")).

    Returns
    -------
    dict
        ``sequence`` (its steps: what `simulate --sequence` reads), ``parameters`` (each std, target and
        ratio), ``worst_ratio``, ``built_in`` (each built-in's worst ratio in the same time), ``evaluations``.

    Examples
    --------
    >>> r = simucal.design_sequence(10.0, reference_minutes=12.5)  # doctest: +SKIP
    >>> r["worst_ratio"] <= 1.0  # doctest: +SKIP
    True
    """
    from simucal.turntable import sequence as seq
    from simucal.turntable import sequence_design as design
    from simucal.turntable.simulate import unit_from_calibration
    ref_minutes = minutes if reference_minutes is None else reference_minutes
    _refuse_design(minutes, ref_minutes, table_rate_dps, evaluations)
    sc, said = unit_from_calibration(calibration, acc_noise_g, gyro_noise_dph)
    name, ref_steps, rows = reference_stds(sc, reference, ref_minutes)
    target = np.array([r["std"] for r in rows])
    found = design.design(lambda steps: np.array([r["std"] for r in sequence_stds(sc, steps)]), minutes, target,
                          table_rate_dps, evaluations, seed, progress)
    best = found.best
    ratio = best.std / target
    record: list[results.Designed] = [{"sensor": r["sensor"], "parameter": r["parameter"], "unit": r["unit"],
                                       "std": float(s), "target": float(t), "ratio": float(q)}
                                      for r, s, t, q in zip(rows, best.std, target, ratio)]
    rate_hz = float(sc.rate_hz or seq.DEFAULT_RATE_HZ)
    return {"sequence": {"name": "designed", "rate_hz": rate_hz, "steps": _steps_record(best.steps)},
            "minutes": float(minutes), "rate_dps": float(table_rate_dps),
            "reference": {"name": name, "steps": _steps_record(ref_steps)}, "reference_minutes": float(ref_minutes),
            "parameters": record, "worst_ratio": best.worst,
            "worst_parameter": f"{rows[best.worst_at]['sensor']} {rows[best.worst_at]['parameter']}",
            "built_in": {k: None if c is None else c.worst for k, c in found.built_in.items()},
            "start": found.start, "evaluations": found.evaluations, "unit": said, "rate_hz": rate_hz,
            "noise_per_sample": {"acc_g": [sc.acc_noise_g] * 3, "gyro_dph": [sc.gyro_noise_dph] * 3}}


def reference_stds(sc: Any, reference: str, minutes: float) -> tuple[str, list[Any], list[results.Observed]]:
    """(its name, its steps, each parameter's std) of a design's reference in `minutes` on the unit sc: a
    built-in's name or a sequence file, its rests fitted to the time; or "best", each parameter's smallest
    std over the built-ins that fit (no steps)."""
    from simucal.turntable import sequence as seq
    if reference != "best":
        name, steps = seq.resolve(reference)
        steps = seq.in_minutes(steps, minutes, f"--sequence {name}")
        return name, steps, sequence_stds(sc, steps)
    each = {}
    for name, make in seq.SEQUENCES.items():
        try:
            each[name] = sequence_stds(sc, seq.in_minutes(make(), minutes, name))
        except InputError:  # its moves leave no rest in this time
            continue
    if not each:
        raise InputError(f"--sequence best: no built-in sequence fits in {minutes:g} min: give more minutes")
    rows = [min(column, key=lambda r: r["std"]) for column in zip(*each.values())]
    return f"best of {', '.join(each)}", [], rows


def sequence_stds(sc: Any, steps: Sequence[Any]) -> list[results.Observed]:
    """Each parameter's std over the steps (turntable/sequence.Step) on the unit sc (a turntable Scenario),
    simulated at seed 0: one pass of the linearised filter about its truth (systematic/observability.py), where the
    calibration's passes converge."""
    from pathlib import Path

    from simucal.io import MeasurementSet as Set
    from simucal.systematic.observability import observability
    from simucal.turntable.sequence import simulate_sequence
    meta, samples, segments, truth = simulate_sequence(sc, list(steps), seed=0)
    return observability(Set(Path("designed sequence"), meta, samples, segments), truth=truth)["parameters"]


def save_sequence(path: str, steps: Sequence[results.SequenceStep]) -> None:
    """A sequence file (axis,angle_deg,rate_dps,rest_s) of a record's steps, as `plan --sequence --design -o`."""
    from simucal.turntable.sequence import Step, write_sequence
    write_sequence(path, [Step(**s) for s in steps])


def _steps_record(steps: Sequence[Step]) -> list[results.SequenceStep]:
    return [{"axis": s.axis, "angle_deg": float(s.angle_deg), "rate_dps": float(s.rate_dps), "rest_s": float(s.rest_s)}
            for s in steps]


def _refuse_design(minutes: float, ref_minutes: float, table_rate_dps: float, evaluations: int) -> None:
    """design_sequence's numbers outside what a table and the search can take, each refused naming its option."""
    from simucal.turntable import sequence as seq
    if not 0 < minutes <= seq.MAX_REST_S / 60:
        raise InputError(f"--minutes {minutes:g}: give a table time of 0 < minutes <= {seq.MAX_REST_S / 60:g}")
    if not 0 < table_rate_dps <= seq.MAX_RATE_DPS:
        raise InputError(f"--table-rate-dps {table_rate_dps:g}: give the table's rate, 0 < rate <= "
                         f"{seq.MAX_RATE_DPS:g} deg/s")
    if evaluations < len(seq.SEQUENCES):
        raise InputError(f"--evaluations {evaluations}: at least {len(seq.SEQUENCES)} (the built-ins are scored first)")
    if not 0 < ref_minutes <= seq.MAX_REST_S / 60:
        raise InputError(f"--reference-minutes {ref_minutes:g}: give 0 < minutes <= {seq.MAX_REST_S / 60:g}")
