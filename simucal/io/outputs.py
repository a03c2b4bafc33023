"""Output safety: a user's recordings are read-only.

Three rules, checked before any work and kept by every writer:
- no command writes into or over any of its inputs (a file given to it, or any file
  inside a folder given to it), whatever --force says;
- an existing folder that holds a measurement set (meta.json or samples.csv) is never
  replaced, nor a file of one written over, unless --force;
- every file is written to a temporary name beside it and renamed (os.replace is
  atomic), so an interrupted run leaves the old file or the new one, never half.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

SET_FILES = ("meta.json", "segments.csv", "samples.csv")


class OutputError(ValueError):
    """An output that would lose or corrupt a user's data."""


def holds_set(folder: Path) -> bool:
    """Whether a folder holds (part of) a measurement set."""
    return any((folder / name).exists() for name in SET_FILES)


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check(inputs=(), files=(), sets=(), folders=(), force=False) -> None:
    """Refuse, before any work, outputs that break the rules above.

    inputs: every path the command reads (files or folders); files: the files it will write;
    sets: the folders it will write a measurement set into; folders: other folders it writes
    files into (both created if absent). Raises OutputError naming the path and the fix."""
    ins = [(Path(p), Path(p).resolve()) for p in inputs if p]
    made = [Path(d) for d in list(sets) + list(folders) if d]
    written = [Path(f) for f in files if f] + [Path(s) / name for s in sets if s for name in SET_FILES]
    for out in made + written:
        where = out.resolve()
        for given, real in ins:
            same = where.exists() and real.exists() and os.path.samefile(where, real)  # hard links too
            if same or _inside(where, real):
                raise OutputError(f"{out}: would write {'over' if same or where == real else 'into'} the input "
                                  f"{given}; simucal never changes its inputs: choose an output outside it")
    for d in made:
        if d.exists() and not d.is_dir():
            raise OutputError(f"{d}: is a file; the output here is a folder")
    for f in [Path(f) for f in files if f]:
        if f.is_dir():
            raise OutputError(f"{f}: is a folder; give a file name")
        if not f.resolve().parent.is_dir() and f.resolve().parent not in {d.resolve() for d in made}:
            raise OutputError(f"{f}: the folder {f.parent} does not exist; create it or choose another path")
        if f.name in SET_FILES and holds_set(f.resolve().parent):
            raise OutputError(f"{f}: would write over a file of the measurement set in {f.parent}; choose another "
                              "name")
    for s in [Path(s) for s in sets if s]:
        if s.is_dir() and holds_set(s) and not force:
            raise OutputError(f"{s}: already holds a measurement set; choose a new folder (or --force to replace it)")


_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def replacing(path, mode: int = 0o666):
    """A temporary path beside `path` (same suffix) for a writer; renamed to `path` when the
    block ends, removed if it raises. mode: the file's, less the umask's bits."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode & ~_UMASK)  # mkstemp makes 0600; a written file gets the user's usual mode
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path, text: str, mode: int = 0o666) -> None:
    """Write a text file by a temporary name and a rename (mode: as replacing's)."""
    with replacing(path, mode) as tmp:
        tmp.write_text(text)
