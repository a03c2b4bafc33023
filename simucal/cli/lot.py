"""The lot command: the calibrations of many units side by side (simucal/api/lot_reporting.py)."""
from __future__ import annotations

import click

from simucal.cli.common import UNITS, InputPath, guard, main


@main.command()
@click.argument("cal_folder", type=InputPath(exists=True, file_okay=False), required=False)
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="lot.json", show_default=True,
              help="The lot report: each parameter's distribution, outliers, limits, model tests, drift.")
@click.option("--html", "html_path", type=click.Path(dir_okay=False), default=None,
              help="Also write a page opening with the lot's verdict, then each parameter's spread over the units.")
@click.option("--limits", "limits_path", type=InputPath(exists=True, dir_okay=False), default=None,
              help="A limits.json of spec limits per parameter ({\"format\": \"simucal.limits/1\", \"limits\": "
                   "{\"acc.b_x\": {\"min\": -0.005, \"max\": 0.005, \"unit\": \"g\"}}}, each in the unit the "
                   "calibrations give; default: none).")
@click.option("--store", "store_url", default=None, help="Instead of CAL_FOLDER: a calibration store's records "
              "(a SQLite file or a SQL server's URL, as simucal store add --store takes).")
@click.option("--since", default=None, help="With --store: records calibrated at or after this UTC time (2026-01-01).")
@click.option("--until", default=None, help="With --store: records calibrated at or before this UTC time.")
@click.option("--model", default=None, help="With --store: records of this model, as the store names it "
                                            "(\"acc acc_baseline, gyro gyro_baseline\").")
@click.option("--station", default=None, help="With --store: records of this station.")
@UNITS
def lot(cal_folder, output, html_path, limits_path, store_url, since, until, model, station, units):
    """A lot of units from their calibration files (calibrate DIR1 DIR2 ... -o CAL_FOLDER) or a store's records:
    which pass, which fail and why (model test, spec limits), outliers, each parameter's spread, drift between
    calibrations of one unit."""
    import json

    from simucal import api
    from simucal.io import outputs
    guard([p for p in (cal_folder, limits_path) if p], files={"-o": output, "--html": html_path})
    report = api.lot(cal_folder, limits_path, store=store_url, since=since, until=until, model=model,
                     station=station)
    outputs.write_text(output, json.dumps(report, indent=1) + "\n")
    from simucal.report.units import lot_in
    shown = lot_in(report, units)  # what is printed and paged; the file in the spec's units
    if html_path:
        from simucal.report.lot_html import lot_page
        outputs.write_text(html_path, lot_page(shown))
    for line in shown["verdict"]:
        click.echo(line)
    for d in shown["drift"]:
        click.echo(f"{d['serial']}: {d['earlier']} -> {d['later']}: " + ", ".join(
            f"{s} {v['verdict']} (chi2 {v['chi2']:.3g} on {v['dof']}, p = {v['p_value']:.2g})"
            for s, v in d["sensors"].items()))
    click.echo(f"next: {report['next']}")
    click.echo(f"wrote {output}" + (f" and {html_path}" if html_path else ""))
