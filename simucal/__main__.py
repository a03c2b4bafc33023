"""`python -m simucal`: the command line, where the console script is not on PATH."""
from simucal.cli import main

main(prog_name="simucal")
