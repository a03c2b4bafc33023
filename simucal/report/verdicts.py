"""The verdicts in words: what a sensor's model test and its candidates say, with the command to
run next (the statistics layers hand over numbers and ids, this module writes
the sentences). api/diagnosing.py asks sensor_verdict of every block once its kind of data has judged it.
"""
from __future__ import annotations

from simucal.fit import family
from simucal.fit.results import ALPHA, ModelTest


def sensor_verdict(block: dict, sensor: str) -> str:
    """A diagnosis block's verdict: its model test and candidates (verdict), and what its kind of data
    added: the effects chosen one by one over a stream's moves (misfit_shares), a gyro's static rows
    where they misfit, and the choice among twins the static rows made."""
    if block.get("explained_by"):  # a test shared with the other sensor (a sequence's filter), one effect at a time
        by = block["explained_by"]
        return (f"{sensor}: the innovations fail their test, which the {by['sensor']} shares (one filter); {by['id']} "
                f"explains the misfit best: add it, then diagnose again to see whether the {sensor} still lacks "
                "an effect.")
    moves = "misfit_shares" in block
    text = verdict("gyro (moves)" if moves else sensor, block["model_test"], block["candidates"],
                   block.get("shape"))
    if block.get("misfit_shares"):
        text += shares_text(block["misfit_shares"])
    st = block["model_test"].get("static_rows") or {}
    if st.get("p_value", 1.0) < ALPHA:
        text += f" At rest: {st['verdict']}."
    return text + block.get("twin_choice", "")


def _fmt_test(base):
    rows = f" over {base['rows']}" if base.get("rows") else ""
    if base["chi2"] is not None and not base["noise"].get("rows_estimated"):
        return f"chi2 {base['chi2']:.1f} on {base['dof']} dof{rows}, p = {base['p_value']:.2g}"
    lof = base["lack_of_fit"]
    t = f"lack-of-fit F {lof['F']:.3g} on ({lof['q']}, {lof['dof']}) dof" if lof.get("F") is not None else "no F test"
    if base["chi2"] is not None:
        t = f"chi2 {base['chi2']:.1f} on {base['dof']} dof with the noise partly estimated, " + t
    return t + rows + (f", p = {base['p_value']:.2g}" if base["p_value"] is not None else "")


def verdict(sensor, base, cands, shape=None) -> str:
    """The model test in words; where it fails, the effect most likely missing (the generic term where
    it explains more than every library effect) and its --add (the diagnosis prints one command with
    every --add after the verdicts: report/console.next_command)."""
    unit = base.get("residual_unit", "")
    rms = f"residual rms {base['residual_rms']:.3g} {unit}".rstrip()
    if base["p_value"] is None:
        return (f"{sensor}: too few degrees of freedom for any test (no noise in the data or stated, and the "
                f"lack-of-fit test needs 4 dof); {rms}; state the noise (--{sensor}-noise-...) or add positions")
    warning = f" WARNING: {base['noise_warning']}." if base.get("noise_warning") else ""
    if not ModelTest.of(base).fails:
        return f"{sensor}: the model explains the data down to the noise ({_fmt_test(base)}; {rms}).{warning}"
    floor = f" against a noise floor {base['noise_floor']:.3g} {unit}" if base.get("noise_floor") else ""
    head = f"{sensor}: the model does not explain the data ({_fmt_test(base)}; {rms}{floor})"
    sig = [c for c in cands if c.get("significant")]
    text = head + "." + warning
    generic = shape and not shape.get("catalog_id")
    if generic:  # it explains more than every library effect (shape_if_unexplained): lead with it
        text += (f" Most likely missing: a term {shape['text']} (rms {shape['residual_rms_after']:.3g} {unit} "
                 "without it), not in the library; a model file with this term is written beside the report: add "
                 "it with --add FILE.")
    outside = None if generic else family.outside_library(base, cands)
    if outside:
        text += f" {outside['text'][0].upper()}{outside['text'][1:]}."
    elif sig:
        c = sig[0]
        after = c.get("residual_rms_after")
        more = (f" With it the residual rms would be {after:.3g} {unit}, still above the floor: more is missing "
                "(see the other candidates)." if after and base.get("noise_floor") and after > 2 * base["noise_floor"]
                else "")
        undecided = c.get("twins_undecided")  # no rows chose between it and its twins: neither is claimed
        text += (f" {'The best library effect, explaining less' if generic else 'Most likely missing'}: {c['id']} "
                 f"({c['meaning']})" + (f" or its twin {', '.join(c['twins'])}" if undecided else "")
                 + f", estimate {c['estimate']:.3g} +- {c['std']:.2g} {c['unit']}, LR "
                 f"{c['statistic']:.1f}, p = {c['p_value']:.2g}."
                 + ("" if generic else " Add neither until a plan tells them apart (below)." if undecided else
                    f" Add it: --add {c['id']}.{more}"))
    elif not shape:
        text += (" No candidate explains it; the missing effect is not in the library (or the plan cannot "
                 "separate it).")
    if shape and shape.get("catalog_id"):
        text += (f" The residual looks like a term {shape['text']} (rms {shape['residual_rms_after']:.3g} {unit} "
                 f"without it): that is the library's {shape['catalog_id']}, too weak alone to pass the gate over "
                 f"every candidate; try it: --add {shape['catalog_id']}.")
    return text


def shares_text(shares) -> str:
    """One sentence on what the chosen effects explain together, with the command to use them, and why
    the selection stopped where the model still fails."""
    s = shares["steps"]
    if not s:
        return ""
    still = "" if s[-1]["p_value_after"] is None or not ModelTest(None, 0, s[-1]["p_value_after"]).fails else \
        f" The selection stopped: {shares['stopped']}."
    head = (f" Together, {', '.join(x['id'] for x in s)} ({len(s)} effects, chosen one by one) explain" if len(s) > 1
            else f" Alone, {s[0]['id']} explains")
    return (f"{head} {100 * (1 - shares['unexplained']):.1f} % of the misfit (chi2 {s[-1]['chi2_after']:.1f} on "
            f"{s[-1]['dof_after']} dof, residual rms {s[-1]['residual_rms_after']:.3g}): "
            f"add {'them' if len(s) > 1 else 'it'}, "
            + " ".join(f"--add {x['id']}" for x in s) + "." + still)
