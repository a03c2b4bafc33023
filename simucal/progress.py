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


class Wait:
    """A wait whose end is not known, under a time limit (a user's model file running in a child
    process): said at once, on a terminal or not, since a silent minute looks like a hang; then its
    seconds against the limit: a bar on a terminal, a line every EVERY_S seconds otherwise."""
    EVERY_S = 10.0

    def __init__(self, text: str, limit_s: float, short: str):
        print(text, file=sys.stderr, flush=True)
        self.limit_s, self.short, self.said = limit_s, short, 0.0
        self.bar = None
        if _shown():
            from tqdm import tqdm
            self.bar = tqdm(total=round(limit_s), desc=short, unit="s", leave=False,
                            bar_format="{desc}: {n:.0f} s of at most {total} s {bar}")

    @property
    def step_s(self) -> float:
        """How often tick() should be called."""
        return 0.5 if self.bar is not None else self.EVERY_S

    def tick(self, elapsed_s: float) -> None:
        if self.bar is not None:
            self.bar.update(min(round(elapsed_s), self.bar.total) - self.bar.n)
        elif elapsed_s - self.said >= self.EVERY_S - 1e-6:
            self.said = elapsed_s
            print(f"{self.short}: {elapsed_s:.0f} s so far, at most {self.limit_s:g} s", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
