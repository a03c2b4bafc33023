"""`simucal derive`: regenerate generated/ from derive/, or check it is fresh."""
from __future__ import annotations

import json
import time
from pathlib import Path

from simucal.models import generated_dir


def run(check: bool = False, model_files=(), out_dir: Path | None = None) -> tuple[list[str], float]:
    """Derive and write (or compare). Returns (stale file names, seconds)."""
    from simucal.derive import codegen
    from simucal.derive.registry import BUILTIN, load_model_file

    t0 = time.perf_counter()
    out_dir = out_dir or generated_dir()
    old = out_dir / "manifest.json"
    files_known = json.loads(old.read_text()).get("model_files", []) if old.is_file() else []
    model_files = sorted(set(map(str, model_files)) | set(files_known))
    models = list(BUILTIN)
    for f in model_files:
        models += load_model_file(f)
    files = codegen.generate(models, model_files)
    if check:
        return codegen.stale(out_dir, files), time.perf_counter() - t0
    codegen.write(out_dir, files)
    return [], time.perf_counter() - t0
