"""A page printed to PDF by a headless Chromium (Chrome's own print: the PDF is the page as a browser lays it
out, so the HTML and the PDF of a certificate are one page). The browser is $SIMUCAL_CHROMIUM, else the first
of BROWSERS on the PATH; none is refused in one line naming the fix, the HTML kept."""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from simucal.errors import CalibrationError

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
TIMEOUT_S = 120.0


def browser() -> str:
    """The Chromium to print with (module doc)."""
    given = os.environ.get("SIMUCAL_CHROMIUM")
    if given:
        if not shutil.which(given):
            raise CalibrationError(f"$SIMUCAL_CHROMIUM={given}: no such program; give the path of a Chromium or "
                                   "Chrome, or unset it")
        return given
    for name in BROWSERS:
        if shutil.which(name):
            return name
    raise CalibrationError("no Chromium or Chrome to print the PDF with (looked for " + ", ".join(BROWSERS)
                           + "): install one (Debian: apt-get install chromium) or set $SIMUCAL_CHROMIUM to its path;"
                             " or leave out the PDF, the HTML page is the same certificate")


def html_to_pdf(page_html: str) -> bytes:
    """The page's PDF (A4, no browser header or footer), printed by browser()."""
    exe = browser()
    with tempfile.TemporaryDirectory(prefix="simucal-pdf-") as tmp:
        src, out = Path(tmp) / "page.html", Path(tmp) / "page.pdf"
        src.write_text(page_html, encoding="utf-8")
        # no header or footer: --no-pdf-header-footer since Chromium 111, --print-to-pdf-no-header before it (each
        # ignores the other's flag), so a lab's older browser prints the same page
        cmd = [exe, "--headless", "--disable-gpu", "--no-sandbox", "--no-pdf-header-footer", "--print-to-pdf-no-header",
               f"--user-data-dir={Path(tmp) / 'profile'}", f"--print-to-pdf={out}", src.as_uri()]
        try:
            res = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise CalibrationError(f"{exe} did not print the PDF within {TIMEOUT_S:g} s") from None
        if not out.is_file() or not out.read_bytes().startswith(b"%PDF"):
            why = (res.stderr.strip().splitlines() or ["no output"])[-1][:300]
            raise CalibrationError(f"{exe} printed no PDF (exit {res.returncode}: {why})")
        return out.read_bytes()
