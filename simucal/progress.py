"""Progress on waits of seconds: a bar or a line on stderr when it is a terminal, nothing
otherwise (pipes, files, CI and the tests stay quiet). tqdm draws the bars."""
from __future__ import annotations

import sys


def _shown() -> bool:
    return sys.stderr.isatty()


def steps(iterable, desc: str, unit: str = "step", total=None):
    """The iterable, with a bar while it runs."""
    if not _shown():
        return iterable
    from tqdm import tqdm
    return tqdm(iterable, desc=desc, unit=unit, total=total, leave=False)


def bar(desc: str, unit: str = "step"):
    """steps() as a one-argument wrapper, for functions that take `progress=`."""
    return lambda iterable: steps(iterable, desc, unit)


def status(text: str) -> None:
    """One line saying what the next seconds are spent on."""
    if _shown():
        print(text, file=sys.stderr, flush=True)
