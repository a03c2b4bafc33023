"""The pages' layout checked without a browser (README, Pages): the text of every figure a page embeds,
as matplotlib draws it, and the page's own HTML.

CI installs only what pyproject.toml pip-installs and downloads nothing at run time, so no Chromium
(playwright's browsers are a download of their own). The figures are the only part of a page whose
layout is not the browser's own text flow: their text is placed by matplotlib, and this reads where
it drew each piece (`Text.draw`, so exactly the tick labels, labels, titles, legend entries and
annotations that are drawn) and finds any two that cross, and any that sits on a plot's marks: a scatter
marker, or a line or its markers inside the axes (a legend's entries excepted: its frame covers the lines).
The page itself, laid out by the browser, is tests/browser.py's.
"""
from __future__ import annotations

from contextlib import contextmanager
from unittest import mock

import numpy as np
from matplotlib.collections import PathCollection
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox
from matplotlib.text import Text

PAGE_PX = 1280  # the window the pages are read in
BODY_PX = 1250  # the pages' body width (report/html.py's stylesheet)
MIN_TEXT_PX = 8.0  # the smallest text height on the page (after the browser scales an image down to the body)
TOUCH_PX = 1.0  # two boxes overlapping by less than this in either direction only touch


def _drawn_texts(fig):
    """(text, its box in pixels) of every text the figure draws."""
    drawn, draw = [], Text.draw

    def record(self, renderer):
        draw(self, renderer)
        if self.get_visible() and self.get_text().strip():
            drawn.append((self, self.get_window_extent(renderer)))
    with mock.patch.object(Text, "draw", record):
        fig.canvas.draw()
    return drawn


def _cross(a, b) -> bool:
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w > TOUCH_PX and h > TOUCH_PX


def _name(t) -> str:
    return repr(t.get_text()[:40])


def _title(fig) -> str:
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    return titles[0] if titles else "untitled figure"


def _on_lines(fig, texts, where) -> list[str]:
    """Each text (a legend's excepted) crossed, inside an axes, by one of its lines or their markers."""
    legends = {id(t) for leg in [ax.get_legend() for ax in fig.axes] + list(fig.legends) if leg
               for t in leg.get_texts()}
    out = []
    for ax in fig.axes:
        for line in (x for x in ax.get_lines() if x.get_visible()):
            path = line.get_transform().transform_path(line.get_path())
            r = line.get_markersize() / 2 * fig.dpi / 72 if line.get_marker() not in (None, "None", "", " ") else None
            for t, bt in texts:
                inside = Bbox.intersection(bt, ax.bbox)
                if id(t) in legends or inside is None or min(inside.width, inside.height) <= TOUCH_PX:
                    continue
                box = inside.expanded(1 - 2 * TOUCH_PX / inside.width, 1 - 2 * TOUCH_PX / inside.height)
                dashed = line.get_linestyle() not in ("None", "", " ") and path.intersects_bbox(box, filled=False)
                dotted = r is not None and bool(((path.vertices > [box.x0 - r, box.y0 - r])
                                                 & (path.vertices < [box.x1 + r, box.y1 + r])).all(1).any())
                if dashed or dotted:
                    out.append(f"{where}: {_name(t)} on a line of the plot")
    return out


def figure_problems(fig, dpi) -> list[str]:
    """Each text crossing another text, sitting on a scatter marker, or smaller than MIN_TEXT_PX on the
    page, named with the figure's first title."""
    texts = _drawn_texts(fig)
    where, out = _title(fig), []
    for i, (a, ba) in enumerate(texts):
        for b, bb in texts[i + 1:]:
            if _cross(ba, bb):
                out.append(f"{where}: {_name(a)} overlaps {_name(b)}")
    for ax in fig.axes:
        for c in ax.collections:
            if not isinstance(c, PathCollection) or not len(c.get_offsets()):
                continue
            xy = c.get_offset_transform().transform(c.get_offsets())
            r = np.sqrt(np.max(c.get_sizes())) / 2 * fig.dpi / 72
            for t, bt in texts:
                near = ((xy[:, 0] > bt.x0 - r) & (xy[:, 0] < bt.x1 + r)
                        & (xy[:, 1] > bt.y0 - r) & (xy[:, 1] < bt.y1 + r))
                if near.any():
                    out.append(f"{where}: {_name(t)} under a marker at {xy[near][0].round()}")
    out += _on_lines(fig, texts, where)
    width_px = fig.get_size_inches()[0] * dpi
    scale = min(1.0, BODY_PX / width_px)
    small = [t for t, bt in texts if t.get_fontsize() * dpi / 72 * scale < MIN_TEXT_PX]
    if small:
        out.append(f"{where}: {len(small)} texts below {MIN_TEXT_PX:g} px on a {PAGE_PX} px page, "
                   f"e.g. {_name(small[0])}")
    return out


@contextmanager
def figures_checked():
    """Within it every figure saved (every figure a page embeds) is checked first; yields (the problems
    found, one string each; the figures)."""
    problems, figures, save = [], [], Figure.savefig

    def check_then_save(self, *args, **kwargs):
        problems.extend(figure_problems(self, kwargs.get("dpi") or self.dpi))
        figures.append(self)
        return save(self, *args, **kwargs)
    with mock.patch.object(Figure, "savefig", check_then_save):
        yield problems, figures


def html_problems(page: str) -> list[str]:
    """The page's own structure: a verdict per sensor and the next command first."""
    out = []
    head = page.split("<h2", 1)[0]
    if "class='verdict" not in head or "class='next'" not in head:
        out.append("the page does not open with the verdicts and the next command (before its first section)")
    return out
