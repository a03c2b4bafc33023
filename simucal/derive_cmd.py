"""`simucal derive`: regenerate generated/ from derive/ (built-in models only), or
check it is fresh and show what differs."""
from __future__ import annotations

import difflib
import time
from pathlib import Path

from simucal import progress
from simucal.fit.models import generated_dir


def run(check: bool = False, out_dir: Path | None = None) -> tuple[list[str], float, str]:
    """Derive the built-in models and write (or compare). Returns (stale file names,
    seconds, a unified diff of the stale files, at most 60 lines)."""
    from simucal.derive import codegen
    from simucal.derive.registry import BUILTIN

    t0 = time.perf_counter()
    progress.status(f"deriving the {len(BUILTIN)} built-in models with SymPy and generating their code (seconds)")
    out_dir = out_dir or generated_dir()
    files = codegen.generate(list(BUILTIN))
    if check:
        stale = codegen.stale(out_dir, files)
        diff: list[str] = []
        for name in stale:
            path = out_dir / name
            old = path.read_text().splitlines(keepends=True) if path.is_file() else []
            diff += difflib.unified_diff(old, files.get(name, "").splitlines(keepends=True),
                                         f"generated/{name} (checked in)", f"generated/{name} (derived now)", n=1)
        return stale, time.perf_counter() - t0, "".join(diff[:60]) + ("...\n" if len(diff) > 60 else "")
    codegen.write(out_dir, files)
    return [], time.perf_counter() - t0, ""
