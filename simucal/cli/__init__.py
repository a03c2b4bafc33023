"""The `simucal` command: thin (arguments, progress, one-line errors); the work is in the modules
it calls. common.py holds the group and what every command shares; the commands are grouped by
what they do (calibrating.py, lot.py, sets.py, tools.py), each registering itself on `main`."""
import os

# A command's numpy without transparent huge pages (read when numpy is imported, which the command line
# does next; a library caller's process keeps its own): numpy asks for them on every array of 4 MB or
# more, and the kernel's compaction on each first touch cost `calibrate` of the 400 Hz set 0.2-0.3 s of
# system time (0.22-0.36 s against 0.43-0.59 s, 4 runs each alternating, load ~1.5; wall 1.34 against 1.50 s
# at best).
os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

from simucal.cli import calibrating, lot, sets, store, tools  # noqa: E402,F401 (each registers its commands on main)
from simucal.cli.common import main  # noqa: E402

__all__ = ["main"]
