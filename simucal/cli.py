"""The `simucal` command."""
from __future__ import annotations

import sys
from pathlib import Path

import click


@click.group()
@click.version_option(package_name="simucal")
def main():
    """Strapdown IMU calibration: derive, simulate, calibrate, audit."""


@main.command()
@click.option("--check", is_flag=True, help="Fail if generated/ differs from what derive writes now.")
@click.option("--model", "model_files", multiple=True, type=click.Path(exists=True, dir_okay=False),
              help="A Python file defining MODELS = [ErrorModel, ...]; generated beside the baseline.")
def derive(check, model_files):
    """Derive the models and (re)write generated/."""
    from simucal import derive_cmd
    stale, secs = derive_cmd.run(check=check, model_files=model_files)
    if check:
        if stale:
            click.echo("generated/ is stale; run `simucal derive`. Differs: " + ", ".join(stale), err=True)
            sys.exit(1)
        click.echo(f"generated/ is up to date ({secs:.1f} s)")
    else:
        click.echo(f"wrote {derive_cmd.generated_dir()} ({secs:.1f} s)")


if __name__ == "__main__":
    main()
