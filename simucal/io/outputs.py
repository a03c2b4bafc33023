"""Output safety: a user's recordings are read-only.

Checked before any work (`check`) and kept by every writer:
- no command writes into or over any of its inputs (a file given to it, or any file
  inside a folder given to it), whatever --force says;
- no two outputs of one command are the same file, or one inside the other (a file
  inside a file, a file inside a measurement set's folder);
- every output's folder (or the nearest existing folder above one to be made) is writable;
- an existing folder that holds a measurement set (meta.json or samples.csv) is never
  replaced, nor a file of one written over, unless --force;
- every file is written to a temporary name beside it and renamed (os.replace is
  atomic), so an interrupted run leaves the old file or the new one, never half;
- all of a command's outputs or none (`all_or_nothing`): the renames into the outputs
  `check` was given wait until the command ends, and a command that fails removes its
  temporaries (and the output folders it made), so no half of its outputs is left.
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from simucal.errors import SimucalError

SET_FILES = ("meta.json", "segments.csv", "samples.csv", "samples.parquet")


class OutputError(SimucalError):
    """An output that would lose or corrupt a user's data."""


def holds_set(folder: Path) -> bool:
    """Whether a folder holds (part of) a measurement set."""
    return any((folder / name).exists() for name in SET_FILES)


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def _labelled(outs) -> list[tuple[str, Path]]:
    """(what, path) of outputs given as {what: path} (e.g. {"-o": ..., "--html": ...}) or as paths."""
    pairs = outs.items() if isinstance(outs, dict) else ((str(p), p) for p in outs)
    return [(what, Path(p)) for what, p in pairs if p]


def _distinct(files, sets, folders) -> None:
    """Two outputs that are the same file, or one inside the other; files may lie in `folders`
    (they are made for them) and one set in another's folder (the demo's)."""
    outs = [(what, p, p.resolve(), kind) for kind, group in (("file", files), ("set", sets), ("folder", folders))
            for what, p in group]
    for i, (wa, a, ra, ka) in enumerate(outs):
        for wb, b, rb, kb in outs[i + 1:]:
            same = ra == rb or (ra.exists() and rb.exists() and os.path.samefile(ra, rb))
            inner = None if same else (a, b) if rb in ra.parents else (b, a) if ra in rb.parents else None
            if inner and (kb if inner[1] is b else ka) == "folder":
                continue
            if inner and ka == kb == "set":
                continue
            if same or inner:
                both = f"{wa} and {wb}" if wa != str(a) or wb != str(b) else "two of the outputs"
                how = f"{inner[0]} inside {inner[1]}" if inner else "the same file"  # inner is None when same
                raise OutputError(f"{a}: {both} would be {how}; give each output its own name")


def _writable(paths) -> None:
    """Each output's place: its folder, or the nearest existing folder above one to be made."""
    seen = set()
    for out, folder in paths:
        place = folder.resolve()
        while not place.exists() and place != place.parent:
            place = place.parent
        if place.is_dir() and place not in seen:
            try:  # a file made and removed: permissions, a read-only file system, /proc all answer alike
                fd, probe = tempfile.mkstemp(dir=place, prefix=".simucal-probe.")
                os.close(fd)
                os.unlink(probe)
            except OSError as e:
                raise OutputError(f"{out}: cannot write in {place} ({e.strerror}); choose another place") from None
            seen.add(place)


def check(inputs=(), files=(), sets=(), folders=(), force=False) -> None:
    """Refuse, before any work, outputs that break the rules above.

    inputs: every path the command reads (files or folders); files: the files it will write
    ({what: path} names each in a refusal, e.g. {"-o": ..., "--html": ...}); sets: the folders it
    will write a measurement set into; folders: other folders it writes files into (both created
    if absent). Raises OutputError naming the path and the fix."""
    labelled = _labelled(files), _labelled(sets), _labelled(folders)
    files, sets, folders = ([p for _, p in group] for group in labelled)
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
    _distinct(*labelled)
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
            raise OutputError(f"{s}: already holds a measurement set; choose a new folder (or --force, force=True in "
                              "Python, to replace it)")
    _writable([(f, f.parent) for f in files] + [(d, d) for d in sets + folders])


_UMASK = os.umask(0)
os.umask(_UMASK)


class _Held:
    """A command's outputs (resolved) and the renames into them that wait for its end."""
    def __init__(self) -> None:
        self.outputs: list[Path] = []
        self.made: list[Path] = []      # output folders absent before: removed again if the command fails
        self.renames: list[tuple[Path, Path]] = []

    def holds(self, path: Path) -> bool:
        real = path.resolve()
        return any(real == o or o in real.parents for o in self.outputs)


_HELD: list[_Held] = []  # the running command's, while all_or_nothing is open


def hold(files=(), folders=()) -> None:
    """Renames into these outputs (files, and folders written into) wait for the command's end."""
    if _HELD:
        for p in [Path(p) for p in list(files) + list(folders) if p]:
            _HELD[-1].outputs.append(p.resolve())
        _HELD[-1].made += [Path(d).resolve() for d in folders if d and not Path(d).exists()]


@contextlib.contextmanager
def all_or_nothing():
    """A command's outputs all written or none: the renames held (`hold`) are done when the block
    ends; if it raises (a refusal's SystemExit too), every held temporary is removed, and the output
    folders the command made, where they are left empty."""
    held = _Held()
    _HELD.append(held)
    try:
        yield held
    except BaseException:
        for tmp, _ in held.renames:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
        for d in reversed(held.made):
            with contextlib.suppress(OSError):
                d.rmdir()  # only where empty
        raise
    else:
        commit()
    finally:
        _HELD.remove(held)


def commit() -> None:
    """Do the held renames now (a command that ends with an exit status of its own after writing)."""
    if _HELD:
        for tmp, path in _HELD[-1].renames:
            os.replace(tmp, path)
        _HELD[-1].renames.clear()


@contextlib.contextmanager
def replacing(path, mode: int = 0o666):
    """A temporary path beside `path` (same suffix) for a writer; renamed to `path` when the
    block ends (or, for a held output, when the command ends), removed if it raises. mode: the file's,
    less the umask's bits."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.stem}.", suffix=f".tmp{path.suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, mode & ~_UMASK)  # mkstemp makes 0600; a written file gets the user's usual mode
        if _HELD and _HELD[-1].holds(path):
            _HELD[-1].renames.append((Path(tmp), path))
        else:
            os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_text(path, text: str, mode: int = 0o666) -> None:
    """Write a text file by a temporary name and a rename (mode: as replacing's)."""
    with replacing(path, mode) as tmp:
        tmp.write_text(text)
