"""A user's own error models: derived into the cache, never into the package.

A model file (MODELS = [ErrorModel, ...], see README) is derived once with
SymPy by the same codegen as the built-in models, into

    <cache>/models/<key>/<name>.py, <name>.c, manifest.json

where <key> hashes the file's bytes and the simucal version, so an edited file
is derived afresh and an unchanged one is loaded without SymPy. An index
(<cache>/models/index.json) maps each model name to its key, so
`--acc-model NAME` finds a model derived earlier from any folder.
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import tempfile
from pathlib import Path

from .models import GeneratedModel, cache_dir, manifest


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
    from .models import load
    load.cache_clear()
    return names, derived


def load_user_model(name: str, compiled: bool = True) -> GeneratedModel:
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


def resolve_add(add, acc_model: str, gyro_model: str) -> tuple[str, str, tuple[str, ...]]:
    """What `--add` names: effect ids (checked; unknown ones refused) and model files
    (derived into the cache; each file's models replace the base model of their sensor).
    Returns (acc base model, gyro base model, effect ids)."""
    from .augmented import check_effect
    ids = []
    for a in add:
        if a.endswith(".py"):
            for name in derive_model_file(a)[0]:
                from .models import load
                if load(name).sensor == "acc":
                    acc_model = name
                else:
                    gyro_model = name
        else:
            check_effect(a)
            ids.append(a)
    return acc_model, gyro_model, tuple(dict.fromkeys(ids))
