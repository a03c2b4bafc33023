"""The tools: derive, audit, demo, montecarlo, plan, bench."""
from __future__ import annotations

import sys
from pathlib import Path

import click

from simucal.errors import InputError
from simucal.cli.common import (
    EFFECT_FILE,
    FORCE,
    MAX_TRIALS,
    MODEL_FILE_RUNS,
    NOISE_DPH,
    NOISE_G,
    POSITIVE,
    SCHEDULER_TRUST,
    SEED,
    SEED_HELP,
    SETS,
    UNITS,
    InputPath,
    Number,
    fail,
    guard,
    main,
    rates_dps,
    refuse_unused,
)


@main.command()
@click.option("--check", is_flag=True, help="Fail if generated/ differs from what derive writes now.")
@click.option("--model", "model_files", multiple=True, type=InputPath(exists=True, dir_okay=False),
              help="A Python file defining MODELS = [ErrorModel, ...]: derived into the cache "
                   "(not generated/), then usable by name from any folder. " + MODEL_FILE_RUNS)
def derive(check, model_files):
    """Derive the built-in models and (re)write generated/; or derive your own model file."""
    from simucal.api import tools
    if model_files:
        for f in model_files:
            click.echo(f"derived {', '.join(tools.derive_model(f))} from {f} into the cache")
        return
    done = tools.derive(check=check)
    if check:
        if done.stale:
            click.echo(done.diff + "generated/ is stale; run `simucal derive`. Differs: " + ", ".join(done.stale),
                       err=True)
            sys.exit(1)
        click.echo(f"generated/ is up to date ({done.seconds:.1f} s)")
    else:
        click.echo(f"wrote {done.folder} ({done.seconds:.1f} s)")


@main.command()
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="audit.md", show_default=True,
              help="The audit, Markdown: each equation, table and claim with its verdict.")
@click.option("--seeds", type=Number(0, 10000, integer=True), default=20, show_default=True,
              help="Simulated tests per setting for the Monte Carlo of the paper's claims (0: skip it).")
def audit(output, seeds):
    """Check the paper's printed equations (4)-(27), Table 1 and 2, term by term at the section-4
    values, and its numeric claims (abstract, Tables 3 and 4) against a Monte Carlo."""
    from simucal import progress
    from simucal.api import tools
    from simucal.io import outputs
    guard(files=[output])
    report = tools.audit(seeds, progress=progress.bar("audit", "item"))
    outputs.write_text(output, report.markdown())
    click.echo(f"wrote {output}: {report.summary()}")


@main.command()
@click.option("-o", "--output", "--out-dir", "out_dir", type=click.Path(file_okay=False), default="out",
              show_default=True,
              help="The folder of everything the demo writes (its sets, calibrations, reports and pages).")
@click.option("--seed", type=SEED, default=0, show_default=True, help=SEED_HELP)
@FORCE
def demo(out_dir, seed, force):
    """The main job end to end on built-in simulated data: a hidden effect found, added,
    calibrated with, applied and validated on another recording; the unit over temperature
    (calibrate --thermal) and the Allan deviation of a still recording; then dong2018's methods, the audit
    and the diagnosis."""
    from simucal.api import tools
    out = Path(out_dir)  # its sets may be replaced where an earlier demo wrote them (its demo.json)
    sets, marker = tools.demo_outputs(out)
    guard(sets=[out] + sets, force=force or marker.is_file(), together=False)  # it reads the sets it writes
    tools.demo(out_dir, seed, click.echo)


@main.command()
@click.option("--scenario", type=click.Choice(["paper"]), default="paper", show_default=True,
              help="dong2018 section 4 (simulate's defaults).")
@click.option("--plan", default=None, help="table1 (default), dodecahedron20, fibonacci24, fibonacci48 or plan.csv.")
@click.option("--trials", type=Number(2, MAX_TRIALS, integer=True), default=10000, show_default=True,
              help="Simulated tests, each fitted: the stds are over these (their own uncertainty about 1/sqrt(2 "
                   "trials)).")
@click.option("--seed", type=SEED, default=0, show_default=True, help=SEED_HELP)
@click.option("--effect", "effects", multiple=True, metavar="ID=VALUE",
              help="Plant a candidate effect in the truth and fit it (repeatable; the augmented model is derived "
                   "and compiled into the cache once, then runs at about two thirds of the base's speed).")
@EFFECT_FILE
@SETS
@click.option("--rates-dps", "rates", default=None, metavar="R1,R2,...",
              help="The rate runs' outer-axis rates in deg/s at each attitude (default the paper's 10); rates of "
                   "both signs, e.g. 10,-10, let g-sensitivity terms show.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="montecarlo.json", show_default=True,
              help="The result: each parameter's truth, mean, std and CRLB.")
@click.option("--scheduler", default="local", show_default=True,
              help="local (this process), processes (a Dask LocalCluster on 127.0.0.1, one worker per core) or a "
                   "Dask scheduler's address: the same numbers on any. " + SCHEDULER_TRUST)
@UNITS
def montecarlo(scenario, plan, trials, seed, effects, effect_file, sets, rates, output, scheduler, units):
    """Monte Carlo of a scenario: simulate, exact fits, unification; std against the Cramer-Rao bound.
    The Python API's simucal.montecarlo(...)."""
    import json

    from simucal import api, progress
    from simucal.io import outputs
    from simucal.sweeps import keep_freed_memory
    guard([plan if plan and Path(plan).exists() else None, effect_file], files={"-o": output})
    keep_freed_memory()  # this process is the command's
    result = api.montecarlo(plan=plan, trials=trials, seed=seed, effects=effects, effect_file=effect_file, sets=sets,
                            rates_dps=rates_dps(rates) if rates else None, scheduler=scheduler,
                            progress=progress.bar("montecarlo", "batch"))
    outputs.write_text(output, json.dumps(result, indent=1) + "\n")
    backend = "; ".join(f"{s} {b}" for s, b in result["backend"].items())
    click.echo(f"{trials} trials in {result['seconds']:.2f} s ({result['trials_per_s']:.0f}/s; {backend}; "
               f"scheduler {scheduler}); "
               f"{result['failed']} failed")
    click.echo(f"{'parameter':18} {'unit':8} {'truth':>12} {'mean':>12} {'std':>10} {'CRLB':>10} {'std/CRLB':>9}")
    from simucal.report.units import montecarlo_in
    for name, v in montecarlo_in(result, units)["parameters"].items():
        click.echo(f"{name:18} {v['unit']:8} {v['truth']:12.5g} {v['mean']:12.5g} {v['std']:10.3g} {v['crlb']:10.3g} "
                   f"{v['std_over_crlb']:9.3f}")
    click.echo(f"wrote {output}")


PAPER_RATE_DPS = 10.0  # api/planning.py's, for the help (tests/test_api_cli.py holds them equal)


def _separation_lines(sep):
    a, b = sep["effects"]
    yield (f"separate {a} from {b}: on this plan the expected likelihood ratios are "
           f"{sep['start']['noncentrality'][0]:.3g} and {sep['start']['noncentrality'][1]:.3g} "
           f"(power {sep['start']['power'][0]:.2f}, {sep['start']['power'][1]:.2f} at alpha {sep['alpha']})")
    if sep["added"]:
        yield (f"  {len(sep['added'])} added positions give {sep['noncentrality'][0]:.3g} and "
               f"{sep['noncentrality'][1]:.3g} (power {sep['power'][0]:.2f}, {sep['power'][1]:.2f}): "
               + ("the target is reached" if sep["reached"] else f"short of {sep['target_power']}"))
        for x in sep["added_rows"][:48]:
            yield f"    outer {x[0]:8.3f}  middle {x[1]:9.4f}  inner {x[2]:9.4f} deg"
    elif sep["reached"]:
        yield "  the plan already tells them apart at the target power"
    if not sep["reached"]:
        yield ("  no positions on the sphere separate them" + (" further" if sep["added"] else "")
               + ": they differ in what the plan cannot vary by direction; " + "; ".join(sep["hints"]))


def _write_design(result, output):
    """The designed plan's CSV (three-axis angles, or hand poses as gravity directions) and its JSON."""
    import json

    from simucal.io import outputs
    out = Path(output or "plan.csv")
    outputs.write_text(out, result["columns"] + "\n" + "".join(",".join(f"{x:.6f}" for x in r) + "\n"
                                                                for r in result["rows"]))
    outputs.write_text(out.with_suffix(".json"), json.dumps(result, indent=1, default=float) + "\n")
    return out


def _plan_sequence(sequence, model_name, add, score_plan, rates, acc_noise_g, gyro_noise_dph, output):
    """plan --sequence: simucal.sequence_observability, printed."""
    import json

    from simucal import api
    from simucal.io import outputs
    guard([sequence if Path(sequence).exists() else None,
           score_plan if score_plan and Path(score_plan).exists() else None],
          files={"-o": output} if output else {})
    r = api.sequence_observability(sequence, model=model_name, add=add, score=score_plan,
                                   rates_dps=rates_dps(rates) if rates else None, acc_noise_g=acc_noise_g,
                                   gyro_noise_dph=gyro_noise_dph)
    obs, crlb, models, plan_name, noise = r["observability"], r["norm"], r["models"], r["plan"], r["noise"]
    n = obs["noise_per_sample"]
    click.echo(f"sequence {r['sequence']['name']}: {models['acc']} and {models['gyro']}"
               + "".join(f" + {a}" for a in add)
               + f", one pass of the linearised filter ({obs['updates']} zero-velocity "
               f"updates; the default unit simulated, noise {max(n['acc_g']):.2g} g and {max(n['gyro_dph']):.2g} "
               f"deg/h per sample); beside it the norm method's CRLB on {plan_name}, noise {noise['acc']:.3g} g and "
               f"{noise['gyro']:.3g} deg/h per position"
               + ("" if r["stated"] else f" (held as long as a rest, {r['rest_n']:g} samples, unless "
                                        "stated)"))
    click.echo(f"  {'parameter':18} {'unit':16} {'prior std':>10} {'sequence std':>13} {'of prior':>9} "
               f"{'CRLB ' + plan_name:>16}")
    for x in obs["parameters"]:
        c = crlb[x["sensor"]]["crlb"].get(x["parameter"])
        click.echo(f"  {x['sensor'] + ' ' + x['parameter']:18} {x['unit']:16} {x['prior_std']:10.3g} {x['std']:13.3g} "
                   f"{x['ratio']:9.2g} {'' if c is None else format(c, '.3g'):>16}")
    if obs["unobserved"]:
        click.echo(f"UNOBSERVED on this sequence (std above {obs['threshold']:g} of its prior, or over "
                   f"{obs['inflation_threshold']:g} times its std were the other states known): "
                   f"{', '.join(obs['unobserved'])}; calibrate --method systematic refuses it: "
                   "turn the unit about each of its axes with each axis up and down (psins19 does)")
    else:
        click.echo(f"every parameter observed (the largest std {max(x['ratio'] for x in obs['parameters']):.2g} of "
                   "its prior)")
    if output:
        kept = {"sequence": r["sequence"], "models": models, "add": r["add"], "observability": obs, "norm": crlb}
        outputs.write_text(output, json.dumps(kept, indent=1, default=float) + "\n")
        click.echo(f"wrote {output}")


def _design_sequence(reference, minutes, reference_minutes, unit_file, acc_noise_g, gyro_noise_dph, rate_dps,
                     evaluations, output):
    """plan --sequence REF --design: simucal.design_sequence, printed, and the sequence written."""
    import json

    from simucal import api, progress
    from simucal.api.planning import save_sequence
    from simucal.io import outputs
    out = Path(output or "sequence.csv")
    guard([p for p in (reference, unit_file) if p and Path(p).exists()],
          files={"-o": str(out), "the sequence's JSON sidecar": str(out.with_suffix(".json"))})
    r = api.design_sequence(minutes, reference=reference, reference_minutes=reference_minutes, calibration=unit_file,
                            acc_noise_g=acc_noise_g, gyro_noise_dph=gyro_noise_dph, table_rate_dps=rate_dps,
                            evaluations=evaluations, progress=progress.bar("designing the sequence", "round"))
    steps = r["sequence"]["steps"]
    click.echo(f"designed: {len(steps)} moves at {r['rate_dps']:g} deg/s in {r['minutes']:g} min for {r['unit']} "
               f"({r['evaluations']} candidates scored, from {r['start']}); targets: {r['reference']['name']}'s "
               f"stds in {r['reference_minutes']:g} min")
    click.echo(f"  {'parameter':18} {'unit':16} {'designed std':>13} {'target':>10} {'ratio':>7}")
    for x in r["parameters"]:
        click.echo(f"  {x['sensor'] + ' ' + x['parameter']:18} {x['unit']:16} {x['std']:13.3g} {x['target']:10.3g} "
                   f"{x['ratio']:7.3f}")
    others = ", ".join(f"{k} {'does not fit' if v is None else format(v, '.3g')}" for k, v in r["built_in"].items())
    click.echo(f"worst ratio {r['worst_ratio']:.3f} ({r['worst_parameter']}); "
               f"the built-ins' moves at {r['rate_dps']:g} deg/s in the same time: {others}")
    if r["worst_ratio"] > 1.0:
        click.echo(f"NOT every parameter reaches its target: {r['worst_parameter']} is {r['worst_ratio']:.3f} of it; "
                   "give more --minutes or --evaluations, or a longer --reference-minutes")
    save_sequence(str(out), steps)
    outputs.write_text(out.with_suffix(".json"), json.dumps(r, indent=1) + "\n")
    click.echo(f"wrote {out} (simucal simulate --sequence {out}) and {out.with_suffix('.json')}")


@main.command()
@click.option("--score", "score_plan", default=None, metavar="PLAN",
              help="Score a plan: table1, dodecahedron20, fibonacci24, fibonacci48 or a CSV "
                   "(outer_deg,middle_deg,inner_deg).")
@click.option("--model", "model_name", default="acc_baseline", show_default=True,
              help="The model scored: a built-in (acc_baseline, gyro_baseline, ...) "
                   "or one derived from your model file (simucal derive --model FILE).")
@click.option("--add", "add", multiple=True, help="Candidate effect ids to add to the model, e.g. acc.quadratic.z "
              "(repeatable).")
@click.option("--positions", type=Number(1, 300, integer=True), default=None,
              help="Design a plan with this many positions.")
@click.option("--criterion", type=click.Choice(["D", "A"]), default="D", show_default=True,
              help="Design: D maximises the Fisher information's determinant (all parameters together), A minimises "
                   "the sum of the parameters' CRLB variances.")
@click.option("--rates-dps", "--rates", "rates", default=None, metavar="R1,R2,...", show_default=f"{PAPER_RATE_DPS:g}",
              help="Gyro models: the outer-axis rate of the rate runs, deg/s (a score: one; a design: rates to choose "
                   "from, e.g. 5,10,20).")
@click.option("--rate-dps", type=Number(-3600.0, 3600.0), default=None, hidden=True,
              help="Deprecated (warns): one rate, deg/s; --rates-dps R takes it.")
@click.option("--table", "kind", type=click.Choice(["three-axis", "hand"]), default="three-axis", show_default=True,
              help="Design for a three-axis table (angles) or hand-placed poses (gravity directions in the unit).")
@click.option("--acc-noise-g", type=NOISE_G, default=None,
              help="Accelerometer models: the noise of one position's mean, g (default: section 4's 1e-5).")
@click.option("--gyro-noise-dph", type=NOISE_DPH, default=None,
              help="Gyro models: the noise of one position's mean, deg/h (default: section 4's 0.01).")
@click.option("--sigma", type=POSITIVE, default=None, hidden=True,
              help="The old name: the model's --acc-noise-g or --gyro-noise-dph.")
@click.option("--separate", "pair", default=None, metavar="ID1,ID2",
              help="With --score: the positions to add so that these two candidate effects are told apart.")
@click.option("--sizes", default=None, metavar="Q1,Q2", help="With --separate: the effects' sizes, in their units.")
@click.option("--power", "target", type=Number(0.0, 1.0, low_open=True), default=0.9, show_default=True,
              help="With --separate: the power to reach.")
@click.option("--sequence", default=None, metavar="NAME|FILE", is_flag=False, flag_value="psins19",
              help="Systematic calibration: each parameter's std over a rotation sequence (psins19, the default, "
                   "sysclbt19, dong2018 or a CSV axis,angle_deg,rate_dps,rest_s; one pass of the filter, "
                   "the default unit at 100 Hz) beside the norm method's CRLB on --score PLAN (default table1); with "
                   "--design, the reference (default psins19; best: each parameter's smallest std over the built-ins).")
@click.option("--design", "design_seq", is_flag=True,
              help="With --sequence: design a sequence of --minutes whose every parameter's std is as far as can be "
                   "under the reference's (in --reference-minutes); written to -o (default sequence.csv, its JSON "
                   "beside).")
@click.option("--minutes", type=Number(0.0, 600.0, low_open=True), default=10.0, show_default=True,
              help="--design: the designed sequence's table time, min.")
@click.option("--reference-minutes", type=Number(0.0, 600.0, low_open=True), default=None,
              help="--design: the reference's table time, its rests scaled to fit (default --minutes).")
@click.option("--calibration", "unit_file", type=click.Path(dir_okay=False), default=None, metavar="CAL.json",
              help="--design: the unit to design for, a calibration file's baseline parameters and white noise per "
                   "sample (default: the simulator's default unit); --acc-noise-g and --gyro-noise-dph give the "
                   "noise per sample at 100 Hz instead.")
@click.option("--table-rate-dps", type=Number(0.0, 400.0, low_open=True), default=60.0, show_default=True,
              help="--design: the table's rate for the moves, deg/s (accelerating at 50 deg/s^2).")
@click.option("--evaluations", type=Number(3, 100_000, integer=True), default=600, show_default=True,
              help="--design: the candidates the search may score (a filter pass each, about 0.05-0.2 s for 10 "
                   "minutes).")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default=None,
              help="Design: the plan CSV or sequence CSV (a JSON sidecar with its scores beside it); score or "
                   "--sequence: the JSON.")
@UNITS
def plan(score_plan, model_name, add, positions, criterion, rate_dps, rates, kind, acc_noise_g, gyro_noise_dph, sigma,
         pair, sizes, target, sequence, design_seq, minutes, reference_minutes, unit_file, table_rate_dps, evaluations,
         output, units):
    """Score a test plan (Fisher information, CRLB, correlations, D and A criteria) or design one; or a
    rotation sequence's observability (--sequence), or design a sequence (--sequence --design)."""
    design = "a sequence's design (--sequence --design)"
    if not design_seq:
        refuse_unused({"minutes": design, "reference_minutes": design, "unit_file": design, "table_rate_dps": design,
                       "evaluations": design})
    if design_seq and sequence is None:
        sequence = "psins19"
    if sequence is not None:
        refuse_unused({"units": "a plan's score or design (--score, --positions)"})
        if positions is not None or pair:
            fail(f"{'--design designs' if design_seq else '--sequence scores'} a rotation sequence; --positions and "
                 "--separate design a plan's positions: give one")
        if design_seq:
            refuse_unused({k: "--sequence without --design" for k in ("score_plan", "model_name", "add", "rates")}
                          | {k: "a plan (--score or --positions)" for k in ("rate_dps", "criterion", "kind", "sigma",
                                                                           "sizes", "target")})
            return _design_sequence(sequence, minutes, reference_minutes, unit_file, acc_noise_g, gyro_noise_dph,
                                    table_rate_dps, evaluations, output)
        return _plan_sequence(sequence, model_name, add, score_plan, rates, acc_noise_g, gyro_noise_dph, output)
    import json

    from simucal import api
    from simucal.io import outputs
    if (score_plan is None) == (positions is None):
        fail("give --score PLAN to score a plan, or --positions N to design one")
    if rate_dps is not None and rates:
        fail(f"--rate-dps {rate_dps:g} and --rates-dps {rates}: give one (--rates-dps)")
    design = "a design (--positions N)"
    refuse_unused({**({"criterion": design, "kind": design} if score_plan is not None else {}),
                   **({"sizes": "--separate ID1,ID2", "target": "--separate ID1,ID2"} if not pair else {})})
    if output:
        guard([score_plan if score_plan and Path(score_plan).exists() else None],
              files={"-o": output, **({"the plan's JSON sidecar": str(Path(output).with_suffix(".json"))}
                                      if positions is not None else {})})
    elif positions is not None:
        guard(files=["plan.csv", "plan.json"])
    from simucal.api.planning import model_sensor
    gyro = model_sensor(model_name, add) == "gyro"
    if not gyro:
        refuse_unused({"rate_dps": "gyro models (rate runs)", "rates": "gyro models (rate runs)"})
    result = api.plan(score_plan, positions=positions, model=model_name, add=add, criterion=criterion,
                      rates_dps=None if rates is None and rate_dps is None else rates_dps(rates or repr(rate_dps)),
                      acc_noise_g=sigma if sigma and not gyro else acc_noise_g,
                      gyro_noise_dph=sigma if sigma and gyro else gyro_noise_dph, table=kind,
                      separate=pair.split(",") if pair else None,
                      sizes=_numbers("--sizes", sizes) if sizes else None, power=target)
    if rate_dps is not None:  # after the refusals, which are one line
        click.echo("warning: --rate-dps is deprecated: --rates-dps R takes one rate (deg/s) as it takes several",
                   err=True)
    for line in _score_lines(result, units):
        click.echo(line)
    for line in _separation_lines(result["separation"]) if pair else ():
        click.echo(line)
    if positions is not None:
        out = _write_design(result, output)
        click.echo(f"wrote {out} and {out.with_suffix('.json')}")
    elif output:
        outputs.write_text(output, json.dumps(result, indent=1, default=float) + "\n")
        click.echo(f"wrote {output}")


def _score_lines(result, units):
    """A plan's score on the console: its noise, criteria and each parameter's CRLB, in the unit system asked."""
    from simucal.report.units import plan_in
    shown = plan_in(result, units)  # the numbers printed; the files in the spec's units
    yield (f"{result['plan']}: {result['model']}, noise {shown['noise']:g} {shown['unit']} per position"
           + (f", rate runs at {', '.join(f'{x:g}' for x in result['rates_dps'])} deg/s" if result["rates_dps"]
              else ""))
    yield (f"  D per position {result['D_per_position']:.6g}, A {result['A']:.4g}, "
           f"largest |correlation| {result['max_abs_correlation']:.2f}")
    for k, v in shown["crlb"].items():
        yield f"  {k:16} CRLB {v:.3g} {shown['units'][k]}"


def _numbers(option, text):
    """A comma-separated list of numbers (--sizes Q1,Q2), or a one-line refusal naming the option."""
    try:
        return [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"{option} {text}: write numbers separated by commas, e.g. 1e-4,2e-4") from None


@main.command()
@click.option("-o", "--output", "--json", "json_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the figures as JSON.")
@click.option("--before", type=InputPath(exists=True, dir_okay=False), default=None,
              help="A previous run's -o (e.g. benchmarks/bench_4a889b5.json), printed beside this run's figures.")
@click.option("--quick", is_flag=True,
              help="Run every step at a size of seconds (a check that the bench runs; its figures measure nothing).")
def bench(json_path, before, quick):
    """Measure the speed figures (fits, Monte Carlo, whole commands) on this machine."""
    from simucal.api import tools
    if json_path:
        guard([before] if before else [], files=[json_path])
    tools.bench(json_path, click.echo, before, "quick" if quick else "full")

