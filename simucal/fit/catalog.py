"""Every error model by name: the built-in ones in generated/, and a user's own,
derived into the cache, never into the package.

A model file (MODELS = [ErrorModel, ...], see README) is derived once with
SymPy by the same codegen as the built-in models, into

    <cache>/models/<key>/<name>.py, <name>.c, manifest.json

where <key> hashes the file's bytes and the simucal version, so an edited file
is derived afresh and an unchanged one is loaded without SymPy. An index
(<cache>/models/index.json) maps each model name to its key, so
`--acc-model NAME` finds a model derived earlier from any folder. A derived model is code
(a Python module, C): it is loaded only from a cache that is the user's alone, or from the
trusted cache (simucal.io.cache), and never by a bytecode file beside it.
"""
from __future__ import annotations

import fcntl
import functools
import hashlib
import json
import os
import re
import signal
import subprocess
import sys
import time
import traceback
import types
from pathlib import Path

from simucal.errors import InputError, SimucalError
from simucal.io import cache
from simucal.fit.aux_inputs import NOT_AUX_COLUMNS
from simucal.fit.models import GeneratedModel, load_builtin, manifest
from simucal.io import outputs


def models_dir() -> Path:
    return cache.cache_dir() / "models"


def _key(path: Path) -> str:
    from simucal.version import __version__  # not importlib.metadata's lookup: 7 ms a process
    h = hashlib.sha256(path.read_bytes())
    h.update(__version__.encode())
    h.update(json.dumps(manifest()["versions"], sort_keys=True).encode())
    return h.hexdigest()[:20]


def _index(own: bool = False) -> dict:
    """Model name -> {key, source}: the trusted cache's index overlaid by the user's (own: the
    user's alone), each checked (UntrustedCache where another user could have written it)."""
    index = {}
    for root, shared in reversed(cache.roots()[:1] if own else cache.roots()):
        p = root / "models" / "index.json"
        if p.is_file():
            cache.check(p, root, shared)
            index.update(json.loads(p.read_text()))
    return index


def _write_atomic(path: Path, text: str):
    """Into a folder cache.own_folder made: never writable by group or others."""
    outputs.write_text(path, text, mode=0o644)


class ModelFileError(SimucalError):
    """A user's model file that cannot be derived: its file and line named, never a simucal bug."""


def derive_timeout_s() -> float:
    return float(os.environ.get("SIMUCAL_DERIVE_TIMEOUT_S", "120"))


def derive_model_file(path) -> tuple[list[str], bool]:
    """Derive a user's model file into the cache (if not there yet) and index its models.
    Returns (model names, whether SymPy had to derive them).

    A model file is Python: its code runs when it is derived, as any plugin's does. It runs
    once, in a child process with a time limit (SIMUCAL_DERIVE_TIMEOUT_S, default 120 s);
    afterwards the cache is keyed by the file's bytes and the file is never run again."""
    if Path(path).is_symlink() and not Path(path).exists():  # resolve() would raise on a loop
        raise ModelFileError(f"{path}: a symbolic link that leads nowhere (a loop of links, or its target is "
                                "missing): give the model file itself")
    path = Path(path).resolve()
    if path.is_dir():
        raise ModelFileError(f"{path}: a folder, where a model file (Python with MODELS = [...]) is expected")
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    key = _key(path)
    cache.own_folder("models")  # the user's alone, or UntrustedCache: the fix named
    found = cache.locate(f"models/{key}/manifest.json")
    derived = found is None
    if found is None:
        folder = cache.own_folder(f"models/{key}")
        found = folder / "manifest.json"
        child = _run_child(path, folder, derive_timeout_s())
        if child.returncode:
            lines = [x for x in child.stderr.splitlines() if x.strip()]
            raise ModelFileError(lines[-1] if child.returncode == 2 and lines else
                                 f"{path}: deriving it failed (exit {child.returncode}): "
                                 + (lines[-1] if lines else "no message"))
        if not found.is_file():  # the file ended the child itself (sys.exit, os._exit)
            raise ModelFileError(f"{path}: running it ended the process before any model was derived (sys.exit or "
                                 "os._exit in the file?); a model file defines MODELS and returns")
    names = sorted(json.loads(found.read_text())["models"])
    _add_to_index({n: {"key": key, "source": str(path)} for n in names})
    _load.cache_clear()  # load's kept models (load.cache_clear)
    return names, derived


def _add_to_index(entries: dict) -> None:
    """The user's index.json with entries added: read, changed and written by one process at a time (an
    exclusive lock on models/index.lock), since two deriving at once (Dask workers sharing a cache) each
    wrote back what it read and one lost the other's entry."""
    fd = os.open(models_dir() / "index.lock", os.O_RDWR | os.O_CREAT, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        index = _index(own=True)
        index.update(entries)
        _write_atomic(models_dir() / "index.json", json.dumps(index, indent=2, sort_keys=True) + "\n")
    finally:
        os.close(fd)  # closing releases the lock


def _run_child(path: Path, folder: Path, limit: float) -> subprocess.CompletedProcess:
    """Run the model file and derive it in a child process, said at once with its limit and followed
    by its seconds (progress.Wait); killed, and refused, at the limit."""
    from simucal.progress import Wait
    wait = Wait(f"deriving {path} with SymPy: its code runs once, in a child process, for at most {limit:g} s "
                "(SIMUCAL_DERIVE_TIMEOUT_S)", limit, f"deriving {path.name}")
    start = time.monotonic()
    try:
        with subprocess.Popen([sys.executable, "-m", "simucal.fit.catalog", str(path), str(folder)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as child:
            while True:
                left = limit - (time.monotonic() - start)
                try:
                    out, err = child.communicate(timeout=max(min(wait.step_s, left), 0.01))
                    return subprocess.CompletedProcess(child.args, child.returncode, out, err)
                except subprocess.TimeoutExpired:
                    if left <= wait.step_s:
                        raise ModelFileError(_timed_out(child, path, limit)) from None
                    wait.tick(time.monotonic() - start)
    finally:
        wait.close()


def _timed_out(child: subprocess.Popen, path: Path, limit: float) -> str:
    """Kill the child at its time limit, and say where it was: the line of the file it was running (its stack,
    which _child_main's faulthandler writes on SIGUSR1), else that it was not in the file's own code."""
    child.send_signal(signal.SIGUSR1)
    try:
        child.communicate(timeout=1.0)  # the stack written meanwhile; the child, looping, does not end
    except subprocess.TimeoutExpired:
        pass
    child.kill()
    stack = child.communicate()[1] or ""
    line = re.search(rf'File "{re.escape(str(path))}", line (\d+)', stack)  # the deepest frame first
    if line:
        return (f"{path}, line {line.group(1)}: deriving it took more than {limit:g} s, still at this line (a loop "
                "that never ends?); fix the file, or allow more time with SIMUCAL_DERIVE_TIMEOUT_S")
    return (f"{path}: deriving it took more than {limit:g} s, in SymPy's import or derivation (not in the file's own "
            "lines); allow more time with SIMUCAL_DERIVE_TIMEOUT_S, or give fewer or simpler terms")


def _derive_into(path: Path, folder: Path) -> None:
    """The child's work: run the model file, derive its models, write them into the cache folder
    (the manifest last, so a folder without one is never taken for a derived model)."""
    from simucal.derive import codegen
    from simucal.derive.registry import load_model_file
    models = load_model_file(path)
    builtin = set(manifest()["models"])
    clash = [m.name for m in models if m.name in builtin]
    if clash:
        raise InputError(f"{path}: model names {clash} are built-in models; give your model another name")
    for m in models:
        outputs_read = sorted({str(s) for s in m.aux} & set(NOT_AUX_COLUMNS))
        if outputs_read:
            raise InputError(f"{path}: model {m.name} reads {', '.join(outputs_read)} as an auxiliary input, but "
                             f"{outputs_read[0]} is a spec sensor column of samples.csv (the raw outputs the model "
                             "maps, or the segment id), which cannot be an auxiliary input; give the input a column "
                             f"of its own (column_input('{outputs_read[0]}_aux', ...) and that column in samples.csv)")
    entries = {}
    for m in models:
        text, entry = codegen.model_module(m, source=str(path))
        _write_atomic(folder / f"{m.name}.py", text)
        _write_atomic(folder / f"{m.name}.c", codegen.c_source(m))
        entries[m.name] = entry
    _write_atomic(folder / "manifest.json",
                  json.dumps({"source": str(path), "models": entries}, indent=2, sort_keys=True) + "\n")


def _where_in(path: Path, e: BaseException) -> str:
    """'FILE, line N' of the deepest frame of the traceback inside the user's file."""
    if isinstance(e, SyntaxError) and e.filename and Path(e.filename).resolve() == path:
        return f"{path}, line {e.lineno}"
    lines = [fr.lineno for fr in traceback.extract_tb(e.__traceback__) if Path(fr.filename).resolve() == path]
    return f"{path}, line {lines[-1]}" if lines else str(path)


def _recursion(path: Path, e: RecursionError) -> str:
    """The line of a RecursionError: where the file runs its own module code again (it includes itself: exec of its
    own text, runpy or load_model_file of its own path), that loop named; else the file's line and the error."""
    frames = [fr for fr in traceback.extract_tb(e.__traceback__) if fr.name == "<module>"]
    again = [fr.lineno for fr in frames if Path(fr.filename).resolve() == path]
    if again and len(again) + sum(fr.filename == "<string>" for fr in frames) > 1:  # exec's text is "<string>"
        return (f"{path}, line {again[0]}: the file runs itself (line {again[0]} runs {path.name} again, which runs "
                f"line {again[0]} again: a loop without end); a model file defines MODELS once: remove that line")
    return f"{_where_in(path, e)}: RecursionError: {e}"


def _child_main(argv) -> int:
    import faulthandler
    faulthandler.register(signal.SIGUSR1, file=sys.stderr, all_threads=False)  # the stack, at the time limit
    path, folder = Path(argv[0]).resolve(), Path(argv[1])
    try:
        _derive_into(path, folder)
    except SyntaxError as e:
        print(f"{_where_in(path, e)}: syntax error: {e.msg}", file=sys.stderr)
        return 2
    except RecursionError as e:
        print(_recursion(path, e), file=sys.stderr)
        return 2
    except Exception as e:  # the user's code raised: name its file and line, and the message
        own = str(e).startswith(str(path))  # simucal's own checks of the file name it already
        print(str(e) if own else f"{_where_in(path, e)}: {type(e).__name__}: {e}", file=sys.stderr)
        return 2
    return 0


def load(name: str, compiled: bool = True) -> GeneratedModel:
    """A model by name: built-in (generated/) first, then the user models derived into the cache. Kept
    per cache folder: a model loaded from one cache is never handed out for another's name, whose checks
    (cache.py) have not been made."""
    return _load(name, compiled, str(cache.cache_dir()), os.environ.get("SIMUCAL_TRUSTED_CACHE"))


@functools.lru_cache(maxsize=None)
def _load(name: str, compiled: bool, cache_folder: str, trusted_folder: str | None) -> GeneratedModel:
    return load_builtin(name, compiled) or _load_user_model(name, compiled)


load.cache_clear = _load.cache_clear  # type: ignore[attr-defined]  # callers that change a cache drop the kept ones


def _load_user_model(name: str, compiled: bool = True) -> GeneratedModel:
    entry = _index().get(name)
    if entry is None:
        raise InputError(f"no model {name!r}: built-in models are {sorted(manifest()['models'])}; a model of your "
                       "own is derived from its file first (`--add FILE`, or `simucal derive --model FILE`)")
    py, c = (cache.locate(f"models/{entry['key']}/{name}.{ext}") for ext in ("py", "c"))
    if py is None or c is None:
        raise InputError(f"model {name!r} was derived from {entry['source']} but its cache "
                         f"{models_dir() / entry['key']} is gone; derive it again: "
                         f"simucal derive --model {entry['source']}")
    # compiled from the checked source here: an import would also load a bytecode file from a __pycache__
    # folder beside it, which the umask may have left writable by the group
    module = types.ModuleType(f"simucal_user_model_{name}_{entry['key']}")
    module.__file__ = str(py)
    exec(compile(py.read_bytes(), str(py), "exec"), module.__dict__)
    return GeneratedModel(name, module, c.read_text(), compiled)


if __name__ == "__main__":  # the child of derive_model_file
    sys.exit(_child_main(sys.argv[1:]))
