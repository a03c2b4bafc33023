"""`simucal.certificate` (`simucal certificate CAL.json`): a calibration's certificate, HTML and PDF of one page
(simucal/report/certificate.py; the PDF printed by a headless Chromium, report/pdf.py)."""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

from simucal.api.arguments import checked
from simucal.api.validating import FORMAT as VALIDATION_FORMAT
from simucal.errors import InputError
from simucal.io import outputs
from simucal.io.calibration import loads
from simucal.version import __version__


def _validation(path: Path, calibration: Path) -> dict[str, Any]:
    """validate's report, refused where it is not one, or is of another calibration file (its bytes' sha256, which
    validate records; a copy of the file under another name is the same calibration)."""
    try:
        report = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise InputError(f"{path}: not a readable validation report ({str(e)[:120]})") from None
    if not isinstance(report, dict) or report.get("format") != VALIDATION_FORMAT:
        raise InputError(f"{path}: not a validation report (format {VALIDATION_FORMAT}: simucal validate CAL.json "
                         "DATA -o validation.json writes one)")
    if report.get("independent") is False:
        raise InputError(f"{path}: a validation on the data the calibration was made from, not independent data; "
                         f"validate on another recording of the unit: simucal validate {calibration} OTHER_DATA -o "
                         "validation.json")
    sha = report.get("calibration_sha256")  # a report written before validate recorded it: matched by name
    if (sha != hashlib.sha256(calibration.read_bytes()).hexdigest() if sha else
            Path(str(report.get("calibration"))).name != calibration.name):
        raise InputError(f"{path}: validates {report.get('calibration')}" + (f" (sha256 {sha[:12]}...)" if sha else "")
                         + f", not {calibration}; give the validation of this calibration: simucal validate "
                         f"{calibration} DATA -o validation.json")
    return report


@checked
def certificate(calibration: str | os.PathLike[str], validation: str | os.PathLike[str] | None = None,
                html: str | os.PathLike[str] | None = None, pdf: str | os.PathLike[str] | None = None) -> str:
    """The certificate of a calibration file: the unit, the file's and the data's sha256, the method and each
    model's test, every parameter with its std u, its expanded uncertainty U = 2 u and u's budget (noise, the
    table's tilt, the model's misfit), the validation on independent data, simucal's version.

    Parameters
    ----------
    calibration : str or os.PathLike[str]
        A calibration file (``simucal calibrate ... -o calibration.json``); read, never written.
    validation : str or os.PathLike[str], optional
        validate's report of this calibration on independent data (``simucal validate CAL DATA -o
        validation.json``); the report of another calibration file is refused.
    html : str or os.PathLike[str], optional
        Also write the page there (never over an input).
    pdf : str or os.PathLike[str], optional
        Also write the same page as PDF, printed by a headless Chromium ($SIMUCAL_CHROMIUM, else chromium or
        google-chrome on the PATH; none: refused, nothing written).

    Returns
    -------
    str
        The certificate's HTML page.
    """
    from simucal.report.certificate import certificate_page  # matplotlib's pages: not at every command's start
    from simucal.report.pdf import html_to_pdf
    cal_path = Path(calibration)
    raw = cal_path.read_bytes()
    inputs = [cal_path] + ([Path(validation)] if validation else [])
    written = {k: Path(v) for k, v in (("html", html), ("pdf", pdf)) if v}
    if written:
        outputs.check(inputs, files={str(p): p for p in written.values()})
    report = _validation(Path(validation), cal_path) if validation else None
    page = certificate_page(loads(raw.decode("utf-8"), cal_path), cal_path.name, hashlib.sha256(raw).hexdigest(),
                            report, __version__)
    printed = html_to_pdf(page) if "pdf" in written else None  # before any file: a failed print writes nothing
    if "html" in written:
        outputs.write_text(written["html"], page)
    if printed is not None:
        with outputs.replacing(written["pdf"]) as tmp:
            tmp.write_bytes(printed)
    return page
