"""The `simucal` command: thin (arguments, progress, one-line errors); the work is in the modules
it calls. common.py holds the group and what every command shares; the commands are grouped by
what they do (calibrating.py, lot.py, sets.py, tools.py), each registering itself on `main`."""
from simucal.cli import calibrating, lot, sets, tools  # noqa: F401 (each registers its commands on main)
from simucal.cli.common import main

__all__ = ["main"]
