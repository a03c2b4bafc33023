"""What every page shares (diagnosis, validation, thermal, noise, field, lot): one stylesheet and one font (the
page's text and its figures' both DejaVu Sans, matplotlib's own), the head (a verdict per sensor, then the one
command to run next), rows folded away, figures embedded as PNG (a full one FULL_IN wide, the body's width; smaller
ones side by side in a grid whose cells they fill), bars on a log scale with the floor. A table wider than a
phone scrolls inside itself; a number never wraps (report/numbers.py)."""
from __future__ import annotations

import base64
import html
import io as _io
import textwrap
from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simucal.report.numbers import cell_html, eng  # noqa: E402

FONT = "DejaVu Sans"  # matplotlib ships it, so the figures have it everywhere; the page asks the browser for it
plt.rcParams.update({"font.family": FONT, "font.size": 9})
DPI = 90  # a 13 in figure is 1170 px: inside the 1250 px body, so a browser never scales its text down
FULL_IN = 13.0  # a figure the body's width (drawn in a constrained layout, so that no margin is cropped off)
CELL_IN = 6.8  # a figure of the grid: 612 px, about a cell of two in the body

STYLE = (f"body{{font-family:'{FONT}',Verdana,sans-serif;max-width:1250px;margin:auto;padding:0 6px;font-size:14px}}"
         "table{border-collapse:collapse;font-size:12px;margin:6px 0} td,th{border:1px solid #ccc;padding:2px 6px}"
         "th{background:#f4f4f4} .bad{color:#b00} .ok{color:#070} .unsure{color:#a60} img{max-width:100%;display:block}"
         ".verdict{margin:0;padding:2px 0} .next{background:#f4f4f4;padding:6px} summary{cursor:pointer;color:#444}"
         "code{font-family:'DejaVu Sans Mono',monospace} table{display:block;overflow-x:auto;max-width:100%} "
         ".n{white-space:nowrap}"
         "h1,.verdict,.next{overflow-wrap:anywhere}"
         ".figs{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(560px,100%),1fr));gap:6px} "
         ".figs img{width:100%}")


def page(title: str, heading: str, verdicts, next_cmd: str, notes=(), body=()) -> str:
    """A page: the heading, each (ok, text) verdict (one per sensor; ok True green, False red, None amber:
    neither, such as a model no test could judge), the next command with its notes, then the body's parts."""
    head = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            "<meta name='viewport' content='width=device-width, initial-scale=1'>"
            f"<style>{STYLE}</style></head><body><h1>{html.escape(heading)}</h1>"]
    head += [f"<p class='verdict {'unsure' if ok is None else 'ok' if ok else 'bad'}'><b>{html.escape(text)}</b></p>"
             for ok, text in verdicts]
    head.append(f"<p class='next'>Next: <code>{html.escape(next_cmd)}</code>"
                + "".join(f"<br>{html.escape(n)}" for n in notes) + "</p>")
    return "\n".join([*head, *body, "</body></html>"])


def folded(summary: str, inner: str) -> str:
    """Rows that say little, one click away."""
    return f"<details><summary>{html.escape(summary)}</summary>{inner}</details>"


def png(fig) -> str:
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    return f'<img src="data:image/png;base64,{base64.b64encode(buf.getvalue()).decode()}">'


def figure(width_in: float, height_in: float, *args, **kwargs):
    """plt.subplots of a page's figure, its margins fixed in inches (the labels' room, no more), so that the PNG
    is as wide as asked (a constrained layout does the same at twice the drawing time)."""
    fig, axes = plt.subplots(*args, figsize=(width_in, height_in), **kwargs)
    fig.subplots_adjust(left=0.85 / width_in, right=1 - 0.15 / width_in, bottom=0.5 / height_in,
                        top=1 - 0.35 / height_in)
    return fig, axes


def grid(images) -> str:
    """Figures side by side (each png()'s, CELL_IN wide), each filling its cell: two in a laptop's window, one on
    a phone."""
    return "<div class='figs'>" + "".join(f"<div>{x}</div>" for x in images if x) + "</div>"


def table(head, rows) -> str:
    """A table: the head's texts, then each row's cells as report/numbers.cell_html writes them."""
    return ("<table><tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in head) + "</tr>"
            + "".join("<tr>" + "".join(f"<td>{cell_html(c)}</td>" for c in r) + "</tr>" for r in rows) + "</table>")


def wrapped(text: str, width: int) -> str:
    return "\n".join(textwrap.wrap(text, width))


def log_bars(ax: Any, labels: Sequence[str], values: Sequence[float], floor: float | None = None,
             unit: str = "") -> None:
    """Bars on a log scale (a calibrated error 1e-3 of the nominal one stays visible), each with its value (as
    the table writes it, report/numbers.py), and the floor as a line in the gaps between the bars: never across
    a bar's value written above it. ax: a matplotlib Axes (Any: matplotlib 3.8's stubs refuse the
    (axes fraction, data) xycoords below)."""
    positive = [v for v in [*values, floor] if v and v > 0] or [1.0]
    low, top = min(positive) / 5, max(positive) * 8  # room above the tallest bar for its value
    shown = [max(v, low) for v in values]  # a zero at the axis's foot, its value written
    ax.bar(labels, shown, color=["#999", "#2a7", "#27a"][:len(values)])
    ax.set_yscale("log")
    ax.set_ylim(low, top)
    ax.set_xlim(-0.5, len(values) - 0.5)
    for k, v in enumerate(values):
        ax.annotate(eng(v), (k, shown[k]), xytext=(0, 2), textcoords="offset points", ha="center", va="bottom",
                    fontsize=8)
    if floor:
        for k in range(len(values) + 1):  # the bars are 0.8 wide: the gaps 0.2, the axis's ends 0.1
            ax.plot([max(k - 0.6, -0.5), min(k - 0.4, len(values) - 0.5)], [floor, floor], color="k", lw=1.5)
        ax.annotate(f"floor {eng(floor)}", (0.0, floor), xycoords=("axes fraction", "data"), xytext=(3, -2),
                    textcoords="offset points", ha="left", va="top", fontsize=8)  # over the nominal bar, tall
    ax.set_ylabel(f"rms ({unit})")
