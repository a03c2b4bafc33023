"""The cache simucal builds into (compiled libraries, derived user models, their index):
~/.cache/simucal, or SIMUCAL_CACHE; and a lab's read-only shared one, SIMUCAL_TRUSTED_CACHE.

What is loaded from a cache runs as the user (a library through ctypes, a derived model as a
Python module), so whoever can write a cache runs code as every user of it. As ssh does with
its keys, nothing is loaded from a folder or file that is not the user's (for the trusted
cache: root's or the user's) or that group or others may write; the user's cache is created
with mode 0700; and a library is loaded only while its bytes have the sha256 recorded at its
build (a sidecar <library>.sha256), so a library changed after its build is rebuilt, not run.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import threading
import warnings
from pathlib import Path

from simucal.errors import CacheWarning, CalibrationError
from simucal.io.outputs import OutputError, write_text

SHARED_MODE = 0o022  # the group's and others' write bits: a file with either may have been written by another user


class UntrustedCache(CalibrationError):
    """A cache folder or file another user could have written: nothing is loaded from it."""


def cache_dir() -> Path:
    """The user's cache: SIMUCAL_CACHE, else $XDG_CACHE_HOME/simucal or ~/.cache/simucal."""
    root = os.environ.get("SIMUCAL_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "simucal")
    return Path(root)


def check_outside(inputs) -> None:
    """Refuse a cache inside an input (compiled libraries are written into it at first use): simucal never
    writes into a user's data."""
    cache = cache_dir().resolve()
    for given in inputs:
        if given and (cache == Path(given).resolve() or Path(given).resolve() in cache.parents):
            raise OutputError(f"SIMUCAL_CACHE={cache_dir()} lies inside the input {given}: simucal would write its "
                              "compiled libraries into your data; set SIMUCAL_CACHE to a folder outside it (or unset "
                              "it for ~/.cache/simucal)")


def trusted_cache_dir() -> Path | None:
    """SIMUCAL_TRUSTED_CACHE: a cache a lab's administrator fills, read only (never written)."""
    root = os.environ.get("SIMUCAL_TRUSTED_CACHE")
    return Path(root) if root else None


def roots() -> list[tuple[Path, bool]]:
    """(cache, whether it is the shared trusted one), the user's own first."""
    trusted = trusted_cache_dir()
    return [(cache_dir(), False)] + ([(trusted, True)] if trusted is not None else [])


def check(path: Path, root: Path, shared: bool = False) -> None:
    """Raise UntrustedCache unless root, each folder below it down to path, and path itself
    belong to the user (shared: to root or the user) and none is writable by group or others."""
    if not hasattr(os, "getuid"):  # Windows: no owner ids or mode bits to check (its ACLs guard the profile)
        return
    owners = {os.getuid(), 0} if shared else {os.getuid()}
    rel = Path(path).relative_to(root).parts
    for p in [root] + [root.joinpath(*rel[:i + 1]) for i in range(len(rel))]:
        st = os.stat(p)
        mode = st.st_mode & 0o7777
        if st.st_uid not in owners:
            why = f"belongs to uid {st.st_uid}, not to you (uid {os.getuid()})" + (" or root" if shared else "")
        elif st.st_mode & SHARED_MODE:
            why = "is writable by group or others"
        else:
            continue
        var = "SIMUCAL_TRUSTED_CACHE" if shared else "SIMUCAL_CACHE"
        fix = f"chmod {'700' if p.is_dir() else 'go-w'} {p}, or " if st.st_uid in owners else ""
        raise UntrustedCache(f"{p} (mode {mode:04o}) {why}: simucal loads nothing from {var} {root} "
                             f"(another user could have put code there); {fix}set {var} to a folder of your own")


def own_folder(sub: str = "") -> Path:
    """The folder `sub` of the user's cache, made (mode 0700) where missing, and checked."""
    root = cache_dir()
    folder = root
    try:
        root.parent.mkdir(parents=True, exist_ok=True)
        for part in ("", *Path(sub).parts):
            folder = folder / part
            folder.mkdir(mode=0o700, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise UntrustedCache(f"{folder} is a file, not a folder: simucal's cache (SIMUCAL_CACHE, else "
                             f"~/.cache/simucal) is {root}; set SIMUCAL_CACHE to a folder of your own") from None
    check(folder, root)
    return folder


def locate(rel: str) -> Path | None:
    """`rel` in the user's cache, else in the trusted cache: the first that exists, checked
    (UntrustedCache where it or a folder above it is not the user's alone); None where none has it."""
    for root, shared in roots():
        path = root / rel
        if path.exists():
            check(path, root, shared)
            return path
    return None


def sha256_of(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def record(lib: Path) -> None:
    """Write the library's sha256 beside it, at its build."""
    write_text(sidecar(lib), sha256_of(lib) + "\n", mode=0o644)


def sidecar(lib: Path) -> Path:
    return lib.with_name(lib.name + ".sha256")


def library(rel: str) -> tuple[Path | None, str | None]:
    """A library built earlier, its folder and file checked (UntrustedCache otherwise): in the
    user's cache, else in the trusted one; with its bytes still those recorded at its build.
    Returns (the library or None, why one found was not taken: changed after its build)."""
    why = None
    for root, shared in roots():
        lib = root / rel
        if not lib.is_file():
            continue
        check(lib, root, shared)
        if not sidecar(lib).is_file():  # built before sha256s were recorded, or a build not finished
            continue
        check(sidecar(lib), root, shared)
        if sidecar(lib).read_text().strip() == sha256_of(lib):
            return lib, None
        why = (f"{lib} changed after its build (its sha256 is not the one recorded in {sidecar(lib).name}): "
               "not loaded, rebuilt")
    return None, why


# no -march=native: a cache may be shared by machines of other CPUs
CFLAGS = ("-O3", "-fno-math-errno", "-shared", "-fPIC")


def compiler() -> str | None:
    """The C compiler builds use, or None (none found, or SIMUCAL_NO_COMPILE set)."""
    if os.environ.get("SIMUCAL_NO_COMPILE"):
        return None
    return shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")


def compile_c(name: str, source: str, instead: str = "the numpy module") -> Path | None:
    """Build C (a model's or the table's generated C, the CSV parser's) into the user's cache, or take
    an earlier build (the user's cache, then SIMUCAL_TRUSTED_CACHE) whose bytes still have the sha256
    recorded at its build; None where no compiler works or the cache is not the user's alone (said in
    one line: `instead` runs). Processes and threads may build the same library at once: each
    compiles from its stdin (the same bytes, whatever the file names) into a file of its own and
    renames it into place."""
    cc = compiler()
    if cc is None:
        return None
    digest = hashlib.sha256((" ".join(CFLAGS) + "\n" + source).encode()).hexdigest()[:16]  # flags change the build
    try:
        lib, changed = library(f"{name}-{digest}.so")
        if lib is not None:
            return lib
        folder = own_folder()
    except UntrustedCache as e:
        warnings.warn(f"{e}; {instead} runs instead", CacheWarning)
        return None
    if changed:
        warnings.warn(changed, CacheWarning)
    lib = folder / f"{name}-{digest}.so"
    tmp = lib.with_suffix(f".{os.getpid()}-{threading.get_ident()}.tmp")
    base = [cc, *CFLAGS, "-x", "c", "-", "-o", str(tmp), "-lm"]
    res = subprocess.run(base + ["-fopenmp"], input=source, capture_output=True, text=True)  # batches over the cores
    if res.returncode != 0:
        res = subprocess.run(base, input=source, capture_output=True, text=True)
    if res.returncode != 0:
        warnings.warn(f"compiling {name}.c failed with {cc}; using {instead} instead:\n{res.stderr[-500:]}")
        tmp.unlink(missing_ok=True)
        return None
    os.chmod(tmp, 0o755)  # cc's mode less the umask: a umask of 002 would leave it writable by the group
    tmp.replace(lib)
    record(lib)
    write_text(lib.with_suffix(".c"), source, mode=0o644)  # kept beside the library: what it was built from
    return lib
