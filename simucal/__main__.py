"""`python -m simucal`: the command line (simucal.cli), where the `simucal` script is not on PATH."""
from simucal.cli import main

main(prog_name="simucal")
