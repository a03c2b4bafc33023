"""Every error model by name: the built-in ones in generated/, and a user's own,
derived into the cache, never into the package.

A model file (MODELS = [ErrorModel, ...], see README) is derived once with
SymPy by the same codegen as the built-in models, into

    <cache>/models/<key>/<name>.py, <name>.c, manifest.json

where <key> hashes the file's bytes and the simucal version, so an edited file
is derived afresh and an unchanged one is loaded without SymPy. An index
(<cache>/models/index.json) maps each model name to its key, so
`--acc-model NAME` finds a model derived earlier from any folder.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import tempfile
from pathlib import Path

from simucal.fit.models import GeneratedModel, cache_dir, load_builtin, manifest


def models_dir() -> Path:
    return cache_dir() / "models"


def _key(path: Path) -> str:
    from importlib.metadata import version
    h = hashlib.sha256(path.read_bytes())
    h.update(version("simucal").encode())
    h.update(json.dumps(manifest()["versions"], sort_keys=True).encode())
    return h.hexdigest()[:20]


def _index() -> dict:
    p = models_dir() / "index.json"
    return json.loads(p.read_text()) if p.is_file() else {}


def _write_atomic(path: Path, text: str):
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-")
    with os.fdopen(fd, "w") as fh:
        fh.write(text)
    os.replace(tmp, path)


def derive_model_file(path) -> tuple[list[str], bool]:
    """Derive a user's model file into the cache (if not there yet) and index its models.
    Returns (model names, whether SymPy had to derive them)."""
    path = Path(path).resolve()
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such model file")
    key = _key(path)
    folder = models_dir() / key
    derived = False
    if not (folder / "manifest.json").is_file():
        from simucal.derive import codegen
        from simucal.derive.registry import load_model_file
        models = load_model_file(path)
        builtin = set(manifest()["models"])
        clash = [m.name for m in models if m.name in builtin]
        if clash:
            raise ValueError(f"{path}: model names {clash} are built-in models; give your model another name")
        entries = {}
        for m in models:
            text, entry = codegen.model_module(m, source=str(path))
            _write_atomic(folder / f"{m.name}.py", text)
            _write_atomic(folder / f"{m.name}.c", codegen.c_source(m))
            entries[m.name] = entry
        _write_atomic(folder / "manifest.json",
                      json.dumps({"source": str(path), "models": entries}, indent=2, sort_keys=True) + "\n")
        derived = True
    names = sorted(json.loads((folder / "manifest.json").read_text())["models"])
    index = _index()
    index.update({n: {"key": key, "source": str(path)} for n in names})
    _write_atomic(models_dir() / "index.json", json.dumps(index, indent=2, sort_keys=True) + "\n")
    load.cache_clear()
    return names, derived


@functools.lru_cache(maxsize=None)
def load(name: str, compiled: bool = True) -> GeneratedModel:
    """A model by name: built-in (generated/) first, then the user models derived into the cache."""
    return load_builtin(name, compiled) or _load_user_model(name, compiled)


def _load_user_model(name: str, compiled: bool = True) -> GeneratedModel:
    entry = _index().get(name)
    if entry is None:
        raise KeyError(f"no model {name!r}: built-in models are {sorted(manifest()['models'])}; a model of your "
                       "own is derived from its file first (`--add FILE`, or `simucal derive --model FILE`)")
    folder = models_dir() / entry["key"]
    py = folder / f"{name}.py"
    if not py.is_file():
        raise KeyError(f"model {name!r} was derived from {entry['source']} but its cache {folder} is gone; "
                       f"derive it again: simucal derive --model {entry['source']}")
    spec = importlib.util.spec_from_file_location(f"simucal_user_model_{name}_{entry['key']}", py)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return GeneratedModel(name, module, (folder / f"{name}.c").read_text(), compiled)
