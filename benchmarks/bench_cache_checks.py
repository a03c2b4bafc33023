"""Benchmark: what the cache's checks cost a command: the lookup of a built library
(the owner and mode of the cache, the library and its sha256 sidecar, the library's sha256)
against the bare existence test it replaced, and against the shortest process that loads a
model (the floor of every command that fits one).
Usage: python3 benchmarks/bench_cache_checks.py   (in a cache of its own: a few seconds)
"""
import os
import subprocess
import sys
import tempfile
import time
import timeit

if __name__ == "__main__":
    os.environ["SIMUCAL_CACHE"] = tempfile.mkdtemp(prefix="simucal-bench-cache-")
    from simucal.io import cache
    from simucal.fit.models import generated_dir
    from simucal.io.cache import compile_c

    lib = compile_c("acc_baseline", (generated_dir() / "acc_baseline.c").read_text())

    def best_us(f, n=2000):
        return min(timeit.repeat(f, number=n, repeat=5)) / n * 1e6

    checked, bare = best_us(lambda: cache.library(lib.name)), best_us(lib.is_file)
    hashed = best_us(lambda: cache.sha256_of(lib))
    walls = []
    for _ in range(5):
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", "from simucal.fit.models import load_builtin; "
                        "assert load_builtin('acc_baseline').backend == 'casadi-c'"], check=True)
        walls.append(time.perf_counter() - t)
    process = min(walls) * 1e6
    print("| library | checked lookup | of it the sha256 | bare lookup (before) | a process loading the model "
          "| the checks' share |\n"
          "|---|---|---|---|---|---|\n"
          f"| {lib.stat().st_size} B | {checked:.0f} us | {hashed:.0f} us | {bare:.1f} us | {process / 1e3:.0f} ms "
          f"| {checked / process:.2%} |")
