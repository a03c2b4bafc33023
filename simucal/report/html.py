"""Self-contained HTML report of a diagnosis: plots embedded as PNG data URIs.

Pictures a test engineer reads at a glance: residuals (in units of their own
standard deviation) against time, against the input direction on the
sphere, against the outer-axis rate, against temperature; the candidate
effects' test statistics; before/after bars when effects were added.
"""
from __future__ import annotations


import html

import numpy as np

from simucal.fit.results import DiagnosisReport, diagnosis_blocks
from simucal.report.console import next_command
from simucal.report.numbers import eng
from simucal.report.page import CELL_IN, FULL_IN, figure, folded, grid, page, plt, png, table

AXES = "xyz"


def _res(rows, key="normalized"):
    use = key if rows[0][key] is not None else "residual"
    return np.array([r[use] for r in rows]), use


def shape_figure(sensor, shape, unit):
    """The residual on the found term's axis against its regressor, with the fitted term."""
    x, r = np.array(shape["points"]["regressor"]), np.array(shape["points"]["residual"])
    fig, ax = figure(CELL_IN, 3.2)
    ax.plot(x, r, "o", ms=4, label=f"{sensor} {shape['axis']} residual")
    ax.plot(x, shape["points"]["term_visible"], "x", ms=5,
            label=f"{eng(shape['estimate'])} * {shape['regressor']}, less what the model absorbs")
    ax.set(xlabel=shape["regressor"], ylabel=f"residual ({unit})", title=f"{sensor}: the shape of the misfit")
    ax.legend(fontsize=8)
    return png(fig)


# a residual row's own fields and the inputs plotted elsewhere
ROW_KEYS = {"segment", "kind", "outer_rate_dps", "t_s", "direction", "residual", "sigma", "normalized", "from_pose",
            "to_pose", "t_span_s", "f_x", "f_y", "f_z", "w2"}


def _varying_inputs(rows):
    """(name, axis label) of the auxiliary inputs in the rows that vary: temp_c and a user's columns."""
    names = [k for k in rows[0] if k not in ROW_KEYS and all(x.get(k) is not None for x in rows)]
    return [(k, "temperature (degC)" if k == "temp_c" else k) for k in names if len({x[k] for x in rows}) > 1]


def residual_figures(sensor, block, unit) -> tuple[list[str], list[str]]:
    """(the figures the body's width: against time; those of the grid: against the input direction on the
    sphere, one map per axis, the outer axis's rate and each varying input)."""
    rows = block["residuals"]
    r, kind = _res(rows)
    ylab = "residual / sigma" if kind == "normalized" else f"residual ({unit})"
    t = np.array([x["t_s"] for x in rows])
    fig, ax = figure(FULL_IN, 3)
    for j in range(3):
        ax.plot(t, r[:, j], "o-", ms=4, lw=0.8, label=f"{sensor} {AXES[j]}")
    if kind == "normalized":
        ax.axhspan(-2, 2, color="0.9", zorder=0, label="+-2 sigma")
    ax.set(xlabel="time (s)", ylabel=ylab, title=f"{sensor}: residual against time")
    ax.legend(fontsize=8, ncol=4)
    full, figs = [png(fig)], list[str]()
    d = np.array([x["direction"] for x in rows])
    lon, lat = np.arctan2(d[:, 1], d[:, 0]), np.arcsin(np.clip(d[:, 2], -1, 1))
    lim = max(np.max(np.abs(r)), 1e-300)
    for j in range(3):  # a map per axis, a cell of the grid each, on one colour scale
        fig, ax = plt.subplots(figsize=(CELL_IN, 3.6), subplot_kw={"projection": "mollweide"}, layout="constrained")
        sc = ax.scatter(lon, lat, c=r[:, j], cmap="coolwarm", vmin=-lim, vmax=lim, s=60, edgecolors="k")
        ax.set_title(f"{sensor} {AXES[j]} residual vs input direction", pad=12)
        ax.set_xticks(np.radians([-90, 0, 90]), [])  # the grid only: a label inside the map sits under the markers
        ax.set_yticks(np.radians([-60, 0, 60]), ["-60", "0", "60 deg"])  # outside the map, at its left edge
        ax.set_xlabel("longitude from +x, grid every 90 deg")
        ax.grid(True, lw=0.5, alpha=0.5)
        fig.colorbar(sc, ax=ax, shrink=0.8, label=ylab)
        figs.append(png(fig))
    rate = np.array([x["outer_rate_dps"] for x in rows])
    if sensor == "gyro" and len(set(rate)) > 1:
        fig, ax = figure(CELL_IN, 3)
        for j in range(3):
            ax.plot(rate, r[:, j], "o", label=AXES[j])
        ax.set(xlabel="outer-axis rate (deg/s)", ylabel=ylab, title="gyro: residual against rate sign and size")
        ax.legend(fontsize=8)
        figs.append(png(fig))
    for name, label in _varying_inputs(rows):  # temperature, a user's column (supply_v, ...)
        x = [row[name] for row in rows]
        fig, ax = figure(CELL_IN, 3)
        for j in range(3):
            ax.plot(x, r[:, j], "o", label=AXES[j])
        ax.set(xlabel=label, ylabel=ylab, title=f"{sensor}: residual against {label}")
        ax.legend(fontsize=8)
        figs.append(png(fig))
    return full, figs


def candidate_figure(sensor, block, n_tested):
    c = [x for x in block["candidates"] if x["separable"]][:12]
    if not c:
        return ""
    fig, ax = figure(FULL_IN, 3)
    colors = ["tab:red" if x.get("significant") else "tab:gray" for x in c]
    ax.barh([x["id"] for x in c][::-1], [x["statistic"] for x in c][::-1], color=colors[::-1])
    from simucal.fit.distributions import chi2_isf
    thr = chi2_isf(0.01 / max(n_tested, 1), 1)
    ax.axvline(thr, color="k", ls="--", lw=1, label=f"significance threshold ({eng(thr)})")
    ax.set(xlabel="likelihood-ratio statistic", title=f"{sensor}: which effect is missing (red: significant)")
    ax.legend(fontsize=8)
    return png(fig)


def before_after_figure(sensor, block, unit):
    a = block["added"]
    r0 = np.sqrt(np.mean(np.array([x["residual"] for x in a["residuals_before"]]) ** 2, axis=0))
    r1 = np.sqrt(np.mean(np.array([x["residual"] for x in block["residuals"]]) ** 2, axis=0))
    fig, ax = figure(CELL_IN, 3)
    x = np.arange(3)
    ax.bar(x - 0.2, r0, 0.4, label="before")
    ax.bar(x + 0.2, r1, 0.4, label="after " + ", ".join(a["effects"]))
    if block["baseline"].get("noise_floor"):
        ax.axhline(block["baseline"]["noise_floor"], color="k", ls="--", label="noise floor")
    ax.set_xticks(x, [f"{sensor} {c}" for c in AXES])
    ax.set(ylabel=f"residual rms ({unit})", title="residual before and after adding")
    ax.legend(fontsize=8)
    return png(fig)


def _table(rows, cols):
    return table(cols, [[r.get(c) for c in cols] for r in rows])


def stream_figures(stream):
    """The stream with its static intervals shaded."""
    figs = []
    fig, ax = figure(FULL_IN, 3)
    ax.plot(stream["t_s"], stream["acc_norm_g"], lw=0.6, color="k")
    det = stream["static_detection"]
    for k, (a, b) in enumerate(det["intervals_s"]):
        ax.axvspan(a, b, color="tab:green", alpha=0.25, label="static (detected)" if k == 0 else None)
    one_g = stream.get("one_g", 1.0)  # 1 g in the unit shown (report/units.diagnosis_in)
    ax.set(xlabel="time (s)", ylabel=f"calibrated |f| ({stream.get('acc_norm_unit', 'g')})",
           ylim=(0.5 * one_g, 1.5 * one_g), title=f"stream: {det['count']} static intervals "
           f"(threshold {det['threshold']:.3g}, window {det['window']} samples, min {det['min_samples']} samples)")
    ax.legend(fontsize=8)
    figs.append(png(fig))
    return figs


def _verdicts(diag: DiagnosisReport) -> list[tuple[bool, str]]:
    """Per sensor (ok, its verdict): the diagnosis's own, as the console prints it."""
    tests = [(b["baseline"]["p_value"], b["verdict"]) for b in diagnosis_blocks(diag).values()]
    return [(p is None or p >= diag["alpha"], verdict) for p, verdict in tests]


CANDIDATE_COLS = ["id", "estimate", "std", "unit", "statistic", "p_value", "delta_aic", "residual_rms_after",
                  "significant", "note"]
SHOWN = 8  # candidates shown unfolded (the significant ones always)


def candidate_tables(cands) -> list[str]:
    """The candidates that say something, then folded away: the rest tested (none significant), and those
    these data have no input for (one line each, their notes alike)."""
    tested = [c for c in cands if c["separable"]]
    shown = [c for k, c in enumerate(tested) if k < SHOWN or c.get("significant")]
    rest = [c for c in tested if c not in shown]
    blind = [c for c in cands if not c["separable"]]
    out = [_table(shown, CANDIDATE_COLS)]
    if rest:
        out.append(folded(f"{len(rest)} more effects tested, none significant", _table(rest, CANDIDATE_COLS)))
    if blind:
        out.append(folded(f"{len(blind)} effects these data cannot test (no input for them)",
                          _table(blind, ["id", "unit", "meaning", "note"])))
    return out


def render(diag: DiagnosisReport) -> str:
    """The page of a diagnosis, in its own units: the spec's, or those report/units.diagnosis_in gave it."""
    from simucal.report.units import param_units_of
    blocks = diagnosis_blocks(diag)
    units = {s: b.get("unit", "g" if s == "acc" else "deg/h") for s, b in blocks.items()}
    parts = []
    if "stream" in diag:
        parts.append("<h2>stream</h2>")
        parts += stream_figures(diag["stream"])
    for s, b in blocks.items():
        parts.append(f"<h2>{s}: the evidence</h2>")
        full, small = residual_figures(s, b, units[s])
        parts += full
        if b.get("shape"):
            parts.append(f"<p>{html.escape(b['shape']['text'])}</p>")
            small.append(shape_figure(s, b["shape"], units[s]))
        parts.append(grid(small))
        if b.get("moves_skipped"):  # a stream's gyro: the moves left out, and why
            parts.append(_table(b["moves_skipped"], ["from_pose", "to_pose", "t_s", "reason"]))
        tested = [c for c in b["candidates"] if c["separable"]]
        parts.append(candidate_figure(s, b, len(tested)))
        parts += candidate_tables(b["candidates"])
        if "added" in b:
            parts.append(grid([before_after_figure(s, b, units[s])]))
            shown = param_units_of(b)
            rows = [{"parameter": k, "unit": v.get("unit", shown.get(k)), **v} for k, v in b["added"]["params"].items()]
            parts.append(_table(rows, ["parameter", "unit", "before", "std_before", "after", "std_after", "truth",
                                       "error_before", "error_after"]))
    cmd, notes = next_command(diag)
    return page("simucal diagnosis", f"Diagnosis of {diag['input']}", _verdicts(diag), cmd, notes, parts)
