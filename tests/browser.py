"""The pages read in a real browser: Debian's headless Chromium driven by Selenium (chromedriver named, so
that selenium-manager downloads nothing), each page rendered at a width and measured as laid out:

- every table rectangular: the same number of columns (cells, with their colspans) in every row, the header's
  included;
- no number split across lines: each number in a table's cell on one line;
- no text on a figure: no text of the page laid over an embedded figure (the figures' own text against
  their marks is tests/page_layout.py's, where matplotlib says where it drew each);
- figures using the width they have: each at least FILL of its column's width, none wider than it, and the
  page no wider than the window (a wide table scrolls inside itself).

The docs site's pages (tests/test_docs.py) are read the same way for one thing, WIDE: no code block or table
wider than its text column.
"""
from __future__ import annotations

import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

import pytest

CHROMIUM, CHROMEDRIVER = "/usr/bin/chromium", "/usr/bin/chromedriver"
INSTALL = "apt-get install -y chromium chromium-driver"
FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync")
WIDTHS = {"desktop": 1280, "phone": 390}  # a laptop's window, a phone's (CSS px)
FILL = 0.85  # a figure narrower than this share of its column leaves the column's width unused
TOUCH_PX = 1.0  # boxes overlapping by less than this in either direction only touch


@contextmanager
def chromium():
    """A headless Chromium (the flags that work without a display, a sandbox or a network), its profile new
    and empty; fails, naming the install, where Debian's chromium and chromium-driver are not there."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not Path(p).exists()]
    if missing:
        pytest.fail(f"{', '.join(missing)} not found: the pages are checked in Debian's Chromium; install it "
                    f"(as root): {INSTALL}")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    profile = tempfile.mkdtemp(prefix="simucal-chromium-")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (*FLAGS, f"--user-data-dir={profile}"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


# Each check returns its problems as strings (an empty list where the page passes).
CHECKS = r"""
const out = [], T = %(touch)s, name = e => (e.textContent || e.alt || e.tagName).trim().slice(0, 40);
const cross = (a, b) => Math.min(a.right, b.right) - Math.max(a.left, b.left) > T &&
                        Math.min(a.bottom, b.bottom) - Math.max(a.top, b.top) > T;
const shown = e => e.checkVisibility();  // a folded row's text is not laid out
const figures = [...document.querySelectorAll('img, svg')].filter(f => !f.parentElement.closest('svg') && shown(f));
document.querySelectorAll('table').forEach((t, k) => {
  const cols = [...t.rows].map(r => [...r.cells].reduce((n, c) => n + c.colSpan, 0));
  if (new Set(cols).size > 1)
    out.push(`table ${k + 1} (${name(t.rows[0])}) is ragged: its rows have ${[...new Set(cols)].join(', ')} columns`);
});
const walker = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
for (let node; (node = walker.nextNode());) {
  if (!node.textContent.trim() || node.parentElement.closest('svg') || !shown(node.parentElement)) continue;
  const range = document.createRange();
  if (node.parentElement.closest('td, th'))
    for (const m of node.textContent.matchAll(/(?<![\w.-])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?/gi)) {
      range.setStart(node, m.index); range.setEnd(node, m.index + m[0].length);
      const tops = new Set([...range.getClientRects()].filter(r => r.width > 0).map(r => Math.round(r.top)));
      if (tops.size > 1) out.push(`the number ${m[0]} is split across lines in '${name(node.parentElement.closest('td, th'))}'`);
    }
  range.selectNodeContents(node);
  for (const r of range.getClientRects())
    figures.forEach((f, k) => { if (cross(r, f.getBoundingClientRect()))
      out.push(`the text '${node.textContent.trim().slice(0, 40)}' lies on figure ${k + 1}`); });
}
figures.forEach((f, k) => {
  const box = f.parentElement, s = getComputedStyle(box);
  const column = box.clientWidth - parseFloat(s.paddingLeft) - parseFloat(s.paddingRight);
  const w = f.getBoundingClientRect().width;
  if (w < %(fill)s * column) out.push(`figure ${k + 1} is ${Math.round(w)} px wide in a ${Math.round(column)} px column`);
  if (w > column + T) out.push(`figure ${k + 1} is ${Math.round(w)} px wide, wider than its ${Math.round(column)} px column`);
});
if (document.documentElement.scrollWidth > innerWidth + T)
  out.push(`the page is ${document.documentElement.scrollWidth} px wide in a ${innerWidth} px window`);
return out;
""" % {"touch": TOUCH_PX, "fill": FILL}  # noqa: E501 (the page's JavaScript, kept as the browser runs it)


# The code blocks and tables wider than their text column (a Sphinx page's div.body, less its padding; the
# page's body elsewhere): scrolled sideways inside themselves or reaching past the column's right edge. A block
# inside one already named is not named again (a div.highlight's pre).
WIDE = r"""
const out = [], named = [], T = %(touch)s;
document.querySelectorAll('pre, div.highlight, table').forEach(e => {
  if (!e.checkVisibility() || named.some(n => n.contains(e))) return;
  const column = e.closest('div.body') || document.body, s = getComputedStyle(column);
  const right = column.getBoundingClientRect().right - parseFloat(s.paddingRight);
  const past = Math.max(e.scrollWidth - e.clientWidth, e.getBoundingClientRect().right - right);
  if (past > T) {
    named.push(e);
    const kind = e.tagName === 'TABLE' ? 'table' : 'code block';
    out.push(`the ${kind} '${e.textContent.trim().split('\n')[0].trim().slice(0, 60)}' is ${Math.round(past)} px wider than its column`);
  }
});
return out;
""" % {"touch": TOUCH_PX}  # noqa: E501 (the page's JavaScript, kept as the browser runs it)


def window(driver, width: int, height: int = 900) -> None:
    """The window's size in CSS px, one device pixel each, as a desktop's."""
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})


def page_problems(driver, page: str, width: int, folder: Path, shot: str | None = None) -> list[str]:
    """The problems (CHECKS) of the page's HTML rendered `width` CSS px wide, a screenshot of the whole page
    saved as folder/shot where named."""
    path = folder / "page.html"
    path.write_text(page, encoding="utf-8")
    window(driver, width)
    driver.get(path.as_uri())
    problems = driver.execute_script(CHECKS)
    if shot:
        window(driver, width, min(driver.execute_script("return document.documentElement.scrollHeight"), 16000))
        driver.save_screenshot(str(folder / shot))
    return problems


def wide_blocks(driver, path: Path, width: int) -> list[str]:
    """The code blocks and tables (WIDE) of the HTML file at path, opened where it lies (its stylesheets
    beside it) in a window `width` CSS px wide, wider than their text column; each named by its first line."""
    window(driver, width)
    driver.get(path.as_uri())
    return driver.execute_script(WIDE)
