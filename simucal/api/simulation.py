"""`simucal.simulate`: a simulated recording as a MeasurementSet (`simucal simulate` writes it): a
turntable test (dong2018 section 4), a field set (ruan2019) or a hand-placed session (Tedaldi)."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Callable, Literal, Mapping, Sequence, Union

from simucal.errors import InputError
from simucal import methods
from simucal.io import results
from simucal.arguments import checked
from simucal.io.measurement_set import MeasurementSet

Pairs = Union[Mapping[str, float], Sequence[str]]  # {name: value} or the command's "NAME=VALUE" strings
SCENARIOS = tuple(methods.SCENARIOS)  # paper, field, handheld, ...: methods.SCENARIOS
ScenarioName = Literal["paper", "sequence", "field", "handheld", "still",
                       "warmup"]  # SCENARIOS for an editor (test_architecture)
# the turntable test's options, by their Python names, with the command's spelling (refusals name both)
TABLE_ONLY = {"sequence": "--sequence", "plan": "--plan", "position_error_arcmin": "--position-error-arcmin",
              "acc_model": "--acc-model",
              "gyro_model": "--gyro-model", "acc_unit": "--acc-unit", "gyro_unit": "--gyro-unit",
              "effect_file": "--effect-file", "sets": "--set", "columns": "--column",
              "temperature_c": "--temperature-c", "t_ref_c": "--t-ref-c",
              "temperature_wander_c": "--temperature-wander-c", "noise_stated": "--no-noise-stated"}
TABLE = ("paper", "sequence")  # the scenarios of a turntable: they take its options
TAKES = {"paper": "--seed, --rate-hz and the turntable's options",
         "field": "--seed, --rate-hz and --heading-accuracy-deg",
         "handheld": "--seed, --rate-hz and --effect", "still": "--seed, --rate-hz and --duration-s",
         "warmup": "--seed, --rate-hz and --duration-s"}
STILL = ("still", "warmup")  # a still stream's scenarios: they take duration_s


def _strings(pairs: Pairs | None, fmt: Callable[[Any], str] = repr) -> list[str]:
    """{name: value} as the command's NAME=VALUE strings (repr: the float read back is the same)."""
    if pairs is None:
        return []
    if isinstance(pairs, Mapping):
        return [f"{k}={fmt(v)}" for k, v in pairs.items()]
    return [str(p) for p in pairs]


def _span(v: float | Sequence[float]) -> str:
    """A column's (low, high) or a temperature's T or (T0, T1) as the command writes it (LOW:HIGH)."""
    return ":".join(repr(float(x)) for x in v) if isinstance(v, (tuple, list)) else str(v)


def resolved_scenario(scenario: str, sequence: str | None) -> str:
    """The scenario named, refused unless one of SCENARIOS; "paper" with a sequence is "sequence" (the same table
    turning through it: that scenario's data)."""
    if scenario not in SCENARIOS:
        raise InputError(f"scenario {scenario!r}: one of {', '.join(SCENARIOS)}")
    return "sequence" if scenario == "paper" and sequence is not None else scenario


def _refuse_unused(scenario: str, table_options: dict[str, Any], effects: Pairs | None,
                   heading_accuracy_deg: float | None,
                   unit_seed: int | None = None, duration_s: float | None = None) -> None:
    """An option the scenario would not use is refused, naming it (Python name and the command's)."""
    if scenario not in STILL and duration_s is not None:
        raise InputError(f"duration_s (--duration-s) {duration_s:g}: a still stream's length "
                         f"(--scenario still or warmup); the {scenario} scenario takes " + TAKES[scenario])
    if scenario in STILL and (unit_seed is not None or effects):
        raise InputError(f"{'unit_seed (--unit-seed)' if unit_seed is not None else 'effects (--effect)'}: the "
                         f"{scenario} scenario's unit is fixed, its truth.json names it; it takes " + TAKES[scenario])
    if scenario in TABLE and unit_seed is not None:
        raise InputError(f"unit_seed (--unit-seed) {unit_seed}: the turntable unit is the scenario's at every seed; "
                         "the hand-placed and field scenarios draw theirs (--scenario handheld or field)")
    if scenario != "field" and heading_accuracy_deg is not None:
        raise InputError(f"heading_accuracy_deg (--heading-accuracy-deg) {heading_accuracy_deg:g}: the field "
                         f"scenario's north reference (--scenario field); a {scenario} test has none")
    given = {} if scenario in TABLE else {**table_options, "effects": effects if scenario == "field" else None}
    unused = [f"{k} ({TABLE_ONLY.get(k, '--effect')})" for k, v in given.items()
              if v is not None and v is not False and not (isinstance(v, (tuple, list, dict)) and not v)]
    if unused:
        raise InputError(f"{', '.join(unused)}: a turntable test's (--scenario paper or sequence); the {scenario} "
                         "scenario takes " + TAKES[scenario])


@checked
def simulate(scenario: ScenarioName = "paper", *, seed: int = 0, rate_hz: float | None = None, plan: str | None = None,
             effects: Pairs | None = None, position_error_arcmin: float | None = None, acc_model: str | None = None,
             gyro_model: str | None = None, acc_unit: str | None = None, gyro_unit: str | None = None,
             effect_file: str | None = None, sets: Pairs | None = None,
             columns: Mapping[str, Any] | Sequence[str] | None = None,
             temperature_c: Any = None, t_ref_c: float | None = None, temperature_wander_c: float | None = None,
             noise_stated: bool = True, heading_accuracy_deg: float | None = None, sequence: str | None = None,
             unit_seed: int | None = None, duration_s: float | None = None) -> MeasurementSet:
    """Simulate a recording of a unit whose truth is known.

    Parameters
    ----------
    scenario : {"paper", "sequence", "field", "handheld", "still", "warmup"} (ScenarioName)
        "paper": a turntable test, dong2018 section 4 (raw pulse/s); "sequence" (or `sequence` given): its table
        turning through a rotation sequence; "field": ruan2019's three positions without a table; "handheld": a
        hand-placed session (a stream in counts, poses held between moves); "still": a unit at rest (for `noise`);
        "warmup": a still board from 15 to 58 degC, a cubic bias per axis (for ``calibrate(..., thermal=True)``).
    seed, unit_seed : int
        numpy's seeds: the recording's, and where the unit is drawn (hand-placed, field) the unit's (default seed).
    rate_hz : float, optional
        Raw samples at this rate (Hz, up to 2000); default: turntable one averaged row per position, else 100 Hz.
    plan, sequence : str, optional
        Turntable: a plan, "table1" (default), "dodecahedron20", "fibonacci24", "fibonacci48" or a CSV of
        outer_deg,middle_deg,inner_deg; or a rotation sequence (``method="systematic"``'s raw data), "psins19",
        "dong2018" or a CSV of axis,angle_deg,rate_dps,rest_s (turntable/sequence.py).
    effects : dict or list of str, optional
        Effects planted in the truth, ``{effect id: value in its term's unit}`` (or "ID=VALUE"),
        e.g. ``{"acc.quadratic.z": 2e-4}``; turntable and hand-placed.
    position_error_arcmin, acc_model, gyro_model, acc_unit, gyro_unit, effect_file, sets, columns :
        Turntable: as `simucal simulate`'s options (``sets``: a model file's true parameters,
        ``{name: value}``; ``columns``: ``{name: (low, high)}``, one value per segment).
    temperature_c : float or (float, float), optional
        Turntable: temp_c, a plateau at T degC or a ramp (T0, T1) over the segments.
    t_ref_c, temperature_wander_c : float, optional
        With `temperature_c`: the unit's T_ref (degC, default 25) and each segment's wander (+- degC, default 0).
    noise_stated : bool
        Turntable: write acc_noise_g / gyro_noise_dph into meta.json (default True).
    heading_accuracy_deg, duration_s : float, optional
        Field: the north reference's accuracy, deg (its error drawn uniform +- this; default 5). Still and
        warm-up: the stream's length, s (default 1800 and 1500).

    Returns
    -------
    MeasurementSet
        The recording, with ``.truth`` (what truth.json holds); ``.write(folder)`` writes both.

    Raises
    ------
    ValueError
        An option the scenario does not use (named), or a malformed value.

    Examples
    --------
    >>> import simucal
    >>> ms = simucal.simulate(seed=1, effects={"acc.quadratic.z": 2e-4})
    >>> ms.truth["acc"]["effects"]
    {'acc.quadratic.z': 0.0002}
    """
    kind = resolved_scenario(scenario, sequence)
    table_options = dict(sequence=sequence, plan=plan, position_error_arcmin=position_error_arcmin, acc_model=acc_model,
                         gyro_model=gyro_model, acc_unit=acc_unit, gyro_unit=gyro_unit, effect_file=effect_file,
                         sets=sets, columns=columns, temperature_c=temperature_c, t_ref_c=t_ref_c,
                         temperature_wander_c=temperature_wander_c, noise_stated=not noise_stated)
    _refuse_unused(kind, table_options, effects, heading_accuracy_deg, unit_seed, duration_s)
    return _simulated(kind, seed, rate_hz, table_options, {"effects": _strings(effects), "unit_seed": unit_seed,
                      "state_noise": noise_stated, "heading_accuracy_deg": heading_accuracy_deg, "seconds": duration_s})


def _simulated(kind: str, seed: int, rate_hz: float | None, table_options: Mapping[str, Any],
               others: Mapping[str, Any]) -> MeasurementSet:
    """simulate()'s set by its scenario's simulator (methods.SCENARIOS), given the options as the command gives
    them: the pairs as "ID=VALUE" strings, a temperature as its span."""
    temperature_c = table_options["temperature_c"]
    options = {**table_options, **others, "sets": _strings(table_options["sets"]),
               "columns": _strings(table_options["columns"], _span),
               "temperature": None if temperature_c is None else _span(temperature_c)}
    meta, samples, segments, truth = methods.SCENARIOS[kind](seed, rate_hz, options)
    return MeasurementSet(Path(f"simulated_{kind}_seed{seed}"), meta, samples, segments,  # the name errors say
                          truth=truth)



MAX_TRIALS = 10_000_000  # ~1.4 GB of estimates, about two minutes compiled


@checked
def montecarlo(*, plan: str | None = None, trials: int = 10_000, seed: int = 0, effects: Pairs | None = None,
               effect_file: str | None = None, sets: Pairs | None = None, rates_dps: Sequence[float] | None = None,
               scheduler: str = "local", progress: Any = None) -> results.MonteCarlo:
    """Monte Carlo of dong2018's turntable test (`simucal montecarlo`): `trials` simulated tests, each fitted
    exactly and unified; every parameter's truth, mean, std over the trials and Cramer-Rao bound.

    Parameters
    ----------
    plan : str, optional
        table1 (default), dodecahedron20, fibonacci24, fibonacci48 or a plan file.
    trials, seed :
        The simulated tests and numpy's seed of their noise.
    effects, effect_file, sets :
        Effects planted in the truth and fitted, as `simulate`'s.
    rates_dps : sequence of float, optional
        The rate runs' outer-axis rates (default the paper's 10 deg/s).
    scheduler : str
        local, processes or a Dask scheduler's address (the same numbers on any).
    progress : optional
        A progress bar's update function (simucal.progress.bar), or None.

    Returns
    -------
    dict
        What `simucal montecarlo -o` writes: per parameter truth, mean, std, crlb; trials per s; failed.

    Examples
    --------
    >>> r = simucal.montecarlo(trials=200)  # doctest: +SKIP
    >>> r["parameters"]["dK_x"]["std"] / r["parameters"]["dK_x"]["crlb"]  # doctest: +SKIP
    """
    from simucal.turntable.montecarlo import run
    from simucal.turntable.simulate import SCENARIOS as TABLE_SCENARIOS
    from simucal.turntable.simulate import plant
    if not 2 <= trials <= MAX_TRIALS:
        raise InputError(f"trials (--trials) {trials}: from 2 to {MAX_TRIALS}")
    if (effects or effect_file) and trials > MAX_TRIALS // 10:  # without a compiler, numpy: ~10x slower
        raise InputError(f"--trials {trials}: with --effect or --effect-file at most {MAX_TRIALS // 10} (about two "
                         "minutes); split the run over seeds")
    sc = TABLE_SCENARIOS["paper"]()
    if plan:
        sc.plan = plan
    if rates_dps:
        sc.outer_rate_dps = tuple(float(r) for r in rates_dps)
    plant(sc, _strings(effects), effect_file, _strings(sets), writes_columns=False)  # averaged rows: no columns
    return run(sc, trials, seed, scheduler=scheduler, progress=progress)
