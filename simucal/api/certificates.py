"""`simucal.certificate` (`simucal certificate CAL.json`): a calibration's certificate, HTML and PDF of one page
(simucal/report/certificate.py; the PDF printed by a headless Chromium, report/pdf.py)."""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from simucal.arguments import checked
from simucal.api.validating import FORMAT as VALIDATION_FORMAT
from simucal.errors import InputError
from simucal.io import outputs
from simucal.io.calibration import loads
from simucal.version import __version__

if TYPE_CHECKING:  # the row's type only: SQLAlchemy loads for a store's record, not for a file
    from simucal.store.schema import RecordRow


def _validation(path: Path, calibration: str, raw: bytes) -> dict[str, Any]:
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
    if (sha != hashlib.sha256(raw).hexdigest() if sha else
            Path(str(report.get("calibration"))).name != Path(calibration).name):
        raise InputError(f"{path}: validates {report.get('calibration')}" + (f" (sha256 {sha[:12]}...)" if sha else "")
                         + f", not {calibration}; give the validation of this calibration: simucal validate "
                         f"{calibration} DATA -o validation.json")
    return report


class _Source(NamedTuple):
    raw: bytes           # the calibration file's bytes
    where: str           # the file's path, or the store's record, as messages name it
    name: str            # as the certificate gives it
    read: list[Path]     # the files read (never written over)
    record: RecordRow | None  # a store's record: its row (the unit's serial as the lab recorded it, when, where)
    apply_line: str      # the page's next command


def _source(calibration: str | os.PathLike[str] | None, store: str | os.PathLike[str] | None,
            record: int | None) -> _Source:
    """The calibration certified: a file, or a store's record (its file byte for byte, as recorded)."""
    if calibration is not None and record is None:
        path = Path(calibration)
        return _Source(path.read_bytes(), str(path), path.name, [path], None,
                       f"simucal apply {path.name} DATA_DIR -o calibrated")
    if record is None or calibration is not None or store is None:
        raise InputError("give a calibration file or a store's record (--store URL --record N), one of them")
    from simucal.api.store import Store
    from simucal.store.schema import local_file
    url = os.fspath(store)
    st = Store(url)
    try:
        raw, row, where = st.file(record), st.record(record), f"record {record} of {st!r}"  # repr: no password
    finally:
        st.close()
    local = local_file(url)
    return _Source(raw, where, where, [local] if local else [], row,
                   "simucal apply CAL.json DATA_DIR -o calibrated (CAL.json: this "
                   f"record's file, simucal.Store(URL).file({record}))")


@checked
def certificate(calibration: str | os.PathLike[str] | None = None, validation: str | os.PathLike[str] | None = None,
                html: str | os.PathLike[str] | None = None, pdf: str | os.PathLike[str] | None = None,
                store: str | os.PathLike[str] | None = None, record: int | None = None) -> str:
    """The certificate of a calibration file: the unit, the file's and the data's sha256, the method and each
    model's test, every entry of the one vocabulary (M_xx .. bias_z, the effects, the method's own name beside
    each) with its std u, its expanded uncertainty U = 2 u and u's budget (noise, the table's tilt, the model's
    misfit), the validation on independent data, simucal's version.

    Parameters
    ----------
    calibration : str or os.PathLike[str], optional
        A calibration file (``simucal calibrate ... -o calibration.json``); read, never written. Or:
    store : str or os.PathLike[str], optional
        A calibration store (a SQLite file or a SQL server's URL, as `simucal.Store` takes), with
    record : int, optional
        its record whose calibration file (as recorded, byte for byte) the certificate is of.
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
    src = _source(calibration, store, record)
    inputs = src.read + ([Path(validation)] if validation else [])
    written = {k: Path(v) for k, v in (("html", html), ("pdf", pdf)) if v}
    if written:
        outputs.check(inputs, files={str(p): p for p in written.values()})
    report = _validation(Path(validation), src.where, src.raw) if validation else None
    page = certificate_page(loads(src.raw.decode("utf-8"), src.where), src.name, hashlib.sha256(src.raw).hexdigest(),
                            report, __version__, src.apply_line, src.record)
    printed = html_to_pdf(page) if "pdf" in written else None  # before any file: a failed print writes nothing
    if "html" in written:
        outputs.write_text(written["html"], page)
    if printed is not None:
        with outputs.replacing(written["pdf"]) as tmp:
            tmp.write_bytes(printed)
    return page
