"""What every page shares (diagnosis, validation, thermal, noise): one stylesheet and one font (the page's
text and its figures' both DejaVu Sans, matplotlib's own), the head (a verdict per sensor, then the one
command to run next), rows folded away, figures embedded as PNG, bars on a log scale with the floor."""
from __future__ import annotations

import base64
import html
import io as _io
import textwrap

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FONT = "DejaVu Sans"  # matplotlib ships it, so the figures have it everywhere; the page asks the browser for it
plt.rcParams.update({"font.family": FONT, "font.size": 9})
DPI = 90  # a 13 in figure is 1170 px: inside the 1250 px body, so a browser never scales its text down

STYLE = (f"body{{font-family:'{FONT}',Verdana,sans-serif;max-width:1250px;margin:auto;font-size:14px}}"
         "table{border-collapse:collapse;font-size:12px;margin:6px 0} td,th{border:1px solid #ccc;padding:2px 6px}"
         "th{background:#f4f4f4} .bad{color:#b00} .ok{color:#070} img{max-width:100%;display:block}"
         ".verdict{margin:0;padding:2px 0} .next{background:#f4f4f4;padding:6px} summary{cursor:pointer;color:#444}"
         "code{font-family:'DejaVu Sans Mono',monospace}")


def page(title: str, heading: str, verdicts, next_cmd: str, notes=(), body=()) -> str:
    """A page: the heading, each (ok, text) verdict (one per sensor), the next command with its notes,
    then the body's parts."""
    head = [f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{STYLE}</style></head><body><h1>{html.escape(heading)}</h1>"]
    head += [f"<p class='verdict {'ok' if ok else 'bad'}'><b>{html.escape(text)}</b></p>" for ok, text in verdicts]
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


def wrapped(text: str, width: int) -> str:
    return "\n".join(textwrap.wrap(text, width))


def log_bars(ax, labels, values, floor=None, unit=""):
    """Bars on a log scale (a calibrated error 1e-3 of the nominal one stays visible), each with its value,
    and the floor as a dashed line."""
    positive = [v for v in [*values, floor] if v and v > 0] or [1.0]
    low, top = min(positive) / 5, max(positive) * 8  # room above the tallest bar for its value
    shown = [max(v, low) for v in values]  # a zero at the axis's foot, its value written
    ax.bar(labels, shown, color=["#999", "#2a7", "#27a"][:len(values)])
    ax.set_yscale("log")
    ax.set_ylim(low, top)
    for k, v in enumerate(values):
        ax.annotate(f"{v:.2g}", (k, shown[k]), xytext=(0, 2), textcoords="offset points", ha="center", va="bottom",
                    fontsize=8)
    if floor:
        ax.axhline(floor, color="k", ls="--", lw=1)
        ax.annotate(f"floor {floor:.2g}", (0.0, floor), xycoords=("axes fraction", "data"), xytext=(3, -2),
                    textcoords="offset points", ha="left", va="top", fontsize=8)  # over the nominal bar, tall
    ax.set_ylabel(f"rms ({unit})")
