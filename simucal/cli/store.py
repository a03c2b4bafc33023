"""A lab's records on the command line: store add, history (simucal.Store; simucal/store/), certificate."""
from __future__ import annotations

import click

from simucal.cli.common import InputPath, guard, main

STORE_HELP = ("The calibration store: a SQLite file (a path or sqlite:///path) or a SQL server's URL "
              "(postgresql://user@host/db); default $SIMUCAL_STORE, else calibrations.db here.")


def store_option(required_default: bool):
    """--store URL, from $SIMUCAL_STORE where not given (calibrate's records only where it is given)."""
    return click.option("--store", "store_url", envvar="SIMUCAL_STORE" if required_default else None,
                        default="calibrations.db" if required_default else None, show_default=required_default,
                        help=STORE_HELP if required_default else
                        "Also record each calibration written into this store (a SQLite file or a SQL server's "
                        "URL, as simucal store add --store takes).")


def record(store_url: str, calibration, station: str | None = None) -> str:
    """Record one calibration (an object, its bytes as written) into the store: the line to print."""
    from simucal import api
    store = api.Store(store_url)
    record_id = store.add(calibration, station=station)
    return f"recorded as record {record_id} in {store!r}"


@main.group()
def store():
    """A lab's calibration store: every unit's calibrations in one database (docs/lab.md)."""


@store.command("add")
@click.argument("calibrations", nargs=-1, required=True, type=InputPath(exists=True, dir_okay=False))
@store_option(True)
@click.option("--serial", default=None, help="The unit's serial where the file has none (default: its meta.json's "
                                             "unit_serial).")
@click.option("--station", default=None, help="Where it was calibrated (default: this host's name).")
@click.option("--time", "time_utc", default=None,
              help="When it was calibrated, UTC (2026-03-01 or 2026-03-01T09:30:00Z; default: now).")
def store_add(calibrations, store_url, serial, station, time_utc):
    """Record calibration files, byte for byte, each a new record (a file recorded before is refused)."""
    from simucal import api
    st = api.Store(store_url)
    for path in calibrations:
        record_id = st.add(path, serial=serial, station=station, time=time_utc)
        click.echo(f"{path}: record {record_id} in {st!r}")


@main.command()
@click.argument("serial")
@store_option(True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="history.json", show_default=True,
              help="The unit's history: each calibration's change since the last and the first, in std, and flags.")
@click.option("--limits", "limits_path", type=InputPath(exists=True, dir_okay=False), default=None,
              help="A limits.json (as simucal lot takes) bounding each parameter's change since the first "
                   "calibration, in its unit (default: none).")
@click.option("--spec", "spec_path", type=InputPath(exists=True, dir_okay=False), default=None,
              help="A limits.json bounding each parameter's value (as simucal lot --limits): the due date, where "
                   "each parameter's trend is expected to leave it (default: none).")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write the unit's page: each parameter's history with its k = 2 band, its trend and spec.")
def history(serial, store_url, output, limits_path, spec_path, html_path):
    """A unit's calibrations from the store: each parameter's change since the last and since the first in units of
    the combined std, flagged where the stds do not explain it (chi2 at ALPHA over the unit's history) or where it
    passes the lab's limits; each parameter's trend, and the date it is expected to leave the spec."""
    import json

    from simucal import api
    from simucal.io import outputs
    inputs = [p for p in (limits_path, spec_path, api.Store.local_file(store_url)) if p]  # the store's file too
    guard(inputs, files={"-o": output, **({"--html": html_path} if html_path else {})})
    report = api.Store(store_url).history(serial, limits_path, spec_path)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    for line in api.store.history_lines(report):
        click.echo(line)
    click.echo(f"wrote {output}")
    if html_path:
        outputs.write_text(html_path, api.store.history_page(report))
        click.echo(f"wrote {html_path}")


@main.command()
@click.argument("calibration", required=False, type=InputPath(exists=True, dir_okay=False))
@click.option("--record", type=int, default=None,
              help="Instead of a calibration file: this record of the store (--store), its file as recorded.")
@store_option(True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="certificate.html", show_default=True,
              help="The certificate page (HTML).")
@click.option("--pdf", type=click.Path(dir_okay=False), default=None,
              help="Also the same page as PDF, printed by a headless Chromium ($SIMUCAL_CHROMIUM, else chromium or "
                   "google-chrome on the PATH).")
@click.option("--validation", type=InputPath(exists=True, dir_okay=False), default=None,
              help="validate's report of this calibration on independent data (simucal validate CAL DATA -o "
                   "validation.json), shown on the certificate.")
def certificate(calibration, record, store_url, output, pdf, validation):
    """A calibration's certificate (of CALIBRATION, a file, or of --record N in --store): the unit, the file's and
    the data's sha256, the method and each model's test, every parameter with its expanded uncertainty (k = 2) and
    its budget, the validation, simucal's version; every number read from the files."""
    from simucal import api
    files = {"-o": output, **({"--pdf": pdf} if pdf else {})}
    inputs = [p for p in (calibration, validation, record is not None and api.Store.local_file(store_url)) if p]
    guard(inputs, files=files)
    api.certificate(calibration, validation=validation, html=output, pdf=pdf,
                    **({"store": store_url, "record": record} if record is not None else {}))
    for path in files.values():
        click.echo(f"wrote {path}")
